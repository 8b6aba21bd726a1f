#pragma once
// The demo rig's mock Hall MCUs (one per recording, on ptys), kept apart from demo_rig.cc so that
// the pty mock's headers stay out of the generator/camera wiring.

#include <memory>
#include <string>
#include <vector>

#include "mocks/rig/sim_options.h"
#include "sessions/orchestrator/rig_operator.h"

namespace msmcal::sim {
struct McuFault;  // mocks/mcu/mock_mcu.h
}  // namespace msmcal::sim

namespace msmcal::twin {

class DemoMcus {
 public:
  DemoMcus();
  ~DemoMcus();  // stops every mock
  DemoMcus(const DemoMcus&) = delete;
  DemoMcus& operator=(const DemoMcus&) = delete;
  // Starts a mock MCU streaming the simulator's Hall model for `run` as fast as it is read;
  // returns its pty device path. `faults`: injected by the mock (none for a normal session).
  std::string Start(const sim::SimOptions& options, orchestrator::HallRun run,
                    const std::vector<sim::McuFault>& faults = {});

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace msmcal::twin
