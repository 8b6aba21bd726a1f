#include "simulation/replay/replay_world.h"

#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>

#include "mocks/camera/place_image.h"

namespace msmcal::replay {

namespace fs = std::filesystem;

fs::path RecordedImagePath(const fs::path& source, const std::string& file) {
  const fs::path accepted = source / file;
  if (fs::is_regular_file(accepted)) return accepted;
  std::string name = file;  // as the orchestrator names kept rejects
  for (char& c : name) c = c == '/' ? '_' : c;
  const fs::path rejected = source / "rejected" / name;
  if (fs::is_regular_file(rejected)) return rejected;
  return {};
}

namespace {

std::vector<fs::path> Resolve(const fs::path& source, const std::vector<std::string>& files) {
  std::vector<fs::path> out;
  for (const auto& file : files) {
    fs::path p = RecordedImagePath(source, file);
    if (p.empty()) {
      std::string name = file;
      for (char& c : name) c = c == '/' ? '_' : c;
      throw std::runtime_error((source / file).string() + ": recorded image missing (nor kept as " +
                               (source / "rejected" / name).string() +
                               "): cannot replay this frame");
    }
    out.push_back(std::move(p));
  }
  return out;
}

template <typename Frames>
std::vector<std::string> Files(const Frames& frames) {
  std::vector<std::string> f;
  for (const auto& x : frames) f.push_back(x.file);
  return f;
}

}  // namespace

ReplayWorld::ReplayWorld(fs::path source, const dataset::Recording& plan,
                         std::function<std::string(orchestrator::HallRun)> hall_device)
    : source_(std::move(source)), hall_device_(std::move(hall_device)) {
  step1_images_ = Resolve(source_, Files(plan.step1));
  step2_images_ = Resolve(source_, Files(plan.step2));
}

sim::FrameSource ReplayWorld::MakeFrameSource() {
  return [this](uint8_t* data, int width, int height, sim::SimPixelFormat fmt, int64_t timestamp_ns,
                uint64_t /*frame_index*/) {
    std::shared_ptr<const cv::Mat> image;
    uint64_t generation = 0;
    {
      std::lock_guard<std::mutex> lock(mu_);
      image = image_;
      generation = generation_;
    }
    if (image) {
      sim::PlaceImage(*image, data, width, height, fmt);
    } else {
      std::memset(data, 0,
                  static_cast<size_t>(width) * static_cast<size_t>(height) *
                      static_cast<size_t>(sim::SimBytesPerPixel(fmt)));
    }
    std::lock_guard<std::mutex> lock(mu_);
    filled_.emplace_back(timestamp_ns, generation);
    while (filled_.size() > 256) filled_.pop_front();
  };
}

void ReplayWorld::Show(const fs::path& file) {
  auto image = std::make_shared<cv::Mat>(cv::imread(file.string(), cv::IMREAD_UNCHANGED));
  if (image->empty()) throw std::runtime_error(file.string() + ": cannot read the recorded image");
  std::lock_guard<std::mutex> lock(mu_);
  image_ = std::move(image);
  ++generation_;
}

void ReplayWorld::PrepareStep1Frame(size_t index) {
  if (index >= step1_images_.size())
    throw std::out_of_range("ReplayWorld: step 1 frame " + std::to_string(index));
  Show(step1_images_[index]);
}

void ReplayWorld::PrepareStep2Frame(size_t index) {
  if (index >= step2_images_.size())
    throw std::out_of_range("ReplayWorld: step 2 frame " + std::to_string(index));
  Show(step2_images_[index]);
}

bool ReplayWorld::FrameShowsCurrentSetup(const camera::FrameInfo& info) const {
  std::lock_guard<std::mutex> lock(mu_);
  for (auto it = filled_.rbegin(); it != filled_.rend(); ++it) {
    if (it->first == info.device_timestamp_ns) return it->second == generation_;
  }
  return false;
}

std::string ReplayWorld::PrepareHallRecording(orchestrator::HallRun run) {
  return hall_device_(run);
}

uint64_t ReplayWorld::generation() const {
  std::lock_guard<std::mutex> lock(mu_);
  return generation_;
}

}  // namespace msmcal::replay
