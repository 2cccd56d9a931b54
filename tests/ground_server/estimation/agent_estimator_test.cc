#include "ground_server/estimation/agent_estimator.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <opencv2/core.hpp>
#include <random>

#include "tests/support/synthetic_views.h"

namespace ag {
namespace {

using test::LookAt;

// A brute-force source: similarity = dot product of global descriptors.
class VectorSource : public AirKeyframeSource {
 public:
  std::vector<std::shared_ptr<const AirKeyframe>> keyframes;
  std::vector<Candidate> Retrieve(const std::vector<float>& global, const std::string& agent,
                                  int k) const override {
    std::vector<Candidate> out;
    for (const auto& kf : keyframes) {
      if (kf->agent != agent) continue;
      double s = 0;
      for (size_t i = 0; i < global.size(); ++i) s += global[i] * kf->global_descriptor[i];
      out.push_back({kf, s});
    }
    std::sort(out.begin(), out.end(), [](auto& a, auto& b) { return a.similarity > b.similarity; });
    if (static_cast<int>(out.size()) > k) out.resize(k);
    return out;
  }
  std::vector<std::shared_ptr<const AirKeyframe>> Recent(const std::string& agent,
                                                         int n) const override {
    std::vector<std::shared_ptr<const AirKeyframe>> out;
    for (auto it = keyframes.rbegin(); it != keyframes.rend() && static_cast<int>(out.size()) < n;
         ++it) {
      if ((*it)->agent == agent) out.push_back(*it);
    }
    return out;
  }
};

struct World {
  std::vector<Eigen::Vector3d> points;
  cv::Mat descriptors;
};

World MakeWorld(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<float> g(0, 1);
  World w;
  for (int i = 0; i < 3000; ++i) {
    if (i % 3 == 0) {
      w.points.emplace_back(15.0, -6 + 12 * u(rng), 3 * u(rng));  // a wall
    } else {
      w.points.emplace_back(4 + 11 * u(rng), -6 + 12 * u(rng), 0.0);  // the ground
    }
  }
  w.descriptors = cv::Mat(static_cast<int>(w.points.size()), 64, CV_32F);
  for (int i = 0; i < w.descriptors.rows; ++i) {
    for (int j = 0; j < 64; ++j) w.descriptors.at<float>(i, j) = g(rng);
    cv::Mat row = w.descriptors.row(i);
    cv::normalize(row, row);
  }
  return w;
}

// Keypoints of the world points a camera sees, with pixel and descriptor noise.
LocalFeatures Observe(const World& w, const Camera& cam, const Pose& T_w_c, std::mt19937& rng,
                      std::vector<int>* ids, double px_noise) {
  std::normal_distribution<double> n(0, 1);
  std::normal_distribution<float> g(0, 0.05f);
  LocalFeatures f;
  f.descriptor_type = "xfeat";
  std::vector<cv::Mat> rows;
  for (size_t i = 0; i < w.points.size() && f.keypoints.size() < 600; ++i) {
    Eigen::Vector2d uv;
    if (!cam.Project(T_w_c.inverse() * w.points[i], &uv) || !cam.InImage(uv, 2)) continue;
    uv += px_noise * Eigen::Vector2d(n(rng), n(rng));
    f.keypoints.push_back(uv.cast<float>());
    f.scores.push_back(1.0f);
    cv::Mat d = w.descriptors.row(static_cast<int>(i)).clone();
    for (int j = 0; j < 64; ++j) d.at<float>(0, j) += g(rng);
    cv::normalize(d, d);
    rows.push_back(d);
    ids->push_back(static_cast<int>(i));
  }
  cv::vconcat(rows, f.descriptors);
  return f;
}

class AgentEstimatorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    rng_.seed(3);
    world_ = MakeWorld(rng_);
    camera_ = std::make_shared<Camera>(test::Pinhole640x480());
    T_wa_wg_ = MakePose4Dof(20, -7, 1.5, 1.1);
    std::normal_distribution<double> n(0, 1);
    std::vector<float> place(512, 0.0f);
    place[0] = 1.0f;
    for (int i = 0; i < 3; ++i) {
      auto kf = std::make_shared<UgvKeyframe>();
      kf->id = i;
      kf->t_ns = i * 500000000LL;
      const Eigen::Vector3d pos(0.6 * i, 0.2 * i, 0.5);
      kf->T_wg_c = LookAt(pos, pos + Eigen::Vector3d(1, 0, -0.08));
      std::vector<int> ids;
      kf->features = Observe(world_, *camera_, kf->T_wg_c, rng_, &ids, 0.3);
      kf->global_descriptor = place;
      for (size_t k = 0; k < ids.size(); ++k) {
        kf->points_wg.push_back(world_.points[ids[k]] +
                                0.01 * Eigen::Vector3d(n(rng_), n(rng_), n(rng_)));
        kf->has_point.push_back(k % 5 != 0);  // some keypoints without depth
      }
      window_.push_back(kf);
    }
    for (int i = 0; i < 3; ++i) AddAirKeyframe(i);
  }

