#include "air_agent/keyframe/keyframe_selector.h"

#include <gtest/gtest.h>

#include "common/core/error.h"

namespace ag {
namespace {

constexpr int64_t kMs = 1000000LL;

TEST(KeyframeSelectorTest, OnePerPeriodAtTenHertz) {
  KeyframeSelector s({});
  int keyframes = 0;
  for (int i = 0; i <= 100; ++i) {  // 10 s at 10 Hz
    const auto d = s.Consider(i * 100 * kMs, Pose::Identity());
    keyframes += d.is_keyframe;
    if (i == 0) {
      EXPECT_EQ(d.reason, KeyframeSelector::Reason::kFirst);
    } else if (i == 10) {
      EXPECT_EQ(d.reason, KeyframeSelector::Reason::kTime);
    }
    EXPECT_EQ(d.is_keyframe, i % 10 == 0) << i;
  }
  EXPECT_EQ(keyframes, 11);
}

TEST(KeyframeSelectorTest, MotionTriggersBetweenPeriods) {
  KeyframeSelector::Options o;
  o.min_translation_m = 1.0;
  o.min_rotation_deg = 20.0;
  KeyframeSelector s(o);
  EXPECT_TRUE(s.Consider(0, Pose::Identity()).is_keyframe);
  EXPECT_FALSE(s.Consider(300 * kMs, MakePose4Dof(0.5, 0, 0, 0)).is_keyframe);
  auto d = s.Consider(400 * kMs, MakePose4Dof(1.2, 0, 0, 0));
  EXPECT_TRUE(d.is_keyframe);
  EXPECT_EQ(d.reason, KeyframeSelector::Reason::kTranslation);
  d = s.Consider(700 * kMs, MakePose4Dof(1.2, 0, 0, 0.5));
  EXPECT_TRUE(d.is_keyframe);
  EXPECT_EQ(d.reason, KeyframeSelector::Reason::kRotation);
  // min_interval_s: fast motion right after a keyframe waits.
  EXPECT_FALSE(s.Consider(750 * kMs, MakePose4Dof(5, 0, 0, 0.5)).is_keyframe);
}

TEST(KeyframeSelectorTest, RejectKeepsTheReference) {
  KeyframeSelector s({});
  EXPECT_TRUE(s.Consider(0, Pose::Identity()).is_keyframe);
  EXPECT_TRUE(s.Consider(1000 * kMs, Pose::Identity()).is_keyframe);
  s.Reject();  // not sent (e.g. over budget): the next frame is due at once
  EXPECT_TRUE(s.Consider(1100 * kMs, Pose::Identity()).is_keyframe);
  EXPECT_FALSE(s.Consider(1200 * kMs, Pose::Identity()).is_keyframe);
  EXPECT_FALSE(s.Consider(900 * kMs, Pose::Identity()).is_keyframe) << "older frame";
}

TEST(KeyframeSelectorTest, OptionsAreChecked) {
  KeyframeSelector::Options o;
  o.period_s = 0;
  EXPECT_THROW(KeyframeSelector{o}, OptionError);
  o.period_s = -1;
  EXPECT_THROW(o.Check(), OptionError);
}

}  // namespace
}  // namespace ag
