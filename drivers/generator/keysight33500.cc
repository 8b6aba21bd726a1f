// Keysight (Agilent) 33500-series driver over SCPI. Sequence per configuration batch: limits
// checked locally, commands sent, SYSTem:ERRor? drained (any entry becomes a kDeviceError Status
// naming the batch). Inside, failures are exceptions (the wire's ScpiError, GeneratorError);
// each interface method turns them into its common::Status at the boundary.
#include <algorithm>
#include <cmath>
#include <exception>
#include <regex>
#include <sstream>

#include "common/check.h"
#include "drivers/generator/function_generator.h"
#include "drivers/generator/safe_state.h"
#include "drivers/scpi/scpi_text.h"

namespace msmcal::gen {

using scpi::FormatNumber;

const char* WaveformName(Waveform w) {
  switch (w) {
    case Waveform::kSin:
      return "SIN";
    case Waveform::kSquare:
      return "SQU";
    case Waveform::kPulse:
      return "PULS";
    case Waveform::kArb:
      return "ARB";
    case Waveform::kDc:
      return "DC";
  }
  return "SIN";
}

// What the 33520B can do. Keysight 33500 Series Operating and Service Guide, APPLy subsystem
// (https://manualshive.com/en/manual/agilent-technologies/agilent-33500-series/2867488?page=168):
// amplitude 1 mVpp to 10 Vpp into 50 ohm, twice that into an open circuit; offset +-5 V into
// 50 ohm, +-10 V into an open circuit, with |Voffset| <= Vmax - Vpp/2 (Vmax 5 V into 50 ohm,
// 10 V high-Z); output termination 1 ohm to 10 kohm or infinite (same guide, "Output
// Termination"). Frequency by function (33500B-series data sheet, 33520B): sine, square and
// pulse up to 30 MHz (ramp 200 kHz; not used by this driver); arbitrary waveforms up to
// 160 MSa/s (the rig configuration's trigger.max_sample_rate_sps).
namespace {
constexpr double kSourceOhm = 50.0;
constexpr double kMaxVppOpen = 20.0;
constexpr double kMaxPeakOpen = 10.0;
constexpr double kMinLoadOhm = 1.0;
constexpr double kMaxLoadOhm = 10e3;
constexpr double kMaxFrequencyHz = 30e6;  // sine, square, pulse
constexpr double kMaxArbSampleRateSps = 160e6;

double LoadFactor(double load_ohm) {
  return std::isinf(load_ohm) ? 1.0 : load_ohm / (load_ohm + kSourceOhm);
}

bool ValidLoad(double load_ohm) {
  return (load_ohm >= kMinLoadOhm && load_ohm <= kMaxLoadOhm) ||
         (std::isinf(load_ohm) && load_ohm > 0);
}
}  // namespace

double Max33520bVppInto(double load_ohm) { return kMaxVppOpen * LoadFactor(load_ohm); }
double Max33520bPeakVInto(double load_ohm) { return kMaxPeakOpen * LoadFactor(load_ohm); }

std::string ChannelLimits::Validate(const std::string& field) const {
  std::ostringstream os;
  os.precision(10);
  auto bad = [&](const char* name, double v, const std::string& constraint) {
    os << field << "." << name << " = " << v << ": " << constraint;
    return os.str();
  };
  if (!(std::isfinite(max_vpp) && max_vpp >= 0.0 && max_vpp <= kMaxVppOpen))
    return bad("max_vpp", max_vpp, "must be finite, in [0, 20] Vpp (33520B open-circuit maximum)");
  if (!(std::isfinite(max_abs_offset_v) && max_abs_offset_v >= 0.0 &&
        max_abs_offset_v <= kMaxPeakOpen))
    return bad("max_abs_offset_v", max_abs_offset_v,
               "must be finite, in [0, 10] V (33520B open-circuit maximum)");
  if (!(std::isfinite(min_frequency_hz) && min_frequency_hz >= 0.0))
    return bad("min_frequency_hz", min_frequency_hz, "must be finite and >= 0");
  if (!(std::isfinite(max_frequency_hz) && max_frequency_hz >= min_frequency_hz &&
        max_frequency_hz <= kMaxFrequencyHz)) {
    os << field << ".max_frequency_hz = " << max_frequency_hz
       << ": must be finite, >= min_frequency_hz (" << min_frequency_hz
       << ") and <= 3e+07 Hz (33520B maximum)";
    return os.str();
  }
  if (!(max_duty > 0.0 && max_duty <= 1.0)) return bad("max_duty", max_duty, "must be in (0, 1]");
  return "";
}

std::string CheckAgainstInstrument(const std::string& field, const ChannelLimits& l,
                                   double load_ohm) {
  std::ostringstream os;
  os.precision(10);
  if (!ValidLoad(load_ohm)) {
    os << field << ": load_ohm = " << load_ohm << ": must be in [1, 10000] ohm or inf (high-Z)";
  } else if (l.max_vpp > Max33520bVppInto(load_ohm) * (1 + 1e-12)) {
    os << field << ".max_vpp = " << l.max_vpp << ": above what the 33520B delivers into "
       << load_ohm << " ohm (" << Max33520bVppInto(load_ohm) << " Vpp)";
  } else if (l.max_abs_offset_v > Max33520bPeakVInto(load_ohm) * (1 + 1e-12)) {
    os << field << ".max_abs_offset_v = " << l.max_abs_offset_v
       << ": above what the 33520B delivers into " << load_ohm << " ohm ("
       << Max33520bPeakVInto(load_ohm) << " V)";
  }
  return os.str();
}

std::string CheckLimits(const std::string& channel_name, const ChannelSetup& s,
                        const ChannelLimits& l) {
  std::ostringstream os;
  os.precision(10);
  const std::string who = channel_name + " (" + l.role + ")";
  double frequency = s.frequency_hz;
  double duty = 0.5;
  if (s.waveform == Waveform::kArb) {
    if (s.arb_samples.empty() || !(s.arb_sample_rate_sps > 0.0)) {
      return who + ": arbitrary waveform needs samples and a sample rate > 0";
    }
    frequency = s.arb_sample_rate_sps / static_cast<double>(s.arb_samples.size());
    const auto high =
        std::count_if(s.arb_samples.begin(), s.arb_samples.end(), [](int16_t v) { return v > 0; });
    duty = static_cast<double>(high) / static_cast<double>(s.arb_samples.size());
  } else if (s.waveform == Waveform::kSquare || s.waveform == Waveform::kPulse) {
    duty = s.square_duty_percent / 100.0;
  } else if (s.waveform == Waveform::kDc) {
    duty = s.offset_v > 0.0 ? 1.0 : 0.0;
  }
  if (!(s.amplitude_vpp >= 0.0) || s.amplitude_vpp > l.max_vpp) {
    os << who << ": amplitude_vpp = " << s.amplitude_vpp << " outside the limit [0, " << l.max_vpp
       << "] Vpp";
  } else if (!(std::abs(s.offset_v) <= l.max_abs_offset_v)) {
    os << who << ": offset_v = " << s.offset_v
       << " outside the limit |offset| <= " << l.max_abs_offset_v << " V";
  } else if (s.waveform != Waveform::kDc &&
             !(frequency >= l.min_frequency_hz && frequency <= l.max_frequency_hz)) {
    os << who << ": frequency_hz = " << frequency << " outside the window [" << l.min_frequency_hz
       << ", " << l.max_frequency_hz << "] Hz";
  } else if (duty > l.max_duty + 1e-12) {
    os << who << ": duty = " << duty << " exceeds max_duty = " << l.max_duty;
  } else if (!ValidLoad(s.load_ohm)) {
    os << who << ": load_ohm = " << s.load_ohm << " must be in [1, 10000] ohm (or inf for high-Z)";
  } else if (!(std::isfinite(s.amplitude_vpp) &&
               s.amplitude_vpp <= Max33520bVppInto(s.load_ohm) * (1 + 1e-12))) {
    os << who << ": amplitude_vpp = " << s.amplitude_vpp << " above the 33520B's "
       << Max33520bVppInto(s.load_ohm) << " Vpp into " << s.load_ohm << " ohm";
  } else if (!(std::abs(s.offset_v) + 0.5 * s.amplitude_vpp <=
               Max33520bPeakVInto(s.load_ohm) * (1 + 1e-12))) {
    os << who << ": |offset_v| + amplitude_vpp/2 = " << std::abs(s.offset_v) + 0.5 * s.amplitude_vpp
       << " above the 33520B's " << Max33520bPeakVInto(s.load_ohm) << " V into " << s.load_ohm
       << " ohm";
  } else if (s.waveform != Waveform::kDc && s.waveform != Waveform::kArb &&
             !(frequency <= kMaxFrequencyHz)) {
    os << who << ": frequency_hz = " << frequency << " above the 33520B's 3e+07 Hz";
  } else if (s.waveform == Waveform::kArb && !(s.arb_sample_rate_sps <= kMaxArbSampleRateSps)) {
    os << who << ": arb_sample_rate_sps = " << s.arb_sample_rate_sps
       << " above the 33520B's 1.6e+08 Sa/s";
  }
  return os.str();
}

bool IsSupportedIdentity(const scpi::Identity& id) {
  const bool vendor = id.manufacturer.rfind("Agilent Technologies", 0) == 0 ||
                      id.manufacturer.rfind("Keysight Technologies", 0) == 0;
  static const std::regex kModel("^335[0-9][0-9][AB]$");
  return vendor && std::regex_match(id.model, kModel);
}

std::string Keysight33500Options::Validate() const {
  if (std::string e = link.Validate(); !e.empty()) return name + "." + e;
  for (int c = 0; c < 2; ++c) {
    const std::string e =
        limits[c].Validate(name + ".channels." + std::to_string(c + 1) + ".limits");
    if (!e.empty()) return e;
  }
  return "";
}

GeneratorError::Kind GeneratorError::KindOf(common::StatusCode code) {
  switch (code) {
    case common::StatusCode::kRefused:
      return Kind::kLimit;
    case common::StatusCode::kWrongDevice:
      return Kind::kIdentity;
    case common::StatusCode::kNotLocked:
      return Kind::kLock;
    case common::StatusCode::kDeviceError:
      return Kind::kInstrument;
    case common::StatusCode::kOk:
    case common::StatusCode::kUnavailable:
    case common::StatusCode::kTimeout:
    case common::StatusCode::kProtocol:
      return Kind::kLink;
  }
  return Kind::kLink;
}

namespace {

class Keysight33500 final : public FunctionGenerator {
 public:
  Keysight33500(const Keysight33500Options& o, scpi::TranscriptSink transcript)
      : options_(o),
        client_(o.link),
        registration_(this, o.name + " (" + client_.Endpoint() + ")") {
    if (transcript) client_.SetTranscriptSink(std::move(transcript));
  }

