#pragma once
// A behavioural simulator of one Keysight 33520B (two channels): the SCPI command set msmcal uses,
// the error queue, *RST defaults, and the physical signals the outputs produce in time. No I/O:
// Process() takes one program message and returns the response message; the TCP server
// (mock_server.h) puts it on a socket.
//
// Thread safety: every public method locks the unit; Process() may be called from any thread.
// Time: the injected clock (nanoseconds, shared by every unit of a rig) is the generator time
// base; trigger and phase-reference instants are read from it.

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace msmcal::sim {

using ClockNs = std::function<int64_t()>;

enum class Function { kSin, kSquare, kPulse, kArb, kDc, kRamp, kNoise };
const char* FunctionName(Function f);  // "SIN", "SQU", ...

enum class TriggerSource { kImmediate, kExternal, kBus, kTimer };

// What one output does, in the shared time base.
struct ChannelSignal {
  Function function = Function::kSin;
  double frequency_hz = 1000.0;
  double amplitude_vpp = 0.1;  // into load_ohm
  double offset_v = 0.0;
  double phase_deg = 0.0;        // PHASe: continuous mode
  double burst_phase_deg = 0.0;  // BURSt:PHASe: start phase of a triggered burst
  double square_duty_percent = 50.0;
  double load_ohm = 50.0;  // +inf = high impedance
  bool output_on = false;
  // Arbitrary waveform in play (FUNC ARB): DAC samples, sample rate, peak-to-peak (V).
  std::shared_ptr<const std::vector<int16_t>> arb_samples;
  std::string arb_name;
  double arb_sample_rate_sps = 40000.0;
  double arb_ptpeak_v = 0.1;
  // Burst mode with infinite cycles waits for a trigger, then runs from start_time_ns.
  bool burst_on = false;
  TriggerSource trigger_source = TriggerSource::kImmediate;
  bool running = true;        // false while armed and waiting for a trigger
  int64_t start_time_ns = 0;  // phase reference: phase_deg applies at this instant
};

struct UnitOptions {
  std::string identity = "Agilent Technologies,33522B,MY52000001,3.05-1.19-2.00-52-00";
  std::string options_reply = "0";  // *OPT?; "MEM" enables 16 M point arbs
  int64_t arb_memory_points = 1'000'000;
};

class Mock33520B {
 public:
  explicit Mock33520B(UnitOptions options, ClockNs clock_ns);

  // One program message (without its terminator; a trailing '\r' is ignored). Returns the
  // response message without '\n', empty when the message held no query.
  std::string Process(const std::string& message);

  // Snapshot of a channel (1 or 2).
  ChannelSignal Signal(int channel) const;
  // Output voltage of `channel` at generator time t_ns (0 V when the output is off; the idle
  // level, the waveform's value at its start phase, while armed).
  double SignalAt(int channel, int64_t t_ns) const;
  bool AnyOutputOn() const;
  std::string ReferenceSourceCurrent() const;  // "INT" or "EXT"
  size_t ErrorCount() const;

  // Wiring, set up by the rig before serving:
  // whether a 10 MHz reference reaches this unit's rear input (unit 2: unit 1's 10 MHz out).
  void SetReferenceInput(std::function<bool()> present);
  // Units whose Ext Trig input is wired to this unit's trigger out.
  void AddTriggerOutTarget(Mock33520B* slave);
  // An edge on the Ext Trig input (from a master's trigger out) at t_ns.
  void ExternalTrigger(int64_t t_ns);

  // Blocks until pred(*this-locked view) holds or the deadline passes; returns pred's value.
  // pred sees the unit through Signal()/AnyOutputOn()-like accessors of the locked state, so it
  // must only call the *Locked accessors below.
  bool WaitUntil(const std::function<bool(const Mock33520B&)>& pred, int64_t timeout_ms) const;
  // Incremented on every state change (for observers).
  uint64_t StateVersion() const;

  // Lock-free accessors for use inside WaitUntil predicates only.
  const ChannelSignal& SignalLocked(int channel) const { return ch_[channel - 1]; }
  bool AnyOutputOnLocked() const { return ch_[0].output_on || ch_[1].output_on; }

 private:
  struct Context;
  using Handler = std::function<std::optional<std::string>(Context&)>;
  struct Entry {
    std::string pattern;
    bool query;
    Handler handler;
  };
  void BuildTable();
  void ResetLocked();
  void PushError(int code, const std::string& message);
  void NotifyLocked();
  void TriggerLocked(TriggerSource source, int64_t t_ns);

  UnitOptions options_;
  ClockNs clock_;
  mutable std::mutex mu_;
  mutable std::condition_variable cv_;
  uint64_t version_ = 0;
  ChannelSignal ch_[2];
  std::deque<std::pair<int, std::string>> errors_;
  std::map<std::string, std::shared_ptr<const std::vector<int16_t>>> volatile_arbs_[2];
  bool border_big_endian_ = true;  // FORMat:BORDer NORMal
  std::string rosc_source_ = "INT";
  bool trigger_out_ = false;
  std::function<bool()> reference_present_;
  std::vector<Mock33520B*> trigger_targets_;
  std::vector<Entry> table_;
};

}  // namespace msmcal::sim
