#include "app/rig_sweep_parameters.h"

#include <yaml-cpp/yaml.h>

#include <cctype>
#include <stdexcept>
#include <utility>

#include "common/file_text.h"
#include "common/yaml_fields.h"
#include "sessions/plan/session_plan.h"
#include "sessions/rig/rig_file.h"
#include "simulation/sweep_points/sim_sweep_parameters.h"

namespace msmcal::app {

namespace fs = std::filesystem;

RigSweepParameters::RigSweepParameters(const std::string& defaults_yaml, std::string origin)
    : origin_(std::move(origin)), defaults_(YAML::Dump(YAML::Load(defaults_yaml))) {}

std::shared_ptr<const RigSweepParameters> RigSweepParameters::FromRigFile(
    const fs::path& rig_file) {
  return std::make_shared<const RigSweepParameters>(rig::LoadRigFile(rig_file).text,
                                                    rig_file.string());
}

std::string RigSweepParameters::Noun() const { return "rig file field"; }

std::string RigSweepParameters::PathHint() const {
  return "(dotted rig file key, e.g. generators.signals.drive.fast.frequency_hz)";
}

std::string RigSweepParameters::LoadFile(const fs::path& file) const {
  return YAML::Dump(YAML::Load(rig::LoadRigFile(file).text));
}

std::string RigSweepParameters::Resolve(const std::string& yaml, const std::string& where,
                                        int repeat, uint64_t* seed) const {
  // The rig file's own messages start "<origin>:<line>: "; the line would be the resolved
  // document's, not the file's, so it is dropped: the origin names the point.
  const std::string origin = where + " (" + origin_ + " with the point's values)";
  rig::RigFile rig;
  try {
    rig = rig::ParseRigFile(yaml, origin);
  } catch (const std::exception& e) {
    std::string m = e.what();
    if (m.rfind(origin + ":", 0) == 0) {
      size_t k = origin.size() + 1;
      while (k < m.size() && std::isdigit(static_cast<unsigned char>(m[k]))) ++k;
      if (k < m.size() && m[k] == ':') m = origin + m.substr(k);
    }
    throw std::runtime_error(m);
  }
  dataset::Recording plan;
  try {
    plan = plan::DesignSessionPlan(rig);
  } catch (const std::exception& e) {
    throw std::runtime_error(where + ": plan design: " + e.what());
  }
  const std::string problem = plan::CheckPlanAgainstRig(plan, rig);
  if (!problem.empty()) throw std::runtime_error(where + ": " + problem);
  if (seed) *seed = static_cast<uint64_t>(repeat);
  return yaml;
}

namespace {

// The stored plan's document: "<file>: cannot open the sweep plan", or a YAML syntax error with
// its line.
YAML::Node LoadPlanDocument(const fs::path& plan_file, std::string* text) {
  *text = common::ReadFileText(plan_file, "cannot open the sweep plan");
  return common::YamlFields(plan_file.string()).Load(*text, "YAML syntax error: ");
}

bool BaseIsRigFile(const YAML::Node& root) {
  if (!root.IsMap()) return false;
  const YAML::Node base = root["base"];
  return base && base.IsMap() && base["generators"] && base["generators"].IsMap();
}

}  // namespace

bool IsRigSweepPlan(const fs::path& plan_file) {
  std::string text;
  return BaseIsRigFile(LoadPlanDocument(plan_file, &text));
}

StoredSweepPlan LoadStoredSweepPlan(const fs::path& plan_file) {
  std::string text;
  const YAML::Node root = LoadPlanDocument(plan_file, &text);
  StoredSweepPlan stored;
  stored.rig = BaseIsRigFile(root);
  std::shared_ptr<const sweep::SweepParameters> parameters =
      stored.rig ? std::make_shared<const RigSweepParameters>(YAML::Dump(root["base"]),
                                                              plan_file.string() + " (its base:)")
                 : simulation::SimSweepParameters();
  stored.plan = sweep::ParseSweepPlan(text, plan_file.string(), plan_file.parent_path(),
                                      std::move(parameters));
  return stored;
}

}  // namespace msmcal::app
