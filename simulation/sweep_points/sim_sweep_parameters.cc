#include "simulation/sweep_points/sim_sweep_parameters.h"

#include <string>

namespace msmcal::simulation {
namespace {

class SimParameters : public sweep::SweepParameters {
 public:
  std::string Noun() const override { return "simulator option"; }
  std::string PathHint() const override {
    return "(dotted config/sim.yaml key, e.g. mirror.fast.frequency_hz)";
  }
  std::string DefaultsYaml() const override { return sim::SimOptionsToYaml(sim::SimOptions{}); }
  std::string LoadFile(const std::filesystem::path& file) const override {
    return sim::SimOptionsToYaml(sim::LoadSimOptions(file));
  }
  std::string Resolve(const std::string& yaml, const std::string& where, int repeat,
                      uint64_t* seed) const override {
    sim::SimOptions options = sim::ParseSimOptions(yaml, where);
    options.seed += static_cast<uint64_t>(repeat);
    if (seed) *seed = options.seed;
    return sim::SimOptionsToYaml(options);
  }
};

}  // namespace

std::shared_ptr<const sweep::SweepParameters> SimSweepParameters() {
  static const auto parameters = std::make_shared<const SimParameters>();
  return parameters;
}

sim::SimOptions PointSimOptions(const sweep::SweepPoint& point) {
  return sim::ParseSimOptions(point.options_yaml, "sweep point " + point.name);
}

}  // namespace msmcal::simulation
