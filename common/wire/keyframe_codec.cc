#include "common/wire/keyframe_codec.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <opencv2/core.hpp>
#include <stdexcept>

#include "common/core/agent_name.h"

namespace ag {
namespace {

// LCM carries bytes; float32/float16 payloads are little-endian by the
// schema. Every target we build for (x86-64, ARM64) is little-endian; refuse
// to build elsewhere rather than send garbage.
static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "wire codec assumes little-endian");

int8_t EncodingConstant(ArrayEncoding e) {
  switch (e) {
    case ArrayEncoding::kFloat32:
      return aglcm::quantized_array_t::FLOAT32;
    case ArrayEncoding::kFloat16:
      return aglcm::quantized_array_t::FLOAT16;
    case ArrayEncoding::kInt8:
      return aglcm::quantized_array_t::INT8;
    case ArrayEncoding::kBits4:
      return aglcm::quantized_array_t::BITS;
  }
  return aglcm::quantized_array_t::FLOAT32;
}

int64_t ExpectedBytes(int8_t encoding, int bits, int64_t count, int64_t dim) {
  const int64_t values = count * dim;
  switch (encoding) {
    case aglcm::quantized_array_t::FLOAT32:
      return values * 4;
    case aglcm::quantized_array_t::FLOAT16:
      return values * 2;
    case aglcm::quantized_array_t::INT8:
      return values;
    case aglcm::quantized_array_t::BITS:
      return count * ((dim * bits + 7) / 8);
    default:
      return -1;
  }
}

}  // namespace

aglcm::quantized_array_t QuantizeArray(const cv::Mat& values, ArrayEncoding encoding) {
  CV_Assert(values.empty() || values.type() == CV_32F);
  aglcm::quantized_array_t out;
  out.encoding = EncodingConstant(encoding);
  out.count = values.rows;
  out.dim = values.cols;
  out.num_scales = 0;
  out.num_offsets = 0;
  const cv::Mat v = values.isContinuous() ? values : values.clone();
  switch (encoding) {
    case ArrayEncoding::kFloat32: {
      out.bits = 32;
      out.data.resize(v.total() * 4);
      if (!v.empty()) std::memcpy(out.data.data(), v.ptr<float>(), out.data.size());
      break;
    }
    case ArrayEncoding::kFloat16: {
      out.bits = 16;
      cv::Mat half;
      if (!v.empty()) v.convertTo(half, CV_16F);
      out.data.resize(v.total() * 2);
      if (!v.empty()) std::memcpy(out.data.data(), half.ptr(), out.data.size());
      break;
    }
    case ArrayEncoding::kInt8: {
      // One scale per vector: unit descriptors differ in their largest entry.
      out.bits = 8;
      out.num_scales = v.rows;
      out.scales.resize(v.rows);
      out.data.resize(v.total());
      for (int r = 0; r < v.rows; ++r) {
        const float* row = v.ptr<float>(r);
        float max_abs = 0;
        for (int c = 0; c < v.cols; ++c) max_abs = std::max(max_abs, std::abs(row[c]));
        const float scale = max_abs > 0 ? max_abs / 127.0f : 1.0f;
        out.scales[r] = scale;
        for (int c = 0; c < v.cols; ++c) {
          const long code = std::lround(row[c] / scale);
          out.data[static_cast<size_t>(r) * v.cols + c] =
              static_cast<uint8_t>(static_cast<int8_t>(std::clamp<long>(code, -127, 127)));
        }
      }
      break;
    }
    case ArrayEncoding::kBits4: {
      // value = offset + code * scale, code in 0..15, two codes per byte,
      // the first value in the low nibble.
      out.bits = 4;
      out.num_scales = out.num_offsets = v.rows;
      out.scales.resize(v.rows);
      out.offsets.resize(v.rows);
      const int row_bytes = (v.cols * 4 + 7) / 8;
      out.data.assign(static_cast<size_t>(v.rows) * row_bytes, 0);
      for (int r = 0; r < v.rows; ++r) {
        const float* row = v.ptr<float>(r);
        float lo = row[0], hi = row[0];
        for (int c = 1; c < v.cols; ++c) {
          lo = std::min(lo, row[c]);
          hi = std::max(hi, row[c]);
        }
        const float scale = hi > lo ? (hi - lo) / 15.0f : 1.0f;
        out.scales[r] = scale;
        out.offsets[r] = lo;
        uint8_t* dst = out.data.data() + static_cast<size_t>(r) * row_bytes;
        for (int c = 0; c < v.cols; ++c) {
          const long code = std::clamp<long>(std::lround((row[c] - lo) / scale), 0, 15);
          dst[c / 2] |= static_cast<uint8_t>(code << ((c % 2) * 4));
        }
      }
      break;
    }
  }
  out.num_bytes = static_cast<int32_t>(out.data.size());
  return out;
}

