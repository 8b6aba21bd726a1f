#include "mocks/generator/mock_33520b.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>

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
      const bool numeric_start = !t.empty() && (std::isdigit(static_cast<unsigned char>(t[0])) ||
                                                t[0] == '+' || t[0] == '-' || t[0] == '.');
      unit.PushError(numeric_start ? -131 : -104,
                     numeric_start ? "Invalid suffix" : "Data type error");
      return std::nullopt;
    }
    if (*v < lo) {
      unit.PushError(-222, "Data out of range;value clipped to lower limit");
      return lo;
    }
    if (*v > hi) {
      unit.PushError(-222, "Data out of range;value clipped to upper limit");
      return hi;
    }
    return v;
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
  const double tau = (!c.running || t_ns < c.start_time_ns)
                         ? 0.0
                         : static_cast<double>(t_ns - c.start_time_ns) * 1e-9;
  const double phase_cycles = (c.burst_on ? c.burst_phase_deg : c.phase_deg) / 360.0;
  switch (c.function) {
    case Function::kSin:
      return c.offset_v +
             0.5 * c.amplitude_vpp * std::sin(2 * kPi * (c.frequency_hz * tau + phase_cycles));
    case Function::kSquare:
    case Function::kPulse: {
      const double f = Frac(c.frequency_hz * tau + phase_cycles);
      return c.offset_v + (f < c.square_duty_percent / 100.0 ? 0.5 : -0.5) * c.amplitude_vpp;
    }
    case Function::kRamp:
      return c.offset_v +
             0.5 * c.amplitude_vpp * (2.0 * Frac(c.frequency_hz * tau + phase_cycles) - 1.0);
    case Function::kArb: {
      if (!c.arb_samples || c.arb_samples->empty()) return c.offset_v;
      const double n = static_cast<double>(c.arb_samples->size());
      const double f = Frac(tau * c.arb_sample_rate_sps / n + phase_cycles);
      size_t k = static_cast<size_t>(std::floor(f * n + 1e-9));
      if (k >= c.arb_samples->size()) k = 0;
      return c.offset_v + 0.5 * c.arb_ptpeak_v * (*c.arb_samples)[k] / 32767.0;
    }
    case Function::kDc:
    case Function::kNoise:
      return c.offset_v;
  }
  return 0.0;
}

std::string Mock33520B::Process(const std::string& message_in) {
  std::lock_guard lock(mu_);
  std::string message = message_in;
  while (!message.empty() && (message.back() == '\r' || message.back() == '\n')) message.pop_back();
  const SplitResult split = SplitProgramMessage(message);
  std::vector<std::string> replies;
  std::vector<std::string> path;
  const uint64_t version_before = version_;
  for (const CommandUnit& unit : split.units) {
    const std::vector<std::string> nodes = ResolvePath(unit, path);
    bool matched = false;
    for (const Entry& e : table_) {
      if (e.query != unit.query) continue;
      auto suffixes = MatchHeader(e.pattern, nodes);
      if (!suffixes) continue;
      matched = true;
      Context ctx{*this, *suffixes, unit, clock_()};
      if (auto reply = e.handler(ctx)) replies.push_back(*reply);
      break;
    }
    if (!matched) PushError(-113, "Undefined header");
  }
  if (split.failure) PushError(split.failure->code, split.failure->message);
  ++version_;
  (void)version_before;
  cv_.notify_all();
  std::string out;
  for (size_t i = 0; i < replies.size(); ++i) {
    if (i) out += ";";
    out += replies[i];
  }
  return out;
}

void Mock33520B::BuildTable() {
  using R = std::optional<std::string>;
  auto set = [this](std::string p, Handler h) { table_.push_back({std::move(p), false, h}); };
  auto get = [this](std::string p, Handler h) { table_.push_back({std::move(p), true, h}); };
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
        {"SINusoid", Function::kSin},  {"SQUare", Function::kSquare}, {"PULSe", Function::kPulse},
        {"ARBitrary", Function::kArb}, {"DC", Function::kDc},         {"RAMP", Function::kRamp},
        {"NOISe", Function::kNoise}};
    for (const auto& [name, f] : kNames) {
      if (MatchMnemonic(name, c.cmd.params[0])) {
        ch->function = f;
        return none;
      }
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
  set("[SOURce#:]FREQuency[:CW]", [none](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    const double hi = ch->function == Function::kRamp ? 200e3 : 30e6;
    if (auto v = c.Number(0, "HZ", 1e-6, hi, 1000.0)) ch->frequency_hz = *v;
    return none;
  });
  get("[SOURce#:]FREQuency[:CW]", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return FormatReplyNumber(c.QueryValue(ch->frequency_hz, 1e-6, 30e6, 1000.0));
  });

  // Amplitude and offset (into the configured load).
  set("[SOURce#:]VOLTage[:LEVel][:IMMediate][:AMPLitude]", [this, none](Context& c) {
    ChannelSignal* ch = c.Channel();
    if (!ch || !c.ParamCount(1, 1)) return none;
    const double lo = MinVpp(ch->load_ohm), hi = MaxVpp(ch->load_ohm);
    if (auto v = c.Number(0, "VPP|V", lo, hi, 0.1)) {
      if (std::abs(ch->offset_v) + *v / 2 > hi / 2 + 1e-12) {
        PushError(-221, "Settings conflict;amplitude and offset exceed the output range");
      } else {
        ch->amplitude_vpp = *v;
      }
    }
    return none;
  });
  get("[SOURce#:]VOLTage[:LEVel][:IMMediate][:AMPLitude]", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return FormatReplyNumber(
        c.QueryValue(ch->amplitude_vpp, MinVpp(ch->load_ohm), MaxVpp(ch->load_ohm), 0.1));
  });
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
    if (auto v = c.Number(0, "DEG", -360.0, 360.0, 0.0)) ch->phase_deg = *v;
    return none;
  });
  get("[SOURce#:]PHASe[:ADJust]", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return FormatReplyNumber(ch->phase_deg);
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
    ch->burst_on = *b;
    ch->running = !*b;
    if (!*b) ch->start_time_ns = c.now_ns;
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
    if (auto v = c.Number(0, "DEG", -360.0, 360.0, 0.0)) ch->burst_phase_deg = *v;
    return none;
  });
  get("[SOURce#:]BURSt:PHASe", [](Context& c) -> R {
    ChannelSignal* ch = c.Channel();
    if (!ch) return std::nullopt;
    return FormatReplyNumber(ch->burst_phase_deg);
  });
  set("[SOURce#:]BURSt:MODE", [this, none](Context& c) {
    if (!c.Channel() || !c.ParamCount(1, 1)) return none;
    if (!MatchMnemonic("TRIGgered", c.cmd.params[0])) {
      PushError(-221, "Settings conflict;the mock models triggered bursts only");
    }
    return none;
  });
  set("[SOURce#:]BURSt:NCYCles", [this, none](Context& c) {
    if (!c.Channel() || !c.ParamCount(1, 1)) return none;
    if (!MatchMnemonic("INFinity", c.cmd.params[0])) {
      PushError(-221, "Settings conflict;the mock models infinite bursts only");
    }
    return none;
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
}

}  // namespace msmcal::sim
