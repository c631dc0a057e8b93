// The transport options' checks (transport/options.hpp): each wrong value is named with why,
// and each value the shipped configs and docs use passes.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include "transport/options.hpp"
#include "transport/zenoh_session.hpp"

using namespace hapticloth::transport;

TEST(ServerName, OneChunkOfAKeyExpression) {
  EXPECT_EQ(server_name_error("default"), "");
  EXPECT_EQ(server_name_error("lab-1_rig"), "");
  EXPECT_NE(server_name_error(""), "");
  for (const char* bad : {"a/b", "a*", "$x", "a?b", "a#b"})
    EXPECT_NE(server_name_error(bad).find(bad), std::string::npos) << bad;
}

TEST(ZenohEndpoint, ProtocolSlashAddress) {
  for (const char* good : {"tcp/127.0.0.1:7447", "udp/127.0.0.1:0", "tcp/[::1]:7447",
                           "tcp/localhost:7447#iface=lo", "unixsock-stream//tmp/z.sock"})
    EXPECT_EQ(zenoh_endpoint_error(good), "") << good;
  for (const char* bad : {"garbage", "/x", "tcp/", "TCP!/1.2.3.4:5", "tcp/127.0.0.1",
                          "tcp/127.0.0.1:99999", "tcp/:7447", "udp/1.2.3.4:port"})
    EXPECT_NE(zenoh_endpoint_error(bad).find(bad), std::string::npos) << bad;
}

TEST(LcmUrl, AProviderLcmHas) {
  for (const char* good : {"udpm://239.255.76.67:7667?ttl=0", "file:///tmp/x.lcm?mode=w", "memq://",
                           "tcpq://127.0.0.1:7700"})
    EXPECT_EQ(lcm_url_error(good), "") << good;
  for (const char* bad : {"nosuch://x", "udpm", "", "239.255.76.67:7667"})
    EXPECT_NE(lcm_url_error(bad), "") << bad;
}

TEST(ZenohSession, APortInUseIsAnOpenErrorWithoutRustSourcePaths) {
  // A TCP port held by a listening socket of this test: zenoh cannot listen on it.
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  ASSERT_GE(fd, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof a;
  ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  ASSERT_EQ(::listen(fd, 1), 0);
  ASSERT_EQ(::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len), 0);
  const std::string port = std::to_string(ntohs(a.sin_port));
  const std::string ep = "tcp/127.0.0.1:" + port;
  try {
    ZenohSession second("", ep);
    ::close(fd);
    FAIL() << "a session listened on " << ep << ", a port in use";
  } catch (const ZenohOpenError& e) {
    ::close(fd);
    const std::string m = e.what();
    EXPECT_NE(m.find(port), std::string::npos) << m;
    EXPECT_NE(m.find("in use"), std::string::npos) << m;
    EXPECT_EQ(m.find(".rs:"), std::string::npos) << m;
    EXPECT_EQ(m.find(".cargo"), std::string::npos) << m;
  }
}
