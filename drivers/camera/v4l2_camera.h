#pragma once
// USB (UVC) and other capture devices through the kernel's V4L2 API: format negotiation, mmap
// streaming, poll with a deadline. Everything goes through V4l2Syscalls, so the driver is tested
// against a fake device (no /dev/video* exists on our build machines).

#include <memory>
#include <string>

#include "drivers/camera/camera.h"
#include "drivers/camera/v4l2_syscalls.h"

namespace msmcal::camera {

struct V4l2CameraOptions {
  std::string path = "/dev/video0";
  std::shared_ptr<V4l2Syscalls> syscalls;  // null = RealV4l2Syscalls()

  std::string Validate() const;
};

// Opens the device and checks it can capture with mmap streaming (VIDIOC_QUERYCAP).
// ROI on V4L2 is a frame size: roi.x/roi.y must be 0; the driver may adjust the size (as the
// kernel API allows), the frames report the size actually used.
OpenCameraResult OpenV4l2Camera(const V4l2CameraOptions& options);

}  // namespace msmcal::camera
