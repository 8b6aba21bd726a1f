// `msmcal plan --rig RIG.yaml --out PLAN_DIR [--force] [--setups FILE]`: designs a session plan
// from the rig file (sessions/plan, docs/lab-path.md) and writes PLAN_DIR/session.yaml +
// camera.yaml in the interchange format, then prints the summary: frames, the prompts a person will
// see, the expected duration and the disk needed. Refuses what the rig's limits forbid (the message
// names the field, the value and the limit; exit status 1), before writing anything. --setups FILE
// also writes the plan's set-ups (sessions/setup) as JSON lines, as a hook would receive them.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include "app/command_registry.h"
#include "sessions/interchange/interchange_io.h"
#include "sessions/plan/session_plan.h"
#include "sessions/rig/rig_file.h"

namespace msmcal::app {
namespace {

struct PlanArgs {
  std::string rig = "config/rig.yaml";
  std::string out;
  bool force = false;
  std::string setups;  // optional: the set-ups' JSON, one per line
};

void RunPlan(const PlanArgs& args) {
  namespace fs = std::filesystem;
  const rig::RigFile rig = rig::LoadRigFile(args.rig);
  const dataset::Recording plan = plan::DesignSessionPlan(rig);
  if (std::string e = plan::CheckPlanAgainstRig(plan, rig); !e.empty())
    throw std::runtime_error(args.rig + ": " + e);
  const fs::path out(args.out);
  if (!args.force && (fs::exists(out / "session.yaml") || fs::exists(out / "camera.yaml")))
    throw std::runtime_error(out.string() + ": holds a plan already (--force replaces it)");
  plan::WritePlanFolder(out, plan);
  if (!args.setups.empty()) {
    std::string lines;
    for (const auto& s : setup::PlanSetups(plan, plan::PoseGeometryOf(rig)).setups)
      lines += setup::SetupToJson(s) + "\n";
    interchange::WriteFileAtomically(args.setups, lines);
  }
  const plan::PlanSummary s = plan::SummarisePlan(plan, rig);
  std::printf("plan: %s (session.yaml, camera.yaml) from %s\n%s", out.c_str(), args.rig.c_str(),
              s.text.c_str());
}

void AddPlanCommand(CLI::App& app) {
  auto args = std::make_shared<PlanArgs>();
  auto* cmd = app.add_subcommand(
      "plan", "Design a session plan (session.yaml + camera.yaml) from the rig file");
  cmd->add_option("--rig", args->rig, "Rig file (docs/rig-file.md)")->capture_default_str();
  cmd->add_option("--out", args->out, "Plan folder to write")->required();
  cmd->add_flag("--force", args->force, "Replace a plan already in the folder");
  cmd->add_option("--setups", args->setups,
                  "Also write the plan's set-ups as JSON lines (what a hook receives) to FILE");
  cmd->callback([args] { RunPlan(*args); });
}

}  // namespace

MSMCAL_REGISTER_COMMANDS(/*order=*/4, AddPlanCommand);

}  // namespace msmcal::app
