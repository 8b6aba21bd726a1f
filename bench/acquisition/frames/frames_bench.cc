// Sustained frames/s and MB/s from a camera into a session folder (PNG) at 10 MP (3840 x 2748
// Mono8), against the camera's rate. The camera is synthetic (a pool of pre-filled buffers, no
// network) so that the figure is the grabber + writer's: run `msmcal camera grab` against the
// mock for the end-to-end figure including GigE Vision on loopback.
//
// Args: png_compression, writer_threads, camera_fps (0 = as fast as the pipeline takes frames).
// Counters: fps and MB/s written (raw frame bytes), dropped frames, PNG MB/s.
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <random>
#include <thread>
#include <vector>

#include "acquisition/frames/frame_grabber.h"
#include "acquisition/frames/frame_writer.h"
#include "drivers/camera/camera.h"

namespace {

using namespace msmcal;

constexpr int kWidth = 3840;
constexpr int kHeight = 2748;

// A free-running camera with a fixed pool of buffers; at camera_fps > 0 it paces frames like a
// real camera and counts a frame as missed when no buffer is free at its time (underrun).
class SyntheticCamera : public camera::Camera, public camera::FrameBufferOwner {
 public:
  SyntheticCamera(int buffers, double fps) : fps_(fps) {
    std::mt19937 rng(7);
    std::normal_distribution<double> noise(0, 2.0);
    for (int b = 0; b < buffers; ++b) {
      pool_.emplace_back(static_cast<size_t>(kWidth) * kHeight);
      auto& buf = pool_.back();
      // A dim scene with read noise and a few bright blobs: like a rig frame.
      for (int y = 0; y < kHeight; ++y) {
        for (int x = 0; x < kWidth; ++x) {
          double v = 20 + 40.0 * x / kWidth + noise(rng);
          if (((x / 240) + (y / 240)) % 2 == 0) v += 120;
          buf[static_cast<size_t>(y) * kWidth + x] =
              static_cast<uint8_t>(std::clamp(v, 0.0, 255.0));
        }
      }
      free_.push_back(b);
    }
  }
  camera::CameraInfo Info() const override {
    return {"bench", "synthetic", "0", kWidth, kHeight, {}};
  }
  camera::Status Configure(const camera::CameraConfig&) override { return camera::Status::Ok(); }
  camera::Status Start() override {
    start_ = std::chrono::steady_clock::now();
    next_ = 0;
    return camera::Status::Ok();
  }
  void Stop() override {}
  camera::FrameResult NextFrame(int64_t timeout_us) override {
    if (fps_ > 0) {
      // The camera exposes frame next_ at start + next_/fps; a frame without a free buffer is lost.
      std::this_thread::sleep_until(start_ + std::chrono::duration<double>(next_ / fps_));
    }
    std::unique_lock<std::mutex> lock(mutex_);
    if (fps_ > 0) {
      if (free_.empty()) {
        ++missed_;
        ++next_;
        return {camera::FrameStatus::kTimeout, {}, "underrun"};
      }
    } else if (!cv_.wait_for(lock, std::chrono::microseconds(timeout_us),
                             [&] { return !free_.empty(); })) {
      return {camera::FrameStatus::kTimeout, {}, "no buffer"};
    }
    const int b = free_.back();
    free_.pop_back();
    camera::FrameInfo info;
    info.width = kWidth;
    info.height = kHeight;
    info.frame_id = next_++;
    return {camera::FrameStatus::kOk,
            camera::Frame(info, pool_[b].data(), pool_[b].size(), alias_,
                          reinterpret_cast<void*>(static_cast<intptr_t>(b))),
            ""};
  }
  camera::Status SoftwareTrigger() override { return camera::Status::Ok(); }
  camera::StreamStats Stats() const override {
    camera::StreamStats s;
    s.underruns = missed_;
    return s;
  }
  void Release(void* token) override {
    std::lock_guard<std::mutex> lock(mutex_);
    free_.push_back(static_cast<int>(reinterpret_cast<intptr_t>(token)));
    cv_.notify_one();
  }
  // Non-owning shared_ptr to this (the camera outlives its frames in the benchmark).
  std::shared_ptr<camera::FrameBufferOwner> alias_{std::shared_ptr<void>(), this};

 private:
  double fps_;
  std::vector<std::vector<uint8_t>> pool_;
  std::vector<int> free_;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::chrono::steady_clock::time_point start_;
  uint64_t next_ = 0;
  uint64_t missed_ = 0;
};

void BM_GrabToPngSession(benchmark::State& state) {
  const int compression = static_cast<int>(state.range(0));
  const int writers = static_cast<int>(state.range(1));
  const double camera_fps = static_cast<double>(state.range(2));
  const uint64_t frames = 12;
  SyntheticCamera camera(/*buffers=*/8, camera_fps);
  const auto dir = std::filesystem::temp_directory_path() /
                   ("msmcal_frames_bench_" + std::to_string(::getpid()));
  double fps = 0, mbps = 0, dropped = 0, png_bytes = 0, seconds = 0;
  for (auto _ : state) {
    std::filesystem::remove_all(dir);
    frames::PngWriterOptions wo;
    wo.dir = dir / "step2";
    wo.png_compression = compression;
    frames::PngFolderWriter writer(wo);
    frames::GrabberOptions go;
    go.max_frames = frames;
    go.queue_capacity = 4;
    go.writer_threads = writers;
    frames::FrameGrabber grabber(camera, writer, go);
    const auto t0 = std::chrono::steady_clock::now();
    if (!grabber.Start()) state.SkipWithError("start failed");
    grabber.Wait();
    grabber.Stop();
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const auto stats = grabber.Stats();
    fps += stats.fps;
    mbps += stats.mb_per_s;
    dropped += static_cast<double>(stats.frames_dropped + camera.Stats().underruns);
    png_bytes += static_cast<double>(stats.bytes_written);
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["fps"] = fps / n;
  state.counters["MB_per_s"] = mbps / n;
  state.counters["dropped_or_missed"] = dropped / n;
  state.counters["png_MB_per_s"] = png_bytes / 1e6 / seconds;
  state.counters["camera_fps"] = camera_fps;
  std::filesystem::remove_all(dir);
}
BENCHMARK(BM_GrabToPngSession)
    ->ArgNames({"png_level", "writers", "camera_fps"})
    ->Args({1, 1, 0})
    ->Args({1, 2, 0})
    ->Args({0, 2, 0})
    ->Args({1, 2, 5})
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
