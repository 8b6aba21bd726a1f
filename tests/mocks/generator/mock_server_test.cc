// The mock's TCP front under clients that misbehave: one that never reads its replies, one that
// sends a line longer than the input buffer. Real sockets on loopback.
#include "mocks/generator/mock_server.h"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <string>
#include <thread>

namespace msmcal::sim {
namespace {

constexpr int kFailAfterMs = 20'000;  // failure bound only; every wait ends on a condition

class Client {
 public:
  explicit Client(int port) {
    fd_ = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connected_ = connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof(a)) == 0;
  }
  ~Client() { close(fd_); }
  bool connected() const { return connected_; }

  bool SendAll(const std::string& bytes) {
    size_t off = 0;
    while (off < bytes.size()) {
      const ssize_t n = send(fd_, bytes.data() + off, bytes.size() - off, MSG_NOSIGNAL);
      if (n <= 0) return false;
      off += static_cast<size_t>(n);
    }
    return true;
  }

  // One line without its '\n'; "<timeout>" when none arrives within the failure bound.
  std::string ReadLine() {
    for (;;) {
      const size_t nl = in_.find('\n');
      if (nl != std::string::npos) {
        std::string line = in_.substr(0, nl);
        in_.erase(0, nl + 1);
        return line;
      }
      if (!Fill()) return "<timeout>";
    }
  }

  // Counts '\n'-terminated replies until `count` arrived; false on timeout.
  bool CountLines(size_t count, const std::string& each) {
    size_t seen = 0;
    while (seen < count) {
      size_t nl;
      while ((nl = in_.find('\n')) != std::string::npos) {
        if (in_.compare(0, nl, each) != 0) return false;
        in_.erase(0, nl + 1);
        if (++seen == count) return true;
      }
      if (!Fill()) return false;
    }
    return true;
  }

 private:
  bool Fill() {
    pollfd p{fd_, POLLIN, 0};
    if (poll(&p, 1, kFailAfterMs) != 1) return false;
    char buf[65536];
    const ssize_t n = recv(fd_, buf, sizeof(buf), 0);
    if (n <= 0) return false;
    in_.append(buf, static_cast<size_t>(n));
    return true;
  }

  int fd_ = -1;
  bool connected_ = false;
  std::string in_;
};

TEST(MockServerTest, UnreadRepliesApplyBackPressureAndOtherClientsStayServed) {
  UnitOptions u;
  u.identity = "K,33520B,1,2";
  Mock33520B unit(u, nullptr);
  ServerLimits limits;
  limits.max_pending_reply_bytes = 64 << 10;
  MockGeneratorServer server(unit, 0, limits);
  server.Start();

  // 4 MiB of queries from a client that does not read (yet): ~5.6 MB of replies.
  std::string queries;
  while (queries.size() < (4u << 20)) queries += "*IDN?\n";
  const size_t n_queries = queries.size() / 6;
  Client flood(server.port());
  ASSERT_TRUE(flood.connected());
  bool sent = false;
  std::thread sender([&] { sent = flood.SendAll(queries); });

  // The server stops reading the flooding connection...
  ASSERT_TRUE(
      server.WaitForStats([](const ServerStats& s) { return s.read_pauses > 0; }, kFailAfterMs));
  // ...and still serves another client.
  Client other(server.port());
  ASSERT_TRUE(other.connected());
  ASSERT_TRUE(other.SendAll("*IDN?\n"));
  EXPECT_EQ(other.ReadLine(), u.identity);

  // Reading the replies lets everything through, in order, nothing dropped.
  EXPECT_TRUE(flood.CountLines(n_queries, u.identity));
  sender.join();
  EXPECT_TRUE(sent);
  const ServerStats st = server.Stats();
  EXPECT_EQ(st.messages, n_queries + 1);
  // Memory per connection: the reply cap plus one reply; one read chunk of input plus the start
  // of a message.
  EXPECT_LE(st.pending_reply_high_water, limits.max_pending_reply_bytes + u.identity.size() + 1);
  EXPECT_LE(st.input_high_water, (size_t{64} << 10) + 6);
  EXPECT_EQ(unit.ErrorCount(), 0u);
}

TEST(MockServerTest, OverlongMessageOverrunsInputBufferAndConnectionStaysUsable) {
  Mock33520B unit(UnitOptions{}, nullptr);
  ServerLimits limits;
  limits.max_message_bytes = 4096;
  MockGeneratorServer server(unit, 0, limits);
  server.Start();
  Client c(server.port());
  ASSERT_TRUE(c.connected());

  // A plain long line, then a long block whose payload holds '\n' (not a terminator).
  std::string block(10000, 'x');
  block[17] = '\n';
  block[5000] = '\n';
  ASSERT_TRUE(c.SendAll("FREQ 1" + std::string(10000, '0') + "\n"));
  ASSERT_TRUE(c.SendAll("DATA:ARB:DAC BIG,#510000" + block + "\n*IDN?\n"));
  EXPECT_EQ(c.ReadLine(), UnitOptions{}.identity);
  ASSERT_TRUE(c.SendAll("SYST:ERR?;ERR?;ERR?;:FREQ?\n"));
  EXPECT_EQ(c.ReadLine(),
            "-363,\"Input buffer overrun\";-363,\"Input buffer overrun\";+0,\"No error\";"
            "+1.0000000000000E+03");
  EXPECT_EQ(server.Stats().input_overruns, 2u);
  // A message of exactly the limit is accepted.
  std::string at_limit = "FREQ 2000";
  at_limit += std::string(4096 - at_limit.size(), ' ');
  ASSERT_TRUE(c.SendAll(at_limit + "\nFREQ?;:SYST:ERR?\n"));
  EXPECT_EQ(c.ReadLine(), "+2.0000000000000E+03;+0,\"No error\"");
}

}  // namespace
}  // namespace msmcal::sim
