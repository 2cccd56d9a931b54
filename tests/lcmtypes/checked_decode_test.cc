// DecodeChecked() on corrupted buffers: it must reject (or, when the damage
// still leaves a well-formed message, faithfully decode) without throwing and
// without trusting a length field it cannot back with bytes.

#include "lcmtypes/checked_decode.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "tests/lcmtypes/test_messages.h"

namespace ag {
namespace {

using test::Encode;

void PutBigEndianInt32(int32_t value, size_t offset, std::vector<uint8_t>* buf) {
  const auto u = static_cast<uint32_t>(value);
  (*buf)[offset] = static_cast<uint8_t>(u >> 24);
  (*buf)[offset + 1] = static_cast<uint8_t>(u >> 16);
  (*buf)[offset + 2] = static_cast<uint8_t>(u >> 8);
  (*buf)[offset + 3] = static_cast<uint8_t>(u);
}

/// The outcome allowed for a damaged buffer: rejected, or decoded into a
/// message that re-encodes to exactly the bytes it was read from.
template <class Msg>
void ExpectRejectedOrFaithful(const std::vector<uint8_t>& bad, const char* what, size_t where) {
  Msg msg;
  const int n = DecodeChecked(bad.data(), static_cast<int>(bad.size()), &msg);
  if (n < 0) return;
  ASSERT_LE(static_cast<size_t>(n), bad.size()) << what << " at " << where;
  EXPECT_EQ(Encode(msg), std::vector<uint8_t>(bad.begin(), bad.begin() + n))
      << what << " at " << where;
}

/// Overwrites every 4-byte window in turn with hostile int32 values: this
/// hits every length field of the message whatever the layout.
template <class Msg>
void ExpectSurvivesHostileLengths(const Msg& sent) {
  const std::vector<uint8_t> buf = Encode(sent);
  const int32_t hostile[] = {-1, std::numeric_limits<int32_t>::min(),
                             std::numeric_limits<int32_t>::max(), 1 << 30, 0};
  for (size_t offset = 8; offset + 4 <= buf.size(); ++offset) {
    for (int32_t value : hostile) {
      std::vector<uint8_t> bad = buf;
      PutBigEndianInt32(value, offset, &bad);
      ExpectRejectedOrFaithful<Msg>(bad, "int32 overwrite", offset);
    }
  }
}

TEST(DecodeChecked, SurvivesHostileLengthsInEveryMessage) {
  ExpectSurvivesHostileLengths(test::MakeAirKeyframe(12));
  ExpectSurvivesHostileLengths(test::MakeCameraInfo());
  ExpectSurvivesHostileLengths(test::MakeRelativePose());
  ExpectSurvivesHostileLengths(test::MakeImage());
  ExpectSurvivesHostileLengths(test::MakeOdometry());
  ExpectSurvivesHostileLengths(test::MakePointCloud(6));
}

TEST(DecodeChecked, RejectsImpossibleKeypointCounts) {
  // The documented layout puts num_keypoints right after the global descriptor.
  const aglcm::air_keyframe_t kf = test::MakeAirKeyframe(12);
  const size_t offset = 8 + (5 + kf.agent.size()) + 20 + (5 + kf.camera_id.size()) + 56 +
                        (5 + kf.descriptor_type.size()) +
                        static_cast<size_t>(kf.global_descriptor._getEncodedSizeNoHash());
  const std::vector<uint8_t> buf = Encode(kf);
  for (int32_t value : {-1, 13, 1 << 20, std::numeric_limits<int32_t>::max()}) {
    std::vector<uint8_t> bad = buf;
    PutBigEndianInt32(value, offset, &bad);
    aglcm::air_keyframe_t msg;
    EXPECT_LT(DecodeChecked(bad.data(), static_cast<int>(bad.size()), &msg), 0) << value;
  }
  // The untouched buffer at the same offset holds 12, so the offset is right.
  std::vector<uint8_t> same = buf;
  PutBigEndianInt32(12, offset, &same);
  EXPECT_EQ(same, buf);
}

TEST(DecodeChecked, SurvivesRandomByteDamage) {
  const std::vector<uint8_t> buf = Encode(test::MakeAirKeyframe(16));
  std::mt19937 rng(12345);
  int rejected = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    std::vector<uint8_t> bad = buf;
    const int flips = 1 + static_cast<int>(rng() % 4);
    for (int f = 0; f < flips; ++f) {
      // Keep the fingerprint so the damage reaches the body.
      bad[8 + rng() % (bad.size() - 8)] = static_cast<uint8_t>(rng());
    }
    aglcm::air_keyframe_t msg;
    if (DecodeChecked(bad.data(), static_cast<int>(bad.size()), &msg) < 0) ++rejected;
    ExpectRejectedOrFaithful<aglcm::air_keyframe_t>(bad, "random damage, trial", trial);
  }
  // Most bytes are payload, but some damage must have hit a length field.
  EXPECT_GT(rejected, 0);
}

TEST(DecodeChecked, RejectsNullAndEmptyBuffers) {
  aglcm::odometry_t msg;
  EXPECT_LT(DecodeChecked(nullptr, 100, &msg), 0);
  const uint8_t byte = 0;
  EXPECT_LT(DecodeChecked(&byte, 0, &msg), 0);
  EXPECT_LT(DecodeChecked(&byte, -5, &msg), 0);
}

}  // namespace
}  // namespace ag
