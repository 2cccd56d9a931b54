#include "common/wire/keyframe_codec.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <random>

#include "common/wire/keyframe_assembler.h"

namespace ag {
namespace {

AirKeyframe MakeKeyframe(int n, int dim, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0, 1);
  std::normal_distribution<float> g(0, 1);
  AirKeyframe kf;
  kf.agent = "uav_1";
  kf.seq = 42;
  kf.t_ns = 1700000000123456789LL;
  kf.camera_id = "cam0";
  kf.T_wa_c =
      MakePose4Dof(1.5, -2.25, 8.0, 0.3) * Pose(Eigen::AngleAxisd(0.9, Eigen::Vector3d::UnitX()));
  kf.features.descriptor_type = "xfeat";
  kf.features.descriptors = cv::Mat(n, dim, CV_32F);
  for (int i = 0; i < n; ++i) {
    kf.features.keypoints.emplace_back(639.0f * u(rng), 479.0f * u(rng));
    kf.features.scores.push_back(1.0f - static_cast<float>(i) / n);
    for (int j = 0; j < dim; ++j) kf.features.descriptors.at<float>(i, j) = g(rng);
    cv::Mat row = kf.features.descriptors.row(i);
    cv::normalize(row, row);
  }
  kf.global_descriptor.resize(512);
  double norm = 0;
  for (float& v : kf.global_descriptor) {
    v = g(rng);
    norm += v * v;
  }
  for (float& v : kf.global_descriptor) v = static_cast<float>(v / std::sqrt(norm));
  return kf;
}

DecodedKeyframe RoundTrip(const AirKeyframe& kf, const PacketFormat& f) {
  const aglcm::air_keyframe_t packet = EncodeKeyframe(kf, f);
  // Through LCM's own bytes, as the ground would receive them.
  std::vector<uint8_t> buffer(packet.getEncodedSize());
  EXPECT_EQ(packet.encode(buffer.data(), 0, static_cast<int>(buffer.size())),
            static_cast<int>(buffer.size()));
  aglcm::air_keyframe_t received;
  EXPECT_EQ(received.decode(buffer.data(), 0, static_cast<int>(buffer.size())),
            static_cast<int>(buffer.size()));
  return DecodeKeyframe(received);
}

TEST(KeyframeCodecTest, Float32IsLossless) {
  const AirKeyframe kf = MakeKeyframe(300, 64, 1);
  PacketFormat f;
  f.descriptors = ArrayEncoding::kFloat32;
  f.global = ArrayEncoding::kFloat32;
  f.scores = true;
  const DecodedKeyframe d = RoundTrip(kf, f);
  ASSERT_TRUE(d.ok) << d.error;
  EXPECT_EQ(d.keyframe.agent, kf.agent);
  EXPECT_EQ(d.keyframe.seq, kf.seq);
  EXPECT_EQ(d.keyframe.t_ns, kf.t_ns);
  EXPECT_EQ(d.keyframe.camera_id, kf.camera_id);
  EXPECT_EQ(d.keyframe.features.descriptor_type, "xfeat");
  EXPECT_TRUE(d.keyframe.T_wa_c.matrix().isApprox(kf.T_wa_c.matrix(), 1e-12));
  EXPECT_EQ(cv::norm(d.keyframe.features.descriptors, kf.features.descriptors, cv::NORM_INF), 0.0);
  for (size_t i = 0; i < 512; ++i) {
    EXPECT_FLOAT_EQ(d.keyframe.global_descriptor[i], kf.global_descriptor[i]);
  }
  // Keypoints: 640 px needs 10 integer bits, leaving 5 fractional (1/32 px).
  for (size_t i = 0; i < kf.features.size(); ++i) {
    EXPECT_LE((d.keyframe.features.keypoints[i] - kf.features.keypoints[i]).cwiseAbs().maxCoeff(),
              0.5f / 32 + 1e-6f);
    EXPECT_NEAR(d.keyframe.features.scores[i], kf.features.scores[i], 0.5 / 255 + 1e-6);
  }
}

TEST(KeyframeCodecTest, QuantisedEncodingsStayWithinTheirError) {
  const AirKeyframe kf = MakeKeyframe(500, 64, 2);
  struct Case {
    ArrayEncoding e;
    double max_abs;  // per value, for unit 64-D vectors
  };
  for (const Case& c : {Case{ArrayEncoding::kFloat16, 1e-3}, Case{ArrayEncoding::kInt8, 0.01},
                        Case{ArrayEncoding::kBits4, 0.06}}) {
    PacketFormat f;
    f.descriptors = c.e;
    f.global = c.e;
    const DecodedKeyframe d = RoundTrip(kf, f);
    ASSERT_TRUE(d.ok) << d.error;
    EXPECT_LE(cv::norm(d.keyframe.features.descriptors, kf.features.descriptors, cv::NORM_INF),
              c.max_abs)
        << ToString(c.e);
    // Quantisation keeps the matching structure: each decoded descriptor is
    // still nearest to its original among all.
    int correct = 0;
    for (int i = 0; i < 500; ++i) {
      double best = -2;
      int arg = -1;
      for (int j = 0; j < 500; ++j) {
        const double s = d.keyframe.features.descriptors.row(i).dot(kf.features.descriptors.row(j));
        if (s > best) best = s, arg = j;
      }
      correct += arg == i;
    }
    EXPECT_EQ(correct, 500) << ToString(c.e);
  }
}

TEST(KeyframeCodecTest, KeepsTheBestKeypointsAndSizeIsExact) {
  const AirKeyframe kf = MakeKeyframe(1200, 64, 3);
  for (ArrayEncoding e : {ArrayEncoding::kFloat32, ArrayEncoding::kFloat16, ArrayEncoding::kInt8,
                          ArrayEncoding::kBits4}) {
    PacketFormat f;
    f.descriptors = e;
    f.max_keypoints = 700;
    const aglcm::air_keyframe_t p = EncodeKeyframe(kf, f);
    EXPECT_EQ(p.num_keypoints, 700);
    EXPECT_EQ(EncodedKeyframeSize("uav_1", "cam0", "xfeat", 700, 64, 512, f), p.getEncodedSize());
    const DecodedKeyframe d = DecodeKeyframe(p);
    ASSERT_TRUE(d.ok);
    // The first 700 (best-scored) keypoints are the ones sent.
    EXPECT_NEAR(d.keyframe.features.keypoints[699].x(), kf.features.keypoints[699].x(), 0.02);
  }
}

TEST(KeyframeCodecTest, MalformedPacketsAreRejectedWithAReason) {
  const AirKeyframe kf = MakeKeyframe(50, 64, 4);
  const aglcm::air_keyframe_t good = EncodeKeyframe(kf, PacketFormat{});
  ASSERT_TRUE(DecodeKeyframe(good).ok);
  struct Case {
    const char* expect;
    std::function<void(aglcm::air_keyframe_t&)> corrupt;
  };
  const std::vector<Case> cases = {
      {"agent name", [](auto& p) { p.agent = "UAV 1"; }},
      {"position", [](auto& p) { p.position[1] = NAN; }},
      {"unit quaternion", [](auto& p) { p.orientation[0] = 3; }},
      {"num_keypoints", [](auto& p) { p.num_keypoints = 49; }},
      {"frac_bits", [](auto& p) { p.keypoint_frac_bits = 20; }},
      {"num_scores", [](auto& p) { p.num_scores = 3; }},
      {"unknown encoding", [](auto& p) { p.descriptors.encoding = 9; }},
      {"expected",
       [](auto& p) {
         p.descriptors.data.pop_back();
         p.descriptors.num_bytes--;
       }},
      {"vectors for",
       [](auto& p) {
         p.descriptors.count = 10;
         p.descriptors.num_scales = 10;
         p.descriptors.scales.resize(10);
         p.descriptors.data.resize(640);
         p.descriptors.num_bytes = 640;
       }},
      {"non-finite scale", [](auto& p) { p.descriptors.scales[0] = INFINITY; }},
      {"one vector",
       [](auto& p) {
         p.global_descriptor.count = 2;
         p.global_descriptor.dim = 256;
       }},
      {"descriptor_type", [](auto& p) { p.descriptor_type = ""; }},
      {"part 3 of 3", [](auto& p) { p.part = 3, p.num_parts = 3; }},
      {"part -1 of 2", [](auto& p) { p.part = -1, p.num_parts = 2; }},
      {"part 0 of 0", [](auto& p) { p.num_parts = 0; }},
      {"global descriptor in part 1 of 3", [](auto& p) { p.part = 1, p.num_parts = 3; }},
  };
  for (const Case& c : cases) {
    aglcm::air_keyframe_t p = good;
    c.corrupt(p);
    const DecodedKeyframe d = DecodeKeyframe(p);
    EXPECT_FALSE(d.ok) << c.expect;
    EXPECT_NE(d.error.find(c.expect), std::string::npos) << "got: " << d.error;
  }
}

// ---------------------------------------------------------------- parts

/// The parts' messages through LCM bytes and DecodeKeyframe, as the ground receives them.
std::vector<DecodedKeyframe> RoundTripParts(const std::vector<aglcm::air_keyframe_t>& parts) {
  std::vector<DecodedKeyframe> out;
  for (const aglcm::air_keyframe_t& part : parts) {
    std::vector<uint8_t> buffer(part.getEncodedSize());
    part.encode(buffer.data(), 0, static_cast<int>(buffer.size()));
    aglcm::air_keyframe_t received;
    EXPECT_EQ(received.decode(buffer.data(), 0, static_cast<int>(buffer.size())),
              static_cast<int>(buffer.size()));
    out.push_back(DecodeKeyframe(received));
    EXPECT_TRUE(out.back().ok) << out.back().error;
  }
  return out;
}

TEST(KeyframePartsTest, PartsFitTheirLimitAndCarryEveryKeypointOnce) {
  const AirKeyframe kf = MakeKeyframe(400, 64, 5);
  for (ArrayEncoding e : {ArrayEncoding::kInt8, ArrayEncoding::kBits4}) {
    PacketFormat f;
    f.descriptors = e;
    f.max_keypoints = 350;
    const int64_t limit = 1400;
    const PartCapacity cap = FitPartCapacity("uav_1", "cam0", "xfeat", 64, 512, f, 1024,
                                             [&](int64_t size) { return size <= limit; });
    ASSERT_GT(cap.rest, cap.first);  // part 0 also carries the global descriptor
    const std::vector<aglcm::air_keyframe_t> parts = EncodeKeyframeParts(kf, f, cap);
    const std::vector<int64_t> sizes =
        EncodedPartSizes("uav_1", "cam0", "xfeat", 350, 64, 512, f, cap);
    ASSERT_EQ(parts.size(), sizes.size());
    // First and last with the global descriptor, full middle parts between.
    EXPECT_EQ(static_cast<int>(parts.size()), 2 + (350 - 2 * cap.first + cap.rest - 1) / cap.rest);
    for (size_t i = 0; i < parts.size(); ++i) {
      const bool with_global = i == 0 || i + 1 == parts.size();
      EXPECT_EQ(parts[i].global_descriptor.count, with_global ? 1 : 0) << "part " << i;
      EXPECT_EQ(parts[i].getEncodedSize(), sizes[i]) << "part " << i;  // the size model is exact
      EXPECT_LE(sizes[i], limit) << "part " << i;
      EXPECT_EQ(parts[i].part, static_cast<int16_t>(i));
      EXPECT_EQ(parts[i].num_parts, static_cast<int16_t>(parts.size()));
    }
    // One more keypoint in a full part would not fit: the capacity is the largest.
    PartCapacity bigger = cap;
    ++bigger.rest;
    EXPECT_GT(EncodedPartSizes("uav_1", "cam0", "xfeat", 2 * cap.first + bigger.rest, 64, 512, f,
                               bigger)[1],
              limit);

    KeyframeAssembler assembler;
    std::vector<KeyframeAssembler::Joined> joined;
    std::string error;
    for (DecodedKeyframe& d : RoundTripParts(parts)) {
      for (auto& j : assembler.Add(std::move(d), 0.0, &error)) joined.push_back(std::move(j));
      EXPECT_EQ(error, "");
    }
    ASSERT_EQ(joined.size(), 1u);  // complete as soon as the last part is in
    const KeyframeAssembler::Joined& j = joined[0];
    EXPECT_TRUE(j.usable);
    EXPECT_EQ(j.parts_received, j.num_parts);
    // The same keyframe as one whole packet would give.
    const DecodedKeyframe whole = RoundTrip(kf, f);
    ASSERT_EQ(j.keyframe.features.size(), whole.keyframe.features.size());
    for (size_t i = 0; i < whole.keyframe.features.size(); ++i) {
      ASSERT_NEAR((j.keyframe.features.keypoints[i] - whole.keyframe.features.keypoints[i]).norm(),
                  0.0, 0.04)  // each part picks its own fixed-point step
          << i;
    }
    EXPECT_EQ(cv::norm(j.keyframe.features.descriptors, whole.keyframe.features.descriptors,
                       cv::NORM_INF),
              0.0);
    EXPECT_EQ(j.keyframe.global_descriptor, whole.keyframe.global_descriptor);
    EXPECT_TRUE(j.keyframe.T_wa_c.isApprox(whole.keyframe.T_wa_c));
    EXPECT_EQ(assembler.pending(), 0u);
  }
}

TEST(KeyframePartsTest, FewKeypointsGoInOnePartAndTooSmallALimitIsNamed) {
  PacketFormat f;
  const auto fits = [](int64_t size) { return size <= 1400; };
  const PartCapacity cap = FitPartCapacity("uav_1", "cam0", "xfeat", 64, 512, f, 1024, fits);
  const std::vector<aglcm::air_keyframe_t> parts =
      EncodeKeyframeParts(MakeKeyframe(cap.first, 64, 6), f, cap);
  ASSERT_EQ(parts.size(), 1u);
  EXPECT_EQ(parts[0].num_parts, 1);
  EXPECT_EQ(PartKeypointCounts(0, cap), std::vector<int>{0});
  // Middle parts full; the last (it repeats the global descriptor) at most `first`.
  EXPECT_EQ(PartKeypointCounts(2 * cap.first + 2 * cap.rest, cap),
            (std::vector<int>{cap.first, cap.rest, cap.rest, cap.first}));
  EXPECT_EQ(PartKeypointCounts(cap.first + 1, cap), (std::vector<int>{cap.first, 1}));
  EXPECT_EQ(PartKeypointCounts(cap.first + cap.rest, cap),
            (std::vector<int>{cap.first, cap.rest - cap.first, cap.first}));
  // A part with the global descriptor and one keypoint is the smallest a
  // limit may allow: just below it is refused, at it every part fits.
  const auto with_global = [](int64_t limit) {
    return [limit](int64_t size) { return size <= limit; };
  };
  const int64_t smallest =
      EncodedPartSizes("uav_1", "cam0", "xfeat", 3, 64, 512, f, PartCapacity{1, 1})[0];
  EXPECT_THROW(
      FitPartCapacity("uav_1", "cam0", "xfeat", 64, 512, f, 1024, with_global(smallest - 1)),
      std::invalid_argument);
  const PartCapacity tight =
      FitPartCapacity("uav_1", "cam0", "xfeat", 64, 512, f, 1024, with_global(smallest));
  EXPECT_GE(tight.first, 1);
  for (const aglcm::air_keyframe_t& p : EncodeKeyframeParts(MakeKeyframe(50, 64, 7), f, tight)) {
    EXPECT_LE(p.getEncodedSize(), smallest) << "part " << p.part;
  }
  // The global descriptor alone (float16, 512-D: 1 kB) does not fit 600 bytes.
  try {
    FitPartCapacity("uav_1", "cam0", "xfeat", 64, 512, f, 1024,
                    [](int64_t size) { return size <= 600; });
    FAIL() << "a 600-byte part cannot hold the global descriptor";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("global descriptor"), std::string::npos) << e.what();
  }
}

