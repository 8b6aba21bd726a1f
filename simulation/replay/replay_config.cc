#include "simulation/replay/replay_config.h"

#include <yaml-cpp/yaml.h>

#include <stdexcept>

#include "common/yaml_fields.h"
#include "drivers/hall_mcu/hall_mcu_config.h"
#include "sessions/orchestrator/orchestrator.h"

namespace msmcal::replay {

namespace fs = std::filesystem;

namespace {

// Replays nest at most this deep (a replay of a replay of ...): guards against a cycle.
constexpr int kMaxReplayDepth = 16;

// root[key], a string ("<origin>:<line>: <key>: missing" / "must be a string").
std::string RequiredString(const YAML::Node& root, const char* key, const std::string& origin) {
  return common::YamlFields(origin).String(root, key, key);
}

}  // namespace

std::string ReplayRunConfigYaml(const fs::path& source, const SourceRun& run) {
  YAML::Emitter e;
  e << YAML::BeginMap;
  e << YAML::Key << "replay_of" << YAML::Value << fs::absolute(source).lexically_normal().string();
  e << YAML::Key << "source_run_kind" << YAML::Value << run.kind;
  e << YAML::Key << "source_run_config_yaml" << YAML::Value << YAML::Literal << run.config_yaml;
  e << YAML::EndMap;
  return std::string(e.c_str()) + "\n";
}

SourceRun ParseReplayRunConfigYaml(const std::string& yaml_text, const std::string& origin,
                                   fs::path* source) {
  const YAML::Node root = common::YamlFields(origin).Load(yaml_text);
  if (!root.IsMap()) throw std::runtime_error(origin + ": expected a YAML map");
  SourceRun run;
  run.kind = RequiredString(root, "source_run_kind", origin);
  run.config_yaml = RequiredString(root, "source_run_config_yaml", origin);
  const std::string from = RequiredString(root, "replay_of", origin);
  if (source) *source = from;
  return run;
}

SourceRun ReadSourceRun(const fs::path& dir) {
  fs::path current = dir;
  orchestrator::SessionJournalState j = orchestrator::ReadSessionJournal(current);
  if (!j.exists)
    throw std::runtime_error(dir.string() +
                             ": no session journal (session.db): only sessions recorded by "
                             "msmcal (demo, lab or replay) can be replayed");
  SourceRun run{j.run_kind, j.run_config_yaml};
  for (int depth = 0; run.kind == "replay"; ++depth) {
    if (depth >= kMaxReplayDepth)
      throw std::runtime_error(dir.string() + ": replays nested more than " +
                               std::to_string(kMaxReplayDepth) + " deep");
    run =
        ParseReplayRunConfigYaml(run.config_yaml, dir.string() + "/session.db (meta config_yaml)");
  }
  if (run.kind != "demo" && run.kind != "lab")
    throw std::runtime_error(dir.string() + "/session.db: run kind '" + run.kind +
                             "' unknown (expected demo, lab or replay)");
  return run;
}

RecordedIdentity IdentityFromTranscript(const std::string& transcript, const std::string& unit) {
  RecordedIdentity r;
  const std::string sent = unit + " > ", received = unit + " < ";
  std::string pending;  // the query whose reply comes next
  size_t start = 0;
  while (start < transcript.size()) {
    size_t end = transcript.find('\n', start);
    if (end == std::string::npos) end = transcript.size();
    const std::string line = transcript.substr(start, end - start);
    start = end + 1;
    if (line.rfind(sent, 0) == 0) {
      pending = line.substr(sent.size());
    } else if (line.rfind(received, 0) == 0) {
      const std::string reply = line.substr(received.size());
      if (pending == "*IDN?" && r.identity.empty()) r.identity = reply;
      if (pending == "*OPT?" && r.options_reply.empty()) r.options_reply = reply;
      pending.clear();
    }
  }
  return r;
}

RigSetup SetupFromSourceRun(const SourceRun& run) {
  RigSetup s;
  if (run.kind == "demo") {
    const sim::SimOptions sim = sim::ParseSimOptions(run.config_yaml, "journal simulator options");
    s.generators = DemoGeneratorConfig(sim, 0, 0);
    s.mcu_rate_hz = static_cast<uint16_t>(sim.hall.sample_rate_hz);
    s.mcu.stall_timeout_ms = 2000;  // as DemoRig::MakeOrchestratorOptions
    return s;
  }
  if (run.kind == "lab") {
    // `msmcal session run` journals {rig_file, camera_address, mcu_device, camera_frame_rate_hz,
    // rig_yaml: <the rig configuration's text>} (app/session_flow.cc RunLabAcquisition); a bare
    // rig configuration is accepted too.
    const std::string origin = "journal config_yaml (lab run)";
    const YAML::Node root = common::YamlFields(origin).Load(run.config_yaml);
    std::string rig_yaml = run.config_yaml;
    if (root.IsMap() && root["rig_yaml"]) rig_yaml = RequiredString(root, "rig_yaml", origin);
    const std::string rig_origin = origin + " rig_yaml";
    s.generators = gen::ParseRigGeneratorConfig(rig_yaml, rig_origin);
    const YAML::Node rig = YAML::Load(rig_yaml);
    if (rig.IsMap() && rig["hall_mcu"]) {
      const hall_mcu::HallMcuConfig mcu = hall_mcu::ParseHallMcuConfig(rig_yaml, rig_origin);
      s.mcu = mcu.link;
      s.mcu_rate_hz = mcu.rate_hz;
      s.mcu_sensor = mcu.sensor;
    }
    return s;
  }
  throw std::runtime_error("run kind '" + run.kind + "': no rig setup (expected demo or lab)");
}

}  // namespace msmcal::replay
