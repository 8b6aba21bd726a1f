#pragma once
// TCP front of a Mock33520B on 127.0.0.1 (raw SCPI socket, like port 5025 of the instrument), with
// fault injection, and the rig's pair of units with their 10 MHz and trigger wiring.
//
// Framing: a program message ends with '\n' outside quoted strings and definite-length blocks
// (a trailing '\r', as pyvisa sends, is ignored); each response message is written in one send.
// Threads: one I/O thread per server; Start()/Stop()/InjectFault()/ReleaseDelayedReplies() may be
// called from any thread.

#include <atomic>
#include <memory>
#include <string>

#include "mocks/generator/mock_33520b.h"

namespace msmcal::sim {

enum class FaultKind {
  kDelayReply,    // hold the reply until ReleaseDelayedReplies() (the client's deadline expires)
  kDropMidReply,  // send the first half of the reply, then close the connection
  kGarbageReply,  // send non-SCPI bytes instead of the reply
};

// Applies once, to a reply of a program message that contains `match` (upper-cased substring
// comparison; empty matches any message), after `skip` such replies went out normally.
struct Fault {
  FaultKind kind = FaultKind::kDelayReply;
  std::string match;
  int skip = 0;
};

class MockGeneratorServer {
 public:
  // port 0 picks a free port (see port() after Start()).
  MockGeneratorServer(Mock33520B& unit, int port);
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

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct GeneratorPairOptions {
  int port1 = 0;                // unit 1: fast/slow sine drives; master of reference and trigger
  int port2 = 0;                // unit 2: laser trigger arb and clock; slave
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
