#pragma once

// The one place that converts between the core keyframe struct and the LCM
// air keyframe packet, with selectable quantisation. The ground decodes with
// the same code; everything else sees only ag::AirKeyframe.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "common/types/keyframe.h"
#include "common/wire/encoding.h"
#include "lcmtypes/aglcm/air_keyframe_t.hpp"
#include "lcmtypes/aglcm/quantized_array_t.hpp"

namespace ag {

/// How a keyframe is packed.
struct PacketFormat {
  int max_keypoints = 1024;                          ///< the best-scored are kept
  ArrayEncoding descriptors = ArrayEncoding::kInt8;  ///< local descriptors
  ArrayEncoding global = ArrayEncoding::kFloat16;    ///< the global descriptor
  bool scores = false;                               ///< send detector scores (1 byte each)
};

/// Quantises rows of `values` (CV_32F, count x dim) into a packed array.
aglcm::quantized_array_t QuantizeArray(const cv::Mat& values, ArrayEncoding encoding);

/// Expands a packed array back to CV_32F. Returns false with `error` naming
/// the problem (unknown encoding, sizes that do not add up, non-finite
/// scales) for malformed input; never throws on bad data.
bool DequantizeArray(const aglcm::quantized_array_t& array, cv::Mat* values, std::string* error);

/// Builds the packet. Keypoints are assumed sorted best first (as the
/// extractors return them); the first min(max_keypoints, n) are sent.
/// Keypoint coordinates become int16 fixed point with the most fractional
/// bits that still hold the largest coordinate.
aglcm::air_keyframe_t EncodeKeyframe(const AirKeyframe& keyframe, const PacketFormat& format);

/// Size in bytes of the encoded LCM message EncodeKeyframe would produce
/// for `keypoints` keypoints of `dim`-D descriptors and a `global_dim`
/// global descriptor (agent, camera id and descriptor type as given). Exact:
/// computed by LCM's own getEncodedSize on a message of that shape.
int64_t EncodedKeyframeSize(const std::string& agent, const std::string& camera_id,
                            const std::string& descriptor_type, int keypoints, int dim,
                            int global_dim, const PacketFormat& format);

/// How many keypoints the parts of a split keyframe hold (air_keyframe_t.lcm:
/// the first and last parts carry the global descriptor, so they hold fewer).
struct PartCapacity {
  int first = 0;  ///< keypoints in a part with the global descriptor (first, last)
  int rest = 0;   ///< keypoints in a part between them
};

/// The keypoints of each part when `keypoints` are split at `capacity`:
/// part 0 filled first, then the middle parts in order, the last with at
/// most `first`. One part when they all fit in part 0.
std::vector<int> PartKeypointCounts(int keypoints, const PartCapacity& capacity);

/// The largest part capacity (up to `max_keypoints` per part) whose encoded
/// parts all satisfy `fits(encoded_size)`. Throws std::invalid_argument
/// naming the smallest size that would do when not even a part with the
/// global descriptor and one keypoint, or a middle part with one, fits.
PartCapacity FitPartCapacity(const std::string& agent, const std::string& camera_id,
                             const std::string& descriptor_type, int dim, int global_dim,
                             const PacketFormat& format, int max_keypoints,
                             const std::function<bool(int64_t encoded_size)>& fits);

/// Encoded size of each part (see EncodedKeyframeSize) for `keypoints`
/// keypoints split at `capacity`.
std::vector<int64_t> EncodedPartSizes(const std::string& agent, const std::string& camera_id,
                                      const std::string& descriptor_type, int keypoints, int dim,
                                      int global_dim, const PacketFormat& format,
                                      const PartCapacity& capacity);

/// Builds the parts of a keyframe split at `capacity` (the first
/// min(max_keypoints, n) keypoints, as EncodeKeyframe sends them). One part,
/// equal to EncodeKeyframe's packet, when they fit in part 0.
std::vector<aglcm::air_keyframe_t> EncodeKeyframeParts(const AirKeyframe& keyframe,
                                                       const PacketFormat& format,
                                                       const PartCapacity& capacity);

struct DecodedKeyframe {
  bool ok = false;
  std::string error;     ///< what is wrong with the packet, when !ok
  AirKeyframe keyframe;  ///< of a part: its keypoints; global descriptor if it has one
  int part = 0;          ///< index of this part
  int num_parts = 1;     ///< parts of the keyframe (1: whole)
};

/// Validates and expands a packet: agent name, part index in range, finite
/// pose with a unit quaternion, keypoint arrays consistent with
/// num_keypoints, descriptor count equal to the keypoint count, global
/// descriptor a single vector (part 0; the last part: one or none) or empty
/// (parts between), all values finite. Descriptors are re-normalised to unit length.
DecodedKeyframe DecodeKeyframe(const aglcm::air_keyframe_t& packet);

}  // namespace ag
