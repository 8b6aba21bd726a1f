#include "processing/plan/frame_design.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <stdexcept>

namespace msmcal::plan {

std::string FrameFile(const char* step, size_t index) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%s/%04zu.png", step, index);
  return buf;
}

std::vector<dataset::Step1Frame> DesignStep1Frames(const Step1FrameOptions& o) {
  if (o.poses < 1)
    throw std::invalid_argument("step 1 frames: poses = " + std::to_string(o.poses) +
                                ": must be >= 1");
  if (o.beams < 1)
    throw std::invalid_argument("step 1 frames: beams = " + std::to_string(o.beams) +
                                ": must be >= 1");
  if (o.exposures < 1)
    throw std::invalid_argument("step 1 frames: exposures = " + std::to_string(o.exposures) +
                                ": must be >= 1");
  std::vector<int> all(o.beams);
  std::iota(all.begin(), all.end(), 1);
  std::vector<dataset::Step1Frame> frames;
  auto add = [&](int pose, std::vector<int> beams) {
    frames.push_back({FrameFile("step1", frames.size()), pose, std::move(beams)});
  };
  for (int l = 0; l < o.poses; ++l) {
    const bool close = static_cast<size_t>(l) < o.close_pose.size() && o.close_pose[l];
    const bool identification = o.identification_frames && l == o.poses - 1;
    if (close) {
      if (!identification)
        for (int id : all) add(l, {id});
    } else {
      add(l, all);
    }
    // Close dots reach into each other's windows, so their single-beam frames do not show every
    // window pixel dot-free: those poses keep the background frame.
    if (o.background_frames && (!identification || close)) add(l, {});
  }
  if (o.identification_frames)
    for (int id : all) add(o.poses - 1, {id});
  if (o.exposures > 1) {
    std::vector<dataset::Step1Frame> repeated;
    for (const auto& f : frames)
      for (int k = 0; k < o.exposures; ++k)
        repeated.push_back({FrameFile("step1", repeated.size()), f.pose, f.beams});
    frames = std::move(repeated);
  }
  return frames;
}

double Distance(const SignalPoint& a, const SignalPoint& b) {
  return std::hypot(a.fast - b.fast, a.slow - b.slow);
}

std::vector<std::vector<int>> GroupBySeparation(const std::vector<SignalPoint>& points,
                                                int max_per_group, double min_separation) {
  if (max_per_group < 1)
    throw std::invalid_argument("max_per_group = " + std::to_string(max_per_group) +
                                ": must be >= 1");
  std::vector<std::vector<int>> groups;
  for (int i = 0; i < static_cast<int>(points.size()); ++i) {
    bool placed = false;
    for (auto& g : groups) {
      if (static_cast<int>(g.size()) >= max_per_group) continue;
      const bool far = std::all_of(g.begin(), g.end(), [&](int k) {
        return Distance(points[i], points[k]) >= min_separation;
      });
      if (far) {
        g.push_back(i);
        placed = true;
        break;
      }
    }
    if (!placed) groups.push_back({i});
  }
  return groups;
}

std::vector<std::vector<int>> ChooseFastOnlyGroups(const std::vector<SignalPoint>& points,
                                                   int frames, int per_frame,
                                                   double min_separation) {
  std::vector<std::vector<int>> groups;
  const int n = static_cast<int>(points.size());
  for (int f = 0; f < frames && n > 0; ++f) {
    std::vector<int> chosen;
    for (int i = 0; i < n && static_cast<int>(chosen.size()) < per_frame; ++i) {
      const int j = (i + f * n / frames) % n;
      const bool far = std::all_of(chosen.begin(), chosen.end(), [&](int k) {
        return std::abs(points[j].fast - points[k].fast) >= min_separation;
      });
      if (far) chosen.push_back(j);
    }
    std::sort(chosen.begin(), chosen.end());
    if (!chosen.empty()) groups.push_back(std::move(chosen));
  }
  return groups;
}

}  // namespace msmcal::plan
