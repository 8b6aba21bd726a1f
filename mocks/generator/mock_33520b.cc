#include "mocks/generator/mock_33520b.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>

#include "common/units.h"
#include "mocks/generator/scpi_parser.h"

namespace msmcal::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kInfReply = 9.9e37;  // SCPI's "INFinity"
constexpr size_t kErrorQueueSize = 20;

double Frac(double x) { return x - std::floor(x); }

std::string Unquote(const std::string& s) {
  if (s.size() >= 2 && (s.front() == '"' || s.front() == '\'') && s.back() == s.front()) {
    return s.substr(1, s.size() - 2);
  }
  return s;
}

// Largest Vpp the 33520B drives into `load_ohm` (10 Vpp into 50 ohm, 20 Vpp open circuit).
double MaxVpp(double load_ohm) {
  return std::isinf(load_ohm) ? 20.0 : 20.0 * load_ohm / (load_ohm + 50.0);
}
double MinVpp(double load_ohm) { return MaxVpp(load_ohm) / 10000.0; }

// Highest frequency of each function on the 30 MHz 33520B (ramp and triangle: 200 kHz).
double MaxFrequency(Function f) {
  return (f == Function::kRamp || f == Function::kTriangle) ? 200e3 : 30e6;
}

// Vpp per Vrms (crest factor x 2) for VOLTage:UNIT VRMS and DBM. Sine, arb, noise and DC use
// the sine's factor (the instrument computes arbs from their samples; the mock does not).
double VppPerVrms(Function f) {
  switch (f) {
    case Function::kSquare:
    case Function::kPulse:
    case Function::kPrbs:
      return 2.0;
    case Function::kRamp:
    case Function::kTriangle:
      return 2.0 * std::sqrt(3.0);
    default:
      return 2.0 * std::sqrt(2.0);
  }
}

double ToVpp(double v, VoltageUnit u, const ChannelSignal& ch) {
  switch (u) {
    case VoltageUnit::kVpp:
      return v;
    case VoltageUnit::kVrms:
      return v * VppPerVrms(ch.function);
    case VoltageUnit::kDbm:
      return std::sqrt(1e-3 * std::pow(10.0, v / 10.0) * ch.load_ohm) * VppPerVrms(ch.function);
  }
  return v;
}

double FromVpp(double vpp, VoltageUnit u, const ChannelSignal& ch) {
  switch (u) {
    case VoltageUnit::kVpp:
      return vpp;
    case VoltageUnit::kVrms:
      return vpp / VppPerVrms(ch.function);
    case VoltageUnit::kDbm: {
      const double vrms = vpp / VppPerVrms(ch.function);
      return 10.0 * std::log10(vrms * vrms / ch.load_ohm / 1e-3);
    }
  }
  return vpp;
}

const char* VoltageUnitName(VoltageUnit u) {
  return u == VoltageUnit::kVrms ? "VRMS" : u == VoltageUnit::kDbm ? "DBM" : "VPP";
}

constexpr double kMinPulseWidth = 16e-9;  // 33520B
constexpr double kMinEdge = 8.4e-9, kMaxEdge = 1e-6;

// Keeps a pulse realisable: width within [16 ns, period - 16 ns], each edge at most 0.625 of
// the shorter of width and period - width (edges give way first). Returns whether it changed
// anything.
bool FitPulse(ChannelSignal& ch) {
  const double period = 1.0 / ch.frequency_hz;
  bool changed = false;
  const double wmax = std::max(kMinPulseWidth, period - kMinPulseWidth);
  if (ch.pulse_width_s < kMinPulseWidth || ch.pulse_width_s > wmax) {
    ch.pulse_width_s = std::clamp(ch.pulse_width_s, kMinPulseWidth, wmax);
    changed = true;
  }
  const double cap =
      std::max(kMinEdge, 0.625 * std::min(ch.pulse_width_s, period - ch.pulse_width_s));
  for (double* e : {&ch.pulse_lead_s, &ch.pulse_trail_s}) {
    if (*e > cap * (1 + 1e-12)) {
      *e = cap;
      changed = true;
    }
  }
  return changed;
}

// 7-bit PRBS (x^7 + x^6 + 1), bit k of the sequence started from all ones.
bool PrbsBit(int64_t k) {
  uint32_t lfsr = 0x7F;
  const int64_t n = ((k % 127) + 127) % 127;
  for (int64_t i = 0; i < n; ++i) {
    const uint32_t bit = ((lfsr >> 6) ^ (lfsr >> 5)) & 1u;
    lfsr = ((lfsr << 1) | bit) & 0x7Fu;
  }
  return (lfsr & 1u) != 0;
}

}  // namespace

const char* FunctionName(Function f) {
  switch (f) {
    case Function::kSin:
      return "SIN";
    case Function::kSquare:
      return "SQU";
    case Function::kPulse:
      return "PULS";
    case Function::kArb:
      return "ARB";
    case Function::kDc:
      return "DC";
    case Function::kRamp:
      return "RAMP";
    case Function::kNoise:
      return "NOIS";
    case Function::kTriangle:
      return "TRI";
    case Function::kPrbs:
      return "PRBS";
  }
  return "SIN";
}

struct Mock33520B::Context {
  Mock33520B& unit;
  std::vector<int> suffix;
  const CommandUnit& cmd;
  int64_t now_ns;

  // Channel from the first numeric suffix; pushes -114 when it is not 1 or 2.
  ChannelSignal* Channel(size_t which = 0) {
    const int c = which < suffix.size() ? suffix[which] : 1;
    if (c < 1 || c > 2) {
      unit.PushError(-114, "Header suffix out of range");
      return nullptr;
    }
    return &unit.ch_[c - 1];
  }
  int ChannelIndex(size_t which = 0) const { return which < suffix.size() ? suffix[which] : 1; }

  bool ParamCount(size_t min, size_t max) {
    if (cmd.params.size() < min) {
      unit.PushError(-109, "Missing parameter");
      return false;
    }
    if (cmd.params.size() > max) {
      unit.PushError(-108, "Parameter not allowed");
      return false;
    }
    return true;
  }

  // Numeric parameter with MIN/MAX/DEF and a unit; out-of-range values are clipped with -222,
  // as the instrument does. nullopt (and -104/-131) when the text is not a number.
  std::optional<double> Number(size_t i, std::string_view unit_name, double lo, double hi,
                               double def) {
    const std::string t = Upper(cmd.params[i]);
    if (MatchMnemonic("MINimum", t)) return lo;
    if (MatchMnemonic("MAXimum", t)) return hi;
    if (MatchMnemonic("DEFault", t)) return def;
    const auto v = ParseNumericWithUnit(t, unit_name);
    if (!v) {
      BadNumber(t);
      return std::nullopt;
    }
    return Clip(*v, lo, hi);
  }

