#pragma once

// LCM provider URLs of the daemons: the kernel receive buffer their UDP
// multicast socket asks for.
//
// A point cloud (~420 kB) or a PNG image is one burst of ~300 datagrams; with
// Linux's default 208 kB socket buffer a receiver loses most of them (the
// README's measurement: 3 to 14 of 20 scans arrived). LCM asks for a larger
// buffer only when the URL says so (udpm://GROUP:PORT?recv_buf_size=N), and
// the kernel silently caps the request at net.core.rmem_max.

#include <cstdint>
#include <optional>
#include <string>

namespace ag {

/// LCM's own default URL (what lcm_create uses for an empty URL when
/// $LCM_DEFAULT_URL is unset; lcm.h of LCM 1.3 and later).
inline const char* kLcmDefaultUrl = "udpm://239.255.76.67:7667?ttl=0";

/// The URL lcm_create would use for `url`: `url` itself, or for an empty one
/// $LCM_DEFAULT_URL, or LCM's default.
std::string EffectiveLcmUrl(const std::string& url);

/// `url` (resolved as EffectiveLcmUrl) with `recv_buf_size=bytes` added when
/// it is a udpm:// URL without a recv_buf_size of its own; any other URL, or
/// bytes <= 0, comes back resolved but otherwise unchanged.
std::string WithLcmReceiveBuffer(const std::string& url, int64_t bytes);

/// The recv_buf_size of a udpm:// URL, if it has one.
std::optional<int64_t> LcmReceiveBufferOf(const std::string& url);

/// What the kernel grants a UDP socket that asks for `bytes` of receive
/// buffer (SO_RCVBUF set, then read back and halved: Linux doubles the value
/// for its bookkeeping). nullopt when no socket could be made.
std::optional<int64_t> GrantedReceiveBuffer(int64_t bytes);

/// net.core.rmem_max (/proc/sys/net/core/rmem_max), if readable.
std::optional<int64_t> KernelRmemMax();

/// The URL a daemon opens LCM with, and what it should log about it.
struct LcmUrlPlan {
  std::string url;        ///< to pass to lcm::LCM
  int64_t requested = 0;  ///< recv_buf_size in the URL (0: none, not udpm)
  int64_t granted = 0;    ///< what the kernel gives a socket asking that (0: unknown)
  std::string info;       ///< one line for the log (always)
  std::string warning;    ///< non-empty: the buffer is smaller than `needed_bytes`
};

/// Adds a receive buffer of `bytes` to a udpm:// URL lacking one (see
/// WithLcmReceiveBuffer), checks what the kernel grants, and when that is
/// below `needed_bytes` explains in `warning` which sysctl to raise.
LcmUrlPlan PlanLcmUrl(const std::string& url, int64_t bytes, int64_t needed_bytes);

}  // namespace ag
