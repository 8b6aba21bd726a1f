#pragma once
// A small but solvable simulated rig for end-to-end session tests: 4 sliding-plate poses, one
// neutral and two fast-only frames, 18 triggers, 2 s Hall recordings (a session takes seconds).

#include "mocks/rig/sim_options.h"

namespace msmcal::testing {

inline sim::SimOptions TinySim() {
  sim::SimOptions o;
  o.seed = 3;
  o.step1.poses = 4;
  o.step2.neutral_frames = 1;
  o.step2.fast_only_frames = 2;
  o.triggers.max_triggers = 18;
  o.hall.background_duration_s = 2.0;
  o.hall.actual_duration_s = 2.0;
  return o;
}

}  // namespace msmcal::testing
