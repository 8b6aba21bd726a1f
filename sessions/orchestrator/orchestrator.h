#pragma once
// The calibration session orchestrator (issue 9): rig check, step 1 (sliding plate poses),
// background Hall recording, step 2 (neutral, fast-only and scan frames with the actual Hall
// recording running), writing an interchange folder. Instruments are reached only through their
// interfaces, opened by an InstrumentFactory (sessions/orchestrator/instruments.h; by default the
// real drivers: SCPI to the two generators, GigE Vision or V4L2 to the camera, the serial link to
// the Hall MCU). The person at the rig is a RigOperator.
//
// Safe state: in the rig check a signal switches every generator opened so far off (the
// driver's registry, gen::SafeStateOfOpenGenerators); from the moment a generator output may be
// on, a SafeStateGuard switches every output off on SIGINT/SIGTERM (then the process ends with
// 128 + signo), on any exception and at the end of the run; the session log (session_log.txt in
// the folder) records what happened. When that safe state is not confirmed and a watchdog is
// armed, the watchdog is asked to act (gen::HandOverToWatchdog) and RunSession throws
// gen::SafeStateNotConfirmed (exit status 76 or 75, docs/watchdog.md).
// Solving is not done here (see app/cmd_demo.cc): the result is a complete interchange folder.
//
// Journal: the session folder is also a session store (sessions/store: session.db beside the
// images). RunSession records as it goes — the plan, the instruments found, every log line as an
// event, the generators' SCPI transcript (also in generators_transcript.txt), each frame with its
// gate figures once its image is on disk (accepted and rejected), each completed Hall recording,
// and the state of every step — so that a session killed at any point (SIGKILL included) can be
// continued with `options.resume` (`msmcal resume DIR`): frames already recorded are not taken
// again, a Hall recording cut short is kept as hall/<name>.partial-<n>.csv and taken again.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "drivers/generator/rig_config.h"
#include "drivers/generator/rig_generators.h"
#include "drivers/generator/watchdog.h"
#include "drivers/hall_mcu/hall_sensor.h"
#include "processing/dataset/recording.h"
#include "sessions/orchestrator/instruments.h"
#include "sessions/orchestrator/quality_gate.h"
#include "sessions/orchestrator/rig_operator.h"
#include "sessions/orchestrator/session_events.h"

namespace msmcal::store {
class Clock;
}

