#pragma once
// The replay rig: every instrument of the calibration rig served by its mock, fed by a recorded
// session folder instead of the simulator — the two Keysight 33520B mocks on loopback TCP
// (SCPI; configured by the orchestrator exactly as in the original run, since the generator
// configuration is rebuilt from the source's journal), the GigE Vision mock camera serving the
// recorded image of the current setup (ReplayWorld), and one mock Hall MCU per recording on a
// pty, replaying hall/<run>.csv and hall/<run>_clock.csv with their MCU times preserved, as fast
// as they are read.
//
// Running the orchestrator against it (RunSession with MakeOrchestratorOptions() and Plan(), the
// world() as operator) reproduces the original session folder: same frames (accepted and
// rejected), same Hall files, same generator transcript, same session.yaml.

#include <filesystem>
#include <memory>
#include <string>

#include "drivers/generator/rig_config.h"
#include "mocks/camera/mock_gv_camera.h"
#include "processing/dataset/recording.h"
#include "sessions/orchestrator/orchestrator.h"
#include "simulation/replay/replay_config.h"
#include "simulation/replay/replay_world.h"

namespace msmcal::sim {
class MockGeneratorPair;  // mocks/generator/mock_server.h
}  // namespace msmcal::sim

namespace msmcal::replay {

struct ReplayRigOptions {
  std::filesystem::path source;              // the recorded session folder (with session.db)
  std::string camera_address = "127.0.0.1";  // one GigE Vision server per address
  double camera_frame_rate_hz = 20.0;
  std::string Validate() const;  // empty when valid; names field, value, constraint
};

class ReplayRig {
 public:
  // Reads the source's plan and journal, checks that every recorded image and Hall file is there
  // (std::runtime_error naming the missing file), then starts the generator pair and the camera
  // (std::runtime_error naming the instrument that could not be served).
  explicit ReplayRig(const ReplayRigOptions& options);
  ~ReplayRig();
  ReplayRig(const ReplayRig&) = delete;
  ReplayRig& operator=(const ReplayRig&) = delete;

  const dataset::Recording& Plan() const { return plan_; }  // the plan the source recorded
  const SourceRun& source_run() const { return source_run_; }
  ReplayWorld& world() { return *world_; }
  sim::MockGvCamera& camera() { return *camera_; }
  int generators_port(int unit) const;

  // The source run's generator configuration, pointed at this rig's mock generators.
  gen::RigGeneratorConfig GeneratorConfig() const;
  // Orchestrator options for a replay into `out_dir`: this rig's instruments, the source's MCU
  // settings, background recorded to the end of the replayed data, run_kind "replay" and
  // run_config_yaml = ReplayRunConfigYaml(source, source_run()).
  orchestrator::OrchestratorOptions MakeOrchestratorOptions(
      const std::filesystem::path& out_dir) const;

 private:
  struct Mcus;
  ReplayRigOptions options_;
  dataset::Recording plan_;
  SourceRun source_run_;
  RigSetup setup_;
  std::string rig_id_, mirror_id_;  // from the source's journal
  std::unique_ptr<Mcus> mcus_;
  std::unique_ptr<ReplayWorld> world_;
  std::unique_ptr<sim::MockGeneratorPair> generators_;
  std::unique_ptr<sim::MockGvCamera> camera_;
};

}  // namespace msmcal::replay
