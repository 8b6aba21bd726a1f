// `msmcal demo [--out DIR] [--seed N] [--config SIM.yaml] [--camera-address ADDR] [--store DIR]`:
// the first command of the README. Starts the mock generators (loopback SCPI), the mock GigE Vision
// camera (rendering the rig simulator's scene for the current setup) and a mock Hall MCU (pty),
// runs a complete calibration session through the real drivers and the orchestrator, then solves
// (`msmcal solve`), calibrates the Hall sensor (`msmcal hall calibrate`, `msmcal hall predict`) in
// this process (sessions/results/finish_steps.h), and prints the verdict and the Table I/II-style
// report compared with the simulator's truth; the HTML report (sessions/report: verdict, tables,
// interactive plots, provenance) goes to DIR/report.html.
// `--guided`: the operator at the rig is prompted on this terminal for every set-up (the guided
// mode, docs/guided.md): the answers go to a ConsoleOperator in front of the simulated world;
// live gate figures are printed and annotated previews written to DIR/previews.
// `--guided --ui web[:PORT]`: the same session answered from the live view's page in a browser
// (app/web_ui.h, docs/guided.md "Live view") instead of this terminal.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/command_registry.h"
#include "app/session_flow.h"
#include "app/web_ui.h"
#include "drivers/generator/safe_state.h"
#include "mocks/rig/sim_options.h"
#include "sessions/interchange/interchange_io.h"
#include "sessions/orchestrator/orchestrator.h"
#include "sessions/report/session_report.h"
#include "sessions/store/session_store.h"
#include "sessions/store/transfer.h"
#include "simulation/truth/truth_comparison.h"