  const std::string& name() const override { return options_.name; }

  void Open() {
    client_.Connect();
    DoIdentify();
  }

  common::Result<scpi::Identity> Identify() override {
    return Returned([&] { return DoIdentify(); });
  }
  common::Result<std::string> Options() override {
    return Returned([&] { return DoOptions(); });
  }
  common::Status Reset() override {
    return Completed([&] { DoReset(); });
  }
  common::Status ConfigureChannel(int channel, const ChannelSetup& s) override {
    return Completed([&] { DoConfigureChannel(channel, s); });
  }
  common::Status ReplaceArb(int channel, const ChannelSetup& s) override {
    return Completed([&] { DoReplaceArb(channel, s); });
  }
  common::Status SetOutput(int channel, bool on) override {
    return Completed([&] { DoSetOutput(channel, on); });
  }
  common::Status SetReference(ReferenceSource source) override {
    return Completed([&] { DoSetReference(source); });
  }
  common::Result<bool> ReferenceLocked() override {
    return Returned([&] { return DoReferenceLocked(); });
  }
  common::Status ArmStart(StartTrigger source, bool trigger_out) override {
    return Completed([&] { DoArmStart(source, trigger_out); });
  }
  common::Status Trigger() override {
    return Completed([&] { DoTrigger(); });
  }
  common::Status SynchronizePhase() override {
    return Completed([&] { DoSynchronizePhase(); });
  }

