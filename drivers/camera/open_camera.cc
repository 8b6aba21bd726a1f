#include "drivers/camera/open_camera.h"

#include <utility>

#include "drivers/camera/aravis_camera.h"
#include "drivers/camera/v4l2_camera.h"

namespace msmcal::camera {

OpenCameraResult OpenCamera(const std::string& device,
                            std::shared_ptr<V4l2Syscalls> v4l2_syscalls) {
  if (device.rfind("v4l2:", 0) == 0) {
    V4l2CameraOptions options;
    options.path = device.substr(5);
    options.syscalls = v4l2_syscalls;
    return OpenV4l2Camera(options);
  }
  if (device.rfind("/dev/", 0) == 0) {
    V4l2CameraOptions options;
    options.path = device;
    options.syscalls = std::move(v4l2_syscalls);
    return OpenV4l2Camera(options);
  }
  AravisCameraOptions options;
  options.device = device.rfind("aravis:", 0) == 0 ? device.substr(7) : device;
  return OpenAravisCamera(options);
}

}  // namespace msmcal::camera