  // -131 for a number with a suffix this header does not take, -104 for a non-number.
  void BadNumber(const std::string& t) {
    const bool numeric_start = !t.empty() && (std::isdigit(static_cast<unsigned char>(t[0])) ||
                                              t[0] == '+' || t[0] == '-' || t[0] == '.');
    unit.PushError(numeric_start ? -131 : -104,
                   numeric_start ? "Invalid suffix" : "Data type error");
  }

  // Clips to [lo, hi] with -222, as the instrument does.
  double Clip(double v, double lo, double hi) {
    if (v < lo) {
      unit.PushError(-222, "Data out of range;value clipped to lower limit");
      return lo;
    }
    if (v > hi) {
      unit.PushError(-222, "Data out of range;value clipped to upper limit");
      return hi;
    }
    return v;
  }

  // Character data among `choices` (long forms like "WIDTh"); returns the short form, or
  // pushes -224 and returns nullopt.
  std::optional<std::string> Choice(const std::vector<const char*>& choices) {
    for (const char* c : choices) {
      if (MatchMnemonic(c, cmd.params[0])) {
        std::string short_form;
        for (const char* p = c; *p; ++p) {
          if (std::isupper(static_cast<unsigned char>(*p)) || std::isdigit(*p)) short_form += *p;
        }
        return short_form;
      }
    }
    unit.PushError(-224, "Illegal parameter value");
    return std::nullopt;
  }

  // An angle (PHASe, BURSt:PHASe) in the UNIT:ANGLe unit, or with a DEG/RAD suffix (S in SEC
  // mode), as degrees
  // clipped to +-360 degrees (+-2 pi rad, +-1 period in SEC) with -222.
  std::optional<double> AngleDeg(const ChannelSignal& ch) {
    const std::string t = Upper(cmd.params[0]);
    if (MatchMnemonic("MINimum", t)) return -360.0;
    if (MatchMnemonic("MAXimum", t)) return 360.0;
    if (MatchMnemonic("DEFault", t)) return 0.0;
    double deg = 0;
    if (auto v = ParseNumericWithUnit(t, "")) {
      deg = unit.angle_unit_ == "RAD"   ? common::RadToDeg(*v)
            : unit.angle_unit_ == "SEC" ? *v * ch.frequency_hz * 360.0
                                        : *v;
    } else if (auto d = ParseNumericWithUnit(t, "DEG")) {
      deg = *d;
    } else if (auto r = ParseNumericWithUnit(t, "RAD")) {
      deg = common::RadToDeg(*r);
    } else if (auto sec = ParseNumericWithUnit(t, "S"); sec && unit.angle_unit_ == "SEC") {
      deg = *sec * ch.frequency_hz * 360.0;
    } else {
      BadNumber(t);
      return std::nullopt;
    }
    return Clip(deg, -360.0, 360.0);
  }
  std::string AngleReply(double deg, const ChannelSignal& ch) const {
    if (unit.angle_unit_ == "RAD") return FormatReplyNumber(common::DegToRad(deg));
    if (unit.angle_unit_ == "SEC") return FormatReplyNumber(deg / 360.0 / ch.frequency_hz);
    return FormatReplyNumber(deg);
  }

  // MIN/MAX query argument ("FREQ? MAX"), else the current value.
  double QueryValue(double current, double lo, double hi, double def) {
    if (cmd.params.empty()) return current;
    const std::string t = Upper(cmd.params[0]);
    if (MatchMnemonic("MINimum", t)) return lo;
    if (MatchMnemonic("MAXimum", t)) return hi;
    if (MatchMnemonic("DEFault", t)) return def;
    unit.PushError(-224, "Illegal parameter value");
    return current;
  }
};

Mock33520B::Mock33520B(UnitOptions options, ClockNs clock_ns)
    : options_(std::move(options)), clock_(std::move(clock_ns)) {
  if (!clock_) {
    clock_ = [] {
      return static_cast<int64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                      std::chrono::steady_clock::now().time_since_epoch())
                                      .count());
    };
  }
  ResetLocked();
  BuildTable();
}

void Mock33520B::ResetLocked() {
  const int64_t now = clock_();
  for (ChannelSignal& c : ch_) {
    c = ChannelSignal{};
    c.start_time_ns = now;
  }
  border_big_endian_ = true;
  rosc_source_ = "INT";
  trigger_out_ = false;
  angle_unit_ = "DEG";
  display_text_.clear();
}

void Mock33520B::PushError(int code, const std::string& message) {
  if (errors_.size() >= kErrorQueueSize) {
    errors_.back() = {-350, "Queue overflow"};
    return;
  }
  errors_.emplace_back(code, message);
}

void Mock33520B::NotifyLocked() {
  ++version_;
  cv_.notify_all();
}

void Mock33520B::TriggerLocked(TriggerSource source, int64_t t_ns) {
  for (ChannelSignal& c : ch_) {
    if (c.burst_on && !c.running && c.trigger_source == source) {
      c.running = true;
      c.start_time_ns = t_ns;
    }
  }
  NotifyLocked();
}

void Mock33520B::ExternalTrigger(int64_t t_ns) {
  std::lock_guard lock(mu_);
  TriggerLocked(TriggerSource::kExternal, t_ns);
}

void Mock33520B::SetReferenceInput(std::function<bool()> present) {
  std::lock_guard lock(mu_);
  reference_present_ = std::move(present);
}

void Mock33520B::AddTriggerOutTarget(Mock33520B* slave) {
  std::lock_guard lock(mu_);
  trigger_targets_.push_back(slave);
}

ChannelSignal Mock33520B::Signal(int channel) const {
  std::lock_guard lock(mu_);
  return ch_[channel - 1];
}

bool Mock33520B::AnyOutputOn() const {
  std::lock_guard lock(mu_);
  return AnyOutputOnLocked();
}

size_t Mock33520B::ErrorCount() const {
  std::lock_guard lock(mu_);
  return errors_.size();
}

void Mock33520B::ReportInputOverrun() {
  std::lock_guard lock(mu_);
  PushError(-363, "Input buffer overrun");
}

uint64_t Mock33520B::ParseWork() const {
  std::lock_guard lock(mu_);
  return work_;
}