  // The UAV's keyframe seq at (8 + i, -2 + i, 9) in the UGV world (i: 0-2),
  // sent at i s; again from the same place for a larger seq (hovering).
  // Scrambled: the keypoints' pixels shuffled, so its descriptors match but
  // no match fits the geometry.
  void AddAirKeyframe(int seq, bool scrambled = false) {
    const int i = seq % 3;
    auto kf = std::make_shared<AirKeyframe>();
    kf->agent = "uav";
    kf->seq = seq;
    kf->t_ns = 1000000000LL * seq;
    kf->camera_id = "cam";
    const Eigen::Vector3d pos_wg(8 + i, -2 + i, 9);
    kf->T_wa_c = LookAt(T_wa_wg_ * pos_wg, T_wa_wg_ * Eigen::Vector3d(11, 0, 0));
    std::vector<int> ids;
    kf->features = Observe(world_, *camera_, T_wa_wg_.inverse() * kf->T_wa_c, rng_, &ids, 0.5);
    if (scrambled) std::shuffle(kf->features.keypoints.begin(), kf->features.keypoints.end(), rng_);
    kf->global_descriptor = std::vector<float>(512, 0.0f);
    kf->global_descriptor[0] = 1.0f;
    source_.keyframes.push_back(kf);
  }

  std::mt19937 rng_;
  World world_;
  std::shared_ptr<Camera> camera_;
  Pose T_wa_wg_;
  UgvWindow window_;
  VectorSource source_;
};

TEST_F(AgentEstimatorTest, RecoversTransformAndPublishesAfterConfirmation) {
  EstimatorOptions options;
  options.retrieval_k = 8;  // every UAV keyframe (all look alike to retrieval)
  // Treat this test's (strong) matches as weak ones: a repeat never confirms.
  options.gate.repeat_min_inlier_fraction = 1e6;
  AgentEstimator estimator("uav", options, camera_);
  estimator.SetAirCamera("cam", camera_);
  const EstimateResult first = estimator.Estimate(0, window_, source_);
  ASSERT_TRUE(first.success) << first.reason;
  EXPECT_FALSE(first.gate.publish) << "a first estimate waits for confirmation";
  EXPECT_EQ(first.air_seqs, (std::vector<int64_t>{0, 1, 2}));
  // The same UAV keyframes again: the same match, not a confirmation.
  const EstimateResult repeated = estimator.Estimate(250000000LL, window_, source_);
  ASSERT_TRUE(repeated.success) << repeated.reason;
  EXPECT_FALSE(repeated.gate.publish);
  EXPECT_NE(repeated.gate.reason.find("1/3"), std::string::npos) << repeated.gate.reason;
  // Each new UAV keyframe makes an estimate a confirmation.
  AddAirKeyframe(3);
  const EstimateResult confirming = estimator.Estimate(500000000LL, window_, source_);
  ASSERT_TRUE(confirming.success) << confirming.reason;
  EXPECT_FALSE(confirming.gate.publish) << "a first fix needs three agreeing estimates";
  EXPECT_NE(confirming.gate.reason.find("2/3"), std::string::npos) << confirming.gate.reason;
  AddAirKeyframe(4);
  const EstimateResult second = estimator.Estimate(1000000000LL, window_, source_);
  ASSERT_TRUE(second.success) << second.reason;
  EXPECT_TRUE(second.gate.publish) << second.gate.reason;
  EXPECT_EQ(second.gate.status, FixStatus::kTracking);
  const double t_err = (second.T_wa_wg.translation() - T_wa_wg_.translation()).norm();
  const double yaw_err =
      std::abs(WrapAngle(ProjectedYaw(second.T_wa_wg.linear()) - 1.1)) * 180 / M_PI;
  EXPECT_LT(t_err, 0.02);
  EXPECT_LT(yaw_err, 0.1);
  EXPECT_GT(second.inliers, 100);
  EXPECT_GT(second.pairs, 3);
  EXPECT_TRUE(second.has_covariance);
  EXPECT_EQ(second.newest_air_t_ns, 4000000000LL);
  std::printf("error %.4f m %.4f deg, %d inliers, %d pairs, %.1f ms (stage1 %.1f, stage2 %.1f)\n",
              t_err, yaw_err, second.inliers, second.pairs, second.timing.total_ms,
              second.timing.stage1_ms, second.timing.stage2_ms);
}

