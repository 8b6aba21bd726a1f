#include "drivers/generator/rig_config.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>

#include "common/file_text.h"
#include "common/yaml_fields.h"
#include "drivers/generator/rig_generators.h"

namespace msmcal::gen {
namespace {

// The rig file's generator section over the shared field reader (common/yaml_fields.h); adds
// `inf` as the spelling of high impedance for the load_ohm fields.
class Reader {
 public:
  explicit Reader(std::string origin) : fields_(std::move(origin)) {}

  [[noreturn]] void Fail(const YAML::Node& node, const std::string& field,
                         const std::string& what) const {
    fields_.Fail(node, field, what);
  }

  YAML::Node Map(const YAML::Node& parent, const std::string& key, const std::string& field,
                 const std::set<std::string>& allowed) const {
    return fields_.Map(parent, key, field, allowed);
  }

  // A finite number; `inf` (high impedance) only where `allow_inf` (load_ohm fields).
  double Number(const YAML::Node& parent, const std::string& key, const std::string& field,
                std::optional<double> def = std::nullopt, bool allow_inf = false) const {
    const YAML::Node n = parent[key];
    const std::string text = n && n.IsScalar() ? n.Scalar() : "";
    if (allow_inf && (text == "inf" || text == "INF" || text == ".inf")) return kHighZ;
    common::NumberRule rule;
    if (!allow_inf) rule.Note("(inf is accepted only for load_ohm: high impedance)");
    return fields_.Number(parent, key, field, def, rule);
  }

  int Int(const YAML::Node& parent, const std::string& key, const std::string& field,
          std::optional<int> def = std::nullopt) const {
    return fields_.Int(parent, key, field, def);
  }

  std::string String(const YAML::Node& parent, const std::string& key, const std::string& field,
                     std::optional<std::string> def = std::nullopt) const {
    return fields_.String(parent, key, field, def);
  }

  YAML::Node Load(const std::string& text) const { return fields_.Load(text); }