/// The decoded parts of a 200-keypoint keyframe `seq` split into several.
std::vector<DecodedKeyframe> SplitKeyframe(int64_t seq, uint32_t seed) {
  AirKeyframe kf = MakeKeyframe(200, 64, seed);
  kf.seq = seq;
  return RoundTripParts(EncodeKeyframeParts(kf, PacketFormat{}, PartCapacity{20, 60}));
}

TEST(KeyframeAssemblerTest, KeepsTheKeypointsOfThePartsThatArrived) {
  KeyframeAssembler assembler(0.5);
  std::vector<DecodedKeyframe> parts = SplitKeyframe(7, 7);
  ASSERT_EQ(parts.size(), 5u);  // 20 + 60 + 60 + 40 + 20
  std::string error;
  EXPECT_TRUE(assembler.Add(std::move(parts[0]), 10.0, &error).empty());
  EXPECT_TRUE(assembler.Add(std::move(parts[2]), 10.01, &error).empty());  // part 1 lost
  EXPECT_TRUE(assembler.Add(std::move(parts[3]), 10.015, &error).empty());
  EXPECT_TRUE(assembler.Add(std::move(parts[4]), 10.02, &error).empty());
  EXPECT_EQ(error, "");
  EXPECT_TRUE(assembler.Expire(10.5).empty());  // not yet 0.5 s after the latest part
  std::vector<KeyframeAssembler::Joined> j = assembler.Expire(10.53);
  ASSERT_EQ(j.size(), 1u);
  EXPECT_TRUE(j[0].usable);
  EXPECT_EQ(j[0].parts_received, 4);
  EXPECT_EQ(j[0].num_parts, 5);
  EXPECT_EQ(j[0].keyframe.seq, 7);
  EXPECT_EQ(j[0].keyframe.features.size(), 140u);
  EXPECT_EQ(j[0].keyframe.features.descriptors.rows, 140);
  EXPECT_EQ(j[0].keyframe.global_descriptor.size(), 512u);
  EXPECT_EQ(assembler.pending(), 0u);
}

