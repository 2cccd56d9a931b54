#pragma once

// The one place that converts between the core keyframe struct and the LCM
// air keyframe packet, with selectable quantisation. The ground decodes with
// the same code; everything else sees only ag::AirKeyframe.

#include <cstdint>
#include <string>

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

struct DecodedKeyframe {
  bool ok = false;
  std::string error;  ///< what is wrong with the packet, when !ok
  AirKeyframe keyframe;
};

/// Validates and expands a packet: agent name, finite pose with a unit
/// quaternion, keypoint arrays consistent with num_keypoints, descriptor
/// count equal to the keypoint count, global descriptor a single vector,
/// all values finite. Descriptors are re-normalised to unit length.
DecodedKeyframe DecodeKeyframe(const aglcm::air_keyframe_t& packet);

}  // namespace ag
