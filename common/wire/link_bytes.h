#pragma once

#include <cstdint>
#include <string>

namespace ag {

/// Bytes that one LCM publish puts on the link, by layer.
struct LinkBytes {
  int64_t payload = 0;     ///< the encoded LCM message
  int64_t lcm_udp = 0;     ///< UDP payloads LCM sends (its headers + channel + message)
  int64_t datagrams = 0;   ///< UDP datagrams (LCM fragments)
  int64_t ip = 0;          ///< IPv4 bytes incl. UDP/IP headers and IP fragmentation at `mtu`
  int64_t ip_packets = 0;  ///< IPv4 packets (fragments); the message is lost if any one is
};

/// Exact byte accounting of LCM's UDP multicast transport (LCM 1.3, Linux):
/// a message whose channel name + NUL + payload fits in 65499 bytes goes in one
/// datagram with the 8-byte "LC02" header; larger ones are split into
/// fragments of at most 65487 bytes of (channel + NUL + payload), each with the
/// 20-byte "LC03" header. Each datagram then gets an 8-byte UDP header and is
/// split by IPv4 into packets of at most `mtu` bytes, each with a 20-byte IP
/// header. The `ip` figure is what a link shaper such as `tc` counts (less the
/// Ethernet framing), so bandwidth budgets are checked against it.
LinkBytes LcmLinkBytes(const std::string& channel, int64_t encoded_size, int mtu = 1500);

}  // namespace ag