namespace msmcal::orchestrator {

// One gate decision on one grabbed frame, for observers (guided previews and live figures,
// sweep progress). Pointers are valid during the call only.
struct FrameReport {
  int step = 1;      // 1 or 2
  size_t index = 0;  // into the plan's step1 / step2 list
  size_t count = 0;  // frames in that step
  std::string file;  // as in session.yaml ("step1/0003.png")
  int attempt = 0;   // 0-based gate attempt (a frame gets max_gate_attempts)
  bool accepted = false;
  bool final = false;                // true: this decision stands (accepted, or the last attempt)
  const GateResult* gate = nullptr;  // what the gate found (null when the gate is off)
  const cv::Mat* image = nullptr;    // the frame as grabbed
};
using FrameObserver = std::function<void(const FrameReport&)>;

// A frame streamed while the orchestrator waits for the person at the rig or for the generators
// (the live view, issue 19): during every RigOperator::Prepare* call made once the camera
// streams, and during each frame's generator change before it (a new laser pattern, the drives
// switched and their settle), a pump thread grabs the free-running camera's frames and hands
// each to OrchestratorOptions::on_live_frame. The pump is stopped and joined before the
// orchestrator grabs again itself; a live frame is never a session frame and is never gated
// nor journalled. Pointers are valid during the call only.
struct LiveFrame {
  // The frame the operator is setting up: step 1 or 2 and its index into the plan's step1 /
  // step2 list; step 0 while a Hall recording is set up (no frame follows directly).
  int step = 0;
  size_t index = 0;
  const cv::Mat* image = nullptr;  // as grabbed (FrameToMat: Mono8/Mono16/RGB8)
  int64_t host_timestamp_ns = 0;   // camera::FrameInfo::host_timestamp_ns
  // The Hall recording running while this frame was streamed ("background"), empty when none:
  // known from the pump itself, so its first frame already says so.
  std::string hall_recording;
};
// Called on the pump thread, never concurrently with itself; it may run concurrently with the
// ProgressFn and the RigStatusObserver (the orchestrator's thread) but not with on_frame (the
// pump is stopped while frames are taken). It should return quickly (the camera's frames queue
// up meanwhile); exceptions it throws are swallowed (the live view never stops a session).
using LiveFrameObserver = std::function<void(const LiveFrame&)>;

// The rig's state as the orchestrator knows it, for observers (the live view's rig panel): sent
// when the outputs go on or off and, during a Hall recording, about twice a second.
struct RigStatus {
  bool outputs_on = false;        // generator outputs (drive coils, laser trigger) may be on
  bool reference_locked = false;  // unit 2 verified locked to unit 1's 10 MHz reference
  std::string hall_recording;     // "background" | "actual" | "" (no recording running)
  uint64_t hall_readings = 0;     // readings delivered in that recording so far
  uint64_t hall_lost = 0;         // readings lost on the link + dropped (recorder queue full)
  double hall_seconds = 0;        // MCU time the recording covers so far
};
// Called from the orchestrator's thread or, during a Hall recording, from a status thread of its
// own (never concurrently with itself).
using RigStatusObserver = std::function<void(const RigStatus&)>;

// Step names recorded in the journal, in order.
inline constexpr const char* kStepRigCheck = "rig_check";
inline constexpr const char* kStep1 = "step1";
inline constexpr const char* kStepBackground = "hall_background";
inline constexpr const char* kStep2 = "step2";  // with the actual Hall recording
inline constexpr const char* kStepSessionWritten = "session_written";

struct OrchestratorOptions {
  std::filesystem::path out_dir;       // created; must be empty or absent
  gen::RigGeneratorConfig generators;  // unit addresses, limits and the signals to apply
  // How the instruments are opened; null: the drivers (MakeDriverInstruments()).
  std::shared_ptr<InstrumentFactory> instruments;
  // The camera, as InstrumentFactory::OpenCamera reads it: a GigE Vision address (opened by
  // address only) or a V4L2 device ("/dev/video0", "v4l2:/dev/video0").
  std::string camera = "127.0.0.1";
  double camera_frame_rate_hz = 10.0;
  std::optional<double>
      camera_exposure_us;        // unset: the camera's own (rig file: camera.exposure_us)
  int frame_timeout_ms = 10000;  // per NextFrame
  int max_stale_frames = 50;     // frames discarded while waiting for the new setup
  int max_gate_attempts = 2;     // fresh frames tried per frame before it is rejected
  // Settle time after a drive output is switched (the resonant fast axis needs many cycles to
  // reach its steady amplitude): this many pattern periods of generator time are waited for
  // (on the host's steady clock, from the OUTPut command's reply) before the operator is asked
  // for the frame, so that only frames exposed after the settle count (the operator's
  // FrameShowsCurrentSetup then rules out frames in flight). 0: no wait.
  double drive_settle_periods = 5.0;
  bool run_quality_gate = true;
  GateOptions gate;
  hall_mcu::HallMcuOptions mcu;  // device is asked from the operator per recording
  uint16_t mcu_rate_hz = 1000;
  // Background recording length (MCU time); 0: until the MCU reports the end of its data (mock
  // and replay sources only; a real MCU streams forever). The actual recording runs for the whole
  // of step 2 and is stopped when step 2 ends, but not before it covers actual_min_seconds of MCU
  // time (or the MCU reports the end of its data): a step 2 that is quick, or that a resume finds
  // already recorded (its actual recording cut short by a fault), still gets a recording that
  // long (rig file step2.hall_actual_min_s). 0: no minimum.
  double background_seconds = 12.0;
  double actual_min_seconds = 0;
  // Every Hall batch passes through it on the recorder's sink thread before the CSV writer
  // (empty: none): a tee, or a fault injected by a test (one that throws stands for a failing
  // sink, disk full on hall/). Observers that throw end the session in the safe state.
  std::function<void(const hall_mcu::HallBatch&)> hall_sink_hook;
  // Called after every gate decision (may be empty).
  FrameObserver on_frame;
  // Called with every typed event of the session (may be empty): frames decided, Hall
  // recordings, step states, the safe state (sessions/orchestrator/session_events.h).
  SessionEventObserver on_event;
  // Frames streamed while the operator is asked (see LiveFrame; may be empty: no pump).
  LiveFrameObserver on_live_frame;
  // The rig's state when it changes (see RigStatus; may be empty).
  RigStatusObserver on_rig_status;
  // Journal metadata (session.db meta keys rig_id, mirror_id, note, run.kind, config_yaml).
  // run_kind tells `msmcal resume` which rig to rebuild: "lab" (config_yaml = the rig
  // configuration), "demo" (config_yaml = the simulator options), "replay" (config_yaml names the
  // recorded session).
  std::string rig_id, mirror_id, note;
  std::string run_kind = "lab";
  std::string run_config_yaml;
  // Continue the session in out_dir (which must hold a session.db written by RunSession) instead
  // of starting one; `plan` must be the plan stored there (see LoadSessionPlan).
  bool resume = false;
  // The generator watchdog process (docs/watchdog.md), started before the first output goes on
  // and stood down once the outputs are confirmed off; it reports into session_log.txt if this
  // process dies first. Empty executable: none (in-process tests); msmcal arms itself.
  gen::WatchdogLaunch watchdog;
  const store::Clock* clock = nullptr;  // journal wall clock; null: the system clock
  std::string Validate() const;         // empty when valid; names field, value, constraint
};

// One line of progress ("step 1: frame 3/15 accepted").
using ProgressFn = std::function<void(const std::string& line)>;

struct FrameOutcome {
  std::string file;
  bool accepted = false;
  std::string reason;         // why it was rejected
  bool from_journal = false;  // recorded before a resume, not taken again
};

struct RigCheckResult {
  bool ok = false;
  std::vector<std::string> problems;  // one per problem found (empty when ok)
  std::vector<std::string> found;     // identities / formats / stream figures
  std::vector<std::pair<std::string, std::string>> instruments;  // (role, identity) found
};

struct SessionResult {
  RigCheckResult rig_check;
  std::vector<FrameOutcome> frames;
  uint64_t background_readings = 0, background_edges = 0;
  uint64_t actual_readings = 0, actual_edges = 0;
  bool safe_state_confirmed = false;
  std::filesystem::path folder;
  bool resumed = false;
  std::vector<std::string> partial_hall_files;  // recordings cut short, kept (resume)
};

// The generator plan for a session: drives and clock from the configuration's signal design, and
// the laser trigger arb rebuilt from the session plan's trigger table (so that the laser fires at
// exactly the times session.yaml records, to within half an arb sample). Throws
// std::invalid_argument when the plan's pattern period differs from the configured drive's or
// the table violates the trigger limits (duty).
gen::RigSignalPlan PlanSessionSignals(const gen::RigSignalsConfig& config,
                                      const dataset::Recording& plan);

// What the generators play for one frame (docs/lab-path.md "Per-frame signals"): the drive outputs
// and the laser pattern (plan trigger ids j; the arb is rebuilt from exactly these). The clock
// (unit 2 ch2) and the laser output stay on, and all four channels keep the time base of the
// start trigger.
struct FrameSignals {
  bool fast_on = false, slow_on = false;
  std::vector<int> triggers;
  bool operator==(const FrameSignals& o) const {
    return fast_on == o.fast_on && slow_on == o.slow_on && triggers == o.triggers;
  }
  bool operator!=(const FrameSignals& o) const { return !(*this == o); }
};
// Step 1 (MSM not mounted): drives off, one pulse per period (the plan's first trigger), so
// the plate shows one dot per unblocked beam.
FrameSignals Step1Signals(const dataset::Recording& plan);
// Step 2: neutral as step 1; fast_only: fast drive on, the frame's triggers; scan: both drives,
// the frame's triggers.
FrameSignals Step2Signals(const dataset::Recording& plan, const dataset::Step2Frame& frame);
// The background Hall recording: both coils driven, one pulse per period.
FrameSignals BackgroundSignals(const dataset::Recording& plan);
// The generator plan with the laser arb of `frame.triggers` (same timing rules as
// PlanSessionSignals: the laser fires at the plan's t_s to within half a sample). Throws
// std::invalid_argument for a trigger id not in the table or an empty pattern.
gen::RigSignalPlan PlanFrameSignals(const gen::RigSignalsConfig& config,
                                    const dataset::Recording& plan, const FrameSignals& frame);

// The rig check alone (what RunSession does first): identifies both generators, resets them and
// checks that unit 2 locks to unit 1's 10 MHz reference, checks the signal design against the
// limits, opens the camera (sensor size against `plan`'s camera when given, Mono8),
// identifies the Hall MCU on `mcu_device` and asks for a status frame. Leaves every generator
// output off. Never throws for instrument problems: they are listed in the result.
RigCheckResult CheckRigOnly(const OrchestratorOptions& options, const dataset::Recording* plan,
                            const std::string& mcu_device);

class RigCheckError : public std::runtime_error {
 public:
  RigCheckError(const RigCheckResult& result);
  const RigCheckResult& result() const { return result_; }