uint64_t Mock33520B::StateVersion() const {
  std::lock_guard lock(mu_);
  return version_;
}

std::string Mock33520B::ReferenceSourceCurrent() const {
  std::lock_guard lock(mu_);
  const bool present = reference_present_ && reference_present_();
  return (rosc_source_ != "INT" && present) ? "EXT" : "INT";
}

bool Mock33520B::WaitUntil(const std::function<bool(const Mock33520B&)>& pred,
                           int64_t timeout_ms) const {
  std::unique_lock lock(mu_);
  return cv_.wait_until(lock,
                        std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms),
                        [&] { return pred(*this); });
}

double Mock33520B::SignalAt(int channel, int64_t t_ns) const {
  std::lock_guard lock(mu_);
  const ChannelSignal& c = ch_[channel - 1];
  if (!c.output_on) return 0.0;
  const bool finite = c.burst_on && !std::isinf(c.burst_ncycles);
  const bool repeating = finite && c.trigger_source == TriggerSource::kImmediate;
  const bool active = c.burst_on ? (!c.burst_gated && (c.running || repeating)) : c.running;
  double tau = (!active || t_ns < c.start_time_ns)
                   ? 0.0
                   : static_cast<double>(t_ns - c.start_time_ns) * 1e-9;
  if (repeating) tau = std::fmod(tau, c.burst_period_s);
  if (finite && c.frequency_hz * tau >= c.burst_ncycles) tau = 0.0;  // burst done: idle level
  const double phase_cycles = (c.burst_on ? c.burst_phase_deg : c.phase_deg) / 360.0;
  const double cycle = Frac(c.frequency_hz * tau + phase_cycles);
  const double sign = c.output_polarity == "INV" ? -1.0 : 1.0;
  const double half = 0.5 * c.amplitude_vpp * sign;
  switch (c.function) {
    case Function::kSin:
      return c.offset_v + half * std::sin(2 * kPi * cycle);
    case Function::kSquare:
      return c.offset_v + (cycle < c.square_duty_percent / 100.0 ? half : -half);
    case Function::kPulse:
      return c.offset_v + (cycle < c.pulse_width_s * c.frequency_hz ? half : -half);
    case Function::kRamp:
    case Function::kTriangle: {
      const double s = c.function == Function::kTriangle ? 0.5 : c.ramp_symmetry_percent / 100.0;
      const double y = cycle < s ? cycle / s : 1.0 - (cycle - s) / (1.0 - s);
      return c.offset_v + half * (2.0 * y - 1.0);
    }
    case Function::kPrbs: {
      const auto k = static_cast<int64_t>(std::floor(c.frequency_hz * tau + phase_cycles));
      return c.offset_v + (PrbsBit(k) ? half : -half);
    }
    case Function::kArb: {
      if (!c.arb_samples || c.arb_samples->empty()) return c.offset_v;
      const double n = static_cast<double>(c.arb_samples->size());
      const double f = Frac(tau * c.arb_sample_rate_sps / n + phase_cycles);
      size_t k = static_cast<size_t>(std::floor(f * n + 1e-9));
      if (k >= c.arb_samples->size()) k = 0;
      return c.offset_v + 0.5 * c.arb_ptpeak_v * sign * (*c.arb_samples)[k] / 32767.0;
    }
    case Function::kDc:
    case Function::kNoise:
      return c.offset_v;
  }
  return 0.0;
}

std::optional<std::string> Mock33520B::ExecuteLocked(const CommandUnit& unit,
                                                     std::vector<std::string>& path) {
  // No header is deeper than the deepest pattern: such a unit is undefined and leaves the path
  // where it was, so a compound line of N units costs O(N) however its headers nest.
  const size_t depth = (unit.common || unit.absolute ? 0 : path.size()) + unit.nodes.size();
  work_ += depth;
  if (depth > max_header_nodes_) {
    PushError(-113, "Undefined header");
    return std::nullopt;
  }
  const std::vector<HeaderNode> nodes = SplitHeaderNodes(ResolvePath(unit, path));
  for (const Entry& e : table_) {
    if (e.query != unit.query) continue;
    auto suffixes = e.pattern.Match(nodes, &work_);
    if (!suffixes) continue;
    Context ctx{*this, *suffixes, unit, clock_()};
    return e.handler(ctx);
  }
  PushError(-113, "Undefined header");
  return std::nullopt;
}

std::string Mock33520B::Process(const std::string& message_in) {
  std::lock_guard lock(mu_);
  std::string_view message = message_in;
  while (!message.empty() && (message.back() == '\r' || message.back() == '\n')) {
    message.remove_suffix(1);
  }
  const SplitResult split = SplitProgramMessage(message);
  work_ += message.size();
  std::vector<std::string> path;
  std::string out;
  size_t replies = 0;
  bool overflowed = false;
  for (const CommandUnit& unit : split.units) {
    std::optional<std::string> reply = ExecuteLocked(unit, path);
    if (!reply) continue;
    if (out.size() + reply->size() + 1 > options_.max_response_bytes) {
      if (!overflowed) PushError(-430, "Query DEADLOCKED");
      overflowed = true;
      continue;
    }
    if (replies++) out += ";";
    out += *reply;
  }
  if (split.failure) PushError(split.failure->code, split.failure->message);
  NotifyLocked();
  return out;
}