bool DequantizeArray(const aglcm::quantized_array_t& a, cv::Mat* values, std::string* error) {
  auto fail = [&](const std::string& what) {
    *error = what;
    return false;
  };
  if (a.count < 0 || a.dim < 0) return fail("negative count or dim");
  if (a.count > 0 && a.dim > 4096) return fail("dim " + std::to_string(a.dim) + " is implausible");
  int expected_bits = 0;
  switch (a.encoding) {
    case aglcm::quantized_array_t::FLOAT32:
      expected_bits = 32;
      break;
    case aglcm::quantized_array_t::FLOAT16:
      expected_bits = 16;
      break;
    case aglcm::quantized_array_t::INT8:
      expected_bits = 8;
      break;
    case aglcm::quantized_array_t::BITS:
      if (a.bits < 1 || a.bits > 8)
        return fail("BITS encoding with bits = " + std::to_string(a.bits));
      // NOLINTNEXTLINE(bugprone-signed-char-misuse): an int8_t count, not a character
      expected_bits = a.bits;
      break;
    default:
      return fail("unknown encoding " + std::to_string(a.encoding));
  }
  if (a.bits != expected_bits) {
    return fail("bits = " + std::to_string(a.bits) + " does not match the encoding");
  }
  const int64_t expected = ExpectedBytes(a.encoding, a.bits, a.count, a.dim);
  if (a.num_bytes != static_cast<int64_t>(a.data.size()) || a.num_bytes != expected) {
    return fail("data holds " + std::to_string(a.data.size()) + " bytes, expected " +
                std::to_string(expected) + " for " + std::to_string(a.count) + " x " +
                std::to_string(a.dim));
  }
  const bool needs_scales =
      a.encoding == aglcm::quantized_array_t::INT8 || a.encoding == aglcm::quantized_array_t::BITS;
  if (needs_scales ? (a.num_scales != 1 && a.num_scales != a.count) : a.num_scales != 0) {
    return fail("num_scales = " + std::to_string(a.num_scales) + " for count " +
                std::to_string(a.count));
  }
  const bool needs_offsets = a.encoding == aglcm::quantized_array_t::BITS;
  if (needs_offsets ? (a.num_offsets != 1 && a.num_offsets != a.count) : a.num_offsets != 0) {
    return fail("num_offsets = " + std::to_string(a.num_offsets) + " for count " +
                std::to_string(a.count));
  }
  if (static_cast<int64_t>(a.scales.size()) != a.num_scales ||
      static_cast<int64_t>(a.offsets.size()) != a.num_offsets) {
    return fail("scale/offset arrays do not match their counts");
  }
  for (float s : a.scales) {
    if (!std::isfinite(s)) return fail("non-finite scale");
  }
  for (float o : a.offsets) {
    if (!std::isfinite(o)) return fail("non-finite offset");
  }
  cv::Mat out(a.count, a.dim, CV_32F);
  switch (a.encoding) {
    case aglcm::quantized_array_t::FLOAT32:
      if (!out.empty()) std::memcpy(out.ptr<float>(), a.data.data(), a.data.size());
      break;
    case aglcm::quantized_array_t::FLOAT16: {
      if (out.empty()) break;
      const cv::Mat half(a.count, a.dim, CV_16F, const_cast<uint8_t*>(a.data.data()));
      half.convertTo(out, CV_32F);
      break;
    }
    case aglcm::quantized_array_t::INT8:
      for (int r = 0; r < a.count; ++r) {
        const float scale = a.scales[a.num_scales == 1 ? 0 : r];
        float* dst = out.ptr<float>(r);
        for (int c = 0; c < a.dim; ++c) {
          dst[c] = scale * static_cast<int8_t>(a.data[static_cast<size_t>(r) * a.dim + c]);
        }
      }
      break;
    case aglcm::quantized_array_t::BITS: {
      const int row_bytes = (a.dim * a.bits + 7) / 8;
      const uint32_t mask = (1u << a.bits) - 1u;
      for (int r = 0; r < a.count; ++r) {
        const float scale = a.scales[a.num_scales == 1 ? 0 : r];
        const float offset = a.offsets[a.num_offsets == 1 ? 0 : r];
        const uint8_t* src = a.data.data() + static_cast<size_t>(r) * row_bytes;
        float* dst = out.ptr<float>(r);
        for (int c = 0; c < a.dim; ++c) {
          // Little-endian bit order: value c occupies bits [c*bits, (c+1)*bits).
          const int bit = c * a.bits;
          uint32_t word = src[bit / 8];
          if (bit / 8 + 1 < row_bytes) word |= static_cast<uint32_t>(src[bit / 8 + 1]) << 8;
          dst[c] = offset + scale * static_cast<float>((word >> (bit % 8)) & mask);
        }
      }
      break;
    }
  }
  if (cv::checkRange(out, true) == false) return fail("non-finite value");
  *values = out;
  return true;
}

