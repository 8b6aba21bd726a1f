#include "simulation/twin/demo_mcus.h"

#include <vector>

#include "mocks/mcu/mock_mcu.h"
#include "mocks/mcu/rig_hall_source.h"

namespace msmcal::twin {

struct DemoMcus::Impl {
  std::vector<std::unique_ptr<sim::MockMcu>> mcus;
};

DemoMcus::DemoMcus() : impl_(std::make_unique<Impl>()) {}

DemoMcus::~DemoMcus() {
  for (auto& m : impl_->mcus) m->Stop();
}

std::string DemoMcus::Start(const sim::SimOptions& options, orchestrator::HallRun run,
                            const std::vector<sim::McuFault>& faults) {
  const sim::HallRecordingKind kind = run == orchestrator::HallRun::kBackground
                                          ? sim::HallRecordingKind::kBackground
                                          : sim::HallRecordingKind::kActual;
  sim::MockMcuOptions mo;
  mo.speed = 0;  // as fast as the host reads
  mo.record_sent = false;
  mo.rate_hz = static_cast<uint16_t>(options.hall.sample_rate_hz);
  mo.faults = faults;
  auto mcu = std::make_unique<sim::MockMcu>(
      mo, std::make_unique<sim::RigHallSource>(options, kind, options.seed));
  mcu->Start();
  const std::string path = mcu->device_path();
  impl_->mcus.push_back(std::move(mcu));
  return path;
}

}  // namespace msmcal::twin
