#pragma once
// GenICam cameras through Aravis 0.8 (GigE Vision; USB3 Vision where Aravis was built with it).
// Aravis stays private to aravis_camera.cc.

#include <memory>
#include <string>

#include "drivers/camera/camera.h"

namespace msmcal::camera {

struct AravisCameraOptions {
  // IP address ("127.0.0.1") or Aravis device id. Opening by address never broadcasts a
  // discovery; opening by id does (Aravis enumerates every interface), so prefer addresses.
  std::string device;
  // GigE Vision stream packet size in bytes (GevSCPSPacketSize); 0 = keep the camera's.
  // 8192 gives 0 lost packets on loopback (docs: camera-notes.md).
  int packet_size = 8192;
  // Let Aravis size the socket receive buffer to the frame (ARV_GV_STREAM_SOCKET_BUFFER_AUTO).
  bool auto_socket_buffer = true;
  bool packet_resend = true;
  // GigE Vision: how long to wait for control when another client holds it (one killed without
  // leaving control keeps it until its heartbeat timeout, 3 s by default); then the open fails.
  int control_wait_ms = 5000;

  std::string Validate() const;
};

// Opens the camera; fails (no throw) when it does not answer (about 2.5 s for an absent GigE
// address) or options are invalid.
OpenCameraResult OpenAravisCamera(const AravisCameraOptions& options);

}  // namespace msmcal::camera