namespace {

/// Whether part `part` of `num_parts` carries the global descriptor: the first
/// and the last, so that a keyframe stays retrievable unless both are lost.
bool CarriesGlobal(int part, int num_parts) { return part == 0 || part == num_parts - 1; }

/// One packet with keypoints [first, first + count) of `kf`, as part `part`
/// of `num_parts`.
aglcm::air_keyframe_t EncodePart(const AirKeyframe& kf, const PacketFormat& format, int first,
                                 int count, int part, int num_parts) {
  aglcm::air_keyframe_t p;
  p.agent = kf.agent;
  p.seq = kf.seq;
  p.part = static_cast<int16_t>(part);
  p.num_parts = static_cast<int16_t>(num_parts);
  p.t_ns = kf.t_ns;
  p.camera_id = kf.camera_id;
  const Eigen::Vector3d t = kf.T_wa_c.translation();
  const Eigen::Quaterniond q(kf.T_wa_c.linear());
  for (int i = 0; i < 3; ++i) p.position[i] = t[i];
  p.orientation[0] = q.w();
  p.orientation[1] = q.x();
  p.orientation[2] = q.y();
  p.orientation[3] = q.z();
  p.descriptor_type = kf.features.descriptor_type;
  const cv::Mat global = CarriesGlobal(part, num_parts)
                             ? cv::Mat(1, static_cast<int>(kf.global_descriptor.size()), CV_32F,
                                       const_cast<float*>(kf.global_descriptor.data()))
                             : cv::Mat(0, 0, CV_32F);
  p.global_descriptor = QuantizeArray(global, format.global);

  const int n = count;
  float max_coord = 1.0f;
  for (int i = first; i < first + n; ++i) {
    max_coord = std::max({max_coord, std::abs(kf.features.keypoints[i].x()),
                          std::abs(kf.features.keypoints[i].y())});
  }
  int frac_bits = 0;
  while (frac_bits < 15 && max_coord * static_cast<float>(1 << (frac_bits + 1)) <= 32767.0f) {
    ++frac_bits;
  }
  p.num_keypoints = n;
  p.keypoint_frac_bits = static_cast<int8_t>(frac_bits);
  p.kp_x.resize(n);
  p.kp_y.resize(n);
  const float unit = static_cast<float>(1 << frac_bits);
  for (int i = 0; i < n; ++i) {
    p.kp_x[i] = static_cast<int16_t>(std::lround(kf.features.keypoints[first + i].x() * unit));
    p.kp_y[i] = static_cast<int16_t>(std::lround(kf.features.keypoints[first + i].y() * unit));
  }
  const bool scores = format.scores && static_cast<int>(kf.features.scores.size()) >= first + n;
  p.num_scores = scores ? n : 0;
  p.scores.resize(p.num_scores);
  for (int i = 0; i < p.num_scores; ++i) {
    p.scores[i] = static_cast<uint8_t>(
        std::clamp<long>(std::lround(255.0f * kf.features.scores[first + i]), 0, 255));
  }
  const cv::Mat desc = kf.features.descriptors.empty() || n == 0
                           ? cv::Mat(0, 0, CV_32F)
                           : kf.features.descriptors.rowRange(first, first + n);
  p.descriptors = QuantizeArray(desc, format.descriptors);
  return p;
}

/// A keyframe of the given shape with zero content, for size computations.
AirKeyframe ShapeKeyframe(const std::string& agent, const std::string& camera_id,
                          const std::string& descriptor_type, int keypoints, int dim,
                          int global_dim) {
  AirKeyframe shape;
  shape.agent = agent;
  shape.camera_id = camera_id;
  shape.features.descriptor_type = descriptor_type;
  shape.features.keypoints.assign(keypoints, Eigen::Vector2f::Zero());
  shape.features.scores.assign(keypoints, 0.0f);
  shape.features.descriptors = cv::Mat::zeros(keypoints, dim, CV_32F);
  shape.global_descriptor.assign(global_dim, 0.0f);
  return shape;
}

int SentKeypoints(const AirKeyframe& kf, const PacketFormat& format) {
  return std::max(0, std::min<int>(format.max_keypoints, static_cast<int>(kf.features.size())));
}

}  // namespace

