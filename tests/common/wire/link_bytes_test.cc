#include "common/wire/link_bytes.h"

#include <gtest/gtest.h>

#include "common/wire/encoding.h"

namespace ag {
namespace {

TEST(LinkBytesTest, SmallMessageIsOneDatagram) {
  const LinkBytes b = LcmLinkBytes("AIR_KF_uav0", 1000);
  EXPECT_EQ(b.datagrams, 1);
  EXPECT_EQ(b.lcm_udp, 8 + 12 + 1000);
  // 1028 bytes of UDP datagram fit one 1500-byte IP packet.
  EXPECT_EQ(b.ip, 1020 + 8 + 20);
  EXPECT_EQ(b.ip_packets, 1);
}

TEST(LinkBytesTest, FragmentationBoundary) {
  const std::string ch = "C";  // 2 bytes with NUL
  EXPECT_EQ(LcmLinkBytes(ch, 65499 - 2).datagrams, 1);
  const LinkBytes two = LcmLinkBytes(ch, 65499 - 1);
  EXPECT_EQ(two.datagrams, 2);
  EXPECT_EQ(two.lcm_udp, 65500 + 2 * 20);  // channel + NUL + payload, two LC03 headers
  const LinkBytes big = LcmLinkBytes(ch, 262144);
  EXPECT_EQ(big.datagrams, (262146 + 65486) / 65487);
  EXPECT_EQ(big.lcm_udp, 262146 + big.datagrams * 20);
}

TEST(LinkBytesTest, IpFragmentationAddsHeaders) {
  // One datagram of 8 + 2 + 10000 bytes -> 10018 bytes with the UDP header,
  // split in 1480-byte IP fragments: 7 packets.
  const LinkBytes b = LcmLinkBytes("C", 10000);
  EXPECT_EQ(b.ip, 10018 + 7 * 20);
  EXPECT_EQ(b.ip_packets, 7);
  EXPECT_GT(LcmLinkBytes("C", 10000, 576).ip, b.ip);
  // Two LCM fragments (datagrams) of 65507 and ~34.7 kB: 45 + 24 IP packets.
  const LinkBytes two = LcmLinkBytes("C", 100000);
  EXPECT_EQ(two.datagrams, 2);
  EXPECT_EQ(two.ip_packets, (65507 + 8 + 1479) / 1480 + (100002 - 65487 + 20 + 8 + 1479) / 1480);
}

TEST(EncodingTest, NamesRoundTrip) {
  for (ArrayEncoding e : {ArrayEncoding::kFloat32, ArrayEncoding::kFloat16, ArrayEncoding::kInt8,
                          ArrayEncoding::kBits4}) {
    EXPECT_EQ(ParseArrayEncoding(ToString(e)), e);
  }
  EXPECT_FALSE(ParseArrayEncoding("float64").has_value());
}

}  // namespace
}  // namespace ag
