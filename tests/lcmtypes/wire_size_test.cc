// Exact encoded sizes of air_keyframe_t against the layout documented in
// lcmtypes/*.lcm: a formula written from the documentation, so any schema
// change that alters the bytes on the radio link fails here. Also prints the
// bandwidth of each encoding at 1 keyframe per second.

#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <string>

#include "tests/lcmtypes/test_messages.h"

namespace ag {
namespace {

using Q = aglcm::quantized_array_t;

/// LCM string: int32 length, the characters, a NUL.
int64_t StringBytes(const std::string& s) { return 4 + static_cast<int64_t>(s.size()) + 1; }

/// quantized_array_t nested in a message, per quantized_array_t.lcm:
/// 22 + 4 * num_scales + 4 * num_offsets + num_bytes.
int64_t QuantizedArrayBytes(int64_t num_scales, int64_t num_offsets, int encoding, int64_t count,
                            int64_t dim, int bits) {
  return 22 + 4 * num_scales + 4 * num_offsets +
         test::QuantizedDataBytes(encoding, count, dim, bits);
}

/// One encoding choice: the quantized_array_t layout parameters.
struct Layout {
  const char* name;
  int8_t encoding;
  int bits;
  bool per_vector;  ///< scales (and BITS offsets) per vector, else one shared
};

int64_t LayoutBytes(const Layout& l, int64_t count, int64_t dim) {
  const int64_t num_params = l.per_vector ? count : 1;
  const int64_t num_scales = (l.encoding == Q::INT8 || l.encoding == Q::BITS) ? num_params : 0;
  const int64_t num_offsets = l.encoding == Q::BITS ? num_params : 0;
  return QuantizedArrayBytes(num_scales, num_offsets, l.encoding, count, dim, l.bits);
}

/// air_keyframe_t, per the size comment in air_keyframe_t.lcm.
int64_t AirKeyframeBytes(const aglcm::air_keyframe_t& kf, const Layout& global, int global_dim,
                         const Layout& local, int local_dim) {
  const int64_t n = kf.num_keypoints;
  return 8                                            // fingerprint
         + StringBytes(kf.agent) + 8 + 2 + 2 + 8      // agent, seq, part, num_parts, t_ns
         + StringBytes(kf.camera_id) + 3 * 8 + 4 * 8  // camera_id, pose
         + StringBytes(kf.descriptor_type)            // descriptor_type
         + LayoutBytes(global, 1, global_dim)         // global_descriptor
         + 4 + 1 + 2 * n + 2 * n                      // keypoints
         + 4 + kf.num_scores                          // scores
         + LayoutBytes(local, n, local_dim);          // descriptors
}

aglcm::air_keyframe_t MakeKeyframe(int num_keypoints, const Layout& global, int global_dim,
                                   const Layout& local, int local_dim) {
  aglcm::air_keyframe_t kf = test::MakeAirKeyframe(num_keypoints);
  kf.global_descriptor =
      test::MakeQuantized(global.encoding, 1, global_dim, global.bits, global.per_vector, 3);
  kf.descriptors = test::MakeQuantized(local.encoding, num_keypoints, local_dim, local.bits,
                                       local.per_vector, 4);
  return kf;
}

constexpr Layout kLocalLayouts[] = {
    {"float32", Q::FLOAT32, 32, false},
    {"float16", Q::FLOAT16, 16, false},
    {"int8/vector", Q::INT8, 8, true},
    {"4-bit/vector", Q::BITS, 4, true},
};
constexpr Layout kGlobalLayouts[] = {
    {"float32", Q::FLOAT32, 32, false},
    {"float16", Q::FLOAT16, 16, false},
    {"int8", Q::INT8, 8, false},
};

TEST(WireSize, QuantizedArrayMatchesTheDocumentedLayout) {
  for (const Layout& l : kLocalLayouts) {
    for (int count : {0, 1, 7, 1024}) {
      for (int dim : {1, 3, 64, 513}) {
        const Q q = test::MakeQuantized(l.encoding, count, dim, l.bits, l.per_vector, 1);
        // Nested size (what an enclosing message pays) plus the fingerprint
        // that a top-level message carries.
        EXPECT_EQ(q._getEncodedSizeNoHash(), LayoutBytes(l, count, dim)) << l.name;
        EXPECT_EQ(q.getEncodedSize(), 8 + LayoutBytes(l, count, dim)) << l.name;
      }
    }
  }
  // Bit packing does not pad rows: 3 vectors of 5 three-bit codes is 45 bits.
  EXPECT_EQ(test::QuantizedDataBytes(Q::BITS, 3, 5, 3), 6);
  for (int bits = 1; bits <= 8; ++bits) {
    const Q q = test::MakeQuantized(Q::BITS, 10, 7, bits, true, 2);
    EXPECT_EQ(q.num_bytes, (70 * bits + 7) / 8);
    EXPECT_EQ(q._getEncodedSizeNoHash(), 22 + 4 * 10 + 4 * 10 + (70 * bits + 7) / 8);
  }
}

TEST(WireSize, AirKeyframeWith1024KeypointsMatchesTheDocumentedLayout) {
  constexpr int kKeypoints = 1024;
  constexpr int kLocalDim = 64;
  constexpr int kGlobalDim = 512;
  std::printf(
      "\nair_keyframe_t, %d keypoints (int16 x, y + uint8 score), %d-D local, %d-D global\n"
      "descriptors; agent \"uav_1\", camera_id \"cam0\", descriptor_type \"xfeat\".\n"
      "Bytes per keyframe and Mbps at 1 keyframe/s (LCM/UDP headers not included):\n",
      kKeypoints, kLocalDim, kGlobalDim);
  std::printf("%-14s", "local \\ global");
  for (const Layout& g : kGlobalLayouts) std::printf(" | %-22s", g.name);
  std::printf("\n");
  for (const Layout& local : kLocalLayouts) {
    std::printf("%-14s", local.name);
    for (const Layout& global : kGlobalLayouts) {
      const aglcm::air_keyframe_t kf =
          MakeKeyframe(kKeypoints, global, kGlobalDim, local, kLocalDim);
      const int64_t expected = AirKeyframeBytes(kf, global, kGlobalDim, local, kLocalDim);
      EXPECT_EQ(kf.getEncodedSize(), expected) << local.name << " / " << global.name;
      EXPECT_EQ(static_cast<int64_t>(test::Encode(kf).size()), expected);
      std::printf(" | %8lld B %7.3f Mbps", static_cast<long long>(expected),
                  static_cast<double>(expected) * 8.0 / 1e6);
    }
    std::printf("\n");
  }
  // The paper's estimate (Lu et al., bandwidth section): 4 bytes per value,
  // 4 * (2n + 64n + 7 + 512) bytes per keyframe.
  const double paper = 4.0 * (2 * kKeypoints + 64 * kKeypoints + 7 + 512);
  std::printf("paper's float32 estimate: %.0f B %.3f Mbps\n", paper, paper * 8.0 / 1e6);
}

}  // namespace
}  // namespace ag
