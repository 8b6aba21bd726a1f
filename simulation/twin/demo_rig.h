#pragma once
// The demo rig: every instrument of the calibration rig served by its mock in this process —
// the two Keysight 33520B units on loopback TCP (SCPI), the GigE Vision camera on an address
// (frames rendered from the rig simulator's scene for the world's current setup), and the Hall
// MCU on a pty (one mock per recording, streaming the simulator's Hall model as fast as it is
// read) — plus the SimulatedWorld the orchestrator's operator actions set.

#include <memory>
#include <string>
#include <vector>

#include "drivers/generator/rig_config.h"
#include "mocks/camera/mock_gv_camera.h"
#include "mocks/mcu/mock_mcu.h"
#include "mocks/rig/rig_simulator.h"
#include "sessions/orchestrator/orchestrator.h"
#include "simulation/twin/demo_mcus.h"
#include "simulation/twin/simulated_world.h"

namespace msmcal::sim {
class MockGeneratorPair;  // mocks/generator/mock_server.h
}  // namespace msmcal::sim

namespace msmcal::twin {

struct DemoRigOptions {
  sim::SimOptions sim;
  std::string camera_address = "127.0.0.1";  // one GigE Vision server per address
  double camera_frame_rate_hz = 20.0;
  // The generators served by another process (`msmcal mock generators`, e.g. with faults): the
  // ports of unit 1 and unit 2 on 127.0.0.1. 0 and 0: the rig serves its own pair.
  int external_generator_port1 = 0, external_generator_port2 = 0;
  // Faults of the rig's own mocks (docs/fault-campaign.md); none by default.
  int64_t camera_lost_after_frames = -1;  // MockGvCameraOptions::lost_after_frames
  std::vector<sim::McuFault> background_mcu_faults, actual_mcu_faults;
  std::string Validate() const;
};

// The generator configuration of the demo rig for `sim`, with the mock units on loopback `port1`
// and `port2`: the demo rig file's fixed limits (never scaled from the request), the simulator's
// drive frequencies and amplitudes. Also what a replay of a demo session plays (sessions/replay).
gen::RigGeneratorConfig DemoGeneratorConfig(const sim::SimOptions& sim, int port1, int port2);

class DemoRig {
 public:
  // Builds the simulator and starts the generator pair and the camera. Throws
  // std::runtime_error naming the instrument that could not be served.
  explicit DemoRig(const DemoRigOptions& options);
  ~DemoRig();
  DemoRig(const DemoRig&) = delete;
  DemoRig& operator=(const DemoRig&) = delete;

  const sim::RigSimulator& sim() const { return *sim_; }
  std::shared_ptr<const sim::RigSimulator> shared_sim() const { return sim_; }
  SimulatedWorld& world() { return *world_; }
  // The rig's own generator pair; not with external generators (calling it then is a bug:
  // MSMCAL_CHECK aborts).
  sim::MockGeneratorPair& generators();
  int generators_port(int unit) const;  // TCP port of unit 1 or 2
  sim::MockGvCamera& camera() { return *camera_; }

  // The generator configuration of this rig: the mocks' ports, limits around the simulated
  // mirror's drive, and the simulator's drive frequencies and amplitudes.
  gen::RigGeneratorConfig GeneratorConfig() const;
  // Orchestrator options pointing at this rig's instruments.
  orchestrator::OrchestratorOptions MakeOrchestratorOptions(
      const std::filesystem::path& out_dir) const;
  // The session plan (trigger table, frame lists; no images, no Hall data).
  dataset::Recording Plan() const;

 private:
  DemoRigOptions options_;
  std::shared_ptr<const sim::RigSimulator> sim_;
  std::unique_ptr<SimulatedWorld> world_;
  std::unique_ptr<sim::MockGeneratorPair> generators_;
  std::unique_ptr<sim::MockGvCamera> camera_;
  std::unique_ptr<DemoMcus> mcus_;
  mutable std::string background_device_;  // started by MakeOrchestratorOptions, handed out once
};

}  // namespace msmcal::twin
