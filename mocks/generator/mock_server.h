#pragma once
// TCP front of a Mock33520B on 127.0.0.1 (raw SCPI socket, like port 5025 of the instrument), with
// fault injection, and the rig's pair of units with their 10 MHz and trigger wiring.
//
// Framing: a program message ends with '\n' outside quoted strings and definite-length blocks
// (a trailing '\r', as pyvisa sends, is ignored); each response message is written in one send.
// Memory per connection is bounded (ServerLimits): a client that sends queries without reading
// the replies is flow-controlled (the server stops reading its socket while its unsent replies
// exceed the cap, and resumes as they drain; nothing is dropped), and a program message longer
// than the input buffer is discarded up to its terminator with -363 "Input buffer overrun"
// (the connection stays usable). One slow or hostile client never blocks the others.
// Threads: one I/O thread per server; Start()/Stop()/InjectFault()/ReleaseDelayedReplies() may be
// called from any thread.

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "mocks/generator/mock_33520b.h"

namespace msmcal::sim {

enum class FaultKind {
  // Reply faults: apply to the reply of a program message that has one (a query).
  kDelayReply,    // hold the reply delay_ms, or until ReleaseDelayedReplies() when delay_ms < 0
  kDropMidReply,  // send the first half of the reply, then close the connection
  kGarbageReply,  // send non-SCPI bytes instead of the reply
  // Message faults: apply to any program message, before the unit sees it.
  kDropConnection,  // close the connection; the message is not executed (a cable pulled)
  kFreeze,  // the connection is no longer served: this message and everything after it is read
            // and ignored, nothing is answered, the socket stays open until the client closes it
            // (an instrument hung on that socket; connections opened afterwards are served)
};

// Applies once, to a program message that contains `match` (upper-cased substring comparison;
// empty matches any message), after `skip` matching messages (reply faults: matching messages
// with a reply) went through normally.
struct Fault {
  FaultKind kind = FaultKind::kDelayReply;
  std::string match;
  int skip = 0;
  int64_t delay_ms = -1;  // kDelayReply only
};

// Parses the command-line form of a fault (`msmcal mock generator(s) --fault`, docs in
// docs/fault-campaign.md): KIND[,after=N][,match=TEXT][,ms=MS] with KIND one of drop (the
// connection), freeze, delay, garbage, drop-mid-reply; `after` is `skip`. Throws
// std::invalid_argument naming the text and what is wrong.
Fault ParseFault(const std::string& text);

// What a unit does with a second SCPI connection while one is open (docs/watchdog.md: the 33500
// series is not documented; we design for one connection at a time).
enum class SecondConnection {
  kServe,  // serve every connection concurrently (default)
  kQueue,  // accept it but serve it only once every earlier connection has closed
  kClose,  // accept it and close it at once (the client reads EOF)
};
// "serve", "queue", "close"; throws std::invalid_argument otherwise.
SecondConnection ParseSecondConnection(const std::string& text);

struct ServerLimits {
  // Unsent reply bytes of one connection above which its socket is not read.
  size_t max_pending_reply_bytes = 1u << 20;
  // The input buffer: the longest program message accepted. 36 MiB holds the largest legal
  // one, a 16 M-point binary arb upload (32 MB of block data) with its header.
  size_t max_message_bytes = 36u << 20;
  SecondConnection second_connection = SecondConnection::kServe;
};

// Counters for tests (all connections since Start()).
struct ServerStats {
  uint64_t connections = 0;
  uint64_t messages = 0;                 // program messages handed to the unit
  uint64_t read_pauses = 0;              // times a connection was flow-controlled
  uint64_t input_overruns = 0;           // messages discarded for length
  uint64_t faults_applied = 0;           // injected faults that took effect
  uint64_t connections_closed = 0;       // by either side
  uint64_t connections_turned_away = 0;  // SecondConnection::kClose
  size_t pending_reply_high_water = 0;   // most unsent reply bytes one connection held
  size_t input_high_water = 0;           // most received, unprocessed bytes one connection held
};

class MockGeneratorServer {
 public:
  // port 0 picks a free port (see port() after Start()).
  MockGeneratorServer(Mock33520B& unit, int port, ServerLimits limits = {});
  ~MockGeneratorServer();
  MockGeneratorServer(const MockGeneratorServer&) = delete;
  MockGeneratorServer& operator=(const MockGeneratorServer&) = delete;

  // Binds and listens on 127.0.0.1, starts the I/O thread. Throws std::runtime_error naming the
  // port when it cannot bind. Connections are accepted once this returns.
  void Start();
  void Stop();
  int port() const;

  void InjectFault(Fault fault);
  void ReleaseDelayedReplies();
  // Connections accepted so far (for tests that check reconnects).
  uint64_t ConnectionsAccepted() const;
  ServerStats Stats() const;
  // Blocks until pred(Stats()) holds or timeout_ms passes; returns pred's last value.
  bool WaitForStats(const std::function<bool(const ServerStats&)>& pred, int64_t timeout_ms) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct GeneratorPairOptions {
  int port1 = 0;  // unit 1: fast/slow sine drives; master of reference and trigger
  int port2 = 0;  // unit 2: laser trigger arb and clock; slave
  ServerLimits limits1, limits2;
  bool reference_wired = true;  // unit 1's 10 MHz out -> unit 2's reference in
  bool trigger_wired = true;    // unit 1's trigger out -> unit 2's Ext Trig in
  UnitOptions unit1;
  UnitOptions unit2;
};

// The rig's two generators in one process, on two ports, sharing one clock (the generator time
// base). Starts serving in the constructor.
class MockGeneratorPair {
 public:
  explicit MockGeneratorPair(GeneratorPairOptions options, ClockNs clock_ns = nullptr);
  ~MockGeneratorPair();

  Mock33520B& unit(int i) { return i == 1 ? *unit1_ : *unit2_; }
  MockGeneratorServer& server(int i) { return i == 1 ? *server1_ : *server2_; }
  int port(int i) const { return i == 1 ? server1_->port() : server2_->port(); }
  void SetReferenceWired(bool wired) { reference_wired_ = wired; }

 private:
  std::atomic<bool> reference_wired_;
  std::unique_ptr<Mock33520B> unit1_, unit2_;
  std::unique_ptr<MockGeneratorServer> server1_, server2_;
};

}  // namespace msmcal::sim
