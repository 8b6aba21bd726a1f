#pragma once
// Grabs frames from a Camera on its own thread and hands them to a FrameSink on writer threads
// through a bounded queue. Frames are moved, never copied (the sink reads the driver's buffer;
// releasing the frame returns the buffer to the driver's pool). When the queue is full the newest
// frame is dropped and counted (the capture thread never blocks on storage). Live statistics:
// frames grabbed/written/dropped, fps and MB/s from an injected clock.

#include <atomic>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "acquisition/frames/bounded_queue.h"
#include "acquisition/frames/frame_writer.h"
#include "drivers/camera/camera.h"

namespace msmcal::frames {

struct GrabberOptions {
  size_t queue_capacity = 4;  // keep below the camera's buffer_count
  int writer_threads = 1;
  int64_t frame_timeout_us = 2'000'000;  // NextFrame deadline
  uint64_t max_frames = 0;               // stop after this many grabbed frames; 0 = until Stop()
  // End the capture after this many NextFrame timeouts in a row, with last_error saying so (a
  // camera that opened but streams nothing); 0 = wait for ever (each timeout counted).
  uint64_t max_consecutive_timeouts = 0;
  std::function<int64_t()> now_ns;  // clock for the rates; null = steady_clock
  std::string Validate() const;
};

struct GrabberStats {
  uint64_t frames_grabbed = 0;
  uint64_t frames_written = 0;
  uint64_t frames_dropped = 0;  // queue full: never written
  uint64_t write_errors = 0;
  uint64_t bytes_written = 0;
  uint64_t timeouts = 0;
  double fps = 0;              // written frames per second since the first grabbed frame
  double mb_per_s = 0;         // frame payload (raw) megabytes per second written, 1 MB = 1e6 bytes
  camera::StreamStats camera;  // the camera's statistics, filled in by Stop()
  std::string last_error;      // camera lost, write failure, ...
  bool running = false;
};

class FrameGrabber {
 public:
  // `camera` must be configured; `camera` and `sink` outlive the grabber.
  FrameGrabber(camera::Camera& camera, FrameSink& sink, GrabberOptions options);
  ~FrameGrabber();  // Stop()
  FrameGrabber(const FrameGrabber&) = delete;
  FrameGrabber& operator=(const FrameGrabber&) = delete;

  camera::Status Start();
  // Ends capture, writes what is queued, joins the threads, stops the camera. Idempotent.
  void Stop();
  // Blocks until capture has ended by itself (max_frames reached or camera lost) and everything
  // queued is written. Only meaningful with max_frames > 0 or an unreliable camera.
  void Wait();
  // Blocks until the capture thread has ended (max_frames reached, camera lost or Stop());
  // writers may still be busy.
  void WaitForCaptureEnd();
  GrabberStats Stats() const;

 private:
  struct Item {
    camera::Frame frame;
    uint64_t index = 0;
  };
  void CaptureLoop();
  void WriterLoop();
  int64_t Now() const;

  camera::Camera& camera_;
  FrameSink& sink_;
  GrabberOptions options_;
  BoundedQueue<Item> queue_;
  std::thread capture_;
  std::vector<std::thread> writers_;
  std::atomic<bool> stop_{false};
  mutable std::mutex mutex_;
  GrabberStats stats_;
  uint64_t raw_bytes_written_ = 0;
  int64_t first_ns_ = -1;
  int64_t last_write_ns_ = -1;
  bool started_ = false;
};

}  // namespace msmcal::frames