aglcm::air_keyframe_t EncodeKeyframe(const AirKeyframe& kf, const PacketFormat& format) {
  return EncodePart(kf, format, 0, SentKeypoints(kf, format), 0, 1);
}

int64_t EncodedKeyframeSize(const std::string& agent, const std::string& camera_id,
                            const std::string& descriptor_type, int keypoints, int dim,
                            int global_dim, const PacketFormat& format) {
  const AirKeyframe shape =
      ShapeKeyframe(agent, camera_id, descriptor_type, keypoints, dim, global_dim);
  return EncodePart(shape, format, 0, keypoints, 0, 1).getEncodedSize();
}

std::vector<int> PartKeypointCounts(int keypoints, const PartCapacity& capacity) {
  std::vector<int> counts{std::min(keypoints, capacity.first)};
  int left = keypoints - counts[0];
  // Middle parts leave at most `first` for the last part (it has the global
  // descriptor too).
  while (left > capacity.first && capacity.rest > 0) {
    counts.push_back(std::min(capacity.rest, left - capacity.first));
    left -= counts.back();
  }
  if (left > 0) counts.push_back(left);
  return counts;
}

PartCapacity FitPartCapacity(const std::string& agent, const std::string& camera_id,
                             const std::string& descriptor_type, int dim, int global_dim,
                             const PacketFormat& format, int max_keypoints,
                             const std::function<bool(int64_t)>& fits) {
  const AirKeyframe shape =
      ShapeKeyframe(agent, camera_id, descriptor_type, max_keypoints, dim, global_dim);
  // Largest k in [lo, max_keypoints] whose part fits (size grows with k).
  const auto largest = [&](bool with_global, int lo) {
    int hi = max_keypoints;
    while (lo < hi) {
      const int mid = lo + (hi - lo + 1) / 2;
      if (fits(EncodePart(shape, format, 0, mid, with_global ? 0 : 1, 3).getEncodedSize())) {
        lo = mid;
      } else {
        hi = mid - 1;
      }
    }
    return lo;
  };
  // Every part holds at least one keypoint: PartKeypointCounts fills the
  // middle parts only while more than `first` are left, so with first = 0
  // the last part (global descriptor included) would get a middle part's load.
  const int64_t first_min = EncodePart(shape, format, 0, 1, 0, 3).getEncodedSize();
  const int64_t rest_min = EncodePart(shape, format, 0, 1, 1, 3).getEncodedSize();
  if (!fits(first_min) || !fits(rest_min)) {
    throw std::invalid_argument("a keyframe part must hold at least " + std::to_string(first_min) +
                                " encoded bytes (pose, global descriptor and one keypoint) and " +
                                std::to_string(rest_min) + " (pose and one keypoint)");
  }
  return {largest(true, 1), largest(false, 1)};
}

std::vector<int64_t> EncodedPartSizes(const std::string& agent, const std::string& camera_id,
                                      const std::string& descriptor_type, int keypoints, int dim,
                                      int global_dim, const PacketFormat& format,
                                      const PartCapacity& capacity) {
  const std::vector<int> counts = PartKeypointCounts(keypoints, capacity);
  const int largest = *std::max_element(counts.begin(), counts.end());
  const AirKeyframe shape =
      ShapeKeyframe(agent, camera_id, descriptor_type, largest, dim, global_dim);
  std::vector<int64_t> sizes;
  for (size_t i = 0; i < counts.size(); ++i) {
    const int part = static_cast<int>(i);
    const int num_parts = static_cast<int>(counts.size());
    sizes.push_back(EncodePart(shape, format, 0, counts[i], part, num_parts).getEncodedSize());
  }
  return sizes;
}

std::vector<aglcm::air_keyframe_t> EncodeKeyframeParts(const AirKeyframe& kf,
                                                       const PacketFormat& format,
                                                       const PartCapacity& capacity) {
  const std::vector<int> counts = PartKeypointCounts(SentKeypoints(kf, format), capacity);
  if (counts.size() > static_cast<size_t>(std::numeric_limits<int16_t>::max())) {
    throw std::invalid_argument("keyframe would need " + std::to_string(counts.size()) +
                                " parts (at most 32767)");
  }
  std::vector<aglcm::air_keyframe_t> parts;
  int first = 0;
  for (size_t i = 0; i < counts.size(); ++i) {
    parts.push_back(EncodePart(kf, format, first, counts[i], static_cast<int>(i),
                               static_cast<int>(counts.size())));
    first += counts[i];
  }
  return parts;
}

