// The daemons' LCM URLs: a udpm:// URL without recv_buf_size gets one, every
// other URL is left alone, and an empty URL resolves as lcm_create would.
#include "common/wire/lcm_url.h"

#include <gtest/gtest.h>

#include <cstdlib>

namespace ag {
namespace {

/// Sets or unsets $LCM_DEFAULT_URL for one test, restoring it afterwards.
class ScopedDefaultUrl {
 public:
  explicit ScopedDefaultUrl(const char* value) {
    if (const char* old = std::getenv("LCM_DEFAULT_URL")) old_ = old;
    if (value) {
      setenv("LCM_DEFAULT_URL", value, 1);
    } else {
      unsetenv("LCM_DEFAULT_URL");
    }
  }
  ~ScopedDefaultUrl() {
    if (old_.empty()) {
      unsetenv("LCM_DEFAULT_URL");
    } else {
      setenv("LCM_DEFAULT_URL", old_.c_str(), 1);
    }
  }

 private:
  std::string old_;
};

TEST(LcmUrl, AddsTheReceiveBufferToUdpmUrls) {
  EXPECT_EQ(WithLcmReceiveBuffer("udpm://239.255.76.67:7667?ttl=0", 8388608),
            "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608");
  EXPECT_EQ(WithLcmReceiveBuffer("udpm://239.255.76.67:7667", 1000),
            "udpm://239.255.76.67:7667?recv_buf_size=1000");
  EXPECT_EQ(WithLcmReceiveBuffer("udpm://", 1000), "udpm://?recv_buf_size=1000");
}

TEST(LcmUrl, KeepsAnExplicitReceiveBufferAndOtherProviders) {
  const std::string given = "udpm://239.255.76.67:7667?recv_buf_size=4096&ttl=0";
  EXPECT_EQ(WithLcmReceiveBuffer(given, 8388608), given);
  EXPECT_EQ(WithLcmReceiveBuffer("memq://", 8388608), "memq://");
  EXPECT_EQ(WithLcmReceiveBuffer("file:///tmp/x.lcm?mode=r", 8388608), "file:///tmp/x.lcm?mode=r");
  EXPECT_EQ(WithLcmReceiveBuffer("udpm://239.255.76.67:7667?ttl=0", 0),
            "udpm://239.255.76.67:7667?ttl=0");
  // An option whose name merely ends like it is another option.
  EXPECT_EQ(WithLcmReceiveBuffer("udpm://?xrecv_buf_size=5", 7),
            "udpm://?xrecv_buf_size=5&recv_buf_size=7");
}

TEST(LcmUrl, EmptyUrlResolvesLikeLcmCreate) {
  {
    ScopedDefaultUrl env(nullptr);
    EXPECT_EQ(EffectiveLcmUrl(""), kLcmDefaultUrl);
    EXPECT_EQ(WithLcmReceiveBuffer("", 100), std::string(kLcmDefaultUrl) + "&recv_buf_size=100");
  }
  {
    ScopedDefaultUrl env("udpm://239.255.0.1:7000?ttl=1");
    EXPECT_EQ(WithLcmReceiveBuffer("", 100), "udpm://239.255.0.1:7000?ttl=1&recv_buf_size=100");
    EXPECT_EQ(EffectiveLcmUrl("memq://"), "memq://");
  }
}

TEST(LcmUrl, ReadsTheReceiveBuffer) {
  EXPECT_EQ(LcmReceiveBufferOf("udpm://?ttl=0&recv_buf_size=123"), 123);
  EXPECT_FALSE(LcmReceiveBufferOf("udpm://?ttl=0").has_value());
  EXPECT_FALSE(LcmReceiveBufferOf("udpm://?recv_buf_size=12x").has_value());
  EXPECT_FALSE(LcmReceiveBufferOf("memq://?recv_buf_size=12").has_value());
}

TEST(LcmUrl, PlanWarnsNamingTheSysctlWhenTheKernelCapsTheBuffer) {
  const std::optional<int64_t> granted_small = GrantedReceiveBuffer(64 * 1024);
  if (!granted_small) GTEST_SKIP() << "no UDP socket could be made here";
  // Ask for more than any kernel grants unprivileged (rmem_max is at most a
  // few hundred MB in practice): the plan must warn and name the sysctl.
  const int64_t huge = int64_t{1} << 30;
  const LcmUrlPlan plan = PlanLcmUrl("udpm://239.255.76.67:7667?ttl=0", huge, huge);
  EXPECT_EQ(plan.requested, huge);
  EXPECT_EQ(plan.url, "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=1073741824");
  ASSERT_GT(plan.granted, 0);
  EXPECT_LT(plan.granted, huge);
  EXPECT_NE(plan.warning.find("net.core.rmem_max"), std::string::npos) << plan.warning;
  const std::optional<int64_t> rmem_max = KernelRmemMax();
  if (rmem_max) {
    EXPECT_EQ(plan.granted, *rmem_max) << "the cap is rmem_max";
  }

  // A need the kernel meets: no warning.
  const LcmUrlPlan fine = PlanLcmUrl("udpm://239.255.76.67:7667?ttl=0", 64 * 1024, 32 * 1024);
  EXPECT_TRUE(fine.warning.empty()) << fine.warning;
  EXPECT_NE(fine.info.find("recv_buf_size=65536"), std::string::npos) << fine.info;

  // Not udpm: nothing to size, nothing to warn about.
  const LcmUrlPlan memq = PlanLcmUrl("memq://", huge, huge);
  EXPECT_EQ(memq.url, "memq://");
  EXPECT_TRUE(memq.warning.empty());
}

}  // namespace
}  // namespace ag
