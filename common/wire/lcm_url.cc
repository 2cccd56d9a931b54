#include "common/wire/lcm_url.h"

#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>

namespace ag {

namespace {

constexpr const char* kUdpm = "udpm://";
constexpr const char* kRecvBufKey = "recv_buf_size";

bool IsUdpm(const std::string& url) { return url.rfind(kUdpm, 0) == 0; }

/// The value of option `key` in the query part of `url` ("" when absent).
std::optional<std::string> QueryValue(const std::string& url, const std::string& key) {
  const size_t query = url.find('?');
  if (query == std::string::npos) return std::nullopt;
  size_t at = query + 1;
  while (at < url.size()) {
    const size_t end = std::min(url.find('&', at), url.size());
    const std::string option = url.substr(at, end - at);
    const size_t eq = option.find('=');
    if (option.substr(0, eq) == key) {
      return eq == std::string::npos ? std::string() : option.substr(eq + 1);
    }
    at = end + 1;
  }
  return std::nullopt;
}

std::string MegaBytes(int64_t bytes) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.1f MB", static_cast<double>(bytes) / 1e6);
  return buf;
}

}  // namespace

std::string EffectiveLcmUrl(const std::string& url) {
  if (!url.empty()) return url;
  const char* env = std::getenv("LCM_DEFAULT_URL");
  if (env != nullptr && env[0] != '\0') return env;
  return kLcmDefaultUrl;
}

std::optional<int64_t> LcmReceiveBufferOf(const std::string& url) {
  if (!IsUdpm(url)) return std::nullopt;
  const std::optional<std::string> value = QueryValue(url, kRecvBufKey);
  if (!value) return std::nullopt;
  char* end = nullptr;
  const long long n = std::strtoll(value->c_str(), &end, 10);
  if (value->empty() || *end != '\0') return std::nullopt;
  return n;
}

std::string WithLcmReceiveBuffer(const std::string& url, int64_t bytes) {
  std::string out = EffectiveLcmUrl(url);
  if (bytes <= 0 || !IsUdpm(out) || QueryValue(out, kRecvBufKey)) return out;
  out += out.find('?') == std::string::npos ? '?' : '&';
  return out + kRecvBufKey + "=" + std::to_string(bytes);
}

std::optional<int64_t> GrantedReceiveBuffer(int64_t bytes) {
  const int fd = socket(AF_INET, SOCK_DGRAM, 0);
  if (fd < 0) return std::nullopt;
  const int request = static_cast<int>(std::min<int64_t>(bytes, 1 << 30));
  int granted = 0;
  socklen_t size = sizeof(granted);
  const bool ok = setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &request, sizeof(request)) == 0 &&
                  getsockopt(fd, SOL_SOCKET, SO_RCVBUF, &granted, &size) == 0;
  close(fd);
  if (!ok) return std::nullopt;
  return granted / 2;  // Linux reports twice the usable size
}

std::optional<int64_t> KernelRmemMax() {
  std::ifstream in("/proc/sys/net/core/rmem_max");
  int64_t value = 0;
  if (!(in >> value)) return std::nullopt;
  return value;
}

LcmUrlPlan PlanLcmUrl(const std::string& url, int64_t bytes, int64_t needed_bytes) {
  LcmUrlPlan plan;
  plan.url = WithLcmReceiveBuffer(url, bytes);
  if (!IsUdpm(plan.url)) {
    plan.info = "LCM url " + plan.url + " (not udpm://: no kernel receive buffer to size)";
    return plan;
  }
  plan.requested = LcmReceiveBufferOf(plan.url).value_or(0);
  if (plan.requested <= 0) {
    plan.info = "LCM url " + plan.url + " (kernel default receive buffer)";
    plan.warning = "LCM url " + plan.url +
                   " has no recv_buf_size: the kernel default buffer (~208 kB) loses large "
                   "messages (point clouds, images); add recv_buf_size=" +
                   std::to_string(needed_bytes > 0 ? needed_bytes : bytes);
    return plan;
  }
  plan.granted = GrantedReceiveBuffer(plan.requested).value_or(0);
  plan.info = "LCM url " + plan.url + "; kernel receive buffer " +
              (plan.granted > 0 ? MegaBytes(plan.granted) : std::string("unknown")) + " (asked " +
              MegaBytes(plan.requested) + ")";
  if (plan.granted > 0 && plan.granted < needed_bytes) {
    const std::optional<int64_t> rmem_max = KernelRmemMax();
    plan.warning =
        "the kernel grants LCM's UDP socket only " + MegaBytes(plan.granted) + " of receive " +
        "buffer (asked " + MegaBytes(plan.requested) + ", need >= " + MegaBytes(needed_bytes) +
        "): it caps requests at net.core.rmem_max" +
        (rmem_max ? " = " + std::to_string(*rmem_max) : std::string()) +
        ", so bursts of large messages (point clouds, images) will be lost; raise it with "
        "`sysctl -w net.core.rmem_max=" +
        std::to_string(plan.requested) + "` (as root; /etc/sysctl.d/ to keep it)";
  }
  return plan;
}

}  // namespace ag
