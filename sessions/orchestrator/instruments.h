#pragma once
// How a session reaches its instruments. Sessions never name a concrete driver: the orchestrator
// asks an InstrumentFactory for the two generator units, the camera and the Hall sensor, from the
// rig configuration (OrchestratorOptions: generators:, camera, hall_mcu:). Every implementation
// talks the instruments' real protocols; the demo and replay rigs (simulation/) serve mocks behind
// the same wires, so they use the drivers' factory too, pointed at the mocks' addresses.

#include <memory>
#include <string>

#include "drivers/camera/camera.h"
#include "drivers/generator/function_generator.h"
#include "drivers/hall_mcu/hall_sensor.h"
#include "drivers/scpi/scpi_client.h"

namespace msmcal::camera {
class V4l2Syscalls;
}

namespace msmcal::orchestrator {

class InstrumentFactory {
 public:
  virtual ~InstrumentFactory() = default;
  // One generator unit (identified on open). `transcript` receives every SCPI exchange (may be
  // empty). Throws std::runtime_error when the unit cannot be reached or identified.
  virtual std::unique_ptr<gen::FunctionGenerator> OpenGenerator(
      const gen::Keysight33500Options& unit, scpi::TranscriptSink transcript) = 0;
  // The camera named by `camera`: a GigE Vision camera by IP address ("192.168.10.20"; never by
  // discovery) or a V4L2 device ("/dev/video0" or "v4l2:/dev/video0"). Never throws: a null
  // camera and the error when it cannot be opened.
  virtual camera::OpenCameraResult OpenCamera(const std::string& camera) = 0;
  // The Hall MCU on `link.device`. Throws std::runtime_error when the link cannot be opened.
  virtual std::unique_ptr<hall_mcu::HallSensor> OpenHallSensor(
      const hall_mcu::HallMcuOptions& link) = 0;
};

struct DriverInstrumentOptions {
  // The system calls under the V4L2 driver; null: the kernel's (through libv4l2). Tests pass a
  // fake device (drivers/camera/testing/fake_v4l2_device.h).
  std::shared_ptr<camera::V4l2Syscalls> v4l2_syscalls;
};

// The drivers: Keysight 33500 over SCPI/TCP, camera::OpenCamera (Aravis by address, V4L2 by
// device), the Hall MCU's serial framing. Thread-compatible; each call opens a new instrument.
std::shared_ptr<InstrumentFactory> MakeDriverInstruments(DriverInstrumentOptions options = {});

}  // namespace msmcal::orchestrator