  scpi::Identity DoIdentify() {
    const std::string reply = client_.Query("*IDN?");
    scpi::Identity id;
    try {
      id = scpi::ParseIdentity(reply);
    } catch (const std::invalid_argument& e) {
      throw GeneratorError(GeneratorError::Kind::kIdentity,
                           Who() + ": bad *IDN? reply: " + e.what());
    }
    if (!IsSupportedIdentity(id)) {
      throw GeneratorError(
          GeneratorError::Kind::kIdentity,
          Who() + " identifies as '" + reply + "', not an Agilent/Keysight 33500-series generator");
    }
    identity_ = id;
    return id;
  }

  std::string DoOptions() { return std::string(scpi::Trim(client_.Query("*OPT?"))); }

  void DoReset() {
    client_.Write("*RST;*CLS");
    client_.WaitOperationComplete();
    Check("*RST;*CLS");
  }

  void DoConfigureChannel(int channel, const ChannelSetup& s) {
    RequireChannel(channel);
    const std::string ch_name = options_.name + ".ch" + std::to_string(channel);
    if (std::string e = CheckLimits(ch_name, s, options_.limits[channel - 1]); !e.empty()) {
      throw GeneratorError(GeneratorError::Kind::kLimit, "refused: " + e);
    }
    const std::string n = std::to_string(channel);
    const std::string src = "SOUR" + n + ":";
    const std::string load = std::isinf(s.load_ohm) ? "INF" : FormatNumber(s.load_ohm);
    Send("OUTP" + n + ":LOAD " + load);
    if (s.waveform == Waveform::kArb) {
      const size_t points = s.arb_samples.size();
      if (points < 8) {
        throw GeneratorError(GeneratorError::Kind::kLimit,
                             "refused: " + ch_name + ": arb has " + std::to_string(points) +
                                 " points, the instrument needs at least 8");
      }
      if (points > 1'000'000 && DoOptions().find("MEM") == std::string::npos) {
        throw GeneratorError(GeneratorError::Kind::kLimit,
                             "refused: " + ch_name + ": arb has " + std::to_string(points) +
                                 " points; more than 1 M needs option MEM (*OPT? = '" +
                                 DoOptions() + "')");
      }
      // Explicit byte order; the payload is written in the same order.
      Send(src + "DATA:VOL:CLE;:FORM:BORD SWAP");
      client_.WriteBlock(src + "DATA:ARB:DAC " + s.arb_name + ",",
                         scpi::Int16Payload(s.arb_samples, /*big_endian=*/false));
      Check(src + "DATA:ARB:DAC " + s.arb_name);
      Send(src + "FUNC:ARB " + s.arb_name + ";:" + src + "FUNC ARB;:" + src + "FUNC:ARB:SRAT " +
           FormatNumber(s.arb_sample_rate_sps));
      Send(src + "VOLT:OFFS 0;:" + src + "FUNC:ARB:PTP " + FormatNumber(s.amplitude_vpp) +
           ";:" + src + "VOLT:OFFS " + FormatNumber(s.offset_v));
    } else {
      std::string cmd = src + "FUNC " + WaveformName(s.waveform);
      if (s.waveform != Waveform::kDc) cmd += ";:" + src + "FREQ " + FormatNumber(s.frequency_hz);
      if (s.waveform == Waveform::kSquare) {
        cmd += ";:" + src + "FUNC:SQU:DCYC " + FormatNumber(s.square_duty_percent);
      }
      Send(cmd);
      Send(src + "VOLT:OFFS 0;:" + src + "VOLT " + FormatNumber(s.amplitude_vpp) + ";:" + src +
           "VOLT:OFFS " + FormatNumber(s.offset_v));
      // PHASe applies in continuous mode, BURSt:PHASe to the triggered start (ArmStart).
      Send(src + "PHAS " + FormatNumber(s.phase_deg) + ";:" + src + "BURS:PHAS " +
           FormatNumber(s.phase_deg));
    }
    Check("configure " + ch_name);
  }

