// The SCPI client against the mock 33520B over loopback: exchanges, blocks, transcripts, and every
// failure mode ending in a typed error within its deadline.
#include "drivers/scpi/scpi_client.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>

#include "drivers/scpi/scpi_text.h"
#include "mocks/generator/mock_server.h"

namespace msmcal::scpi {
namespace {

class ScpiClientTest : public ::testing::Test {
 protected:
  void SetUp() override { server_.Start(); }
  ScpiClientOptions Options(int io_timeout_ms = 2000) {
    ScpiClientOptions o;
    o.port = server_.port();
    o.io_timeout_ms = io_timeout_ms;
    return o;
  }
  sim::Mock33520B unit_{sim::UnitOptions{}, nullptr};
  sim::MockGeneratorServer server_{unit_, 0};
};

TEST_F(ScpiClientTest, QueryWriteAndTranscript) {
  std::vector<TranscriptEntry> transcript;
  int64_t fake_ns = 0;
  ScpiClient c(Options(), [&] { return fake_ns += 10; });
  c.SetTranscriptSink([&](const TranscriptEntry& e) { transcript.push_back(e); });
  c.Connect();
  EXPECT_EQ(ParseIdentity(c.Query("*IDN?")).model, "33522B");
  c.Write("FREQ 2 KHZ");
  EXPECT_DOUBLE_EQ(ParseNumber(c.Query("FREQ?")), 2000.0);
  c.CheckErrors("FREQ 2 KHZ");
  c.WaitOperationComplete();
  ASSERT_GE(transcript.size(), 6u);
  EXPECT_TRUE(transcript[0].to_instrument);
  EXPECT_EQ(transcript[0].text, "*IDN?");
  EXPECT_FALSE(transcript[1].to_instrument);
  EXPECT_EQ(transcript[0].time_ns, 10);
}

TEST_F(ScpiClientTest, InstrumentErrorNamesCommandAndEntries) {
  ScpiClient c(Options());
  c.Connect();
  c.Write("FREQ 1 FOO;BOGUS");
  try {
    c.CheckErrors("FREQ 1 FOO;BOGUS");
    FAIL();
  } catch (const ScpiError& e) {
    EXPECT_EQ(e.kind(), ErrorKind::kInstrument);
    const std::string m = e.what();
    EXPECT_NE(m.find("-131"), std::string::npos) << m;
    EXPECT_NE(m.find("-113"), std::string::npos) << m;
    EXPECT_NE(m.find("FREQ 1 FOO;BOGUS"), std::string::npos) << m;
  }
  c.CheckErrors("nothing");  // queue drained
}

TEST_F(ScpiClientTest, BlockPayloadWithNewlinesIsByteExact) {
  ScpiClient c(Options());
  c.Connect();
  std::vector<int16_t> samples = {0x0A0A, 0x0A00, -32767, 32767, 10, 13, 0x3B3B, 0x2323};
  c.Write("FORM:BORD SWAP");
  c.WriteBlock("DATA:ARB:DAC NL,", Int16Payload(samples, false));
  c.CheckErrors("upload");
  EXPECT_EQ(c.Query("DATA:ATTR:POIN? NL"), "+8");
  c.Write("FUNC:ARB NL");
  c.CheckErrors("select");
}

TEST_F(ScpiClientTest, DelayedReplyTimesOutAndDropsTheLink) {
  ScpiClient c(Options(/*io_timeout_ms=*/200));
  c.Connect();
  server_.InjectFault({sim::FaultKind::kDelayReply, "*IDN?"});
  try {
    c.Query("*IDN?");
    FAIL();
  } catch (const ScpiError& e) {
    EXPECT_EQ(e.kind(), ErrorKind::kTimeout);
    EXPECT_NE(std::string(e.what()).find("*IDN?"), std::string::npos);
  }
  EXPECT_FALSE(c.IsConnected());
  server_.ReleaseDelayedReplies();  // arrives on the closed link, never confuses the next one
  c.Reconnect();
  EXPECT_EQ(c.Query("*OPC?"), "1");
}

TEST_F(ScpiClientTest, DroppedConnectionMidReply) {
  ScpiClient c(Options());
  c.Connect();
  server_.InjectFault({sim::FaultKind::kDropMidReply, "*IDN?"});
  try {
    c.Query("*IDN?");
    FAIL();
  } catch (const ScpiError& e) {
    EXPECT_EQ(e.kind(), ErrorKind::kConnectionLost) << e.what();
  }
  EXPECT_FALSE(c.IsConnected());
  EXPECT_THROW(c.Query("*IDN?"), ScpiError);  // no silent reconnect
}

TEST_F(ScpiClientTest, GarbageReply) {
  ScpiClient c(Options());
  c.Connect();
  server_.InjectFault({sim::FaultKind::kGarbageReply, ""});
  try {
    c.Query("*IDN?");
    FAIL();
  } catch (const ScpiError& e) {
    EXPECT_EQ(e.kind(), ErrorKind::kGarbage) << e.what();
  }
}

TEST(ScpiClientConnectTest, RefusedConnectionIsTyped) {
  // Bind then stop a server to get a port with no listener.
  sim::Mock33520B unit(sim::UnitOptions{}, nullptr);
  sim::MockGeneratorServer server(unit, 0);
  server.Start();
  const int port = server.port();
  server.Stop();
  ScpiClientOptions o;
  o.port = port;
  o.connect_timeout_ms = 1000;
  ScpiClient c(o);
  try {
    c.Connect();
    FAIL();
  } catch (const ScpiError& e) {
    EXPECT_EQ(e.kind(), ErrorKind::kConnectFailed);
  }
  EXPECT_THROW(c.Query("*IDN?"), ScpiError);
}

// A host name is resolved by name (not only numeric addresses) and the instrument answers.
TEST_F(ScpiClientTest, ConnectsByHostName) {
  ScpiClientOptions o = Options();
  o.host = "localhost";
  ScpiClient c(o);
  try {
    c.Connect();
  } catch (const ScpiError& e) {
    GTEST_SKIP() << "localhost does not resolve to the mock's address here: " << e.what();
  }
  EXPECT_NE(c.Query("*IDN?").find(",335"), std::string::npos);
}

// Name resolution cannot be cancelled; it runs on its own thread and the connect timeout bounds
// the wait. A lookup that never returns (blocked on a pipe nobody writes) gives up in time.
TEST(ScpiClientConnectTest, ABlockedLookupIsBoundedByTheTimeout) {
  int fds[2];
  ASSERT_EQ(pipe(fds), 0);
  const int read_end = fds[0];
  const auto t0 = std::chrono::steady_clock::now();
  const auto r = detail::CallWithin(
      [read_end] {
        char c;
        (void)!read(read_end, &c, 1);
        return std::vector<std::string>{"late"};
      },
      /*timeout_ms=*/100);
  const auto waited = std::chrono::steady_clock::now() - t0;
  EXPECT_FALSE(r.has_value());
  EXPECT_GE(waited, std::chrono::milliseconds(100));
  EXPECT_LT(waited, std::chrono::seconds(5));
  ASSERT_EQ(write(fds[1], "x", 1), 1);  // lets the abandoned lookup finish
  close(fds[1]);
  // A lookup that finishes hands over its result, and what it throws reaches the caller.
  EXPECT_EQ(detail::CallWithin(
                [] {
                  return std::vector<std::string>{"a", "b"};
                },
                5000),
            (std::vector<std::string>{"a", "b"}));
  EXPECT_THROW(
      detail::CallWithin(
          []() -> std::vector<std::string> { throw std::runtime_error("no such host"); }, 5000),
      std::runtime_error);
}

TEST(ScpiClientConnectTest, AnUnknownHostIsAConnectFailure) {
  ScpiClientOptions o;
  o.host = "no-such-instrument.invalid";  // RFC 2606: never resolves
  o.port = 5025;
  o.connect_timeout_ms = 2000;
  ScpiClient c(o);
  try {
    c.Connect();
    FAIL();
  } catch (const ScpiError& e) {
    EXPECT_EQ(e.kind(), ErrorKind::kConnectFailed);
    EXPECT_NE(std::string(e.what()).find("cannot resolve host"), std::string::npos) << e.what();
  }
}

TEST(ScpiClientOptionsTest, ValidateNamesField) {
  ScpiClientOptions o;
  o.port = 70000;
  EXPECT_EQ(o.Validate(), "port = 70000: must be in [1, 65535]");
  EXPECT_THROW(ScpiClient{o}, std::invalid_argument);
}

}  // namespace
}  // namespace msmcal::scpi
