#pragma once
// Annotated preview images of grabbed frames (guided mode, issue 9): what the quality gate found,
// drawn over the frame, so the operator can see at a glance why a frame was accepted or not.
//
// Drawn: each found board's inner corners (small circles), its outline, its origin corner (large
// circle, "O"), its X and Y axis directions (arrows along the canonical corner order: X towards
// corner 1, Y towards corner cols) and its name; every laser dot with its index (gate order) and
// its 2-sigma centroid ellipse from Dot::cov_px2 (drawn to scale — usually sub-pixel, so a ring
// of fixed size marks the dot as well); a banner on top (file, step, ACCEPTED / REJECTED with the
// reason, dots found/expected, saturated %).

#include <filesystem>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "processing/dataset/recording.h"
#include "sessions/orchestrator/orchestrator.h"
#include "sessions/orchestrator/quality_gate.h"

namespace msmcal::orchestrator {

struct PreviewLabels {
  std::string file;  // as in session.yaml ("step1/0003.png")
  int step = 1;
  // One per GateResult::boards entry, in the same order (step 1: sliding, world; step 2: world).
  std::vector<std::string> board_names;
  std::vector<dataset::BoardSpec> board_specs;  // cols/rows give the axis corners
};

// Labels for a frame of `step` with the gate's board order.
PreviewLabels MakePreviewLabels(const std::string& file, int step,
                                const dataset::BoardSpec& world_board,
                                const dataset::BoardSpec& sliding_board);

// Returns an 8-bit BGR copy of `image` (CV_8U or CV_16U, 1 or 3 channels; 16-bit is scaled by
// 1/257) downscaled to at most `max_width_px` wide (aspect kept; <= 0: full size) with the gate's
// findings drawn at the output scale. `image` is not modified. Throws std::invalid_argument for
// other image types or an empty image.
cv::Mat AnnotatePreview(const cv::Mat& image, const GateResult& gate, const PreviewLabels& labels,
                        int max_width_px = 1600);

// "step1/0003.png" -> "step1_0003.jpg".
std::string PreviewFileName(const std::string& file);

// Writes `annotated` as session_dir/previews/<PreviewFileName(file)> (JPEG, quality 90)
// atomically (temporary + rename); returns the path. Throws std::runtime_error naming the file.
std::filesystem::path WritePreview(const std::filesystem::path& session_dir,
                                   const std::string& file, const cv::Mat& annotated);

// An observer that writes the preview of every accepted frame (gate on; frames without a gate
// result are drawn with an empty one). Write failures are reported through `warn` (may be empty)
// and never stop the session.
FrameObserver MakePreviewWriter(const std::filesystem::path& session_dir,
                                const dataset::BoardSpec& world_board,
                                const dataset::BoardSpec& sliding_board,
                                std::function<void(const std::string&)> warn = {});

}  // namespace msmcal::orchestrator
