#pragma once

// Decoding LCM messages that arrive from a radio link, i.e. from untrusted
// bytes. lcm-gen 1.3.1's C++ decode() trusts the lengths written inside the
// buffer: a negative string or array length makes it throw std::length_error,
// and a large one makes it allocate and zero-fill that many elements (up to
// 16 GB for a double array) before it notices that the buffer is too short.
// DecodeChecked() first walks the shape of the buffer, checking every string
// and array length against the bytes that remain without allocating anything,
// and only then runs the generated decode().
//
// The walks below mirror the .lcm files field by field; when a message
// changes, its walk must change with it (tests/lcmtypes checks every message
// against its own encoder, so a stale walk fails the tests, not silently).

#include <cstdint>
#include <cstring>
#include <exception>

#include "lcmtypes/aglcm/air_keyframe_t.hpp"
#include "lcmtypes/aglcm/camera_info_t.hpp"
#include "lcmtypes/aglcm/image_t.hpp"
#include "lcmtypes/aglcm/odometry_t.hpp"
#include "lcmtypes/aglcm/point_cloud_t.hpp"
#include "lcmtypes/aglcm/quantized_array_t.hpp"
#include "lcmtypes/aglcm/relative_pose_t.hpp"

namespace ag {
namespace internal {

/// Steps through an LCM-encoded buffer (big-endian, as LCM writes it) without
/// ever reading or skipping past its end.
class LcmShapeScanner {
 public:
  LcmShapeScanner(const uint8_t* data, int64_t size) : data_(data), size_(size) {}

  /// Skips `n` bytes of fixed-size fields; false when fewer remain.
  bool Skip(int64_t n) {
    if (n < 0 || n > size_ - pos_) return false;
    pos_ += n;
    return true;
  }

  /// Reads a big-endian int32.
  bool Int32(int32_t* value) {
    if (size_ - pos_ < 4) return false;
    const uint8_t* p = data_ + pos_;
    *value = static_cast<int32_t>((uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) |
                                  (uint32_t{p[2]} << 8) | uint32_t{p[3]});
    pos_ += 4;
    return true;
  }

  /// Reads an array length field, which must not be negative.
  bool Count(int32_t* count) { return Int32(count) && *count >= 0; }

  /// Skips an array of `count` elements of `element_bytes` each.
  bool Array(int32_t count, int64_t element_bytes) { return Skip(count * element_bytes); }

  /// Skips an LCM string: an int32 length that counts the terminating NUL
  /// (so >= 1; decode() would throw on 0), then the characters and the NUL.
  /// LCM's encoder never writes a NUL inside the string, so one is damage.
  bool String() {
    int32_t length = 0;
    if (!Int32(&length) || length < 1 || length > size_ - pos_) return false;
    const uint8_t* chars = data_ + pos_;
    if (chars[length - 1] != 0 || std::memchr(chars, 0, length - 1) != nullptr) return false;
    pos_ += length;
    return true;
  }

  int64_t Position() const { return pos_; }

