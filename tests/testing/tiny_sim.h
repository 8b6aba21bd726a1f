#pragma once
// A small but solvable simulated rig for end-to-end session tests: 4 sliding-plate poses, one
// neutral and two fast-only frames, 18 triggers, 2 s Hall recordings (a session takes seconds),
// and the camera at half resolution (1224 x 1024, same field of view): a quarter of the pixels
// to render, stream and measure.

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
  o.camera.width = 1224;
  o.camera.height = 1024;
  o.camera.fx = o.camera.fy = 1000.0;
  o.camera.cx = 611.5;
  o.camera.cy = 511.5;
  o.triggers.min_separation_px = 13.0;
  return o;
}

}  // namespace msmcal::testing
