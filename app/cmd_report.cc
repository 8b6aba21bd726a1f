// `msmcal report DIR`: (re)writes DIR/report.html. A session folder (session.yaml or results/)
// gets its session report (the verdict, tables, plots, provenance: sessions/report); a sweep
// folder (sweep.yaml) gets the sweep report across its points, after (re)writing every point's own
// report. The session's provenance stored in results/summary.json is kept; the command line that
// regenerated the report is added to it.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>

#include "app/command_registry.h"
#include "app/rig_sweep_parameters.h"
#include "sessions/report/session_report.h"
#include "sessions/report/sweep_report.h"
#include "sessions/sweep/sweep_plan.h"
#include "simulation/truth/truth_comparison.h"

namespace msmcal::app {
namespace {

namespace fs = std::filesystem;

struct ReportArgs {
  std::string dir;
  bool quiet = false;
};

void RunReport(const ReportArgs& args) {
  const fs::path dir = fs::absolute(args.dir);
  if (!fs::is_directory(dir)) throw std::runtime_error(dir.string() + ": not a folder");
  const report::ReportOptions options{/*session_process=*/false, {}};
  if (fs::exists(dir / "sweep.yaml")) {
    // A simulated sweep's or a rig sweep's plan (its base: holds the rig file's fields).
    const sweep::SweepPlan plan = LoadStoredSweepPlan(dir / "sweep.yaml").plan;
    const report::SweepReport r =
        report::WriteSweepReport(dir, plan, sweep::ExpandPoints(plan), simulation::SimTruthSource(),
                                 /*write_point_reports=*/true, options);
    if (!args.quiet) std::printf("%s", r.text.c_str());
    std::printf("sweep report: %s (%d of %d point reports written)\n",
                (dir / "report.html").string().c_str(), r.reported, r.points);
    return;
  }
  if (!fs::exists(dir / "session.yaml") && !fs::exists(dir / "results"))
    throw std::runtime_error(dir.string() +
                             ": neither a session folder (session.yaml, results/) nor a sweep "
                             "folder (sweep.yaml)");
  const report::SessionReport r =
      report::WriteSessionReport(dir, options, simulation::SimTruthSource());
  if (!args.quiet) std::printf("%s", r.text.c_str());
  std::printf("report: %s\n", (dir / "report.html").string().c_str());
}

void AddReportCommands(CLI::App& app) {
  auto args = std::make_shared<ReportArgs>();
  auto* cmd = app.add_subcommand(
      "report",
      "(Re)write DIR/report.html: a session folder's calibration report (verdict, tables, "
      "interactive plots, provenance) or a sweep folder's report across its points");
  cmd->add_option("DIR", args->dir, "Session folder or sweep folder")->required();
  cmd->add_flag("--quiet", args->quiet, "Print only the report's path");
  cmd->callback([args] { RunReport(*args); });
}

}  // namespace

MSMCAL_REGISTER_COMMANDS(/*order=*/45, AddReportCommands);

}  // namespace msmcal::app
