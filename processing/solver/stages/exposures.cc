#include "processing/solver/stages/exposures.h"

#include <algorithm>
#include <tuple>

namespace msmcal::solver {

ExposureScenes CollapseExposures(const dataset::Recording& in) {
  ExposureScenes e;
  dataset::Recording& r = e.recording;
  r = in;  // everything but the frame lists (the solver reads no Hall data; a copy is cheap)
  r.step1.clear();
  r.step2.clear();
  auto sorted = [](std::vector<int> v) {
    std::sort(v.begin(), v.end());
    return v;
  };
  std::map<std::pair<int, std::vector<int>>, size_t> step1_scene;
  for (const auto& f : in.step1) {
    const auto [it, added] =
        step1_scene.emplace(std::make_pair(f.pose, sorted(f.beams)), r.step1.size());
    if (added) r.step1.push_back(f);
    e.members[r.step1[it->second].file].push_back(f.file);
  }
  std::map<std::tuple<int, std::vector<int>, std::vector<int>>, size_t> step2_scene;
  for (const auto& f : in.step2) {
    const auto key = std::make_tuple(static_cast<int>(f.kind), sorted(f.triggers), sorted(f.beams));
    const auto [it, added] = step2_scene.emplace(key, r.step2.size());
    if (added) r.step2.push_back(f);
    e.members[r.step2[it->second].file].push_back(f.file);
  }
  for (const auto& [file, m] : e.members)
    if (m.size() > 1) {
      e.averaged_frames += static_cast<int>(m.size());
      ++e.scenes;
    }
  if (e.scenes == 0) return ExposureScenes{};
  return e;
}

std::string ExposureScenes::SceneOf(const std::string& file) const {
  std::string scene = file;
  for (const auto& [first, files] : members)
    if (std::find(files.begin(), files.end(), file) != files.end()) scene = first;
  return scene;
}

std::string ExposureScenes::Note() const {
  return "exposures: " + std::to_string(averaged_frames) + " frames are repeated " +
         "exposures of " + std::to_string(scenes) +
         " scene(s); each scene's exposures were averaged and measured as one "
         "image (named by its first frame)";
}

cv::Mat AverageExposures(const std::vector<std::string>& files, const ImageLoader& load) {
  cv::Mat sum, first;
  for (const auto& f : files) {
    const cv::Mat img = load(f);
    if (img.empty()) throw SolveError(f + ": cannot read the image");
    if (first.empty()) {
      first = img;
      sum = cv::Mat::zeros(img.size(), CV_MAKETYPE(CV_32F, img.channels()));
    } else if (img.size() != first.size() || img.type() != first.type()) {
      throw SolveError(f + ": an exposure of the same scene as " + files[0] +
                       " but its size or pixel format differs");
    }
    cv::Mat fl;
    img.convertTo(fl, CV_32F);
    sum += fl;
  }
  const double k = static_cast<double>(files.size());
  cv::Mat out;
  sum.convertTo(out, CV_MAKETYPE(CV_16U, first.channels()),
                first.depth() == CV_8U ? 257.0 / k : 1.0 / k);
  return out;
}

cv::Mat LoadScene(const ExposureScenes& scenes, const ImageLoader& input, const std::string& file) {
  if (!scenes.Collapsed()) return input(file);
  const auto it = scenes.members.find(file);
  if (it != scenes.members.end() && it->second.size() > 1)
    return AverageExposures(it->second, input);
  cv::Mat img = input(file);
  if (img.depth() != CV_8U) return img;
  cv::Mat wide;
  img.convertTo(wide, CV_MAKETYPE(CV_16U, img.channels()), 257.0);
  return wide;
}

}  // namespace msmcal::solver