 private:
  common::YamlFields fields_;
};

Keysight33500Options ReadUnit(const Reader& r, const YAML::Node& gens, const std::string& key) {
  const std::string f = "generators." + key;
  const YAML::Node u =
      r.Map(gens, key, f, {"host", "port", "connect_timeout_ms", "io_timeout_ms", "channels"});
  Keysight33500Options o;
  o.name = key;
  o.link.host = r.String(u, "host", f + ".host");
  o.link.port = r.Int(u, "port", f + ".port");
  o.link.connect_timeout_ms = r.Int(u, "connect_timeout_ms", f + ".connect_timeout_ms", 3000);
  o.link.io_timeout_ms = r.Int(u, "io_timeout_ms", f + ".io_timeout_ms", 3000);
  const YAML::Node chs = r.Map(u, "channels", f + ".channels", {"1", "2"});
  for (int c = 1; c <= 2; ++c) {
    const std::string cf = f + ".channels." + std::to_string(c);
    const YAML::Node ch = r.Map(chs, std::to_string(c), cf,
                                {"role", "max_vpp", "max_abs_offset_v", "min_frequency_hz",
                                 "max_frequency_hz", "max_duty"});
    ChannelLimits& l = o.limits[c - 1];
    l.role = r.String(ch, "role", cf + ".role");
    l.max_vpp = r.Number(ch, "max_vpp", cf + ".max_vpp");
    l.max_abs_offset_v = r.Number(ch, "max_abs_offset_v", cf + ".max_abs_offset_v");
    l.min_frequency_hz = r.Number(ch, "min_frequency_hz", cf + ".min_frequency_hz");
    l.max_frequency_hz = r.Number(ch, "max_frequency_hz", cf + ".max_frequency_hz");
    l.max_duty = r.Number(ch, "max_duty", cf + ".max_duty", 1.0);
  }
  return o;
}

signal::SineDrive ReadSine(const Reader& r, const YAML::Node& drive, const std::string& key) {
  const std::string f = "generators.signals.drive." + key;
  const YAML::Node n =
      r.Map(drive, key, f, {"frequency_hz", "amplitude_vpp", "offset_v", "phase_deg"});
  signal::SineDrive s;
  s.frequency_hz = r.Number(n, "frequency_hz", f + ".frequency_hz");
  s.amplitude_vpp = r.Number(n, "amplitude_vpp", f + ".amplitude_vpp");
  s.offset_v = r.Number(n, "offset_v", f + ".offset_v", 0.0);
  s.phase_deg = r.Number(n, "phase_deg", f + ".phase_deg", 0.0);
  return s;
}

LogicLevels ReadLevels(const Reader& r, const YAML::Node& sig, const std::string& key) {
  const std::string f = "generators.signals." + key;
  const YAML::Node n = r.Map(sig, key, f, {"low_v", "high_v", "load_ohm"});
  LogicLevels l;
  l.low_v = r.Number(n, "low_v", f + ".low_v");
  l.high_v = r.Number(n, "high_v", f + ".high_v");
  l.load_ohm = r.Number(n, "load_ohm", f + ".load_ohm", kHighZ, /*allow_inf=*/true);
  return l;
}

}  // namespace

RigGeneratorConfig ParseRigGeneratorConfig(const std::string& yaml_text,
                                           const std::string& origin) {
  const Reader r(origin);
  const YAML::Node root = r.Load(yaml_text);
  if (!root.IsMap()) r.Fail(root, "(root)", "must be a mapping");
  const YAML::Node gens = r.Map(root, "generators", "generators", {"unit1", "unit2", "signals"});
  RigGeneratorConfig c;
  c.unit1 = ReadUnit(r, gens, "unit1");
  c.unit2 = ReadUnit(r, gens, "unit2");
  const YAML::Node sig =
      r.Map(gens, "signals", "generators.signals", {"drive", "laser", "clock", "trigger"});
  const YAML::Node drive =
      r.Map(sig, "drive", "generators.signals.drive", {"fast", "slow", "load_ohm"});
  c.signals.fast = ReadSine(r, drive, "fast");
  c.signals.slow = ReadSine(r, drive, "slow");
  c.signals.coil_load_ohm = r.Number(drive, "load_ohm", "generators.signals.drive.load_ohm", 50.0,
                                     /*allow_inf=*/true);
  c.signals.laser = ReadLevels(r, sig, "laser");
  c.signals.clock = ReadLevels(r, sig, "clock");
  const std::string tf = "generators.signals.trigger";
  const YAML::Node t = r.Map(sig, "trigger", tf,
                             {"spacing", "min_separation", "max_triggers", "min_points",
                              "max_points", "max_sample_rate_sps", "pulse_width_s", "max_duty"});
  signal::TriggerDesignOptions& o = c.signals.trigger;
  o.spacing = r.Number(t, "spacing", tf + ".spacing", o.spacing);
  o.min_separation = r.Number(t, "min_separation", tf + ".min_separation", o.min_separation);
  o.max_triggers = r.Int(t, "max_triggers", tf + ".max_triggers", o.max_triggers);
  o.min_points = r.Int(t, "min_points", tf + ".min_points", static_cast<int>(o.min_points));
  o.max_points = r.Int(t, "max_points", tf + ".max_points", static_cast<int>(o.max_points));
  o.max_sample_rate_sps =
      r.Number(t, "max_sample_rate_sps", tf + ".max_sample_rate_sps", o.max_sample_rate_sps);
  o.pulse_width_s = r.Number(t, "pulse_width_s", tf + ".pulse_width_s", o.pulse_width_s);
  o.max_duty = r.Number(t, "max_duty", tf + ".max_duty", o.max_duty);
  return c;
}

RigGeneratorConfig LoadRigGeneratorConfig(const std::string& path) {
  return ParseRigGeneratorConfig(common::ReadFileText(path, "cannot open the rig configuration"),
                                 path);
}

std::string RigGeneratorConfig::Validate() const {
  if (std::string e = unit1.Validate(); !e.empty()) return "generators." + e;
  if (std::string e = unit2.Validate(); !e.empty()) return "generators." + e;
  if (std::string e = signals.trigger.Validate(); !e.empty()) return "generators.signals." + e;
  std::ostringstream os;
  for (const auto& [name, l] :
       {std::pair{"laser", signals.laser}, std::pair{"clock", signals.clock}}) {
    if (!(l.high_v > l.low_v)) {
      os << "generators.signals." << name << ".high_v = " << l.high_v << ": must be > low_v ("
         << l.low_v << ")";
      return os.str();
    }
  }
  if (!(signals.coil_load_ohm > 0.0)) {
    os << "generators.signals.drive.load_ohm = " << signals.coil_load_ohm << ": must be > 0";
    return os.str();
  }
  // Each channel's limits against what the 33520B delivers into the load it is wired to.
  const std::pair<const Keysight33500Options*, int> channels[] = {
      {&unit1, 1}, {&unit1, 2}, {&unit2, 1}, {&unit2, 2}};
  const double loads[] = {signals.coil_load_ohm, signals.coil_load_ohm, signals.laser.load_ohm,
                          signals.clock.load_ohm};
  std::set<std::string> roles;
  for (size_t k = 0; k < 4; ++k) {
    const auto& [unit, ch] = channels[k];
    const std::string field =
        "generators." + unit->name + ".channels." + std::to_string(ch) + ".limits";
    const ChannelLimits& l = unit->limits[ch - 1];
    if (std::string e = CheckAgainstInstrument(field, l, loads[k]); !e.empty()) return e;
    if (!roles.insert(l.role).second) {
      return "generators." + unit->name + ".channels." + std::to_string(ch) + ".role = '" + l.role +
             "': another channel has the same role (each channel drives one thing)";
    }
  }
  // The laser trigger is a train of sparse pulses: a duty limit near 1 would let the laser fire
  // continuously (config/rig.yaml: 0.01).
  const ChannelLimits& laser = unit2.limits[0];
  if (!(laser.max_duty <= kMaxLaserDuty)) {
    os << "generators." << unit2.name << ".channels.1.max_duty = " << laser.max_duty
       << ": the laser trigger's duty limit must be <= " << kMaxLaserDuty;
    return os.str();
  }
  if (!(signals.trigger.max_duty <= kMaxLaserDuty)) {
    os << "generators.signals.trigger.max_duty = " << signals.trigger.max_duty
       << ": must be <= " << kMaxLaserDuty << " (sparse laser pulses)";
    return os.str();
  }
  RigSignalPlan plan;
  try {
    plan = PlanRigSignals(signals);
  } catch (const std::invalid_argument& e) {
    return std::string("generators.signals: ") + e.what();
  }
  const std::pair<const ChannelSetup*, std::pair<const Keysight33500Options*, int>> checks[] = {
      {&plan.unit1_ch1, {&unit1, 1}},
      {&plan.unit1_ch2, {&unit1, 2}},
      {&plan.unit2_ch1, {&unit2, 1}},
      {&plan.unit2_ch2, {&unit2, 2}}};
  for (const auto& [setup, where] : checks) {
    const auto& [unit, ch] = where;
    const std::string e = CheckLimits("generators." + unit->name + ".ch" + std::to_string(ch),
                                      *setup, unit->limits[ch - 1]);
    if (!e.empty()) return e;
  }
  return "";
}

}  // namespace msmcal::gen
