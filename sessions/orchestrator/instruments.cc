#include "sessions/orchestrator/instruments.h"

#include <utility>

#include "drivers/camera/open_camera.h"

namespace msmcal::orchestrator {
namespace {

class DriverInstruments : public InstrumentFactory {
 public:
  explicit DriverInstruments(DriverInstrumentOptions options) : options_(std::move(options)) {}

  std::unique_ptr<gen::FunctionGenerator> OpenGenerator(const gen::Keysight33500Options& unit,
                                                        scpi::TranscriptSink transcript) override {
    return gen::OpenKeysight33500(unit, std::move(transcript));
  }

  camera::OpenCameraResult OpenCamera(const std::string& camera) override {
    // A session opens its camera by address or device only: "aravis:ID" would broadcast a GigE
    // Vision discovery on every interface.
    if (camera.rfind("aravis:", 0) == 0)
      return {nullptr, "camera " + camera +
                           ": a session opens a GigE Vision camera by address only (aravis:ID "
                           "broadcasts a discovery)"};
    return camera::OpenCamera(camera, options_.v4l2_syscalls);
  }

  std::unique_ptr<hall_mcu::HallSensor> OpenHallSensor(
      const hall_mcu::HallMcuOptions& link) override {
    return hall_mcu::OpenHallMcu(link);
  }

 private:
  DriverInstrumentOptions options_;
};

}  // namespace

std::shared_ptr<InstrumentFactory> MakeDriverInstruments(DriverInstrumentOptions options) {
  return std::make_shared<DriverInstruments>(std::move(options));
}

}  // namespace msmcal::orchestrator
