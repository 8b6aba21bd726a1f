#pragma once
// Sweep plans (issue 9, sweep mode): a YAML file that names options to vary, expanded into one
// calibration session ("point") per combination and repeat. What the options are is not known
// here: a SweepParameters (the simulation layer's simulator options,
// simulation/sweep_points/sim_sweep_parameters.h) gives their schema, defaults and validation.
//
// Plan format (docs/sweep.md, config/sweep-example.yaml):
//   base_config: FILE        # optional, simulator options (config/sim.yaml keys), relative to
//                            # the plan file
//   base:                    # optional, simulator options laid over base_config / the defaults
//     step1: {poses: 4}
//   axes:                    # option path (dotted, config/sim.yaml keys) -> list of values
//     mirror.fast.frequency_hz: [200, 205]
//     triggers.max_triggers: [18, 30]
//   repeats: 2               # optional (default 1): repeat r uses seed = base seed + r
//   order: [triggers.max_triggers, mirror.fast.frequency_hz, repeats]   # optional nesting,
//                            # outermost first; default: the axes in file order, repeats last
//   note: free text          # optional
// Unknown keys, unknown option paths and bad values throw std::runtime_error naming the plan
// file, the line and the key.

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace msmcal::sweep {

// The option set a sweep varies, as YAML documents: a mapping whose leaves are numbers, bools,
// lists of numbers or lists of lists of numbers. Implementations are immutable.
class SweepParameters {
 public:
  virtual ~SweepParameters() = default;
  // What one option is called in messages ("simulator option").
  virtual std::string Noun() const = 0;
  // Appended to "unknown <noun>" for an axis path that names no option.
  virtual std::string PathHint() const = 0;
  // The defaults with every field; its leaves are the schema for base: and axis values.
  virtual std::string DefaultsYaml() const = 0;
  // A base_config file as a document with every field. Throws std::runtime_error (the reason).
  virtual std::string LoadFile(const std::filesystem::path& file) const = 0;
  // Validates `yaml` (every field present) and returns it in canonical form (every field) with
  // the repeat applied (the simulator: seed + repeat), and its seed. Throws std::runtime_error
  // starting with `where` and naming the problem.
  virtual std::string Resolve(const std::string& yaml, const std::string& where, int repeat,
                              uint64_t* seed) const = 0;
};

struct SweepAxis {
  std::string path;                 // dotted option path ("mirror.fast.frequency_hz")
  std::vector<std::string> values;  // each value as YAML flow text ("205", "[110, 135]")
  int line = 0;                     // 1-based line of the key in the plan (0: unknown)
};

struct SweepPlan {
  std::string source;  // the plan file (for messages)
  // The effective base options (defaults < base_config < base:) as YAML with every field
  // (SweepParameters::Resolve), so that the plan is self-contained once loaded.
  std::string base_yaml;
  std::vector<SweepAxis> axes;  // in nesting order (outermost first), see `order`
  int repeats = 1;
  // Position of the repeat loop in the nesting order: 0 = outermost, axes.size() = innermost.
  size_t repeat_level = 0;
  std::string note;
  std::shared_ptr<const SweepParameters> parameters;  // never null in a parsed plan
};

// One session of the sweep.
struct SweepPoint {
  size_t index = 0;  // 0-based, in run order
  int repeat = 0;    // 0 .. repeats-1
  // (option path, value text) in SweepPlan::axes order (the nesting order).
  std::vector<std::pair<std::string, std::string>> values;
  // The effective options (SweepParameters::Resolve: every field, repeat applied) and seed.
  std::string options_yaml;
  uint64_t seed = 0;
  std::string name;  // the point's folder name (PointFolderName)
  // "fast.frequency_hz=205 triggers.max_triggers=18 r0" for progress lines and tables.
  std::string Label() const;
};

// Parses a plan of `parameters`. `source_name` names the plan in messages; `base_dir` resolves
// base_config.
SweepPlan ParseSweepPlan(const std::string& yaml_text, const std::string& source_name,
                         const std::filesystem::path& base_dir,
                         std::shared_ptr<const SweepParameters> parameters);
// Reads and parses a plan file (base_config relative to the file's folder).
SweepPlan LoadSweepPlan(const std::filesystem::path& file,
                        std::shared_ptr<const SweepParameters> parameters);

// The Cartesian product of the axes times the repeats, in nesting order (the innermost loop
// varies fastest). Throws std::runtime_error naming the plan, the axis and value when a point's
// options are invalid (SweepParameters::Resolve).
std::vector<SweepPoint> ExpandPoints(const SweepPlan& plan);

// Short display name of an option path: its last two components ("fast.frequency_hz").
std::string ShortAxisName(const std::string& path);
// "p003-fast.frequency_hz=205-triggers.max_triggers=18-r1": 1-based index (3 digits at least), the
// short axis names with their values (list values without brackets and spaces, commas as '_'), the
// repeat; characters outside [A-Za-z0-9._=+-] become '_',
// at most 120 characters (the index keeps truncated names unique).
std::string PointFolderName(size_t index, int repeat,
                            const std::vector<std::pair<std::string, std::string>>& values);

// The plan as a self-contained YAML document (base: with every field, axes, repeats, order,
// note), readable by ParseSweepPlan: written to DIR/sweep.yaml by the sweep runner.
std::string SweepPlanToYaml(const SweepPlan& plan);

// Empty when `stored` and `requested` expand to the same points (names and options);
// otherwise the first difference, for refusing a resume with a changed plan.
std::string ComparePlans(const SweepPlan& stored, const SweepPlan& requested);

}  // namespace msmcal::sweep