TEST_F(AgentEstimatorTest, AKeyframeWithoutInliersIsNoNewEvidence) {
  EstimatorOptions options;
  options.retrieval_k = 8;
  options.gate.repeat_min_inlier_fraction = 1e6;  // a repeat never confirms
  AgentEstimator estimator("uav", options, camera_);
  estimator.SetAirCamera("cam", camera_);
  ASSERT_TRUE(estimator.Estimate(0, window_, source_).success);
  // A new UAV keyframe whose matches are all outliers: stage 2 keeps it (it
  // is in the time stretch), but the estimate still rests on keyframes 0-2
  // only, and must not count as a confirmation.
  AddAirKeyframe(3, /*scrambled=*/true);
  const EstimateResult outliers = estimator.Estimate(250000000LL, window_, source_);
  ASSERT_TRUE(outliers.success) << outliers.reason;
  EXPECT_EQ(outliers.air_seqs, (std::vector<int64_t>{0, 1, 2, 3})) << "keyframe 3 was matched";
  EXPECT_FALSE(outliers.gate.publish);
  EXPECT_NE(outliers.gate.reason.find("1/3"), std::string::npos) << outliers.gate.reason;
  // A new keyframe with inliers is new evidence.
  AddAirKeyframe(4);
  const EstimateResult confirming = estimator.Estimate(500000000LL, window_, source_);
  ASSERT_TRUE(confirming.success) << confirming.reason;
  EXPECT_NE(confirming.gate.reason.find("2/3"), std::string::npos) << confirming.gate.reason;
}

TEST_F(AgentEstimatorTest, AblationsRun) {
  for (int config = 0; config < 3; ++config) {
    EstimatorOptions o;
    o.use_stage1 = config == 2;
    o.stage2.use_reprojection = config >= 1;
    AgentEstimator estimator("uav", o, camera_);
    estimator.SetAirCamera("cam", camera_);
    const EstimateResult r = estimator.Estimate(0, window_, source_);
    ASSERT_TRUE(r.success) << config << ": " << r.reason;
    EXPECT_LT((r.T_wa_wg.translation() - T_wa_wg_.translation()).norm(), 0.1) << config;
  }
}

TEST_F(AgentEstimatorTest, ExplainsMissingCameraInfoAndEmptyWindow) {
  AgentEstimator estimator("uav", EstimatorOptions{}, camera_);
  EstimateResult r = estimator.Estimate(0, window_, source_);
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.reason.find("camera_info"), std::string::npos) << r.reason;
  estimator.SetAirCamera("cam", camera_);
  r = estimator.Estimate(0, {}, source_);
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.reason.find("no UGV keyframe"), std::string::npos);
  AgentEstimator other("uav_2", EstimatorOptions{}, camera_);
  other.SetAirCamera("cam", camera_);
  r = other.Estimate(0, window_, source_);
  EXPECT_FALSE(r.success) << "another agent's keyframes are never used";
}

