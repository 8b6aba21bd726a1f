// libFuzzer target: sweep plans (ParseSweepPlan, SweepPlanToYaml, ComparePlans; docs/sweep.md).
//
// The plan parser is generic over the option set it varies (sweep::SweepParameters: the
// simulator's options for `msmcal sweep`, the rig file's for a rig sweep). Here it varies a small
// option set of the target's own (FuzzOptions below: nested maps, integers, decimals, a bool, a
// text field, a list and a list of lists, the simulator's paths for the seeds' sake), resolved
// in microseconds. The real option sets' parsers have their own targets (sim_yaml: ParseSimOptions
// and SimOptionsToYaml; rig_yaml: ParseRigFile); with them this target spent ~10 ms per input
// re-parsing the 100-line simulator defaults for every expanded point (25-280 exec/s).
//
// base_config names a file relative to the plan's folder: the target runs with a folder holding
// sim.yaml (FuzzOptions' defaults) so that it can be reached; inputs naming /dev, /proc or /sys
// are skipped (reading a device is not the parser's problem).
// Checks: returns or throws std::runtime_error naming the plan; an accepted plan written with
// SweepPlanToYaml parses again to a plan that writes the same text and expands to the same
// points (ComparePlans empty).
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>

#include "fuzz/fuzz_util.h"
#include "sessions/sweep/sweep_plan.h"

using namespace msmcal;
using fuzz::Check;
namespace fs = std::filesystem;

namespace {

// Every field with its default; the leaves are the schema (sweep::SweepParameters).
constexpr const char* kDefaults = R"(seed: 7
mirror:
  fast: {frequency_hz: 205, amplitude_vpp: 2.0, phase_deg: 0}
  slow: {frequency_hz: 5, amplitude_vpp: 4.0}
triggers: {max_triggers: 40, spacing: 0.25}
camera: {mono: false, kind: bgr8}
beams: {offsets_mm: [[1.2, -0.8], [-1.5, 0.6]], weights: [1, 2, 3]}
step1: {poses: 4}
step2: {neutral_frames: 1, fast_only_frames: 2}
hall: {background_duration_s: 4, actual_duration_s: 4}
)";

// A plan may expand to 10 000 points (sweep_plan.cc: kMaxPoints, unit-tested); here every point
// is resolved four times per input, so plans of more points are refused by the target (as a
// Resolve error, which the parser reports as the plan's): big plans repeat the same code and
// held the rate at tens of inputs per second.
constexpr int kMaxFuzzPoints = 8;

// Integer fields and their ranges; every other number is a finite decimal in [-1e6, 1e6].
struct IntRange {
  const char* path;
  int64_t lo, hi;
};
constexpr IntRange kIntegers[] = {{"triggers.max_triggers", 1, 2000},
                                  {"step1.poses", 1, 100},
                                  {"step2.neutral_frames", 0, 20},
                                  {"step2.fast_only_frames", 0, 20}};
const std::set<std::string> kKinds = {"bgr8", "mono8", "mono16"};

std::string Num(double v) {
  std::ostringstream os;
  os.precision(17);
  os << v;
  return os.str();
}

// A simple option set with a canonical form: the sweep parser's SweepParameters for fuzzing.
class FuzzOptions : public sweep::SweepParameters {
 public:
  std::string Noun() const override { return "fuzz option"; }
  std::string PathHint() const override { return "(e.g. mirror.fast.frequency_hz)"; }
  std::string DefaultsYaml() const override { return kDefaults; }
  std::string LoadFile(const fs::path& file) const override {
    std::ifstream in(file);
    if (!in) throw std::runtime_error(file.string() + ": cannot read");
    std::stringstream ss;
    ss << in.rdbuf();
    return Resolve(ss.str(), file.string(), 0, nullptr);
  }
  std::string Resolve(const std::string& yaml, const std::string& where, int repeat,
                      uint64_t* seed) const override {
    if (resolves_left_-- <= 0)
      throw std::runtime_error(where + ": more than " + std::to_string(kMaxFuzzPoints) +
                               " points (the fuzz target's cap)");
    YAML::Node doc;
    try {
      doc = YAML::Load(yaml);
    } catch (const YAML::Exception& e) {
      throw std::runtime_error(where + ": " + e.what());
    }
    YAML::Emitter out;
    static const YAML::Node schema = YAML::Load(kDefaults);
    Walk(schema, doc, "", where, repeat, seed, out);
    return std::string(out.c_str()) + "\n";
  }

  // Resolve calls allowed before the next Budget (each throws std::runtime_error after).
  void Budget(int resolves) const { resolves_left_ = resolves; }

 private:
  mutable int resolves_left_ = 0;

  static double Number(const YAML::Node& n, const std::string& path, const std::string& where) {
    if (!n.IsScalar()) throw std::runtime_error(where + ": " + path + ": expected a number");
    const std::string& t = n.Scalar();
    char* end = nullptr;
    const double v = std::strtod(t.c_str(), &end);
    if (t.empty() || end != t.c_str() + t.size() || !std::isfinite(v) || std::abs(v) > 1e6)
      throw std::runtime_error(where + ": " + path + " = '" + t +
                               "': expected a finite number in [-1e6, 1e6]");
    return v;
  }

