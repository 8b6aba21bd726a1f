#pragma once
// What a solve says about its frames: results/detections.csv (interchange-format.md: first
// columns file,step,used,reason), an annotated image of a dropped or partly used frame, and the
// summary of drops with a hint that names the setting to change. Pure functions of the
// pipeline's FrameDetection rows (the CLI writes the files).

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "processing/solver/pipeline.h"

namespace msmcal::solver {

// The CSV text, header first. Free text (reason, note) has commas replaced by semicolons so that
// every CSV reader splits it into the same columns.
std::string FormatDetectionsCsv(const std::vector<FrameDetection>& detections);
// The header's column names, in order.
std::vector<std::string> DetectionsCsvColumns();

// An 8-bit BGR copy of `image` (any type the solver reads) with what the solver saw drawn on
// it: each board's corners (origin ringed) and outline, the frame's dots on the board's plane
// (green rings, numbered), blobs refused at plane level (orange crosses), and a banner with the
// file, the verdict and the reason.
cv::Mat AnnotateFrame(const cv::Mat& image, const FrameDetection& detection);

// The frames dropped, the most common reason and a hint.
struct DropSummary {
  int frames = 0, dropped = 0, partial = 0;
  std::string common_reason;  // the reason with numbers replaced by N
  int common_count = 0;
  std::string hint;  // empty when nothing was dropped
};
DropSummary SummariseDrops(const std::vector<FrameDetection>& detections);

}  // namespace msmcal::solver