// Seconds as the nanosecond times frames carry.
std::vector<int64_t> Seconds(const std::vector<double>& s) {
  std::vector<int64_t> t;
  t.reserve(s.size());
  for (double x : s) t.push_back(static_cast<int64_t>(x * 1e9));
  return t;
}

TEST(StretchWithMostWeight, KeepsTheStretchWithTheMostInliers) {
  // Two passes over the same place, 30 s apart: the second has more inliers.
  const auto t = Seconds({2, 3, 5, 33, 34, 36, 37});
  const std::vector<int> w = {40, 50, 10, 30, 30, 20, 25};
  EXPECT_EQ(StretchWithMostWeight(t, w, 10.0),
            (std::vector<bool>{false, false, false, true, true, true, true}));
  // Any order of frames; the span is inclusive.
  EXPECT_EQ(StretchWithMostWeight(Seconds({36, 2, 26, 12}), {5, 5, 5, 1}, 10.0),
            (std::vector<bool>{true, false, true, false}));
  // A tie goes to the later stretch (nearer to the UAV's present).
  EXPECT_EQ(StretchWithMostWeight(Seconds({0, 1, 20, 21}), {10, 10, 5, 15}, 5.0),
            (std::vector<bool>{false, false, true, true}));
}

TEST(PivotedBiasCovariance, LeavesThePivotAtTheTranslationSigmaAndGrowsWithDistanceFromIt) {
  const double st = 0.1, syaw = 0.3 * M_PI / 180;
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(5, -3, 1);
  // At the ground world's origin the floor is the plain diagonal.
  const Eigen::Matrix4d C0 = PivotedBiasCovariance(T, Eigen::Vector3d::Zero(), st, syaw);
  EXPECT_TRUE(C0.isApprox(
      Eigen::Vector4d(st * st, st * st, st * st, syaw * syaw).asDiagonal().toDenseMatrix()));
  // With the UGV 80 m away: where T maps a ground point p (R p + t) moves
  // with (t, yaw) by [I, z x R p]; propagated, the pivot itself is as
  // uncertain as sigma_t, while the origin (t itself) is off by 80 m x yaw.
  const Eigen::Vector3d pivot(60, 50, 2);
  const Eigen::Matrix4d C = PivotedBiasCovariance(T, pivot, st, syaw);
  auto mapped = [&](const Eigen::Vector3d& p) {
    Eigen::Matrix<double, 3, 4> J;
    J << Eigen::Matrix3d::Identity(), Eigen::Vector3d::UnitZ().cross(T.linear() * p);
    return Eigen::Matrix3d(J * C * J.transpose());
  };
  EXPECT_TRUE(mapped(pivot).isApprox(st * st * Eigen::Matrix3d::Identity(), 1e-9));
  const double lever = pivot.head<2>().norm();
  EXPECT_NEAR((C.topLeftCorner<2, 2>().trace()), 2 * st * st + std::pow(lever * syaw, 2), 1e-9);
  EXPECT_NEAR(C(2, 2), st * st, 1e-12);
  EXPECT_NEAR(C(3, 3), syaw * syaw, 1e-12);
  // What counts is the distance from the pivot: a point twice as far from
  // the origin, as far beyond the pivot, is off by the same lever.
  const Eigen::Vector3d across = 2 * pivot - Eigen::Vector3d(0, 0, 2 * pivot.z());
  EXPECT_NEAR((mapped(across).topLeftCorner<2, 2>().trace()),
              2 * st * st + std::pow(lever * syaw, 2), 1e-9);
}

TEST(StretchWithMostWeight, NoLimitKeepsAllAndMismatchedSizesAreRejected) {
  EXPECT_EQ(StretchWithMostWeight(Seconds({0, 100}), {1, 1}, 0.0), (std::vector<bool>{true, true}));
  EXPECT_TRUE(StretchWithMostWeight({}, {}, 10.0).empty());
  EXPECT_THROW(StretchWithMostWeight(Seconds({0, 1}), {1}, 10.0), std::invalid_argument);
}

}  // namespace
}  // namespace ag
