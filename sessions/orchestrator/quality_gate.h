#pragma once
// Per-frame quality gates applied before a frame is accepted into a session:
//   step 1: both boards (sliding and world) found; step 2: the world board found;
//   no saturation beyond use; the expected number of laser dots inside the visible area of the
//   board plane the beams hit (step 1: the sliding board, step 2: the world board; blobs
//   elsewhere are not counted). A rejected frame says why.

#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "processing/dataset/recording.h"
#include "processing/vision/checkerboard.h"
#include "processing/vision/dots.h"

namespace msmcal::orchestrator {

// The gate counts dots in the image without the solver's board-plane roundness check, so it
// keeps the strict image-space roundness (laser spots <= 1.2 on the simulated rig).
inline vision::DotOptions GateDotOptions() {
  vision::DotOptions o;
  o.max_elongation = 1.3;
  return o;
}

struct GateOptions {
  vision::DotOptions dots = GateDotOptions();
  vision::CheckerboardOptions boards;
  // Largest fraction of all pixels at full scale (sensor saturation beyond use).
  double max_saturated_pixel_fraction = 0.01;
  // Dots must lie inside the board's squares area grown by this many squares (the board plane's
  // visible printed area): step 1 around the sliding board (a plate that carries the spots
  // beside its pattern needs more: the rig file's sliding_plate.dot_margin_squares), step 2
  // around the world board (step2.dot_margin_squares).
  double step1_margin_squares = 1.0;
  double step2_margin_squares = 1.0;
  double MarginSquares(int step) const {
    return step == 1 ? step1_margin_squares : step2_margin_squares;
  }
  // Detections allowed beyond the expected dots: the dot detector may report small board-corner
  // residue near a board edge (the solver's association ignores it). Fewer dots than expected
  // always reject.
  int max_extra_dots = 1;
  std::string Validate() const;  // empty when valid; names field, value and constraint
};

struct GateResult {
  bool accepted = false;
  std::string reason;  // why it was rejected (empty when accepted)
  int dots_found = 0;  // inside the plane's visible area
  int dots_expected = 0;
  double saturated_fraction = 0;
  // What the gate detected, for previews and live figures: boards in the order checked
  // (step 1: sliding, world; step 2: world; empty entries were not found; boards after the first
  // missing one are not searched) and the dots (empty when the gate stopped before them).
  std::vector<std::optional<vision::CheckerboardDetection>> boards;
  std::vector<vision::Dot> dots;  // every dot detected, inside the visible area or not
};

// step: 1 or 2. dots_expected: beams x max(1, triggers) of the frame.
GateResult CheckFrame(const cv::Mat& image, int step, int dots_expected,
                      const dataset::BoardSpec& world_board,
                      const dataset::BoardSpec& sliding_board, const GateOptions& options);

}  // namespace msmcal::orchestrator
