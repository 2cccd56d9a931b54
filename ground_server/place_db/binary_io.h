#pragma once

// Checked binary files for the place database snapshot (internal).
//
// The snapshot files are written in host byte order; every target this
// project builds for (x86-64, ARM64) is little-endian, which the .cc asserts.
// Readers never trust a length read from a file: every count is checked
// against the bytes that remain before anything is allocated, so a truncated
// or corrupt file is reported, not turned into a huge allocation or a crash.

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

namespace ag::internal {

/// CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320, the one zlib and
/// PNG use). Pass the previous value as `crc` to continue a running checksum;
/// Crc32("123456789") == 0xCBF43926.
uint32_t Crc32(const void* data, size_t size, uint32_t crc = 0);

/// A problem reading a snapshot file. `missing` distinguishes "cannot open"
/// from "opened but the content is wrong" (truncated, corrupt, unsupported).
class SnapshotReadError : public std::runtime_error {
 public:
  SnapshotReadError(std::string file, const std::string& problem, bool missing = false)
      : std::runtime_error(problem), file_(std::move(file)), missing_(missing) {}
  const std::string& File() const { return file_; }
  bool Missing() const { return missing_; }

 private:
  std::string file_;
  bool missing_;
};

/// Writes a new file (fails if it exists) through a buffer, keeping the size
/// and a running CRC-32 of everything written. Close() flushes, fsyncs and
/// closes; any failure (disk full, I/O error) throws std::runtime_error naming
/// the file. The destructor closes without syncing (after an error).
class FileWriter {
 public:
  explicit FileWriter(std::string path);
  ~FileWriter();
  FileWriter(const FileWriter&) = delete;
  FileWriter& operator=(const FileWriter&) = delete;

  void Write(const void* data, size_t size);
  template <class T>
  void Pod(const T& value) {
    static_assert(std::is_trivially_copyable_v<T>);
    Write(&value, sizeof(T));
  }
  /// u32 length, then the bytes.
  void String(const std::string& s);
  /// Writes the CRC-32 of everything written so far (it is not part of itself).
  void WriteCrc();
  void Close();

  uint64_t Size() const { return size_; }
  /// CRC-32 of everything written so far.
  uint32_t Crc() const { return crc_; }

 private:
  void Flush();
  void WriteAll(const char* data, size_t size);

  std::string path_;
  int fd_ = -1;
  std::vector<char> buffer_;
  uint64_t size_ = 0;
  uint32_t crc_ = 0;
};

/// Reads a file through a buffer, keeping the offset and a running CRC-32.
/// Every failure throws SnapshotReadError naming the file and byte offset.
class FileReader {
 public:
  explicit FileReader(std::string path);
  ~FileReader();
  FileReader(const FileReader&) = delete;
  FileReader& operator=(const FileReader&) = delete;

  void Read(void* out, size_t size);
  template <class T>
  T Pod() {
    static_assert(std::is_trivially_copyable_v<T>);
    T value;
    Read(&value, sizeof(T));
    return value;
  }
  /// Reads a u32 length and that many bytes; longer than `max_size` is corrupt.
  std::string String(size_t max_size);
  /// Reads a u32 element count, checked against the bytes that remain.
  uint32_t Count(size_t element_size);
  /// Reads the stored CRC-32 and compares it with the CRC of all bytes before it.
  void ExpectCrc();
  /// Throws unless the whole file has been read.
  void ExpectEnd();

  uint64_t Size() const { return size_; }
  uint64_t Offset() const { return offset_; }
  uint64_t Remaining() const { return size_ - offset_; }
  /// CRC-32 of everything read so far.
  uint32_t Crc() const { return crc_; }
  const std::string& Path() const { return path_; }
  [[noreturn]] void Fail(const std::string& problem) const;

 private:
  std::string path_;
  int fd_ = -1;
  uint64_t size_ = 0;
  uint64_t offset_ = 0;
  uint32_t crc_ = 0;
  std::vector<char> buffer_;
  size_t buffer_begin_ = 0;
  size_t buffer_end_ = 0;
};

/// Size and CRC-32 of a whole file (SnapshotReadError when it cannot be read).
struct FileDigest {
  uint64_t size = 0;
  uint32_t crc = 0;
};
FileDigest DigestFile(const std::string& path);

/// fsync of a file or directory, so a rename that follows is durable.
/// Throws std::runtime_error naming the path.
void SyncPath(const std::string& path);

}  // namespace ag::internal