 private:
  const uint8_t* data_;
  int64_t size_;
  int64_t pos_ = 0;
};

// One walk per message, after the 8-byte fingerprint (nested messages have
// none). The pointer argument only selects the overload.

inline bool ScanBody(LcmShapeScanner& s, const aglcm::quantized_array_t* /*type*/) {
  int32_t n = 0;
  return s.Skip(1 + 4 + 4 + 1)             // encoding, count, dim, bits
         && s.Count(&n) && s.Array(n, 4)   // scales
         && s.Count(&n) && s.Array(n, 4)   // offsets
         && s.Count(&n) && s.Array(n, 1);  // data
}

inline bool ScanBody(LcmShapeScanner& s, const aglcm::air_keyframe_t* /*type*/) {
  const aglcm::quantized_array_t* quantized = nullptr;
  int32_t num_keypoints = 0;
  int32_t num_scores = 0;
  return s.String()                                                 // agent
         && s.Skip(8 + 2 + 2 + 8)                                   // seq, part, num_parts, t_ns
         && s.String()                                              // camera_id
         && s.Skip(3 * 8 + 4 * 8)                                   // position, orientation
         && s.String()                                              // descriptor_type
         && ScanBody(s, quantized)                                  // global_descriptor
         && s.Count(&num_keypoints) && s.Skip(1)                    // keypoint_frac_bits
         && s.Array(num_keypoints, 2) && s.Array(num_keypoints, 2)  // kp_x, kp_y
         && s.Count(&num_scores) && s.Array(num_scores, 1)          // scores
         && ScanBody(s, quantized);                                 // descriptors
}

inline bool ScanBody(LcmShapeScanner& s, const aglcm::camera_info_t* /*type*/) {
  int32_t n = 0;
  return s.String() && s.String()         // agent, camera_id
         && s.Skip(8)                     // t_ns
         && s.String()                    // model
         && s.Skip(4 + 4 + 4 * 8)         // width, height, intrinsics
         && s.Count(&n) && s.Array(n, 8)  // distortion
         && s.Skip(1 + 16 * 8 + 8);       // has_T_body_camera, T_body_camera, time_offset_s
}

inline bool ScanBody(LcmShapeScanner& s, const aglcm::relative_pose_t* /*type*/) {
  return s.String() && s.String()           // agent, ground_agent
         && s.Skip(4 * 8 + 1)               // seq, t_ns, air_t_ns, air_seq, status
         && s.String()                      // status_reason
         && s.Skip(4 * 8 + 16 * 8 + 16 * 8  // x, y, z, yaw, T_wa_wg, covariance
                   + 4 + 4 + 4 + 4 + 4);    // num_inliers .. solve_time_s
}

inline bool ScanBody(LcmShapeScanner& s, const aglcm::image_t* /*type*/) {
  int32_t n = 0;
  return s.Skip(8) && s.String()           // t_ns, frame_id
         && s.Skip(4 + 4) && s.String()    // width, height, encoding
         && s.Skip(4)                      // step
         && s.Count(&n) && s.Array(n, 1);  // data
}

inline bool ScanBody(LcmShapeScanner& s, const aglcm::odometry_t* /*type*/) {
  return s.Skip(8) && s.String() && s.String()  // t_ns, world_frame_id, body_frame_id
         && s.Skip(3 * 8 + 4 * 8)               // position, orientation
         && s.Skip(1 + 3 * 8 + 3 * 8)           // has_twist, velocities
         && s.Skip(1 + 36 * 8);                 // has_pose_covariance, pose_covariance
}

inline bool ScanBody(LcmShapeScanner& s, const aglcm::point_cloud_t* /*type*/) {
  int32_t n = 0;
  int32_t num_intensities = 0;
  return s.Skip(8) && s.String()                                            // t_ns, frame_id
         && s.Count(&n) && s.Array(n, 4) && s.Array(n, 4) && s.Array(n, 4)  // x, y, z
         && s.Count(&num_intensities) && s.Array(num_intensities, 4);       // intensity
}

}  // namespace internal

/// Decodes one LCM message of type `Msg` (an aglcm type) from untrusted bytes,
/// e.g. a packet off the radio link. Returns the number of bytes decoded, or
/// -1 when the bytes are not a well-formed `Msg`: another type's fingerprint,
/// truncated, or a negative or impossible string/array length. Never throws,
/// and never allocates more than the buffer itself could hold. `*msg` is
/// unspecified after a failure. Semantic checks (e.g. num_bytes matching the
/// encoding of a quantized_array_t) are the caller's.
template <class Msg>
int DecodeChecked(const void* data, int size, Msg* msg) noexcept {
  if (data == nullptr || size < 0) return -1;
  internal::LcmShapeScanner scanner(static_cast<const uint8_t*>(data), size);
  if (!scanner.Skip(8) || !internal::ScanBody(scanner, static_cast<const Msg*>(nullptr))) {
    return -1;
  }
  try {
    const int decoded = msg->decode(data, 0, size);  // checks the fingerprint
    // A walk that ends elsewhere than decode() means the walk lags the schema.
    return decoded == scanner.Position() ? decoded : -1;
  } catch (const std::exception&) {
    return -1;  // std::bad_alloc for a well-formed but huge message
  }
}

}  // namespace ag