DecodedKeyframe DecodeKeyframe(const aglcm::air_keyframe_t& p) {
  DecodedKeyframe out;
  auto fail = [&](const std::string& what) {
    out.error = "air keyframe from '" + p.agent + "' seq " + std::to_string(p.seq) + ": " + what;
    return out;
  };
  if (!IsValidAgentName(p.agent)) return fail("invalid agent name");
  if (p.num_parts < 1 || p.part < 0 || p.part >= p.num_parts) {
    return fail("part " + std::to_string(p.part) + " of " + std::to_string(p.num_parts) +
                " (need 0 <= part < num_parts)");
  }
  for (double v : p.position) {
    if (!std::isfinite(v)) return fail("non-finite camera position");
  }
  Eigen::Quaterniond q(p.orientation[0], p.orientation[1], p.orientation[2], p.orientation[3]);
  if (!q.coeffs().allFinite() || std::abs(q.norm() - 1.0) > 1e-3) {
    return fail("camera orientation is not a unit quaternion");
  }
  if (p.num_keypoints < 0 || static_cast<int>(p.kp_x.size()) != p.num_keypoints ||
      static_cast<int>(p.kp_y.size()) != p.num_keypoints) {
    return fail("keypoint arrays do not match num_keypoints");
  }
  if (p.keypoint_frac_bits < 0 || p.keypoint_frac_bits > 15) {
    return fail("keypoint_frac_bits " + std::to_string(p.keypoint_frac_bits) + " out of 0..15");
  }
  if (p.num_scores != 0 && p.num_scores != p.num_keypoints) {
    return fail("num_scores must be 0 or num_keypoints");
  }
  if (p.descriptor_type.empty()) return fail("empty descriptor_type");
  std::string error;
  cv::Mat descriptors, global;
  if (!DequantizeArray(p.descriptors, &descriptors, &error)) return fail("descriptors: " + error);
  if (descriptors.rows != p.num_keypoints) {
    return fail("descriptors hold " + std::to_string(descriptors.rows) + " vectors for " +
                std::to_string(p.num_keypoints) + " keypoints");
  }
  if (!DequantizeArray(p.global_descriptor, &global, &error))
    return fail("global descriptor: " + error);
  // Part 0 carries the global descriptor, the last part may repeat it.
  if ((p.part == 0 || !global.empty()) && (global.rows != 1 || global.cols == 0)) {
    return fail("global descriptor must be one vector");
  }
  if (p.part > 0 && p.part < p.num_parts - 1 && !global.empty()) {
    return fail("global descriptor in part " + std::to_string(p.part) + " of " +
                std::to_string(p.num_parts) + " (only the first and last have one)");
  }

  out.part = p.part;
  out.num_parts = p.num_parts;
  AirKeyframe& kf = out.keyframe;
  kf.agent = p.agent;
  kf.seq = p.seq;
  kf.t_ns = p.t_ns;
  kf.camera_id = p.camera_id;
  kf.T_wa_c = Pose::Identity();
  kf.T_wa_c.linear() = q.normalized().toRotationMatrix();
  kf.T_wa_c.translation() = Eigen::Vector3d(p.position[0], p.position[1], p.position[2]);
  kf.features.descriptor_type = p.descriptor_type;
  const float unit = 1.0f / static_cast<float>(1 << p.keypoint_frac_bits);
  kf.features.keypoints.resize(p.num_keypoints);
  for (int i = 0; i < p.num_keypoints; ++i) {
    kf.features.keypoints[i] = Eigen::Vector2f(p.kp_x[i] * unit, p.kp_y[i] * unit);
  }
  kf.features.scores.resize(p.num_scores);
  for (int i = 0; i < p.num_scores; ++i) kf.features.scores[i] = p.scores[i] / 255.0f;
  // Quantisation shortens or lengthens vectors slightly; matching assumes
  // unit rows. Rows already unit (float32) are left bit-exact.
  for (int r = 0; r < descriptors.rows; ++r) {
    cv::Mat row = descriptors.row(r);
    const double norm = cv::norm(row);
    if (norm > 0 && std::abs(norm - 1.0) > 1e-5) row /= norm;
  }
  kf.features.descriptors = descriptors;
  if (!global.empty()) {
    kf.global_descriptor.assign(global.ptr<float>(), global.ptr<float>() + global.cols);
  }
  const double gnorm = global.empty() ? 0.0 : cv::norm(global);
  if (gnorm > 0 && std::abs(gnorm - 1.0) > 1e-5) {
    for (float& v : kf.global_descriptor) v = static_cast<float>(v / gnorm);
  }
  out.ok = true;
  return out;
}

}  // namespace ag
