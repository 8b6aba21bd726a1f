#pragma once
// The demo rig's mock Hall MCUs (one per recording, on ptys). Kept apart from demo_rig.cc because
// mocks/mcu/mock_mcu.h and mocks/generator/mock_server.h both declare msmcal::sim::FaultKind and
// msmcal::sim::Fault and cannot be included in the same translation unit.

#include <memory>
#include <string>

#include "mocks/rig/sim_options.h"
#include "sessions/orchestrator/rig_operator.h"

namespace msmcal::orchestrator {

class DemoMcus {
 public:
  DemoMcus();
  ~DemoMcus();  // stops every mock
  DemoMcus(const DemoMcus&) = delete;
  DemoMcus& operator=(const DemoMcus&) = delete;
  // Starts a mock MCU streaming the simulator's Hall model for `run` as fast as it is read;
  // returns its pty device path.
  std::string Start(const sim::SimOptions& options, HallRun run);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace msmcal::orchestrator
