// The mock's TCP front under clients that misbehave: one that never reads its replies, one that
// sends a line longer than the input buffer; the injected faults of the fault campaign (drop,
// freeze, timed delay) and the one-connection-at-a-time modes. Real sockets on loopback.
#include "mocks/generator/mock_server.h"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <memory>
#include <stdexcept>
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

  // True when the server closed the connection (EOF) within the failure bound, nothing before.
  bool PeerClosed() {
    pollfd p{fd_, POLLIN, 0};
    if (poll(&p, 1, kFailAfterMs) != 1) return false;
    char c;
    return recv(fd_, &c, 1, 0) == 0;
  }
  // True when bytes are waiting to be read right now (no wait).
  bool HasInput() {
    pollfd p{fd_, POLLIN, 0};
    return !in_.empty() || poll(&p, 1, 0) == 1;
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

namespace msmcal::sim {
namespace {

UnitOptions Identity() {
  UnitOptions u;
  u.identity = "K,33520B,1,2";
  return u;
}

TEST(MockServerFaultTest, ParseFaultReadsTheCommandLineFormAndNamesWhatIsWrong) {
  Fault f = ParseFault("drop,after=3,match=OUTP2 ON");
  EXPECT_EQ(f.kind, FaultKind::kDropConnection);
  EXPECT_EQ(f.skip, 3);
  EXPECT_EQ(f.match, "OUTP2 ON");
  f = ParseFault("delay,match=*OPC?,ms=5000");
  EXPECT_EQ(f.kind, FaultKind::kDelayReply);
  EXPECT_EQ(f.delay_ms, 5000);
  EXPECT_EQ(ParseFault("freeze").kind, FaultKind::kFreeze);
  EXPECT_EQ(ParseFault("garbage").kind, FaultKind::kGarbageReply);
  EXPECT_EQ(ParseFault("drop-mid-reply").kind, FaultKind::kDropMidReply);
  auto error = [](const std::string& text) {
    try {
      ParseFault(text);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error("melt").find("--fault 'melt': unknown kind 'melt'"), std::string::npos);
  EXPECT_NE(error("drop,after=-1").find("after=-1: not a non-negative integer"), std::string::npos);
  EXPECT_NE(error("delay").find("delay needs ms=MS"), std::string::npos);
  EXPECT_NE(error("drop,ms=5").find("ms= applies to delay only"), std::string::npos);
  EXPECT_NE(error("drop,when=now").find("unknown key 'when'"), std::string::npos);
  EXPECT_EQ(ParseSecondConnection("queue"), SecondConnection::kQueue);
  EXPECT_THROW(ParseSecondConnection("refuse"), std::invalid_argument);
}

TEST(MockServerFaultTest, DropClosesTheConnectionWithoutExecutingTheMessage) {
  Mock33520B unit(Identity(), nullptr);
  MockGeneratorServer server(unit, 0);
  server.InjectFault(ParseFault("drop,match=OUTP1"));
  server.Start();
  Client a(server.port());
  ASSERT_TRUE(a.SendAll("*IDN?\n"));
  EXPECT_EQ(a.ReadLine(), "K,33520B,1,2");
  ASSERT_TRUE(a.SendAll("OUTP1 ON\n"));
  EXPECT_TRUE(a.PeerClosed());
  Client b(server.port());  // the instrument itself is fine
  ASSERT_TRUE(b.SendAll("OUTP1?\n"));
  EXPECT_EQ(b.ReadLine(), "0");
  EXPECT_EQ(server.Stats().faults_applied, 1u);
}

TEST(MockServerFaultTest, FreezeIgnoresEverythingOnThatConnectionAndServesTheNextOne) {
  Mock33520B unit(Identity(), nullptr);
  MockGeneratorServer server(unit, 0);
  server.InjectFault(ParseFault("freeze,after=1"));
  server.Start();
  Client a(server.port());
  ASSERT_TRUE(a.SendAll("*IDN?\n"));
  EXPECT_EQ(a.ReadLine(), "K,33520B,1,2");
  ASSERT_TRUE(a.SendAll("OUTP1 ON\n*IDN?\n"));
  ASSERT_TRUE(
      server.WaitForStats([](const ServerStats& s) { return s.messages == 3; }, kFailAfterMs));
  Client b(server.port());
  ASSERT_TRUE(b.SendAll("OUTP1?\n"));
  EXPECT_EQ(b.ReadLine(), "0");  // OUTP1 ON was not executed
  EXPECT_FALSE(a.HasInput());    // and the frozen connection's query got no reply
  EXPECT_EQ(server.Stats().connections_closed, 0u);  // it stays open
}

TEST(MockServerFaultTest, TimedDelayHoldsTheReplyAndTheRepliesAfterIt) {
  Mock33520B unit(Identity(), nullptr);
  MockGeneratorServer server(unit, 0);
  server.InjectFault(ParseFault("delay,match=*OPC?,ms=300"));
  server.Start();
  Client a(server.port());
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(a.SendAll("*OPC?\n*IDN?\n"));
  EXPECT_EQ(a.ReadLine(), "1");
  EXPECT_GE(std::chrono::steady_clock::now() - t0, std::chrono::milliseconds(300));
  EXPECT_EQ(a.ReadLine(), "K,33520B,1,2");  // in order: a slow instrument, not a reordering one
}

TEST(MockServerFaultTest, QueuedSecondConnectionIsServedWhenTheFirstCloses) {
  Mock33520B unit(Identity(), nullptr);
  ServerLimits limits;
  limits.second_connection = SecondConnection::kQueue;
  MockGeneratorServer server(unit, 0, limits);
  server.Start();
  auto a = std::make_unique<Client>(server.port());
  ASSERT_TRUE(a->SendAll("*IDN?\n"));
  EXPECT_EQ(a->ReadLine(), "K,33520B,1,2");
  Client b(server.port());
  ASSERT_TRUE(b.connected());  // accepted...
  ASSERT_TRUE(b.SendAll("*IDN?\n"));
  ASSERT_TRUE(
      server.WaitForStats([](const ServerStats& s) { return s.connections == 2; }, kFailAfterMs));
  ASSERT_TRUE(a->SendAll("*OPC?\n"));
  EXPECT_EQ(a->ReadLine(), "1");
  EXPECT_EQ(server.Stats().messages, 2u);  // ...but not read while the first is open
  EXPECT_FALSE(b.HasInput());
  a.reset();
  EXPECT_EQ(b.ReadLine(), "K,33520B,1,2");
}

TEST(MockServerFaultTest, ClosedSecondConnectionIsTurnedAwayAndTheNextOneServed) {
  Mock33520B unit(Identity(), nullptr);
  ServerLimits limits;
  limits.second_connection = SecondConnection::kClose;
  MockGeneratorServer server(unit, 0, limits);
  server.Start();
  auto a = std::make_unique<Client>(server.port());
  ASSERT_TRUE(a->SendAll("*IDN?\n"));
  EXPECT_EQ(a->ReadLine(), "K,33520B,1,2");
  Client b(server.port());
  EXPECT_TRUE(b.PeerClosed());
  EXPECT_EQ(server.Stats().connections_turned_away, 1u);
  a.reset();
  ASSERT_TRUE(server.WaitForStats([](const ServerStats& s) { return s.connections_closed == 2; },
                                  kFailAfterMs));
  Client c(server.port());
  ASSERT_TRUE(c.SendAll("*IDN?\n"));
  EXPECT_EQ(c.ReadLine(), "K,33520B,1,2");
}

}  // namespace
}  // namespace msmcal::sim
