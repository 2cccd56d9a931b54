#include "ground_server/place_db/binary_io.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>

namespace ag::internal {

static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__,
              "place_db snapshots are little-endian; a big-endian port needs byte swapping");

namespace {

constexpr size_t kBufferSize = size_t{1} << 20;

constexpr std::array<uint32_t, 256> MakeCrcTable() {
  std::array<uint32_t, 256> table{};
  for (uint32_t i = 0; i < 256; ++i) {
    uint32_t c = i;
    for (int bit = 0; bit < 8; ++bit) c = (c & 1U) ? 0xEDB88320U ^ (c >> 1) : c >> 1;
    table[i] = c;
  }
  return table;
}

constexpr std::array<uint32_t, 256> kCrcTable = MakeCrcTable();

std::string ErrnoText() { return std::strerror(errno); }

}  // namespace

uint32_t Crc32(const void* data, size_t size, uint32_t crc) {
  const auto* bytes = static_cast<const unsigned char*>(data);
  uint32_t c = ~crc;
  for (size_t i = 0; i < size; ++i) c = kCrcTable[(c ^ bytes[i]) & 0xFFU] ^ (c >> 8);
  return ~c;
}

// ---------------------------------------------------------------- FileWriter

FileWriter::FileWriter(std::string path) : path_(std::move(path)) {
  fd_ = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd_ < 0) throw std::runtime_error("cannot create " + path_ + ": " + ErrnoText());
  buffer_.reserve(kBufferSize);
}

FileWriter::~FileWriter() {
  if (fd_ >= 0) ::close(fd_);
}

void FileWriter::Write(const void* data, size_t size) {
  crc_ = Crc32(data, size, crc_);
  size_ += size;
  const char* bytes = static_cast<const char*>(data);
  if (buffer_.size() + size > kBufferSize) Flush();
  if (size >= kBufferSize) {
    WriteAll(bytes, size);  // large blobs skip the buffer
    return;
  }
  buffer_.insert(buffer_.end(), bytes, bytes + size);
}

void FileWriter::String(const std::string& s) {
  Pod(static_cast<uint32_t>(s.size()));
  Write(s.data(), s.size());
}

void FileWriter::WriteCrc() {
  const uint32_t crc = crc_;
  Pod(crc);
}

void FileWriter::Flush() {
  WriteAll(buffer_.data(), buffer_.size());
  buffer_.clear();
}

void FileWriter::WriteAll(const char* data, size_t size) {
  size_t done = 0;
  while (done < size) {
    const ssize_t n = ::write(fd_, data + done, size - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) throw std::runtime_error("cannot write " + path_ + ": " + ErrnoText());
    done += static_cast<size_t>(n);
  }
}

void FileWriter::Close() {
  Flush();
  if (::fsync(fd_) != 0) throw std::runtime_error("cannot fsync " + path_ + ": " + ErrnoText());
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) throw std::runtime_error("cannot close " + path_ + ": " + ErrnoText());
}

// ---------------------------------------------------------------- FileReader

FileReader::FileReader(std::string path) : path_(std::move(path)) {
  fd_ = ::open(path_.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd_ < 0) throw SnapshotReadError(path_, "cannot open: " + ErrnoText(), true);
  struct stat st {};
  if (::fstat(fd_, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd_);
    fd_ = -1;
    throw SnapshotReadError(path_, "not a regular file", true);
  }
  size_ = static_cast<uint64_t>(st.st_size);
  buffer_.resize(kBufferSize);
}

FileReader::~FileReader() {
  if (fd_ >= 0) ::close(fd_);
}

void FileReader::Fail(const std::string& problem) const {
  throw SnapshotReadError(path_, problem + " (at byte " + std::to_string(offset_) + " of " +
                                     std::to_string(size_) + ")");
}

void FileReader::Read(void* out, size_t size) {
  if (size > Remaining()) {
    Fail("truncated: needs " + std::to_string(size) + " more bytes, only " +
         std::to_string(Remaining()) + " remain");
  }
  char* dst = static_cast<char*>(out);
  size_t done = 0;
  while (done < size) {
    if (buffer_begin_ == buffer_end_) {
      ssize_t n = 0;
      do {
        n = ::read(fd_, buffer_.data(), buffer_.size());
      } while (n < 0 && errno == EINTR);
      if (n <= 0) Fail(n < 0 ? "read error: " + ErrnoText() : "file shrank while reading");
      buffer_begin_ = 0;
      buffer_end_ = static_cast<size_t>(n);
    }
    const size_t take = std::min(size - done, buffer_end_ - buffer_begin_);
    std::memcpy(dst + done, buffer_.data() + buffer_begin_, take);
    buffer_begin_ += take;
    done += take;
  }
  crc_ = Crc32(out, size, crc_);
  offset_ += size;
}

std::string FileReader::String(size_t max_size) {
  const auto size = Pod<uint32_t>();
  if (size > max_size || size > Remaining()) {
    Fail("corrupt string length " + std::to_string(size));
  }
  std::string s(size, '\0');
  Read(s.data(), size);
  return s;
}

uint32_t FileReader::Count(size_t element_size) {
  const auto count = Pod<uint32_t>();
  if (element_size > 0 && count > Remaining() / element_size) {
    Fail("corrupt element count " + std::to_string(count) + " (file too short for it)");
  }
  return count;
}

void FileReader::ExpectCrc() {
  const uint32_t computed = crc_;
  const auto stored = Pod<uint32_t>();
  if (stored != computed) {
    char text[96];
    std::snprintf(text, sizeof(text), "checksum mismatch: stored CRC-32 %08x, computed %08x",
                  stored, computed);
    Fail(std::string(text) + "; the file is corrupt");
  }
}

void FileReader::ExpectEnd() {
  if (Remaining() != 0) Fail(std::to_string(Remaining()) + " unexpected trailing bytes");
}

// ---------------------------------------------------------------- helpers

FileDigest DigestFile(const std::string& path) {
  FileReader reader(path);
  std::vector<char> chunk(kBufferSize);
  while (reader.Remaining() > 0) {
    reader.Read(chunk.data(),
                static_cast<size_t>(std::min<uint64_t>(chunk.size(), reader.Remaining())));
  }
  return {reader.Size(), reader.Crc()};
}

void SyncPath(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw std::runtime_error("cannot open " + path + " to fsync: " + ErrnoText());
  const int rc = ::fsync(fd);
  const std::string error = rc != 0 ? ErrnoText() : "";
  ::close(fd);
  if (rc != 0) throw std::runtime_error("cannot fsync " + path + ": " + error);
}

}  // namespace ag::internal