TEST(KeyframeAssemblerTest, ANewerKeyframeFinishesTheOlderOne) {
  KeyframeAssembler assembler(5.0);
  std::vector<DecodedKeyframe> a = SplitKeyframe(1, 8);
  std::vector<DecodedKeyframe> b = SplitKeyframe(2, 9);
  std::string error;
  // Parts arrive out of order; parts 3 and 4 of keyframe 1 are lost.
  EXPECT_TRUE(assembler.Add(std::move(a[1]), 0.0, &error).empty());
  EXPECT_TRUE(assembler.Add(std::move(a[0]), 0.0, &error).empty());
  EXPECT_TRUE(assembler.Add(std::move(a[2]), 0.0, &error).empty());
  std::vector<KeyframeAssembler::Joined> j = assembler.Add(std::move(b[1]), 0.1, &error);
  ASSERT_EQ(j.size(), 1u);
  EXPECT_EQ(j[0].keyframe.seq, 1);
  EXPECT_EQ(j[0].parts_received, 3);
  EXPECT_TRUE(j[0].usable);
  EXPECT_EQ(j[0].keyframe.features.size(), 140u);
  // Part order, not arrival order: the first keypoint is part 0's first.
  const AirKeyframe original = MakeKeyframe(200, 64, 8);
  EXPECT_NEAR((j[0].keyframe.features.keypoints[0] - original.features.keypoints[0]).norm(), 0,
              0.1);
  // Keyframe 2 lost its first and last parts, both with the global
  // descriptor: unusable, said so.
  EXPECT_TRUE(assembler.Add(std::move(b[2]), 0.2, &error).empty());
  EXPECT_TRUE(assembler.Add(std::move(b[3]), 0.3, &error).empty());
  j = assembler.Expire(10.0);
  ASSERT_EQ(j.size(), 1u);
  EXPECT_FALSE(j[0].usable);
  EXPECT_EQ(j[0].parts_received, 3);
  EXPECT_EQ(error, "");
}

