#pragma once
// The parts of a session run shared by `msmcal demo`, `msmcal resume`, `msmcal sweep` and
// `msmcal replay`: a simulated acquisition on the demo rig (mocks in this process, real drivers),
// and the steps after acquisition (solve, Hall calibration and prediction, sessions/results/
// finish_steps.h) run in this process, with their results recorded into the session's journal.

#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mocks/rig/sim_options.h"
#include "processing/dataset/recording.h"
#include "sessions/orchestrator/orchestrator.h"
#include "sessions/orchestrator/rig_operator.h"
#include "sessions/setup/setup.h"

namespace msmcal::orchestrator {
class HookOperator;
}

namespace msmcal::app {

struct DemoAcquisitionOptions {
  sim::SimOptions sim;
  std::string camera_address = "127.0.0.1";
  double camera_frame_rate_hz = 20.0;
  bool resume = false;  // continue the session journalled in the folder
  // Who stands at the rig. Empty: the demo rig's SimulatedWorld itself. Otherwise called with
  // the world and the plan; the returned operator is used for the session (e.g. the guided
  // console operator in front of the world).
  std::function<std::unique_ptr<orchestrator::RigOperator>(orchestrator::RigOperator& world,
                                                           const dataset::Recording& plan)>
      make_operator;
  // Last changes to the orchestrator options before the run (observers, gate options, ...).
  std::function<void(orchestrator::OrchestratorOptions&)> adjust_options;
  orchestrator::ProgressFn progress;
  std::string note = "msmcal demo";
  // `msmcal demo --generator-ports P1,P2`: the generators are served by another process on
  // 127.0.0.1 (e.g. `msmcal mock generators --fault ...`); 0, 0: the demo rig serves its own.
  int external_generator_port1 = 0, external_generator_port2 = 0;
  // `msmcal demo --mock-fault`: faults of the demo rig's own mocks, docs/fault-campaign.md:
  // "camera:lost@N" (the camera is unplugged after N frames), "mcu-background:SPEC",
  // "mcu-actual:SPEC" (SPEC as `msmcal mock mcu --fault`: flip@N, drop@N, reset@N, stall@N[:ms]).
  // Not journalled: a resumed session meets no fault.
  std::vector<std::string> mock_faults;
  // Called with the plan and the session folder once the rig is up, before the session runs
  // (e.g. to start the live view; may be empty).
  std::function<void(const dataset::Recording& plan, const std::filesystem::path& out)> before_run;
};

// Guided demo: a ConsoleOperator on stdin/stdout in front of the simulated world (pose hints from
// the simulator's step-1 options), live quality figures and annotated previews (previews/).
void MakeGuided(DemoAcquisitionOptions& acq);

class WebUi;
// Guided demo on the live view's page (`--ui web`, app/web_ui.h): as MakeGuided (live figures
// printed, previews written), but the operator is the web page's WebOperator in front of the
// simulated world, and the page gets the camera, the figures and the rig's state. `web` must
// outlive the acquisition; its view is started when the plan is known.
void MakeGuidedWeb(DemoAcquisitionOptions& acq, WebUi* web);

// Starts the demo rig for `options.sim`, runs (or resumes) the session into `out` with run_kind
// "demo" (the simulator options are journalled, so `msmcal resume` can rebuild the rig), and
// writes the simulator's truth to out/truth. Throws what RunSession throws.
orchestrator::SessionResult RunDemoAcquisition(const std::filesystem::path& out,
                                               const DemoAcquisitionOptions& options);

// A session on the real rig (run_kind "lab"), guided: the operator at the terminal is told what
// to do before every frame and Hall recording (orchestrator::ConsoleOperator on stdin/stdout, no
// simulated world behind it), sees the live quality figures, and every accepted frame's annotated
// preview goes to previews/.
struct LabAcquisitionOptions {
  std::string rig_yaml;        // the rig configuration's text (generators:, hall_mcu:)
  std::string rig_origin;      // its file name, for messages
  std::string camera_address;  // GigE Vision address or V4L2 device (OrchestratorOptions::camera)
  std::string mcu_device;      // empty: the rig configuration's hall_mcu.device
  double camera_frame_rate_hz = 10.0;
  dataset::Recording plan;  // session.yaml + camera.yaml of the plan (no images)
  std::string rig_id, mirror_id, note;
  bool resume = false;
  int input_fd = 0, output_fd = 1;  // the operator's terminal
  WebUi* web = nullptr;  // not null: the operator is the live view's page (`--ui web`) instead
  orchestrator::ProgressFn progress;
  // From the rig file (sessions/rig) when the session has one:
  std::optional<double> camera_exposure_us;
  double background_seconds = 12.0;        // step2.hall_background_s
  double actual_min_seconds = 0;           // step2.hall_actual_min_s
  std::vector<setup::PoseGeometry> poses;  // sliding_plate: the set-ups' pose hints
  // Who changes the rig: "console" (the guided terminal) or "hook:CMD" (CMD through /bin/sh -c
  // with each set-up's JSON on stdin, docs/lab-path.md). ParseOperatorSpec checks it.
  std::string operator_spec = "console";
  int hook_timeout_ms = 600'000;
  // A rig sweep's point (docs/lab-path.md "Rig sweeps"): the session folder whose step 1 and
  // background Hall recording this session reuses (orchestrator::SeedSessionFromReference; `plan`
  // from PlanWithReferenceStep1). Nobody is at the rig (orchestrator::FixedRigOperator: MSM
  // mounted, camera at C2, never a prompt); a hook receives only the truth request at the end.
  // No live figures, no previews. Empty: a whole guided session.
  std::filesystem::path reference;
  // Last changes to the orchestrator options before the run (a sweep's event observer).
  std::function<void(orchestrator::OrchestratorOptions&)> adjust_options;
};
// "console" -> empty; "hook:CMD" -> CMD. Throws std::invalid_argument naming --operator.
std::string ParseOperatorSpec(const std::string& spec);
// The final truth request through a hook after a session (a failed one is a warning: the
// session is complete).
void SendTruthRequest(orchestrator::HookOperator& hook, const std::filesystem::path& out,
                      const orchestrator::ProgressFn& progress);
// The same without a session's hook operator: runs `hook_command` once with the truth request
// for out/truth (a rig sweep's point). A failing hook is a warning through `progress` (may be
// empty); returns true when the hook exited 0.
bool SendTruthRequest(const std::string& hook_command, int timeout_ms,
                      const std::filesystem::path& out, const orchestrator::ProgressFn& progress);
// Runs (or resumes) the session into `out`. The journal keeps what a resume needs: the rig
// configuration's text, the camera address, the MCU device.
orchestrator::SessionResult RunLabAcquisition(const std::filesystem::path& out,
                                              const LabAcquisitionOptions& options);
// The options a lab session journalled (for `msmcal resume`): everything but the plan, the
// terminal and the progress callback. Throws std::runtime_error naming the folder.
LabAcquisitionOptions LabOptionsFromJournal(const std::filesystem::path& dir,
                                            const std::string& config_yaml);
// Reads a plan folder: session.yaml and camera.yaml as the interchange format defines them (the
// frame lists name the images to take; none need exist). Throws naming the file and field.
dataset::Recording ReadPlanFolder(const std::filesystem::path& dir);

struct FinishOptions {
  bool skip_done = true;  // skip steps whose outputs exist (resume)
  bool echo = true;  // print each step as its command and its output; else into DIR/finish_log.txt
  int threads = 2;
};
struct FinishResult {
  bool solved = false, hall_calibrated = false, hall_predicted = false;
  bool ok() const { return solved && hall_calibrated && hall_predicted; }
};

// The steps after a written session (session.yaml present), in this process, as
// `msmcal solve DIR --threads N`, `msmcal hall calibrate DIR` and `msmcal hall predict`
// (results/hall_poses.csv) run them. `notes` gets "msmcal <command>: ok" or
// "msmcal <command>: FAILED: <the step's error>" per step run. With skip_done, a
// step whose output exists (results/summary.json, results/hall_model.yaml,
// results/hall_poses.csv) is not run again. When the folder has a journal (session.db), the
// results/ files are stored into it and the steps "solve" / "hall_calibration" recorded.
FinishResult FinishSession(const std::filesystem::path& dir, const FinishOptions& options,
                           std::vector<std::string>* notes);

}  // namespace msmcal::app
