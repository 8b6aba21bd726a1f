#pragma once
// Opens any camera the drivers support from one device string:
//   "v4l2:/dev/video0" or "/dev/video0"  -> V4L2
//   "aravis:ID"                           -> Aravis by device id (discovery broadcast!)
//   anything else ("127.0.0.1")           -> Aravis by address

#include <memory>
#include <string>

#include "drivers/camera/camera.h"

namespace msmcal::camera {

class V4l2Syscalls;

// `v4l2_syscalls`: the system calls under a V4L2 device (null: the kernel's); tests pass a fake.
OpenCameraResult OpenCamera(const std::string& device,
                            std::shared_ptr<V4l2Syscalls> v4l2_syscalls = nullptr);

}  // namespace msmcal::camera