  static void Walk(const YAML::Node& schema, const YAML::Node& doc, const std::string& path,
                   const std::string& where, int repeat, uint64_t* seed, YAML::Emitter& out) {
    const std::string name = path.empty() ? "(top level)" : path;
    if (schema.IsMap()) {
      if (!doc.IsMap()) throw std::runtime_error(where + ": " + name + ": expected a mapping");
      for (const auto& kv : doc) {
        if (!kv.first.IsScalar() || !schema[kv.first.Scalar()])
          throw std::runtime_error(where + ": " + name + ": unknown key");
      }
      out << YAML::BeginMap;
      for (const auto& kv : schema) {
        const std::string key = kv.first.Scalar();
        const std::string sub = path.empty() ? key : path + "." + key;
        const YAML::Node v = doc[key];
        if (!v) throw std::runtime_error(where + ": " + sub + ": missing");
        out << YAML::Key << key << YAML::Value;
        Walk(kv.second, v, sub, where, repeat, seed, out);
      }
      out << YAML::EndMap;
      return;
    }
    if (schema.IsSequence()) {
      const bool nested = schema[0].IsSequence();
      if (!doc.IsSequence() || doc.size() < 1 || doc.size() > 16)
        throw std::runtime_error(where + ": " + path + ": expected a list of 1 to 16 entries");
      out << YAML::Flow << YAML::BeginSeq;
      for (const auto& e : doc) {
        if (!nested) {
          out << Num(Number(e, path, where));
          continue;
        }
        if (!e.IsSequence() || e.size() != 2)
          throw std::runtime_error(where + ": " + path + ": expected pairs of numbers");
        out << YAML::Flow << YAML::BeginSeq << Num(Number(e[0], path, where))
            << Num(Number(e[1], path, where)) << YAML::EndSeq;
      }
      out << YAML::EndSeq;
      return;
    }
    const std::string& def = schema.Scalar();
    if (def == "true" || def == "false") {
      bool b = false;
      if (!doc.IsScalar() || !YAML::convert<bool>::decode(doc, b))
        throw std::runtime_error(where + ": " + path + ": expected true or false");
      out << b;
    } else if (path == "camera.kind") {
      if (!doc.IsScalar() || !kKinds.count(doc.Scalar()))
        throw std::runtime_error(where + ": " + path + ": expected bgr8, mono8 or mono16");
      out << doc.Scalar();
    } else if (path == "seed") {
      const double v = Number(doc, path, where);
      if (v < 0 || v != std::floor(v))
        throw std::runtime_error(where + ": seed: expected an integer >= 0");
      const uint64_t s = static_cast<uint64_t>(v) + static_cast<uint64_t>(repeat);
      if (seed) *seed = s;
      out << std::to_string(s);
    } else {
      const double v = Number(doc, path, where);
      for (const IntRange& r : kIntegers) {
        if (path != r.path) continue;
        if (v != std::floor(v) || v < static_cast<double>(r.lo) || v > static_cast<double>(r.hi))
          throw std::runtime_error(where + ": " + path + ": expected an integer in [" +
                                   std::to_string(r.lo) + ", " + std::to_string(r.hi) + "]");
      }
      out << Num(v);
    }
  }
};

std::shared_ptr<const FuzzOptions> Options() {
  static const auto options = std::make_shared<const FuzzOptions>();
  return options;
}

const fs::path& BaseDir() {
  static const fs::path dir = [] {
    fs::path d = fs::temp_directory_path() / ("msmcal-sweep-fuzz-" + std::to_string(getpid()));
    fs::create_directories(d);
    std::ofstream(d / "sim.yaml") << kDefaults;
    return d;
  }();
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text = fuzz::Text(data, size);
  if (text.find("/dev") != std::string::npos || text.find("/proc") != std::string::npos ||
      text.find("/sys") != std::string::npos)
    return 0;
  // base_config, base and the points; twice that for ComparePlans' two expansions.
  const int budget = kMaxFuzzPoints + 2;
  sweep::SweepPlan plan;
  Options()->Budget(budget);
  if (!fuzz::Returns([&] { plan = sweep::ParseSweepPlan(text, "plan.yaml", BaseDir(), Options()); },
                     "plan.yaml"))
    return 0;
  const std::string written = sweep::SweepPlanToYaml(plan);
  sweep::SweepPlan back;
  Options()->Budget(budget);
  fuzz::MustReturn(
      [&] { back = sweep::ParseSweepPlan(written, "plan.yaml", BaseDir(), Options()); },
      "ParseSweepPlan(SweepPlanToYaml)");
  Check(sweep::SweepPlanToYaml(back) == written, "sweep plan round trip differs");
  std::string diff;
  Options()->Budget(2 * budget);
  fuzz::MustReturn([&] { diff = sweep::ComparePlans(plan, back); }, "ComparePlans");
  Check(diff.empty(), "re-read plan expands differently: " + diff);
  return 0;
}
