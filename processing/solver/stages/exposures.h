#pragma once
// Stage: exposure collapsing (docs/solver.md, "Repeated exposures"). Repeated exposures of one
// static scene (step 1 frames with the same pose and beams; step 2 frames with the same kind,
// triggers and beams) are averaged pixel by pixel and measured as one image: their noise falls
// by sqrt(K) while the covariance stays that of one measurement.

#include <map>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "processing/dataset/recording.h"
#include "processing/solver/solve_types.h"

namespace msmcal::solver {

struct ExposureScenes {
  // Scene (named by its first exposure's file) -> the files averaged into it, itself first.
  // Empty when no scene has more than one exposure: the recording is measured as it is.
  std::map<std::string, std::vector<std::string>> members;
  // One frame per scene (the first exposure's entry); everything else as the input's. Only
  // meaningful when Collapsed().
  dataset::Recording recording;
  int averaged_frames = 0;  // frames in scenes of more than one exposure
  int scenes = 0;           // such scenes
  bool Collapsed() const { return scenes > 0; }
  // The scene `file` belongs to (`file` itself when it is alone or nothing was collapsed).
  std::string SceneOf(const std::string& file) const;
  // What was averaged, for SolveOutput::notes.
  std::string Note() const;
};

// Groups the frames of `recording` into scenes as above.
ExposureScenes CollapseExposures(const dataset::Recording& recording);

// The pixel mean of `files` (8-bit input: 16-bit output scaled by 257, so that full scale stays
// full scale and a pixel saturated in every exposure reads as saturated; 16-bit: 16-bit).
// Throws SolveError when a file cannot be read or differs in size or pixel format.
cv::Mat AverageExposures(const std::vector<std::string>& files, const ImageLoader& load);

// The image of a frame of the collapsed recording. Nothing collapsed: `input(file)`. Otherwise
// a scene's average, or a single exposure as 16-bit (8-bit scaled by 257), so that the images
// whose backgrounds are pooled (RefineDotsOnBackgrounds) share one scale.
cv::Mat LoadScene(const ExposureScenes& scenes, const ImageLoader& input, const std::string& file);

}  // namespace msmcal::solver
