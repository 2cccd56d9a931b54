#include "common/wire/link_bytes.h"

namespace ag {
namespace {

constexpr int64_t kShortHeader = 8;             // LC02: magic, seqno
constexpr int64_t kLongHeader = 20;             // LC03: magic, seqno, size, offset, no, count
constexpr int64_t kShortMaxPayload = 65499;     // channel + NUL + message, one datagram
constexpr int64_t kFragmentMaxPayload = 65487;  // per LC03 fragment
constexpr int64_t kUdpHeader = 8;
constexpr int64_t kIpHeader = 20;

// IPv4 bytes of one UDP datagram carrying `udp_payload` bytes.
int64_t IpBytes(int64_t udp_payload, int mtu) {
  const int64_t datagram = udp_payload + kUdpHeader;
  // IP fragments carry multiples of 8 bytes except the last.
  const int64_t per_fragment = ((mtu - kIpHeader) / 8) * 8;
  const int64_t fragments = (datagram + per_fragment - 1) / per_fragment;
  return datagram + fragments * kIpHeader;
}

}  // namespace

LinkBytes LcmLinkBytes(const std::string& channel, int64_t encoded_size, int mtu) {
  LinkBytes out;
  out.payload = encoded_size;
  const int64_t body = static_cast<int64_t>(channel.size()) + 1 + encoded_size;
  if (body <= kShortMaxPayload) {
    out.datagrams = 1;
    out.lcm_udp = kShortHeader + body;
    out.ip = IpBytes(out.lcm_udp, mtu);
    out.ip_packets = (out.ip - out.lcm_udp - kUdpHeader) / kIpHeader;
    return out;
  }
  out.datagrams = (body + kFragmentMaxPayload - 1) / kFragmentMaxPayload;
  out.lcm_udp = body + out.datagrams * kLongHeader;
  for (int64_t i = 0; i < out.datagrams; ++i) {
    const int64_t chunk = i + 1 < out.datagrams ? kFragmentMaxPayload
                                                : body - (out.datagrams - 1) * kFragmentMaxPayload;
    out.ip += IpBytes(kLongHeader + chunk, mtu);
  }
  // Every IP packet adds one IP header, every datagram one UDP header.
  out.ip_packets = (out.ip - out.lcm_udp - out.datagrams * kUdpHeader) / kIpHeader;
  return out;
}

}  // namespace ag
