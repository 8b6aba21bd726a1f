#pragma once
// The scene shaped like the independent simulator's folders of issue 15 (one case of many):
// 1600 x 1200 camera, a 17 x 12 world board of 15 mm squares seen at ~60 degrees in the step 1
// view (squares of ~10 x 18 px), the 9 x 6 sliding board of 10 mm squares next to it, saturated
// spots of sigma ~1.3 px, BGR, one exposure per step 1 frame.

#include <cstdint>

#include "mocks/rig/sim_options.h"

namespace msmcal::testing {

inline sim::SimOptions IndependentLikeScene(uint64_t seed) {
  sim::SimOptions s;
  s.seed = seed;
  s.world_board = {17, 12, 15.0};
  s.sliding_board = {9, 6, 10.0};
  s.geometry.board_aim_mm = {120, 82};
  s.geometry.mirror_distance_mm = 200;
  s.beams.spanning_angle_deg = 30;
  s.mirror.slow.amplitude_vpp = 2;
  s.camera.width = 1600;
  s.camera.height = 1200;
  s.camera.fx = s.camera.fy = 1250;
  s.camera.cx = 799.5;
  s.camera.cy = 599.5;
  s.camera.c1_centre_mm = {-640, 82, -560};
  s.camera.c1_target_mm = {60, 82, -150};
  s.camera.c2_centre_mm = {200, 90, -550};
  s.camera.c2_target_mm = {120, 82, 0};
  s.render.dot_sigma_mm = 0.6;
  s.render.dot_peak = 2.0;
  s.render.colour = true;
  s.step1.exposures = 1;
  return s;
}

}  // namespace msmcal::testing
