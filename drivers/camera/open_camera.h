#pragma once
// Opens any camera the drivers support from one device string:
//   "v4l2:/dev/video0" or "/dev/video0"  -> V4L2
//   "aravis:ID"                           -> Aravis by device id (discovery broadcast!)
//   anything else ("127.0.0.1")           -> Aravis by address

#include <string>

#include "drivers/camera/camera.h"

namespace msmcal::camera {

OpenCameraResult OpenCamera(const std::string& device);

}  // namespace msmcal::camera
