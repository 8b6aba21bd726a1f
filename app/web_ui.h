#pragma once
// `--ui web[:PORT]` of `msmcal demo --guided` and `msmcal session run` (issue 19): the live view
// (sessions/live_view) wired into a session: its server, its WebOperator in front of the
// session's inner operator (the demo's simulated world; none in the lab), and the orchestrator's
// observers (gate decisions, the preview pump's live frames, the rig's state, progress lines).

#include <CLI/CLI.hpp>
#include <memory>
#include <string>

#include "processing/dataset/recording.h"
#include "sessions/live_view/live_server.h"
#include "sessions/live_view/live_view.h"
#include "sessions/live_view/web_operator.h"
#include "sessions/orchestrator/orchestrator.h"

namespace msmcal::app {

struct WebUiArgs {
  std::string ui;    // "" (the console) | "web" | "web:PORT"
  std::string bind;  // --ui-bind ADDR: serve on another address than 127.0.0.1 (token required)
  bool enabled() const { return !ui.empty(); }
};
// Adds --ui and --ui-bind to `command`.
void AddWebUiOptions(CLI::App* command, WebUiArgs* args);

class WebUi {
 public:
  // Validates the arguments (throws std::invalid_argument naming the option); starts nothing.
  explicit WebUi(const WebUiArgs& args);
  ~WebUi();

  // Creates the view for `plan` (copied) and starts the server; prints the URL on stdout.
  // Throws std::runtime_error when the port cannot be bound. Called once. `gate`: the session's
  // quality gate (the overlay draws where it counts the dots).
  void Start(const dataset::Recording& plan, const std::filesystem::path& session_dir,
             const orchestrator::GateOptions& gate = {});
  // The operator for the session (after Start): a WebOperator in front of `inner` (may be null:
  // the lab, then options carry the MCU device and host clock).
  std::unique_ptr<orchestrator::RigOperator> MakeOperator(live_view::WebOperatorOptions options,
                                                          orchestrator::RigOperator* inner);
  // Chains the view's observers into `o` (may be called before Start: they forward once the
  // view exists).
  void Observe(orchestrator::OrchestratorOptions& o);
  void AddLogLine(const std::string& line);
  // The acquisition ended: done, or aborted (with the reason) in the safe state.
  void Finished(bool done, const std::string& message);
  std::string url() const;

 private:
  struct Shared;
  WebUiArgs args_;
  live_view::LiveServerOptions server_options_;
  std::shared_ptr<Shared> shared_;
};

}  // namespace msmcal::app
