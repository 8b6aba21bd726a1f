#pragma once
// How a recorded session's instruments were configured, recovered from its journal, so that a
// replay drives the mocks with the same signals and the orchestrator with the same options.
//
// The journal (session.db) records run.kind and config_yaml (OrchestratorOptions::run_kind /
// run_config_yaml): "demo" sessions hold the simulator options, "lab" sessions the rig
// configuration (config/rig.yaml), "replay" sessions the YAML written by ReplayRunConfigYaml()
// (the source folder and the source's own kind and configuration, so a replay of a replay does
// not need the first recording to exist).

#include <cstdint>
#include <filesystem>
#include <string>

#include "drivers/generator/rig_config.h"
#include "drivers/hall_mcu/hall_sensor.h"
#include "mocks/rig/sim_options.h"
#include "simulation/twin/demo_rig.h"

namespace msmcal::replay {

// The acquisition a recording came from (never "replay": replays are resolved to their source).
struct SourceRun {
  std::string kind;         // "demo" | "lab"
  std::string config_yaml;  // simulator options (demo) or rig configuration (lab)
};

// Reads `dir`'s journal and resolves replays to the original run. Throws std::runtime_error
// naming the folder when there is no journal, the kind is unknown or the YAML is malformed.
SourceRun ReadSourceRun(const std::filesystem::path& dir);

// The journal config_yaml of a replay of `source` (absolute path recorded).
std::string ReplayRunConfigYaml(const std::filesystem::path& source, const SourceRun& run);
// Inverse of ReplayRunConfigYaml (`origin` names the text in messages). Throws
// std::runtime_error naming origin and the missing/malformed key.
SourceRun ParseReplayRunConfigYaml(const std::string& yaml_text, const std::string& origin,
                                   std::filesystem::path* source = nullptr);

// What the orchestrator of the original run was given, apart from instrument addresses.
struct RigSetup {
  gen::RigGeneratorConfig generators;  // link host/port still to be pointed at the mocks
  uint16_t mcu_rate_hz = 1000;
  hall_mcu::HallMcuOptions mcu;         // OrchestratorOptions::mcu (device set per recording)
  hall_mcu::SensorSettings mcu_sensor;  // the mock MCU's power-up settings (quantisation)
};

// What a recorded generators_transcript.txt ("unit1 > *IDN?" / "unit1 < Agilent ...", one line
// per exchange) says about `unit` ("unit1" | "unit2"): the reply to its first *IDN? and *OPT?
// (empty when the transcript has none), so the mock answers as the recorded instrument did.
struct RecordedIdentity {
  std::string identity;
  std::string options_reply;
};
RecordedIdentity IdentityFromTranscript(const std::string& transcript, const std::string& unit);

// The demo rig's generator configuration (simulation/twin/demo_rig.h).
using twin::DemoGeneratorConfig;

// The setup of a source run: for "demo" what DemoRig::MakeOrchestratorOptions sets; for "lab"
// the rig configuration's `generators:` and (when present) `hall_mcu:` sections. The background
// recording length is not part of it: a replay records until the replayed data ends. Throws
// std::runtime_error naming the kind, or the YAML's problem.
RigSetup SetupFromSourceRun(const SourceRun& run);

}  // namespace msmcal::replay