 private:
  RigCheckResult result_;
};

// Runs the whole acquisition. `plan` holds the session's boards, beams, drive, clock, trigger
// table and frame lists (images and Hall recordings are what this acquires); it is written as
// session.yaml/camera.yaml last, once everything else is in place. Rejected frames are left out
// of the written session, listed in the result and kept as rejected/<step>_<name>.png. Throws
// RigCheckError (the list of problems) when the rig check fails, std::runtime_error for other
// failures (after the safe state).
SessionResult RunSession(const OrchestratorOptions& options, const dataset::Recording& plan,
                         RigOperator& rig_operator, const ProgressFn& progress);

// What a journal says about a session, for `msmcal resume` and the sweep runner.
struct SessionJournalState {
  bool exists = false;    // a session.db is there
  bool complete = false;  // session.yaml written (kStepSessionWritten done)
  std::string run_kind;   // OrchestratorOptions::run_kind
  std::string run_config_yaml;
  std::string rig_id, mirror_id, note;
  std::vector<std::pair<std::string, std::string>> steps;  // (name, pending|running|done)
  size_t frames_recorded = 0;
};
SessionJournalState ReadSessionJournal(const std::filesystem::path& dir);
// The plan RunSession stored in `dir`'s journal. Throws std::runtime_error naming the folder.
dataset::Recording LoadSessionPlan(const std::filesystem::path& dir);

}  // namespace msmcal::orchestrator
