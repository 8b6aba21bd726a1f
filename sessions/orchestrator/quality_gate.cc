#include "sessions/orchestrator/quality_gate.h"

#include <opencv2/core.hpp>

namespace msmcal::orchestrator {

std::string GateOptions::Validate() const {
  if (!(max_saturated_pixel_fraction >= 0 && max_saturated_pixel_fraction <= 1))
    return "GateOptions.max_saturated_pixel_fraction = " +
           std::to_string(max_saturated_pixel_fraction) + ": must be in [0, 1]";
  if (max_extra_dots < 0)
    return "GateOptions.max_extra_dots = " + std::to_string(max_extra_dots) + ": must be >= 0";
  if (!(step1_margin_squares >= 0 && step1_margin_squares <= 1000))
    return "GateOptions.step1_margin_squares = " + std::to_string(step1_margin_squares) +
           ": must be in [0, 1000]";
  if (!(step2_margin_squares >= 0 && step2_margin_squares <= 1000))
    return "GateOptions.step2_margin_squares = " + std::to_string(step2_margin_squares) +
           ": must be in [0, 1000]";
  if (std::string e = dots.Validate(); !e.empty()) return "GateOptions.dots: " + e;
  if (std::string e = boards.Validate(); !e.empty()) return "GateOptions.boards: " + e;
  return {};
}

namespace {

double SaturatedFraction(const cv::Mat& image) {
  const double full = image.depth() == CV_16U ? 65535.0 : 255.0;
  cv::Mat flat = image.reshape(1);
  const int saturated = cv::countNonZero(flat >= full);
  return static_cast<double>(saturated) / static_cast<double>(flat.total());
}

}  // namespace

GateResult CheckFrame(const cv::Mat& image, int step, int dots_expected,
                      const dataset::BoardSpec& world_board,
                      const dataset::BoardSpec& sliding_board, const GateOptions& options) {
  GateResult r;
  r.dots_expected = dots_expected;
  if (image.empty()) {
    r.reason = "empty image";
    return r;
  }
  r.saturated_fraction = SaturatedFraction(image);
  if (r.saturated_fraction > options.max_saturated_pixel_fraction) {
    r.reason = "saturated: " + std::to_string(r.saturated_fraction * 100) +
               " % of pixels at full scale (limit " +
               std::to_string(options.max_saturated_pixel_fraction * 100) + " %)";
    return r;
  }
  const vision::BoardSize world{world_board.cols, world_board.rows};
  const vision::BoardSize sliding{sliding_board.cols, sliding_board.rows};
  std::vector<std::optional<vision::CheckerboardDetection>>& found = r.boards;
  if (step == 1) {
    found = vision::DetectCheckerboards(image, {sliding, world}, options.boards);
    if (!found[0]) {
      r.reason = "sliding board (" + std::to_string(sliding.cols) + "x" +
                 std::to_string(sliding.rows) + ") not found";
      return r;
    }
    if (!found[1]) {
      r.reason = "world board (" + std::to_string(world.cols) + "x" + std::to_string(world.rows) +
                 ") not found";
      return r;
    }
  } else {
    found = {vision::DetectCheckerboard(image, world, options.boards)};
    if (!found[0]) {
      r.reason = "world board (" + std::to_string(world.cols) + "x" + std::to_string(world.rows) +
                 ") not found";
      return r;
    }
  }
  // A copy: vision::DetectDots writes its top-hat into the caller's pixels (dots.cc:155-161,
  // `signal = image` shares the buffer), and the frame must be saved unchanged.
  r.dots = vision::DetectDots(image.clone(), options.dots);
  // Only dots inside the visible area of the plane the beams hit count: a blob elsewhere (board
  // residue on the other board, a reflection in the scene) neither makes nor spoils a frame,
  // and a beam that missed the plane leaves its count short.
  const vision::BoardArea area(*found[0], step == 1 ? sliding : world);
  const double margin = options.MarginSquares(step);
  const char* plane = step == 1 ? "sliding" : "world";
  int outside = 0;
  const vision::Dot* first_outside = nullptr;
  for (const auto& d : r.dots) {
    if (area.Contains(d.px, margin)) {
      ++r.dots_found;
    } else if (++outside == 1) {
      first_outside = &d;
    }
  }
  if (r.dots_found < dots_expected || r.dots_found > dots_expected + options.max_extra_dots) {
    r.reason = "expected " + std::to_string(dots_expected) + " dots";
    if (options.max_extra_dots > 0)
      r.reason += " (up to " + std::to_string(options.max_extra_dots) + " extra detections)";
    r.reason += " on the " + std::string(plane) + " board's visible area, found " +
                std::to_string(r.dots_found);
    if (first_outside) {
      char buf[160];
      std::snprintf(buf, sizeof(buf), " (%d more outside it, the first at (%.1f, %.1f) px)",
                    outside, first_outside->px.x(), first_outside->px.y());
      r.reason += buf;
    }
    return r;
  }
  r.accepted = true;
  return r;
}

}  // namespace msmcal::orchestrator
