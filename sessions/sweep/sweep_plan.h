#pragma once
// Sweep plans (issue 9, sweep mode): a YAML file that names simulator options to vary, expanded
// into one calibration session ("point") per combination and repeat.
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
#include <string>
#include <utility>
#include <vector>

#include "mocks/rig/sim_options.h"

namespace msmcal::sweep {

struct SweepAxis {
  std::string path;                 // dotted simulator option path ("mirror.fast.frequency_hz")
  std::vector<std::string> values;  // each value as YAML flow text ("205", "[110, 135]")
  int line = 0;                     // 1-based line of the key in the plan (0: unknown)
};

struct SweepPlan {
  std::string source;  // the plan file (for messages)
  // The effective base simulator options (defaults < base_config < base:) as YAML with every
  // field (SimOptionsToYaml), so that the plan is self-contained once loaded.
  std::string base_yaml;
  std::vector<SweepAxis> axes;  // in nesting order (outermost first), see `order`
  int repeats = 1;
  // Position of the repeat loop in the nesting order: 0 = outermost, axes.size() = innermost.
  size_t repeat_level = 0;
  std::string note;
};

// One session of the sweep.
struct SweepPoint {
  size_t index = 0;  // 0-based, in run order
  int repeat = 0;    // 0 .. repeats-1
  // (option path, value text) in SweepPlan::axes order (the nesting order).
  std::vector<std::pair<std::string, std::string>> values;
  sim::SimOptions sim;  // the effective simulator options (seed = base seed + repeat)
  std::string name;     // the point's folder name (PointFolderName)
  // "fast.frequency_hz=205 triggers.max_triggers=18 r0" for progress lines and tables.
  std::string Label() const;
};

// Parses a plan. `source_name` names the plan in messages; `base_dir` resolves base_config.
SweepPlan ParseSweepPlan(const std::string& yaml_text, const std::string& source_name,
                         const std::filesystem::path& base_dir);
// Reads and parses a plan file (base_config relative to the file's folder).
SweepPlan LoadSweepPlan(const std::filesystem::path& file);

// The Cartesian product of the axes times the repeats, in nesting order (the innermost loop
// varies fastest). Throws std::runtime_error naming the plan, the axis and value when a point's
// simulator options are invalid (SimOptions::Validate).
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

// Empty when `stored` and `requested` expand to the same points (names and simulator options);
// otherwise the first difference, for refusing a resume with a changed plan.
std::string ComparePlans(const SweepPlan& stored, const SweepPlan& requested);

}  // namespace msmcal::sweep
