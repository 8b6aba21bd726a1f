#include "acquisition/frames/frame_grabber.h"

#include <chrono>
#include <sstream>

namespace msmcal::frames {

std::string GrabberOptions::Validate() const {
  std::ostringstream out;
  if (queue_capacity < 1 || queue_capacity > 1024) {
    out << "GrabberOptions.queue_capacity = " << queue_capacity << ": must be in [1, 1024]";
  } else if (writer_threads < 1 || writer_threads > 64) {
    out << "GrabberOptions.writer_threads = " << writer_threads << ": must be in [1, 64]";
  } else if (frame_timeout_us <= 0) {
    out << "GrabberOptions.frame_timeout_us = " << frame_timeout_us << ": must be > 0";
  }
  return out.str();
}

FrameGrabber::FrameGrabber(camera::Camera& camera, FrameSink& sink, GrabberOptions options)
    : camera_(camera), sink_(sink), options_(std::move(options)), queue_(options_.queue_capacity) {}

FrameGrabber::~FrameGrabber() { Stop(); }

int64_t FrameGrabber::Now() const {
  if (options_.now_ns) return options_.now_ns();
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

camera::Status FrameGrabber::Start() {
  if (std::string error = options_.Validate(); !error.empty()) {
    return camera::Status::Error(error);
  }
  if (started_) return camera::Status::Error("FrameGrabber::Start: already started");
  if (camera::Status s = camera_.Start(); !s) return s;
  started_ = true;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stats_.running = true;
  }
  for (int i = 0; i < options_.writer_threads; ++i) writers_.emplace_back([this] { WriterLoop(); });
  capture_ = std::thread([this] { CaptureLoop(); });
  return camera::Status::Ok();
}

void FrameGrabber::CaptureLoop() {
  uint64_t index = 0;
  uint64_t timeouts_in_a_row = 0;
  while (!stop_.load()) {
    if (options_.max_frames > 0 && index >= options_.max_frames) break;
    camera::FrameResult r = camera_.NextFrame(options_.frame_timeout_us);
    if (r.status == camera::FrameStatus::kTimeout) {
      std::lock_guard<std::mutex> lock(mutex_);
      ++stats_.timeouts;
      if (options_.max_consecutive_timeouts > 0 &&
          ++timeouts_in_a_row >= options_.max_consecutive_timeouts) {
        stats_.last_error = "no frame in " + std::to_string(timeouts_in_a_row) + " waits of " +
                            std::to_string(options_.frame_timeout_us / 1000) +
                            " ms in a row (is the camera streaming and triggered?)";
        break;
      }
      continue;
    }
    timeouts_in_a_row = 0;
    if (r.status != camera::FrameStatus::kOk) {
      std::lock_guard<std::mutex> lock(mutex_);
      stats_.last_error = r.message;
      break;
    }
    const int64_t now = Now();
    Item item{std::move(r.frame), index++};
    const bool queued = queue_.TryPush(item);
    std::lock_guard<std::mutex> lock(mutex_);
    if (first_ns_ < 0) first_ns_ = now;
    ++stats_.frames_grabbed;
    if (!queued) ++stats_.frames_dropped;  // item (and its buffer) released at scope end
  }
  queue_.Close();
}

void FrameGrabber::WriterLoop() {
  while (std::optional<Item> item = queue_.Pop()) {
    const FrameSink::Result result = sink_.Write(item->frame, item->index);
    const uint64_t raw = item->frame.size_bytes();
    item->frame.Reset();  // back to the driver before taking the lock
    const int64_t now = Now();
    std::lock_guard<std::mutex> lock(mutex_);
    if (result.ok) {
      ++stats_.frames_written;
      stats_.bytes_written += result.bytes;
      raw_bytes_written_ += raw;
      last_write_ns_ = now;
    } else {
      ++stats_.write_errors;
      stats_.last_error = result.message;
    }
  }
}

void FrameGrabber::WaitForCaptureEnd() {
  if (capture_.joinable()) capture_.join();
}

void FrameGrabber::Wait() {
  WaitForCaptureEnd();
  for (auto& w : writers_) {
    if (w.joinable()) w.join();
  }
  std::lock_guard<std::mutex> lock(mutex_);
  stats_.running = false;
}

void FrameGrabber::Stop() {
  stop_ = true;
  Wait();
  writers_.clear();
  if (started_) {
    const camera::StreamStats camera_stats = camera_.Stats();
    camera_.Stop();
    std::lock_guard<std::mutex> lock(mutex_);
    stats_.camera = camera_stats;
    started_ = false;
  }
}

GrabberStats FrameGrabber::Stats() const {
  GrabberStats stats;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stats = stats_;
    if (first_ns_ >= 0 && last_write_ns_ > first_ns_) {
      const double seconds = static_cast<double>(last_write_ns_ - first_ns_) * 1e-9;
      stats.fps = static_cast<double>(stats.frames_written) / seconds;
      stats.mb_per_s = static_cast<double>(raw_bytes_written_) / 1e6 / seconds;
    }
  }
  return stats;
}

}  // namespace msmcal::frames
