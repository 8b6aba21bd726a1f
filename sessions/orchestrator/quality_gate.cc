#include "sessions/orchestrator/quality_gate.h"

#include <opencv2/core.hpp>

namespace msmcal::orchestrator {

std::string GateOptions::Validate() const {
  if (!(max_saturated_pixel_fraction >= 0 && max_saturated_pixel_fraction <= 1))
    return "GateOptions.max_saturated_pixel_fraction = " +
           std::to_string(max_saturated_pixel_fraction) + ": must be in [0, 1]";
  if (max_extra_dots < 0)
    return "GateOptions.max_extra_dots = " + std::to_string(max_extra_dots) + ": must be >= 0";
  if (!(outline_margin_squares >= 0))
    return "GateOptions.outline_margin_squares = " + std::to_string(outline_margin_squares) +
           ": must be >= 0";
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
  const std::vector<vision::Dot>& dots = r.dots;
  r.dots_found = static_cast<int>(dots.size());
  if (r.dots_found < dots_expected || r.dots_found > dots_expected + options.max_extra_dots) {
    r.reason = "expected " + std::to_string(dots_expected) + " dots";
    if (options.max_extra_dots > 0)
      r.reason += " (up to " + std::to_string(options.max_extra_dots) + " extra detections)";
    r.reason += ", found " + std::to_string(r.dots_found);
    return r;
  }
  const auto outline = vision::SquaresOutline(*found[0], step == 1 ? sliding : world,
                                              options.outline_margin_squares);
  for (const auto& d : dots) {
    if (!vision::InsideOutline(outline, d.px)) {
      char buf[160];
      std::snprintf(buf, sizeof(buf), "dot at (%.1f, %.1f) px outside the %s board's visible area",
                    d.px.x(), d.px.y(), step == 1 ? "sliding" : "world");
      r.reason = buf;
      return r;
    }
  }
  r.accepted = true;
  return r;
}

}  // namespace msmcal::orchestrator