  void DoReplaceArb(int channel, const ChannelSetup& s) {
    RequireChannel(channel);
    const std::string ch_name = options_.name + ".ch" + std::to_string(channel);
    MSMCAL_CHECK(s.waveform == Waveform::kArb && !s.arb_name.empty())
        << Who() << ": ReplaceArb needs an arb setup with a name";
    if (std::string e = CheckLimits(ch_name, s, options_.limits[channel - 1]); !e.empty()) {
      throw GeneratorError(GeneratorError::Kind::kLimit, "refused: " + e);
    }
    const std::string src = "SOUR" + std::to_string(channel) + ":";
    Send("FORM:BORD SWAP");
    client_.WriteBlock(src + "DATA:ARB:DAC " + s.arb_name + ",",
                       scpi::Int16Payload(s.arb_samples, /*big_endian=*/false));
    Check(src + "DATA:ARB:DAC " + s.arb_name);
    Send(src + "FUNC:ARB " + s.arb_name);
    Check("replace arb " + ch_name);
  }

  void DoSetOutput(int channel, bool on) {
    RequireChannel(channel);
    const std::string cmd = "OUTP" + std::to_string(channel) + (on ? " ON" : " OFF");
    Send(cmd);
    Check(cmd);
  }

  void DoSetReference(ReferenceSource source) {
    const std::string cmd =
        std::string("ROSC:SOUR ") + (source == ReferenceSource::kExternal ? "EXT" : "INT");
    Send(cmd);
    client_.WaitOperationComplete();
    Check(cmd);
  }

