#pragma once
// Where a frame's exposure lies on the host clock, from the camera's own timestamp.
//
// A frame's host timestamp (FrameInfo::host_timestamp_ns) is when the driver received it: the
// exposure ended earlier by the read-out, the transfer and whatever the host was doing meanwhile
// (a loaded machine delays delivery by hundreds of milliseconds; a frame queued in the driver by
// seconds). The camera's timestamp (device_timestamp_ns) marks the exposure on the camera's clock
// (GigE Vision: at the exposure or at the read-out, by model; V4L2: the kernel's capture time).
// DeviceClockMap puts that mark on the host clock as device + offset, the offset being the
// smallest (host - device) among the recent frames: the frame delivered fastest (the usual
// minimum-delay estimate of a one-way clock offset). Its error is that fastest frame's delay
// (the mapped time is late by it, never early): callers that need "exposed after T" add a
// margin for it.
//
// The camera's clock may drift against the host's (ppm) and restarts when the camera does: the
// minimum is taken over the last `window` frames, and a frame whose (host - device) differs from
// it by more than `reset_ns` (a device clock reset, a different camera) starts the estimate again.
//
// Thread safety: none (one consumer thread, the orchestrator's).

#include <cstddef>
#include <cstdint>
#include <deque>
#include <optional>

#include "drivers/camera/camera.h"

namespace msmcal::camera {

class DeviceClockMap {
 public:
  explicit DeviceClockMap(size_t window = 64, int64_t reset_ns = 10'000'000'000);

  // Takes the frame's timestamp pair; frames without a device timestamp (0) are ignored.
  void Observe(const FrameInfo& info);

  // Host time of a device timestamp; nullopt before any frame with a device timestamp.
  std::optional<int64_t> HostNs(int64_t device_ns) const;
  // The current offset estimate (host - device, ns); nullopt before any frame.
  std::optional<int64_t> OffsetNs() const;
  size_t frames() const { return deltas_.size(); }

 private:
  size_t window_;
  int64_t reset_ns_;
  std::deque<int64_t> deltas_;  // host - device of the recent frames, oldest first
};

}  // namespace msmcal::camera
