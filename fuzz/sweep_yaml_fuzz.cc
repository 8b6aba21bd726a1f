// libFuzzer target: sweep plans (ParseSweepPlan over the simulator options, docs/sweep.md).
//
// base_config names a file relative to the plan's folder: the target runs with a folder holding
// sim.yaml (config/sim.yaml's defaults) so that it can be reached; inputs naming /dev or /proc
// are skipped (reading a device is not the parser's problem).
// Checks: returns or throws std::runtime_error naming the plan; an accepted plan written with
// SweepPlanToYaml parses again to a plan that writes the same text and expands to the same
// points (ComparePlans empty).
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "fuzz/fuzz_util.h"
#include "mocks/rig/sim_options.h"
#include "sessions/sweep/sweep_plan.h"
#include "simulation/sweep_points/sim_sweep_parameters.h"

using namespace msmcal;
using fuzz::Check;
namespace fs = std::filesystem;

namespace {

const fs::path& BaseDir() {
  static const fs::path dir = [] {
    fs::path d = fs::temp_directory_path() / ("msmcal-sweep-fuzz-" + std::to_string(getpid()));
    fs::create_directories(d);
    std::ofstream(d / "sim.yaml") << sim::SimOptionsToYaml(sim::SimOptions{});
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
  sweep::SweepPlan plan;
  if (!fuzz::Returns(
          [&] {
            plan = sweep::ParseSweepPlan(text, "plan.yaml", BaseDir(),
                                         simulation::SimSweepParameters());
          },
          "plan.yaml"))
    return 0;
  const std::string written = sweep::SweepPlanToYaml(plan);
  sweep::SweepPlan back;
  fuzz::MustReturn(
      [&] {
        back = sweep::ParseSweepPlan(written, "plan.yaml", BaseDir(),
                                     simulation::SimSweepParameters());
      },
      "ParseSweepPlan(SweepPlanToYaml)");
  Check(sweep::SweepPlanToYaml(back) == written, "sweep plan round trip differs");
  std::string diff;
  fuzz::MustReturn([&] { diff = sweep::ComparePlans(plan, back); }, "ComparePlans");
  Check(diff.empty(), "re-read plan expands differently: " + diff);
  return 0;
}
