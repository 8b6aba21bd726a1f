#pragma once
// The simulator's options (mocks/rig/sim_options.h, config/sim.yaml keys) as what a sweep varies:
// each point of a sweep plan is one sim::SimOptions, repeat r running with seed + r.

#include <memory>

#include "mocks/rig/sim_options.h"
#include "sessions/sweep/sweep_plan.h"

namespace msmcal::simulation {

std::shared_ptr<const sweep::SweepParameters> SimSweepParameters();

// The simulator options of a point of a plan of SimSweepParameters() (its options_yaml parsed).
sim::SimOptions PointSimOptions(const sweep::SweepPoint& point);

}  // namespace msmcal::simulation
