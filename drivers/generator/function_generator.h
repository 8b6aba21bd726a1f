#pragma once
// The narrow interface the rig code uses for a two-channel function generator, and the safety
// limits every implementation enforces before anything reaches the instrument.

#include <cstdint>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/status.h"
#include "drivers/scpi/scpi_client.h"
#include "drivers/scpi/scpi_text.h"

namespace msmcal::gen {

enum class Waveform { kSin, kSquare, kPulse, kArb, kDc };
const char* WaveformName(Waveform w);  // SCPI mnemonic: "SIN", "SQU", "PULS", "ARB", "DC"

constexpr double kHighZ = std::numeric_limits<double>::infinity();

// Everything one channel produces. Voltages are into load_ohm (kHighZ = high impedance), as the
// instrument's OUTPut:LOAD setting interprets them.
struct ChannelSetup {
  Waveform waveform = Waveform::kSin;
  double frequency_hz = 1000.0;  // SIN/SQU/PULS; ARB: sample rate / points
  double amplitude_vpp = 0.1;    // ARB: peak-to-peak of the full DAC range
  double offset_v = 0.0;
  double phase_deg = 0.0;
  double square_duty_percent = 50.0;
  double load_ohm = 50.0;
  // ARB only: int16 DAC samples (-32767..32767), played at arb_sample_rate_sps.
  std::string arb_name;
  std::vector<int16_t> arb_samples;
  double arb_sample_rate_sps = 0.0;
};

// Safety limits of one channel (from the rig configuration: what the coil or the laser input
// tolerates). A setup outside them is refused, never clipped.
struct ChannelLimits {
  std::string role = "unused";  // e.g. "fast_coil", "laser_trigger"
  double max_vpp = 0.0;
  double max_abs_offset_v = 0.0;
  double min_frequency_hz = 0.0;
  double max_frequency_hz = 0.0;
  // Highest fraction of the period the output may sit above its mid level (laser duty).
  double max_duty = 1.0;
  std::string Validate(const std::string& field) const;  // empty when valid
};

// What a Keysight 33520B channel can produce (sources in keysight33500.cc). Voltages are into
// `load_ohm` as the instrument interprets them (kHighZ: open circuit); the output has a 50 ohm
// source impedance, so the open-circuit maximum scales by load / (load + 50).
double Max33520bVppInto(double load_ohm);    // 10 Vpp into 50 ohm, 20 Vpp open circuit
double Max33520bPeakVInto(double load_ohm);  // |offset| + Vpp/2: 5 V into 50 ohm, 10 V open
// Empty when `limits` (field name `field`) are finite and inside what the instrument can do
// into `load_ohm`; otherwise names the field, its value and the instrument's bound.
std::string CheckAgainstInstrument(const std::string& field, const ChannelLimits& limits,
                                   double load_ohm);

// Empty when `setup` respects `limits` and the instrument's own range; otherwise names the
// channel, field, value and limit.
std::string CheckLimits(const std::string& channel_name, const ChannelSetup& setup,
                        const ChannelLimits& limits);

// What RigGenerators (the session's composite) throws when a unit's Status is not ok; kind() is
// the Status's code, grouped (kLink: no connection, a timeout, a malformed reply).
class GeneratorError : public std::runtime_error {
 public:
  enum class Kind { kLimit, kIdentity, kLock, kInstrument, kLink };
  GeneratorError(Kind kind, const std::string& message)
      : std::runtime_error(message), kind_(kind) {}
  // From a unit's failed Status: the kind grouped from its code, the code kept.
  explicit GeneratorError(const common::Status& status)
      : std::runtime_error(status.message), kind_(KindOf(status.code)), code_(status.code) {}
  Kind kind() const { return kind_; }
  // The Status code it came from (kTimeout, kUnavailable, kProtocol, ...); kOk when it was made
  // from a kind alone.
  common::StatusCode code() const { return code_; }
  static Kind KindOf(common::StatusCode code);