void Mock33520B::BuildTable() {
  using R = std::optional<std::string>;
  auto set = [this](const char* p, Handler h) {
    table_.push_back({HeaderPattern(p), false, std::move(h)});
  };
  auto get = [this](const char* p, Handler h) {
    table_.push_back({HeaderPattern(p), true, std::move(h)});
  };
  const R none = std::nullopt;

  // IEEE 488.2 common commands.
  get("*IDN", [this](Context&) -> R { return options_.identity; });
  get("*OPT", [this](Context&) -> R { return options_.options_reply; });
  get("*OPC", [](Context&) -> R { return "1"; });
  set("*OPC", [none](Context&) { return none; });
  set("*WAI", [none](Context&) { return none; });
  get("*ESR", [](Context&) -> R { return "+0"; });
  get("*STB", [](Context&) -> R { return "+0"; });
  set("*CLS", [this, none](Context&) {
    errors_.clear();
    return none;
  });
  set("*RST", [this, none](Context&) {
    ResetLocked();
    return none;
  });
  set("*TRG", [this, none](Context& c) {
    TriggerLocked(TriggerSource::kBus, c.now_ns);
    if (trigger_out_) {
      for (Mock33520B* s : trigger_targets_) s->ExternalTrigger(c.now_ns);
    }
    return none;
  });

  get("SYSTem:ERRor[:NEXT]", [this](Context&) -> R {
    if (errors_.empty()) return "+0,\"No error\"";
    auto [code, msg] = errors_.front();
    errors_.pop_front();
    char buf[16];
    std::snprintf(buf, sizeof(buf), "%+d", code);
    return std::string(buf) + ",\"" + msg + "\"";
  });

  // Function.
  set("[SOURce#:]FUNCtion[:SHAPe]", [this, none](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    static const std::pair<const char*, Function> kNames[] = {
        {"SINusoid", Function::kSin}, {"SQUare", Function::kSquare},
        {"PULSe", Function::kPulse},  {"ARBitrary", Function::kArb},
        {"DC", Function::kDc},        {"RAMP", Function::kRamp},
        {"NOISe", Function::kNoise},  {"TRIangle", Function::kTriangle},
        {"PRBS", Function::kPrbs}};
    for (const auto& [name, f] : kNames) {
      if (!MatchMnemonic(name, c.cmd.params[0])) continue;
      if (ch->burst_on && (f == Function::kDc || (f == Function::kNoise && !ch->burst_gated))) {
        PushError(-221, "Settings conflict;function not allowed in this burst mode");
        return none;
      }
      ch->function = f;
      if (ch->frequency_hz > MaxFrequency(f)) {
        ch->frequency_hz = MaxFrequency(f);
        PushError(-221, "Settings conflict;frequency reduced to the function's maximum");
      }
      if (f == Function::kPulse && FitPulse(*ch)) {
        PushError(-221, "Settings conflict;pulse width or edge time adjusted");
      }
      return none;
    }
    PushError(-224, "Illegal parameter value");
    return none;
  });
  get("[SOURce#:]FUNCtion[:SHAPe]", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return std::string(FunctionName(ch->function));
  });

  // Frequency.
  // A new period keeps the pulse width (HOLD WIDTh) or its duty cycle (HOLD DCYCle).
  auto set_frequency = [this](ChannelSignal& ch, double f) {
    if (ch.pulse_hold == "DCYC") ch.pulse_width_s *= ch.frequency_hz / f;
    ch.frequency_hz = f;
    if (FitPulse(ch) && ch.function == Function::kPulse) {
      PushError(-221, "Settings conflict;pulse width or edge time adjusted");
    }
  };
  set("[SOURce#:]FREQuency[:CW]", [none, set_frequency](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    if (auto v = c.Number(0, "HZ", 1e-6, MaxFrequency(ch->function), 1000.0)) {
      set_frequency(*ch, *v);
    }
    return none;
  });
  get("[SOURce#:]FREQuency[:CW]", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return FormatReplyNumber(
        c.QueryValue(ch->frequency_hz, 1e-6, MaxFrequency(ch->function), 1000.0));
  });

  // Amplitude and offset (into the configured load).
  // Amplitude in the channel's VOLTage:UNIT, or in the unit its suffix names (VPP, VRMS, DBM).
  set("[SOURce#:]VOLTage[:LEVel][:IMMediate][:AMPLitude]", [this, none](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    const double lo = MinVpp(ch->load_ohm), hi = MaxVpp(ch->load_ohm);
    const std::string t = Upper(c.cmd.params[0]);
    std::optional<double> vpp;
    if (MatchMnemonic("MINimum", t)) {
      vpp = lo;
    } else if (MatchMnemonic("MAXimum", t)) {
      vpp = hi;
    } else if (MatchMnemonic("DEFault", t)) {
      vpp = 0.1;
    } else {
      std::optional<VoltageUnit> unit;
      std::optional<double> v;
      if ((v = ParseNumericWithUnit(t, ""))) {
        unit = ch->voltage_unit;
      } else if ((v = ParseNumericWithUnit(t, "VRMS"))) {
        unit = VoltageUnit::kVrms;
      } else if ((v = ParseNumericWithUnit(t, "DBM"))) {
        unit = VoltageUnit::kDbm;
      } else if ((v = ParseNumericWithUnit(t, "VPP|V"))) {
        unit = VoltageUnit::kVpp;
      }
      if (!v) {
        c.BadNumber(t);
        return none;
      }
      if (*unit == VoltageUnit::kDbm && std::isinf(ch->load_ohm)) {
        PushError(-221, "Settings conflict;dBm needs a finite output load");
        return none;
      }
      vpp = c.Clip(ToVpp(*v, *unit, *ch), lo, hi);
    }
    if (std::abs(ch->offset_v) + *vpp / 2 > hi / 2 + 1e-12) {
      PushError(-221, "Settings conflict;amplitude and offset exceed the output range");
    } else {
      ch->amplitude_vpp = *vpp;
    }
    return none;
  });
  get("[SOURce#:]VOLTage[:LEVel][:IMMediate][:AMPLitude]", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    const double vpp =
        c.QueryValue(ch->amplitude_vpp, MinVpp(ch->load_ohm), MaxVpp(ch->load_ohm), 0.1);
    return FormatReplyNumber(FromVpp(vpp, ch->voltage_unit, *ch));
  });
  set("[SOURce#:]VOLTage:UNIT", [this, none](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    const auto u = c.Choice({"VPP", "VRMS", "DBM"});
    if (!u) return none;
    if (*u == "DBM" && std::isinf(ch->load_ohm)) {
      PushError(-221, "Settings conflict;dBm needs a finite output load");
      return none;
    }
    ch->voltage_unit = *u == "VRMS"  ? VoltageUnit::kVrms
                       : *u == "DBM" ? VoltageUnit::kDbm
                                     : VoltageUnit::kVpp;
    return none;
  });
  get("[SOURce#:]VOLTage:UNIT", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return std::string(VoltageUnitName(ch->voltage_unit));
  });
  // High and low levels: the same state as amplitude and offset (high = offset + Vpp / 2).
  // Setting one keeps the other; a high level not above the low level by the minimum amplitude
  // is refused with -221.
  auto set_level = [this, none](Context& c, bool high) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    const double lim = MaxVpp(ch->load_ohm) / 2;
    const auto v = c.Number(0, "V", -lim, lim, high ? 0.05 : -0.05);
    if (!v) return none;
    const double hi = high ? *v : ch->offset_v + ch->amplitude_vpp / 2;
    const double lo = high ? ch->offset_v - ch->amplitude_vpp / 2 : *v;
    if (hi - lo < MinVpp(ch->load_ohm) * (1 - 1e-9)) {
      PushError(-221, "Settings conflict;high level must exceed low level");
      return none;
    }
    ch->amplitude_vpp = hi - lo;
    ch->offset_v = (hi + lo) / 2;
    return none;
  };
  auto get_level = [](Context& c, bool high) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    const double lim = MaxVpp(ch->load_ohm) / 2;
    const double level = ch->offset_v + (high ? 0.5 : -0.5) * ch->amplitude_vpp;
    return FormatReplyNumber(c.QueryValue(level, -lim, lim, high ? 0.05 : -0.05));
  };
  set("[SOURce#:]VOLTage[:LEVel][:IMMediate]:HIGH",
      [set_level](Context& c) { return set_level(c, true); });
  set("[SOURce#:]VOLTage[:LEVel][:IMMediate]:LOW",
      [set_level](Context& c) { return set_level(c, false); });
  get("[SOURce#:]VOLTage[:LEVel][:IMMediate]:HIGH",
      [get_level](Context& c) { return get_level(c, true); });
  get("[SOURce#:]VOLTage[:LEVel][:IMMediate]:LOW",
      [get_level](Context& c) { return get_level(c, false); });
  set("[SOURce#:]VOLTage[:LEVel][:IMMediate]:OFFSet", [this, none](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    const double hi = MaxVpp(ch->load_ohm) / 2;
    if (auto v = c.Number(0, "V", -hi, hi, 0.0)) {
      if (std::abs(*v) + ch->amplitude_vpp / 2 > hi + 1e-12) {
        PushError(-221, "Settings conflict;amplitude and offset exceed the output range");
      } else {
        ch->offset_v = *v;
      }
    }
    return none;
  });
  get("[SOURce#:]VOLTage[:LEVel][:IMMediate]:OFFSet", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return FormatReplyNumber(ch->offset_v);
  });

  // Phase.
  set("[SOURce#:]PHASe[:ADJust]", [none](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    if (auto v = c.AngleDeg(*ch)) ch->phase_deg = *v;
    return none;
  });
  get("[SOURce#:]PHASe[:ADJust]", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return c.AngleReply(ch->phase_deg, *ch);
  });
  set("[SOURce#:]PHASe:SYNChronize", [this, none](Context& c) {
    for (ChannelSignal& ch : ch_) {
      if (ch.running) ch.start_time_ns = c.now_ns;
    }
    return none;
  });

  // Square duty cycle.
  set("[SOURce#:]FUNCtion:SQUare:DCYCle", [none](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    if (auto v = c.Number(0, "PCT", 0.01, 99.99, 50.0)) ch->square_duty_percent = *v;
    return none;
  });
  get("[SOURce#:]FUNCtion:SQUare:DCYCle", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return FormatReplyNumber(ch->square_duty_percent);
  });

  // Output and load.
  set("OUTPut#[:STATe]", [none](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    const auto b = ParseBoolean(c.cmd.params[0]);
    if (!b) {
      c.unit.PushError(-224, "Illegal parameter value");
      return none;
    }
    if (*b && !ch->output_on && !ch->burst_on) ch->running = true;
    ch->output_on = *b;
    return none;
  });
  get("OUTPut#[:STATe]", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return std::string(ch->output_on ? "1" : "0");
  });
  set("OUTPut#:LOAD", [none](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    const std::string t = Upper(c.cmd.params[0]);
    if (MatchMnemonic("INFinity", t)) {
      ch->load_ohm = kInf;
      if (ch->voltage_unit == VoltageUnit::kDbm) ch->voltage_unit = VoltageUnit::kVpp;
    } else if (auto v = c.Number(0, "OHM", 1.0, 10e3, 50.0)) {
      ch->load_ohm = *v;
    }
    // The instrument rescales amplitude limits with the load; keep the set value if it fits.
    ch->amplitude_vpp = std::min(ch->amplitude_vpp, MaxVpp(ch->load_ohm));
    return none;
  });
  get("OUTPut#:LOAD", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return FormatReplyNumber(std::isinf(ch->load_ohm) ? kInfReply : ch->load_ohm);
  });
  set("OUTPut:TRIGger[:STATe]", [this, none](Context& c) {
    if (!c.ParamCount(1, 1)) return none;
    const auto b = ParseBoolean(c.cmd.params[0]);
    if (!b) {
      PushError(-224, "Illegal parameter value");
    } else {
      trigger_out_ = *b;
    }
    return none;
  });
  get("OUTPut:TRIGger[:STATe]",
      [this](Context&) -> R { return std::string(trigger_out_ ? "1" : "0"); });

  // Arbitrary waveforms.
  set("FORMat:BORDer", [this, none](Context& c) {
    if (!c.ParamCount(1, 1)) return none;
    if (MatchMnemonic("NORMal", c.cmd.params[0])) {
      border_big_endian_ = true;
    } else if (MatchMnemonic("SWAPped", c.cmd.params[0])) {
      border_big_endian_ = false;
    } else {
      PushError(-224, "Illegal parameter value");
    }
    return none;
  });
  get("FORMat:BORDer",
      [this](Context&) -> R { return std::string(border_big_endian_ ? "NORM" : "SWAP"); });

  auto store_arb = [this](Context& c, const std::string& name_in, std::vector<int16_t> samples) {
    const std::string name = Upper(Unquote(name_in));
    const int ci = c.ChannelIndex() - 1;
    if (name.empty() || name.size() > 12 || !std::isalpha(static_cast<unsigned char>(name[0]))) {
      PushError(-224, "Illegal parameter value;arb name must be 1-12 characters, letter first");
      return;
    }
    const int64_t max_points = options_.options_reply.find("MEM") != std::string::npos
                                   ? 16'000'000
                                   : options_.arb_memory_points;
    if (samples.size() < 8 || static_cast<int64_t>(samples.size()) > max_points) {
      PushError(-222, "Data out of range;arb needs 8 to " + std::to_string(max_points) + " points");
      return;
    }
    int64_t used = 0;
    for (const auto& [n, s] : volatile_arbs_[ci]) {
      if (n != name) used += static_cast<int64_t>(s->size());
    }
    if (used + static_cast<int64_t>(samples.size()) > max_points) {
      PushError(-225, "Out of memory");
      return;
    }
    volatile_arbs_[ci][name] = std::make_shared<const std::vector<int16_t>>(std::move(samples));
  };
  set("[SOURce#:]DATA:ARBitrary:DAC", [this, none, store_arb](Context& c) {
    if (!c.Channel() || !c.ParamCount(2, 1 << 24)) return none;
    std::vector<int16_t> samples;
    const std::string& p1 = c.cmd.params[1];
    if (c.cmd.params.size() == 2 && !p1.empty() && p1[0] == '#') {
      // Definite-length block of int16 in the FORMat:BORDer order.
      const size_t n = p1.size() > 1 ? static_cast<size_t>(p1[1] - '0') : 0;
      const size_t header = 2 + n;
      if (n < 1 || n > 9 || p1.size() < header) {
        PushError(-161, "Invalid block data");
        return none;
      }
      const size_t len = std::stoul(p1.substr(2, n));
      if (p1.size() != header + len || len % 2 != 0) {
        PushError(-161, "Invalid block data");
        return none;
      }
      samples.resize(len / 2);
      for (size_t i = 0; i < samples.size(); ++i) {
        const auto b0 = static_cast<uint8_t>(p1[header + 2 * i]);
        const auto b1 = static_cast<uint8_t>(p1[header + 2 * i + 1]);
        const uint16_t u = border_big_endian_ ? static_cast<uint16_t>((b0 << 8) | b1)
                                              : static_cast<uint16_t>((b1 << 8) | b0);
        samples[i] = static_cast<int16_t>(u);
      }
    } else {
      for (size_t i = 1; i < c.cmd.params.size(); ++i) {
        const auto v = ParseNumericWithUnit(c.cmd.params[i], "");
        if (!v || *v < -32768 || *v > 32767) {
          PushError(-222, "Data out of range;DAC values are -32767 to +32767");
          return none;
        }
        samples.push_back(static_cast<int16_t>(std::lround(*v)));
      }
    }
    for (int16_t& s : samples) {
      if (s < -32767) {
        PushError(-222, "Data out of range;DAC values are -32767 to +32767");
        return none;
      }
    }
    store_arb(c, c.cmd.params[0], std::move(samples));
    return none;
  });
  set("[SOURce#:]DATA:ARBitrary", [this, none, store_arb](Context& c) {
    if (!c.Channel() || !c.ParamCount(2, 1 << 24)) return none;
    std::vector<int16_t> samples;
    for (size_t i = 1; i < c.cmd.params.size(); ++i) {
      const auto v = ParseNumericWithUnit(c.cmd.params[i], "");
      if (!v || *v < -1.0 || *v > 1.0) {
        PushError(-222, "Data out of range;values are -1 to +1");
        return none;
      }
      samples.push_back(static_cast<int16_t>(std::lround(*v * 32767.0)));
    }
    store_arb(c, c.cmd.params[0], std::move(samples));
    return none;
  });
  set("[SOURce#:]DATA:VOLatile:CLEar", [this, none](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch) return none;
    volatile_arbs_[c.ChannelIndex() - 1].clear();
    ch->arb_name.clear();
    ch->arb_samples.reset();
    return none;
  });
  get("[SOURce#:]DATA:VOLatile:CATalog", [this](Context& c) -> R {
    if (!c.Channel()) return std::nullopt;
    std::string out;
    for (const auto& [name, s] : volatile_arbs_[c.ChannelIndex() - 1]) {
      out += (out.empty() ? "\"" : ",\"") + name + "\"";
    }
    return out.empty() ? std::string("\"\"") : out;
  });
  get("[SOURce#:]DATA:VOLatile:FREE", [this](Context& c) -> R {
    if (!c.Channel()) return std::nullopt;
    int64_t used = 0;
    for (const auto& [n, s] : volatile_arbs_[c.ChannelIndex() - 1])
      used += static_cast<int64_t>(s->size());
    return "+" + std::to_string(options_.arb_memory_points - used);
  });
  get("[SOURce#:]DATA:ATTRibute:POINts", [this](Context& c) -> R {
    if (!c.Channel()) return std::nullopt;
    const int ci = c.ChannelIndex() - 1;
    const std::string name =
        c.cmd.params.empty() ? ch_[ci].arb_name : Upper(Unquote(c.cmd.params[0]));
    auto it = volatile_arbs_[ci].find(name);
    if (it == volatile_arbs_[ci].end()) {
      PushError(-224, "Illegal parameter value;arb not in volatile memory");
      return std::string("+0");
    }
    return "+" + std::to_string(it->second->size());
  });
  set("[SOURce#:]FUNCtion:ARBitrary", [this, none](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    const std::string name = Upper(Unquote(c.cmd.params[0]));
    auto& mem = volatile_arbs_[c.ChannelIndex() - 1];
    auto it = mem.find(name);
    if (it == mem.end()) {
      PushError(-224, "Illegal parameter value;arb not in volatile memory");
      return none;
    }
    ch->arb_name = name;
    ch->arb_samples = it->second;
    return none;
  });
  get("[SOURce#:]FUNCtion:ARBitrary", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return "\"" + ch->arb_name + "\"";
  });
  set("[SOURce#:]FUNCtion:ARBitrary:SRATe", [none](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    if (auto v = c.Number(0, "SA/S|HZ", 1e-6, 160e6, 40e3)) ch->arb_sample_rate_sps = *v;
    return none;
  });
  get("[SOURce#:]FUNCtion:ARBitrary:SRATe", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return FormatReplyNumber(c.QueryValue(ch->arb_sample_rate_sps, 1e-6, 160e6, 40e3));
  });
  set("[SOURce#:]FUNCtion:ARBitrary:PTPeak", [this, none](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    const double lo = MinVpp(ch->load_ohm), hi = MaxVpp(ch->load_ohm);
    if (auto v = c.Number(0, "VPP|V", lo, hi, 0.1)) {
      if (std::abs(ch->offset_v) + *v / 2 > hi / 2 + 1e-12) {
        PushError(-221, "Settings conflict;amplitude and offset exceed the output range");
      } else {
        ch->arb_ptpeak_v = *v;
        ch->amplitude_vpp = *v;
      }
    }
    return none;
  });
  get("[SOURce#:]FUNCtion:ARBitrary:PTPeak", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return FormatReplyNumber(ch->arb_ptpeak_v);
  });

  // Reference oscillator.
  set("[SOURce:]ROSCillator:SOURce", [this, none](Context& c) {
    if (!c.ParamCount(1, 1)) return none;
    const std::string& p = c.cmd.params[0];
    if (MatchMnemonic("INTernal", p)) {
      rosc_source_ = "INT";
    } else if (MatchMnemonic("EXTernal", p)) {
      rosc_source_ = "EXT";
    } else if (MatchMnemonic("AUTO", p)) {
      rosc_source_ = "AUTO";
    } else {
      PushError(-224, "Illegal parameter value");
    }
    return none;
  });
  get("[SOURce:]ROSCillator:SOURce", [this](Context&) -> R { return rosc_source_; });
  get("[SOURce:]ROSCillator:SOURce:CURRent", [this](Context&) -> R {
    const bool present = reference_present_ && reference_present_();
    return std::string((rosc_source_ != "INT" && present) ? "EXT" : "INT");
  });

  // Burst and trigger.
  set("[SOURce#:]BURSt:STATe", [none](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    const auto b = ParseBoolean(c.cmd.params[0]);
    if (!b) {
      c.unit.PushError(-224, "Illegal parameter value");
      return none;
    }
    if (*b &&
        (ch->function == Function::kDc || (ch->function == Function::kNoise && !ch->burst_gated))) {
      c.unit.PushError(-221, "Settings conflict;function not allowed in this burst mode");
      return none;
    }
    ch->burst_on = *b;
    ch->running = !*b;
    ch->start_time_ns = c.now_ns;
    return none;
  });
  get("[SOURce#:]BURSt:STATe", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return std::string(ch->burst_on ? "1" : "0");
  });
  set("[SOURce#:]BURSt:PHASe", [none](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    if (auto v = c.AngleDeg(*ch)) ch->burst_phase_deg = *v;
    return none;
  });
  get("[SOURce#:]BURSt:PHASe", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return c.AngleReply(ch->burst_phase_deg, *ch);
  });
  set("[SOURce#:]BURSt:MODE", [none](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    if (auto m = c.Choice({"TRIGgered", "GATed"})) ch->burst_gated = *m == "GAT";
    return none;
  });
  get("[SOURce#:]BURSt:MODE", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return std::string(ch->burst_gated ? "GAT" : "TRIG");
  });
  // A finite burst must fit its period (internal trigger): period > N / f + 1 us. A period too
  // short is raised to fit, with -221, as the instrument does.
  auto fit_burst_period = [this](ChannelSignal& ch) {
    if (std::isinf(ch.burst_ncycles)) return;
    const double need = ch.burst_ncycles / ch.frequency_hz + 1e-6;
    if (ch.burst_period_s < need) {
      ch.burst_period_s = std::min(need, 8000.0);
      PushError(-221, "Settings conflict;burst period increased to fit the burst count");
    }
  };
  set("[SOURce#:]BURSt:NCYCles", [none, fit_burst_period](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    if (MatchMnemonic("INFinity", c.cmd.params[0])) {
      ch->burst_ncycles = kInf;
    } else if (auto v = c.Number(0, "", 1.0, 1e8, 1.0)) {
      ch->burst_ncycles = std::round(*v);
      fit_burst_period(*ch);
    }
    return none;
  });
  get("[SOURce#:]BURSt:NCYCles", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    const double n = std::isinf(ch->burst_ncycles) ? kInfReply : ch->burst_ncycles;
    return FormatReplyNumber(c.QueryValue(n, 1.0, 1e8, 1.0));
  });
  set("[SOURce#:]BURSt:INTernal:PERiod", [none, fit_burst_period](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    if (auto v = c.Number(0, "S", 1e-6, 8000.0, 10e-3)) {
      ch->burst_period_s = *v;
      fit_burst_period(*ch);
    }
    return none;
  });
  get("[SOURce#:]BURSt:INTernal:PERiod", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return FormatReplyNumber(c.QueryValue(ch->burst_period_s, 1e-6, 8000.0, 10e-3));
  });
  set("TRIGger#:SOURce", [none](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    const std::string& p = c.cmd.params[0];
    if (MatchMnemonic("IMMediate", p)) {
      ch->trigger_source = TriggerSource::kImmediate;
    } else if (MatchMnemonic("EXTernal", p)) {
      ch->trigger_source = TriggerSource::kExternal;
    } else if (MatchMnemonic("BUS", p)) {
      ch->trigger_source = TriggerSource::kBus;
    } else if (MatchMnemonic("TIMer", p)) {
      ch->trigger_source = TriggerSource::kTimer;
    } else {
      c.unit.PushError(-224, "Illegal parameter value");
    }
    return none;
  });
  get("TRIGger#:SOURce", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    switch (ch->trigger_source) {
      case TriggerSource::kImmediate:
        return std::string("IMM");
      case TriggerSource::kExternal:
        return std::string("EXT");
      case TriggerSource::kBus:
        return std::string("BUS");
      case TriggerSource::kTimer:
        return std::string("TIM");
    }
    return std::string("IMM");
  });

  // A character-data setting of a channel: the reply is the short form of the choice.
  auto channel_choice = [&](const char* pattern, std::vector<const char*> choices,
                            std::string ChannelSignal::*field) {
    set(pattern, [none, choices, field](Context& c) {
      ChannelSignal* ch = c.Channel();
      if (!ch || !c.ParamCount(1, 1)) return none;
      if (auto v = c.Choice(choices)) (*ch).*field = *v;
      return none;
    });
    get(pattern, [field](Context& c) -> R {
      ChannelSignal* ch = c.Channel();
      if (!ch) return std::nullopt;
      return (*ch).*field;
    });
  };
  // A numeric setting of a channel with fixed limits (clipped with -222, MIN/MAX/DEF).
  auto channel_number = [&](const char* pattern, const char* unit_name, double lo, double hi,
                            double def, double ChannelSignal::*field) {
    set(pattern, [none, unit_name, lo, hi, def, field](Context& c) {
      ChannelSignal* ch = c.Channel();
      if (!ch || !c.ParamCount(1, 1)) return none;
      if (auto v = c.Number(0, unit_name, lo, hi, def)) (*ch).*field = *v;
      return none;
    });
    get(pattern, [lo, hi, def, field](Context& c) -> R {
      ChannelSignal* ch = c.Channel();
      if (!ch) return std::nullopt;
      return FormatReplyNumber(c.QueryValue((*ch).*field, lo, hi, def));
    });
  };

  channel_number("[SOURce#:]FUNCtion:RAMP:SYMMetry", "PCT", 0.0, 100.0, 100.0,
                 &ChannelSignal::ramp_symmetry_percent);
  channel_choice("[SOURce#:]FUNCtion:ARBitrary:ADVance", {"TRIGger", "SRATe"},
                 &ChannelSignal::arb_advance);
  channel_choice("[SOURce#:]FUNCtion:ARBitrary:FILTer", {"NORMal", "STEP", "OFF"},
                 &ChannelSignal::arb_filter);
  channel_choice("[SOURce#:]BURSt:GATE:POLarity", {"NORMal", "INVerted"},
                 &ChannelSignal::burst_gate_polarity);
  channel_choice("OUTPut#:POLarity", {"NORMal", "INVerted"}, &ChannelSignal::output_polarity);
  channel_choice("TRIGger#:SLOPe", {"POSitive", "NEGative"}, &ChannelSignal::trigger_slope);
  channel_number("TRIGger#:DELay", "S", 0.0, 1000.0, 0.0, &ChannelSignal::trigger_delay_s);

  // Pulse: period (= 1 / frequency, for every function), width or duty cycle (HOLD says which
  // a period change keeps), edge times; FitPulse keeps them realisable, with -221 when it has
  // to adjust.
  auto fit_pulse = [this](ChannelSignal& ch) {
    if (FitPulse(ch)) PushError(-221, "Settings conflict;pulse width or edge time adjusted");
  };
  set("[SOURce#:]FUNCtion:PULSe:PERiod", [none, set_frequency](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    if (auto v = c.Number(0, "S", 1.0 / MaxFrequency(ch->function), 1e6, 1e-3)) {
      set_frequency(*ch, 1.0 / *v);
    }
    return none;
  });
  get("[SOURce#:]FUNCtion:PULSe:PERiod", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return FormatReplyNumber(
        c.QueryValue(1.0 / ch->frequency_hz, 1.0 / MaxFrequency(ch->function), 1e6, 1e-3));
  });
  set("[SOURce#:]FUNCtion:PULSe:WIDTh", [none, fit_pulse](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    if (auto v = c.Number(0, "S", kMinPulseWidth, 1e6, 100e-6)) {
      ch->pulse_width_s = *v;
      fit_pulse(*ch);
    }
    return none;
  });
  get("[SOURce#:]FUNCtion:PULSe:WIDTh", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    const double wmax = std::max(kMinPulseWidth, 1.0 / ch->frequency_hz - kMinPulseWidth);
    return FormatReplyNumber(c.QueryValue(ch->pulse_width_s, kMinPulseWidth, wmax, 100e-6));
  });
  set("[SOURce#:]FUNCtion:PULSe:DCYCle", [none, fit_pulse](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    if (auto v = c.Number(0, "PCT", 0.0, 100.0, 10.0)) {
      ch->pulse_width_s = *v / 100.0 / ch->frequency_hz;
      fit_pulse(*ch);
    }
    return none;
  });
  get("[SOURce#:]FUNCtion:PULSe:DCYCle", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return FormatReplyNumber(
        c.QueryValue(100.0 * ch->pulse_width_s * ch->frequency_hz, 0.0, 100.0, 10.0));
  });
  channel_choice("[SOURce#:]FUNCtion:PULSe:HOLD", {"WIDTh", "DCYCle"}, &ChannelSignal::pulse_hold);
  auto set_edges = [none, fit_pulse](Context& c, bool lead, bool trail) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    if (auto v = c.Number(0, "S", kMinEdge, kMaxEdge, 10e-9)) {
      if (lead) ch->pulse_lead_s = *v;
      if (trail) ch->pulse_trail_s = *v;
      fit_pulse(*ch);
    }
    return none;
  };
  auto get_edge = [](Context& c, bool lead) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return FormatReplyNumber(
        c.QueryValue(lead ? ch->pulse_lead_s : ch->pulse_trail_s, kMinEdge, kMaxEdge, 10e-9));
  };
  set("[SOURce#:]FUNCtion:PULSe:TRANsition[:BOTH]",
      [set_edges](Context& c) { return set_edges(c, true, true); });
  set("[SOURce#:]FUNCtion:PULSe:TRANsition:LEADing",
      [set_edges](Context& c) { return set_edges(c, true, false); });
  set("[SOURce#:]FUNCtion:PULSe:TRANsition:TRAiling",
      [set_edges](Context& c) { return set_edges(c, false, true); });
  // TRANsition? and TRANsition:BOTH? answer the leading edge.
  get("[SOURce#:]FUNCtion:PULSe:TRANsition[:BOTH]",
      [get_edge](Context& c) { return get_edge(c, true); });
  get("[SOURce#:]FUNCtion:PULSe:TRANsition:LEADing",
      [get_edge](Context& c) { return get_edge(c, true); });
  get("[SOURce#:]FUNCtion:PULSe:TRANsition:TRAiling",
      [get_edge](Context& c) { return get_edge(c, false); });

  // Unit-wide settings and information.
  set("UNIT:ANGLe", [this, none](Context& c) {
    if (!c.ParamCount(1, 1)) return none;
    if (MatchMnemonic("DEFault", c.cmd.params[0])) {
      angle_unit_ = "DEG";
    } else if (auto u = c.Choice({"DEGree", "RADian", "SECond"})) {
      angle_unit_ = *u;
    }
    return none;
  });
  get("UNIT:ANGLe", [this](Context&) -> R { return angle_unit_; });
  set("DISPlay:TEXT[:DATA]", [this, none](Context& c) {
    if (!c.ParamCount(1, 1)) return none;
    const std::string& p = c.cmd.params[0];
    if (p.size() < 2 || (p.front() != '"' && p.front() != '\'') || p.back() != p.front()) {
      PushError(-151, "Invalid string data");
      return none;
    }
    display_text_ = Unquote(p);
    return none;
  });
  get("DISPlay:TEXT[:DATA]", [this](Context&) -> R { return "\"" + display_text_ + "\""; });
  set("DISPlay:TEXT:CLEar", [this, none](Context&) {
    display_text_.clear();
    return none;
  });
  set("SYSTem:BEEPer[:IMMediate]", [none](Context&) { return none; });
  get("SYSTem:VERSion", [](Context&) -> R { return std::string("1999.0"); });
  get("*TST", [](Context&) -> R { return std::string("+0"); });  // self-test passed
  auto register_byte = [&](const char* name, int Mock33520B::*field) {
    set(name, [this, none, field](Context& c) {
      if (!c.ParamCount(1, 1)) return none;
      if (auto v = c.Number(0, "", 0.0, 255.0, 0.0)) this->*field = static_cast<int>(*v);
      return none;
    });
    get(name, [this, field](Context&) -> R { return "+" + std::to_string(this->*field); });
  };
  register_byte("*ESE", &Mock33520B::ese_);
  register_byte("*SRE", &Mock33520B::sre_);

  for (const Entry& e : table_)
    max_header_nodes_ = std::max(max_header_nodes_, e.pattern.max_nodes());
}

}  // namespace msmcal::sim
