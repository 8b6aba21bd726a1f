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

#include "mocks/generator/scpi_parser.h"

namespace msmcal::sim {

using ClockNs = std::function<int64_t()>;

enum class Function { kSin, kSquare, kPulse, kArb, kDc, kRamp, kNoise, kTriangle, kPrbs };
const char* FunctionName(Function f);  // "SIN", "SQU", ...

// VOLTage:UNIT: the unit VOLTage sets and answers in (amplitude_vpp is always Vpp).
enum class VoltageUnit { kVpp, kVrms, kDbm };

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
  double ramp_symmetry_percent = 100.0;
  double load_ohm = 50.0;  // +inf = high impedance
  VoltageUnit voltage_unit = VoltageUnit::kVpp;
  std::string output_polarity = "NORM";  // NORM or INV
  // Pulse: the period is 1 / frequency_hz; HOLD says what a period change keeps.
  double pulse_width_s = 100e-6;
  double pulse_lead_s = 10e-9;  // 10 %..90 % edge times
  double pulse_trail_s = 10e-9;
  std::string pulse_hold = "WIDT";  // WIDT or DCYC
  bool output_on = false;
  // Arbitrary waveform in play (FUNC ARB): DAC samples, sample rate, peak-to-peak (V).
  std::shared_ptr<const std::vector<int16_t>> arb_samples;
  std::string arb_name;
  double arb_sample_rate_sps = 40000.0;
  double arb_ptpeak_v = 0.1;
  std::string arb_advance = "SRAT";  // SRAT or TRIG
  std::string arb_filter = "NORM";   // NORM, STEP or OFF
  // Burst mode. Triggered: waits for a trigger, then runs burst_ncycles cycles (+inf: until
  // burst mode ends) from start_time_ns; with TRIGger:SOURce IMMediate a finite burst repeats
  // every burst_period_s from start_time_ns. Gated: the gate is the Ext Trig level, which the
  // mock does not model (its trigger input takes edges only), so the output idles.
  bool burst_on = false;
  bool burst_gated = false;
  double burst_ncycles = 1.0;
  double burst_period_s = 10e-3;
  std::string burst_gate_polarity = "NORM";  // NORM or INV
  TriggerSource trigger_source = TriggerSource::kImmediate;
  std::string trigger_slope = "POS";  // POS or NEG
  double trigger_delay_s = 0.0;
  bool running = true;        // false while armed and waiting for a trigger
  int64_t start_time_ns = 0;  // phase reference: phase_deg applies at this instant
};

struct UnitOptions {
  std::string identity = "Agilent Technologies,33522B,MY52000001,3.05-1.19-2.00-52-00";
  std::string options_reply = "0";  // *OPT?; "MEM" enables 16 M point arbs
  int64_t arb_memory_points = 1'000'000;
  // Largest response message Process() returns; queries of a program message past it are
  // executed but their replies dropped, with -430 "Query DEADLOCKED" (the output queue is full
  // and the controller is not reading it).
  size_t max_response_bytes = 1u << 20;
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
  // The transport's input buffer overflowed (a program message longer than it accepts): queues
  // -363 "Input buffer overrun".
  void ReportInputOverrun();
  // Elementary parsing steps done so far (bytes split, header nodes resolved, pattern nodes
  // compared): a cost measure for tests that check parsing is linear in the message length.
  uint64_t ParseWork() const;

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
    HeaderPattern pattern;
    bool query;
    Handler handler;
  };
  void BuildTable();
  std::optional<std::string> ExecuteLocked(const CommandUnit& unit, std::vector<std::string>& path);
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
  std::string angle_unit_ = "DEG";  // UNIT:ANGLe: DEG, RAD or SEC
  std::string display_text_;
  int ese_ = 0, sre_ = 0;
  std::vector<Entry> table_;
  size_t max_header_nodes_ = 0;  // deepest header of table_
  uint64_t work_ = 0;
};

}  // namespace msmcal::sim