  bool DoReferenceLocked() { return scpi::Trim(client_.Query("ROSC:SOUR:CURR?")) == "EXT"; }

  void DoArmStart(StartTrigger source, bool trigger_out) {
    const std::string src_name = source == StartTrigger::kBus ? "BUS" : "EXT";
    std::string cmd;
    for (int c = 1; c <= 2; ++c) {
      const std::string n = std::to_string(c);
      cmd += "SOUR" + n + ":BURS:MODE TRIG;NCYC INF;STAT ON;:TRIG" + n + ":SOUR " + src_name + ";:";
    }
    cmd += std::string("OUTP:TRIG ") + (trigger_out ? "ON" : "OFF");
    Send(cmd);
    Check("arm start trigger (" + src_name + ")");
  }

  void DoTrigger() {
    Send("*TRG");
    client_.WaitOperationComplete();
    Check("*TRG");
  }

  void DoSynchronizePhase() {
    Send("PHAS:SYNC");
    Check("PHAS:SYNC");
  }

  // On the open connection, then once more on a new one: an instrument that dropped the
  // connection under the OUTP OFF (or a connection left with a stale reply) must not leave the
  // outputs on until the watchdog fires (the fault campaign's scpi-drop-safe-state).
  bool SafeState() noexcept override {
    for (int attempt = 0; attempt < 2; ++attempt) {
      try {
        if (attempt > 0) {
          client_.Reconnect();
        } else if (!client_.IsConnected()) {
          client_.Connect();
        }
        client_.Write("OUTP1 OFF;:OUTP2 OFF");
        if (client_.Query("OUTP1?;:OUTP2?") == "0;0") return true;
      } catch (...) {
      }
    }
    return false;
  }

