#pragma once
// An in-process fake of one V4L2 capture device behind the V4l2Syscalls seam, faithful to the
// kernel's semantics where the driver depends on them (videodev2 API, single-planar capture,
// MMAP streaming):
//   - QUERYCAP, ENUM_FMT, ENUM_FRAMESIZES (discrete), G/S/TRY_FMT (size snapped to the nearest
//     offered size, unknown fourcc replaced by the first format), G/S_PARM, G/S_CTRL (exposure
//     absolute, exposure auto, gain), REQBUFS (count clamped to [1, max_buffers]; 0 frees; EBUSY
//     while streaming or mapped), QUERYBUF, QBUF/DQBUF (EINVAL on a buffer in the wrong state,
//     EAGAIN when nothing is done: the fake is always non-blocking), STREAMON/OFF (OFF returns
//     every buffer to the application), unknown requests ENOTTY.
//   - Buffers live in a memfd, so the driver's real mmap works; the device fd is an eventfd that
//     is readable exactly when a filled buffer waits, so a real poll() works and wakes across
//     threads.
//   - Faults: any ioctl can be made to fail with an errno (EAGAIN, EIO, EBUSY, ...), Unplug()
//     makes every later call fail with ENODEV and poll report POLLERR|POLLHUP, and produced frames
//     can carry V4L2_BUF_FLAG_ERROR, a short bytesused or a sequence gap.
// Frames are produced by the test (ProduceFrame) or, with SetAutoProduce(true), on demand inside
// Poll when nothing is ready (deterministic, no threads). Thread-safe.

#include <sys/types.h>

#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "drivers/camera/v4l2_syscalls.h"

namespace msmcal::camera::testing {

class FakeV4l2Device : public V4l2Syscalls {
 public:
  struct Format {
    uint32_t fourcc = 0;
    int bytes_per_pixel = 1;
    std::vector<std::pair<int, int>> sizes;  // discrete sizes, width x height
  };
  struct Options {
    std::string path = "/dev/video0";
    std::vector<Format> formats;  // empty = GREY and Y16 at 640x480 and 320x240, RGB24 640x480
    uint32_t max_buffers = 32;
  };
  struct FrameFault {
    bool error_flag = false;     // V4L2_BUF_FLAG_ERROR on the buffer
    uint32_t short_bytes = 0;    // bytesused = size - short_bytes
    uint32_t skip_sequence = 0;  // sequence numbers skipped before this frame
  };

  FakeV4l2Device() : FakeV4l2Device(Options{}) {}
  explicit FakeV4l2Device(Options options);
  ~FakeV4l2Device() override;

  // V4l2Syscalls.
  int Open(const char* path, int flags) override;
  int Close(int fd) override;
  int Ioctl(int fd, unsigned long request, void* arg) override;
  void* Mmap(void* addr, size_t length, int prot, int flags, int fd, off_t offset) override;
  int Munmap(void* addr, size_t length) override;
  int Poll(struct pollfd* fds, nfds_t nfds, int timeout_ms) override;

  // Fills the oldest queued buffer with the test pattern for its sequence number and marks it
  // done. False (and an underrun counted) when the application has no buffer queued.
  bool ProduceFrame();
  bool ProduceFrame(const FrameFault& fault);
  void SetAutoProduce(bool on);
  // The next `count` calls of `request` fail with `err` (before any other check).
  void FailIoctl(unsigned long request, int err, int count = 1);
  // Device removal: every later call fails with ENODEV; a blocked poll wakes.
  void Unplug();

  // Pattern byte i of the frame with sequence number `sequence`. The first 8 bytes of every
  // frame hold the sequence (little-endian) so that a test can check a frame is whole.
  static uint8_t PatternByte(uint64_t sequence, size_t i);

  // Inspection.
  bool streaming() const;
  int open_fds() const;
  int mapped_buffers() const;
  int queued_buffers() const;
  uint64_t underruns() const;
  uint32_t current_fourcc() const;

 private:
  enum class BufState { kDequeued, kQueued, kDone };
  struct Buffer {
    BufState state = BufState::kDequeued;
    uint32_t bytesused = 0;
    uint32_t flags = 0;
    uint32_t sequence = 0;
    int64_t timestamp_us = 0;
  };

  int IoctlLocked(unsigned long request, void* arg);
  bool ProduceLocked(const FrameFault& fault);
  void FreeBuffersLocked();
  void UpdateReadableLocked();
  bool IsOurs(int fd) const;
  const Format* FindFormat(uint32_t fourcc) const;
  void SnapFormat(void* v4l2_format) const;
  uint32_t BufferLength() const;
  uint32_t BufferStride() const;

  Options options_;
  mutable std::mutex mutex_;
  std::vector<int> fds_;
  bool unplugged_ = false;
  bool streaming_ = false;
  bool auto_produce_ = false;
  int mapped_ = 0;
  std::map<uintptr_t, size_t> mappings_;
  int memfd_ = -1;
  std::vector<Buffer> buffers_;
  std::deque<uint32_t> queued_;
  std::deque<uint32_t> done_;
  uint32_t sequence_ = 0;
  uint64_t underruns_ = 0;
  bool readable_ = false;
  // Current format.
  uint32_t fourcc_ = 0;
  int width_ = 0;
  int height_ = 0;
  uint32_t frame_period_num_ = 1;
  uint32_t frame_period_den_ = 30;
  int32_t exposure_100us_ = 100;
  int32_t exposure_auto_ = 3;
  int32_t gain_ = 0;
  std::map<unsigned long, std::pair<int, int>> failures_;  // request -> (errno, count)
};

}  // namespace msmcal::camera::testing