namespace msmcal::app {
namespace {

namespace fs = std::filesystem;

struct DemoArgs {
  std::string out = "msmcal-demo";
  std::string config;
  std::optional<uint64_t> seed;  // none: the config's
  std::string camera_address = "127.0.0.1";
  std::string store;  // session store folder to import the finished session into (optional)
  bool guided = false;
  std::vector<int> generator_ports;      // --generator-ports P1,P2 (docs/fault-campaign.md)
  std::vector<std::string> mock_faults;  // --mock-fault
  WebUiArgs web;                         // --ui web[:PORT], --ui-bind (with --guided)
};

// --guided: a ConsoleOperator on stdin/stdout in front of the simulated world (with the
// simulator's sliding-plate poses as hints), live gate figures and previews of accepted frames.

void RunDemo(const DemoArgs& args) {
  const auto start = std::chrono::steady_clock::now();
  auto elapsed = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  DemoAcquisitionOptions acq;
  acq.sim = args.config.empty() ? sim::SimOptions{} : sim::LoadSimOptions(args.config);
  if (args.seed) acq.sim.seed = *args.seed;
  acq.camera_address = args.camera_address;
  if (args.generator_ports.size() == 2) {
    acq.external_generator_port1 = args.generator_ports[0];
    acq.external_generator_port2 = args.generator_ports[1];
  }
  acq.mock_faults = args.mock_faults;
  const fs::path out = fs::absolute(args.out);
  if (fs::exists(out) && !fs::is_empty(out))
    throw std::runtime_error(out.string() +
                             ": exists and is not empty (choose another --out, or continue an "
                             "interrupted session with `msmcal resume " +
                             out.string() + "`)");
  // Checked before the run, not found after it: the store is created new.
  if (!args.store.empty() && fs::exists(args.store))
    throw CLI::ValidationError("--store", args.store +
                                              " already exists (the finished session is imported "
                                              "into a new session-store folder)");
  if (args.web.enabled() && !args.guided)
    throw CLI::ValidationError("--ui", "--ui web needs --guided");

  std::printf(
      "msmcal demo: starting the mock rig (2 generators on loopback SCPI, GigE Vision "
      "camera on %s, Hall MCU on a pty)...\n",
      acq.camera_address.c_str());
  std::fflush(stdout);
  std::unique_ptr<WebUi> web;
  if (args.web.enabled()) web = std::make_unique<WebUi>(args.web);
  std::vector<std::string> notes;
  acq.progress = [&](const std::string& line) {
    std::printf("[%6.1f s] %s\n", elapsed(), line.c_str());
    std::fflush(stdout);
    notes.push_back(line);
    if (web) web->AddLogLine(line);
  };
  if (web)
    MakeGuidedWeb(acq, web.get());
  else if (args.guided)
    MakeGuided(acq);
  orchestrator::SessionResult session;
  try {
    session = RunDemoAcquisition(out, acq);
  } catch (const std::exception& e) {
    if (web) web->Finished(/*done=*/false, e.what());
    throw;
  }
  if (web)
    web->Finished(/*done=*/true, "acquisition complete: solving, then the report (see the log)");
  size_t rejected = 0;
  for (const auto& f : session.frames) rejected += f.accepted ? 0 : 1;
  std::printf(
      "[%6.1f s] acquisition done: %zu frames (%zu rejected), Hall %llu + %llu readings; "
      "truth written to %s/truth\n",
      elapsed(), session.frames.size(), rejected,
      static_cast<unsigned long long>(session.background_readings),
      static_cast<unsigned long long>(session.actual_readings), out.string().c_str());

  const FinishResult finished = FinishSession(out, FinishOptions{}, &notes);
  if (!args.store.empty()) {
    store::ImportOptions io;
    io.rig_id = "demo-rig (mock instruments)";
    io.mirror_id = "simulated MSM, seed " + std::to_string(acq.sim.seed);
    io.note = "msmcal demo";
    const store::SystemClock clock;
    auto stored = store::ImportInterchange(out, args.store, clock, io);
    if (fs::exists(out / "results")) store::PutResultsFromFolder(*stored, out / "results");
    std::printf("session stored in %s\n", args.store.c_str());
    notes.push_back("session stored in " + args.store);
  }
  const report::SessionReport report = report::WriteSessionReport(
      out, {/*session_process=*/true, notes}, simulation::SimTruthSource());
  std::printf("\n%s", report.text.c_str());
  std::printf("\nreport: %s   (total %.1f s)\n", (out / "report.html").string().c_str(), elapsed());
  if (web) web->AddLogLine("report: " + (out / "report.html").string());
  if (!finished.ok()) throw CLI::RuntimeError(1);
}

void AddDemoCommands(CLI::App& app) {
  auto args = std::make_shared<DemoArgs>();
  auto* demo = app.add_subcommand(
      "demo", "Run a complete simulated calibration through the real drivers and mock instruments");
  demo->add_option("--out", args->out, "Session folder to create (must be absent or empty)");
  demo->add_option("--seed", args->seed, "Simulator seed (default: the config's)");
  demo->add_option("--config", args->config, "Simulator configuration (config/sim.yaml keys)");
  demo->add_option("--camera-address", args->camera_address,
                   "Address the mock GigE Vision camera serves on (port 3956)");
  demo->add_option("--store", args->store,
                   "Also import the finished session (with results/) into this new session-store "
                   "folder");
  demo->add_option("--generator-ports", args->generator_ports,
                   "Use generators served by another process on 127.0.0.1:P1 (unit 1) and P2 "
                   "(unit 2), e.g. `msmcal mock generators`, instead of the demo rig's own")
      ->delimiter(',')
      ->expected(2)
      ->check(CLI::Range(1, 65535));
  demo->add_option("--mock-fault", args->mock_faults,
                   "Inject a fault into the demo rig's own mocks (repeatable): camera:lost@N, "
                   "mcu-background:SPEC, mcu-actual:SPEC with SPEC flip@N|drop@N|reset@N|"
                   "stall@N[:ms] (docs/fault-campaign.md)");
  demo->add_flag("--guided", args->guided,
                 "Prompt for every rig set-up on this terminal (Enter / r / q), print live gate "
                 "figures and write annotated previews to DIR/previews");
  AddWebUiOptions(demo, &args->web);
  demo->callback([args] {
    const gen::OpenGeneratorsGuard signals;  // from the start: docs/watchdog.md
    RunDemo(*args);
  });
}

}  // namespace

MSMCAL_REGISTER_COMMANDS(/*order=*/5, AddDemoCommands);

}  // namespace msmcal::app