  void Disconnect() noexcept override {
    try {
      client_.Close();
    } catch (...) {
    }
  }

 private:
  std::string Who() const { return "'" + options_.name + "' at " + client_.Endpoint(); }

  void RequireChannel(int channel) const {
    MSMCAL_CHECK(channel == 1 || channel == 2)
        << Who() << ": channel " << channel << " does not exist (1 or 2)";
  }

  // The implementation's exceptions (the wire's ScpiError, GeneratorError for limits, identity
  // and the error queue) as the interface's Status.
  static common::Status StatusOf(const std::exception_ptr& e) {
    try {
      std::rethrow_exception(e);
    } catch (const GeneratorError& g) {
      return common::Status::Error(g.what(), CodeOf(g.kind()));
    } catch (const scpi::ScpiError& w) {
      return common::Status::Error(w.what(), CodeOf(w.kind()));
    }
  }
  static common::StatusCode CodeOf(GeneratorError::Kind k) {
    switch (k) {
      case GeneratorError::Kind::kLimit:
        return common::StatusCode::kRefused;
      case GeneratorError::Kind::kIdentity:
        return common::StatusCode::kWrongDevice;
      case GeneratorError::Kind::kLock:
        return common::StatusCode::kNotLocked;
      case GeneratorError::Kind::kInstrument:
        return common::StatusCode::kDeviceError;
      case GeneratorError::Kind::kLink:
        return common::StatusCode::kUnavailable;
    }
    return common::StatusCode::kDeviceError;
  }
  static common::StatusCode CodeOf(scpi::ErrorKind k) {
    switch (k) {
      case scpi::ErrorKind::kTimeout:
        return common::StatusCode::kTimeout;
      case scpi::ErrorKind::kGarbage:
        return common::StatusCode::kProtocol;
      case scpi::ErrorKind::kInstrument:
        return common::StatusCode::kDeviceError;
      case scpi::ErrorKind::kConnectFailed:
      case scpi::ErrorKind::kConnectionLost:
      case scpi::ErrorKind::kNotConnected:
        return common::StatusCode::kUnavailable;
    }
    return common::StatusCode::kUnavailable;
  }
  template <typename F>
  common::Status Completed(F&& f) {
    try {
      f();
      return common::Status::Ok();
    } catch (const GeneratorError&) {
      return StatusOf(std::current_exception());
    } catch (const scpi::ScpiError&) {
      return StatusOf(std::current_exception());
    }
  }
  template <typename F>
  auto Returned(F&& f) -> common::Result<decltype(f())> {
    try {
      return f();
    } catch (const GeneratorError&) {
      return StatusOf(std::current_exception());
    } catch (const scpi::ScpiError&) {
      return StatusOf(std::current_exception());
    }
  }

  void Send(const std::string& command) { client_.Write(command); }

  void Check(const std::string& context) {
    try {
      client_.CheckErrors(context);
    } catch (const scpi::ScpiError& e) {
      if (e.kind() == scpi::ErrorKind::kInstrument) {
        throw GeneratorError(GeneratorError::Kind::kInstrument, e.what());
      }
      throw;
    }
  }

  Keysight33500Options options_;
  scpi::ScpiClient client_;
  scpi::Identity identity_;
  // Last: registered once the client exists, unregistered before anything else is destroyed (a
  // signal's safe state may call SafeState() from another thread until then).
  OpenGeneratorRegistration registration_;
};

}  // namespace

std::unique_ptr<FunctionGenerator> OpenKeysight33500(const Keysight33500Options& options,
                                                     scpi::TranscriptSink transcript) {
  if (std::string e = options.Validate(); !e.empty()) {
    throw std::invalid_argument("generator options: " + e);
  }
  auto gen = std::make_unique<Keysight33500>(options, std::move(transcript));
  gen->Open();
  return gen;
}

}  // namespace msmcal::gen