 private:
  Kind kind_;
  common::StatusCode code_ = common::StatusCode::kOk;
};

enum class ReferenceSource { kInternal, kExternal };
enum class StartTrigger { kBus, kExternal };

// A two-channel generator. Every method returns the drivers' one result type (common/status.h):
// ok when it completed and the instrument's error queue was empty afterwards; otherwise the
// Status names the unit, its endpoint and the command, with a code: kRefused (a limit: nothing
// was sent), kWrongDevice (identity), kDeviceError (the error queue), kUnavailable / kTimeout /
// kProtocol (the wire). A channel other than 1 or 2 is a bug (MSMCAL_CHECK). Not thread-safe
// except SafeState(), which may run from a signal-watcher thread while another call is in
// flight.
class FunctionGenerator {
 public:
  virtual ~FunctionGenerator() = default;
  virtual const std::string& name() const = 0;

  // *IDN? and *OPT?; refuses instruments outside the supported family (kWrongDevice).
  virtual common::Result<scpi::Identity> Identify() = 0;
  virtual common::Result<std::string> Options() = 0;
  // *RST and *CLS: defaults, outputs off, error queue empty.
  virtual common::Status Reset() = 0;
  // Checks the channel's limits, then configures it (output state unchanged).
  virtual common::Status ConfigureChannel(int channel, const ChannelSetup& setup) = 0;
  virtual common::Status SetOutput(int channel, bool on) = 0;
  // Replaces the samples of the arb `setup.arb_name` that the channel plays (configured by
  // ConfigureChannel with the same name, point count and sample rate) and selects it again,
  // without clearing volatile memory, re-arming or touching the output: the running burst keeps
  // its start (the mock 33520B and the twin keep the channel's phase reference; on a real
  // 33500 this is the documented assumption of docs/lab-path.md "Per-frame signals", to be checked
  // on the bench with a scope on Trig Out and the laser input). Checks the limits first.
  virtual common::Status ReplaceArb(int channel, const ChannelSetup& setup) = 0;
  virtual common::Status SetReference(ReferenceSource source) = 0;
  // True when the unit runs on the external 10 MHz reference.
  virtual common::Result<bool> ReferenceLocked() = 0;
  // Both channels wait in infinite triggered bursts for `source`; with `trigger_out` the unit
  // forwards its trigger on the rear Trig Out connector.
  virtual common::Status ArmStart(StartTrigger source, bool trigger_out) = 0;
  // *TRG (bus trigger), then *OPC?.
  virtual common::Status Trigger() = 0;
  virtual common::Status SynchronizePhase() = 0;
  // Every output off. Never throws; reconnects first if the connection was lost. Returns true
  // when the instrument confirmed (both OUTPut? replies 0).
  virtual bool SafeState() noexcept = 0;
  // Closes the connection (thread-safe like SafeState(); waits for the exchange in flight), so
  // that an instrument serving one connection at a time lets another client in (the watchdog,
  // docs/watchdog.md). Later calls return kUnavailable; SafeState() reconnects.
  virtual void Disconnect() noexcept = 0;
};

struct Keysight33500Options {
  std::string name = "generator";
  scpi::ScpiClientOptions link;
  ChannelLimits limits[2];
  std::string Validate() const;  // names "<name>.<field>"
};

// Connects (deadline-bound) and identifies. The returned driver owns its connection. Throws
// scpi::ScpiError (no connection) or GeneratorError(kIdentity) when it cannot return one.
std::unique_ptr<FunctionGenerator> OpenKeysight33500(const Keysight33500Options& options,
                                                     scpi::TranscriptSink transcript = nullptr);

// True for identities of the 33500 series ("Agilent Technologies" or "Keysight Technologies",
// model 335xxA/B). Exposed for tests.
bool IsSupportedIdentity(const scpi::Identity& identity);

}  // namespace msmcal::gen