TEST(KeyframeAssemblerTest, TheLastPartStandsInForALostFirst) {
  KeyframeAssembler assembler;
  std::vector<DecodedKeyframe> parts = SplitKeyframe(4, 13);
  const std::vector<float> global = parts[0].keyframe.global_descriptor;
  std::string error;
  for (size_t i = 1; i + 1 < parts.size(); ++i) assembler.Add(std::move(parts[i]), 0.0, &error);
  EXPECT_TRUE(assembler.Expire(0.1).empty());
  assembler.Add(std::move(parts.back()), 0.0, &error);
  const std::vector<KeyframeAssembler::Joined> j = assembler.Expire(1.0);
  ASSERT_EQ(j.size(), 1u);
  EXPECT_TRUE(j[0].usable);
  EXPECT_EQ(j[0].keyframe.global_descriptor, global);
  EXPECT_EQ(j[0].keyframe.features.size(), 180u);
  EXPECT_EQ(error, "");
}

TEST(KeyframeAssemblerTest, ContradictingAndRepeatedPartsAreRefusedWithAReason) {
  KeyframeAssembler assembler;
  std::vector<DecodedKeyframe> parts = SplitKeyframe(3, 10);
  std::vector<DecodedKeyframe> copy = SplitKeyframe(3, 10);
  std::vector<DecodedKeyframe> other = SplitKeyframe(3, 11);  // same seq, another pose
  std::string error;
  assembler.Add(std::move(parts[0]), 0.0, &error);
  EXPECT_TRUE(assembler.Add(std::move(copy[0]), 0.0, &error).empty());
  EXPECT_NE(error.find("received twice"), std::string::npos) << error;
  other[1].keyframe.T_wa_c.translation().x() += 1.0;
  EXPECT_TRUE(assembler.Add(std::move(other[1]), 0.0, &error).empty());
  EXPECT_NE(error.find("camera pose differs"), std::string::npos) << error;
  DecodedKeyframe wrong_count = std::move(copy[2]);
  wrong_count.num_parts = 9;
  EXPECT_TRUE(assembler.Add(std::move(wrong_count), 0.0, &error).empty());
  EXPECT_NE(error.find("num_parts differs"), std::string::npos) << error;
  // What was accepted is kept: the good parts still join.
  assembler.Add(std::move(parts[1]), 0.0, &error);
  assembler.Add(std::move(parts[2]), 0.0, &error);
  assembler.Add(std::move(parts[3]), 0.0, &error);
  const std::vector<KeyframeAssembler::Joined> j = assembler.Add(std::move(parts[4]), 0.0, &error);
  ASSERT_EQ(j.size(), 1u);
  EXPECT_EQ(j[0].parts_received, 5);
  EXPECT_EQ(j[0].keyframe.features.size(), 200u);
}

TEST(KeyframeAssemblerTest, WholeKeyframesPassStraightThrough) {
  KeyframeAssembler assembler;
  std::string error;
  const AirKeyframe kf = MakeKeyframe(30, 64, 12);
  const std::vector<KeyframeAssembler::Joined> j =
      assembler.Add(RoundTrip(kf, PacketFormat{}), 0.0, &error);
  ASSERT_EQ(j.size(), 1u);
  EXPECT_TRUE(j[0].usable);
  EXPECT_EQ(j[0].num_parts, 1);
  EXPECT_EQ(j[0].keyframe.features.size(), 30u);
  EXPECT_EQ(assembler.pending(), 0u);
}

}  // namespace
}  // namespace ag
