#pragma once
// SCPI over a raw TCP socket (port 5025), with a deadline on every operation. Boost.Asio stays in
// the .cc (pimpl). Thread safety: every public method is serialised by an internal mutex, so a
// safe-state call from another thread waits for the exchange in flight (bounded by its deadline)
// and never interleaves bytes with it.

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace msmcal::scpi {

enum class ErrorKind {
  kConnectFailed,   // could not connect within the deadline
  kTimeout,         // a write or read did not complete within its deadline
  kConnectionLost,  // the peer closed or reset the connection
  kGarbage,         // a reply that is not a well-formed SCPI response
  kInstrument,      // the instrument's error queue reported an error for a command
  kNotConnected,    // an operation on a closed client
};
const char* ErrorKindName(ErrorKind kind);

// Every failure of the client is a ScpiError: kind() says what happened; what() names the
// endpoint and the command involved.
class ScpiError : public std::runtime_error {
 public:
  ScpiError(ErrorKind kind, const std::string& message)
      : std::runtime_error(message), kind_(kind) {}
  ErrorKind kind() const { return kind_; }

 private:
  ErrorKind kind_;
};

struct ScpiClientOptions {
  std::string host = "127.0.0.1";
  int port = 5025;
  int connect_timeout_ms = 3000;
  int io_timeout_ms = 3000;
  // Longest reply line accepted (a guard against a peer that never sends '\n').
  size_t max_line_bytes = 1 << 20;
  std::string Validate() const;  // empty when valid; names field, value and constraint
};

// One exchange as it went over the wire (without the trailing '\n'; blocks as "#<n><len><...>"
// with the payload elided to its size). time_ns comes from the injected clock.
struct TranscriptEntry {
  int64_t time_ns = 0;
  bool to_instrument = true;
  std::string text;
};
using TranscriptSink = std::function<void(const TranscriptEntry&)>;
using ClockNs = std::function<int64_t()>;  // any monotonic nanosecond clock

class ScpiClient {
 public:
  // `clock_ns` stamps transcript entries (default: steady clock). Does not connect.
  explicit ScpiClient(ScpiClientOptions options, ClockNs clock_ns = nullptr);
  ~ScpiClient();
  ScpiClient(const ScpiClient&) = delete;
  ScpiClient& operator=(const ScpiClient&) = delete;

  void Connect();  // throws ScpiError(kConnectFailed)
  void Close();
  bool IsConnected() const;
  // Closes and connects again. Callers decide when that is safe (see the driver).
  void Reconnect();

  // Sends `command` + '\n'.
  void Write(const std::string& command);
  // Sends `command` + '\n' and reads one reply line (without '\n'); throws kGarbage when the line
  // holds non-printable bytes.
  std::string Query(const std::string& command);
  // Sends `prefix` + definite-length block of `payload` + '\n' (payload bytes may contain '\n').
  void WriteBlock(const std::string& prefix, const std::string& payload);
  // Sends `command` and reads a definite-length block reply; returns the payload.
  std::string QueryBlock(const std::string& command);

  // Drains SYSTem:ERRor? until +0; if any entry was an error, throws ScpiError(kInstrument)
  // naming `context` (the command batch that caused it) and every entry.
  void CheckErrors(const std::string& context);
  // *OPC? and expects 1.
  void WaitOperationComplete();

  void SetTranscriptSink(TranscriptSink sink);
  const ScpiClientOptions& options() const { return options_; }
  std::string Endpoint() const;

 private:
  struct Impl;
  ScpiClientOptions options_;
  std::unique_ptr<Impl> impl_;
};

namespace detail {
// Runs `lookup` (a blocking name resolution: getaddrinfo cannot be cancelled) on a thread of its
// own and waits at most `timeout_ms` for it. Returns its result (rethrows what it threw), or
// nullopt when it did not finish in time; the thread then finishes on its own and owns all it
// touches. ScpiClient::Connect resolves through it inside connect_timeout_ms; exposed for tests.
std::optional<std::vector<std::string>> CallWithin(std::function<std::vector<std::string>()> lookup,
                                                   int timeout_ms);
}  // namespace detail

}  // namespace msmcal::scpi
