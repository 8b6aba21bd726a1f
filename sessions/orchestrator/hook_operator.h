#pragma once
// `--operator hook:CMD` (docs/lab-path.md): a RigOperator for a rig changed by a program (a
// motorised rig, the twin's `msmcal mock hands`). Before each physical change (the set-ups of the
// plan, sessions/setup: the same grouping as the console's prompts) it runs CMD through
// `/bin/sh -c CMD` with the set-up's JSON (setup::SetupToJson, one line) on its standard input,
// and goes on when CMD exits 0. A non-zero exit, a hook killed by a signal, a hook that cannot
// be started or that runs longer than `timeout_ms` (then its process group is killed) throws
// HookFailed naming the command, the set-up and the status: RunSession then switches the
// generator outputs off (the safe state) and records the error.
//
// After the session, RequestTruth sends {"msmcal_setup": 1, "kind": "truth_request", "dir": ...}
// through the same hook (the twin's hands writes its ground truth there). A hook must exit 0 and
// ignore a `kind` it does not know.
//
// With an inner RigOperator (the demo's SimulatedWorld) the inner operator changes the rig after
// the hook confirmed and decides frame freshness; without one (the lab) frames count when they
// reached the host settle_ns after the hook returned (or after the frame's Prepare call for an
// unchanged set-up), as ConsoleOperator's lab mode.
//
// Thread safety: called from the orchestrator's thread only.

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "processing/dataset/recording.h"
#include "sessions/orchestrator/rig_operator.h"
#include "sessions/orchestrator/setup_operator.h"
#include "sessions/setup/setup.h"

namespace msmcal::orchestrator {

class HookFailed : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct HookOperatorOptions {
  std::string command;       // run as /bin/sh -c command
  int timeout_ms = 600'000;  // per call, > 0
  std::vector<setup::PoseGeometry> poses;
  // Lab only (no inner operator), as ConsoleOperatorOptions:
  std::string mcu_device;
  std::function<int64_t()> host_clock_ns;
  int64_t settle_ns = 300'000'000;
  int64_t exposure_ns = 0;  // as SetupWalkOptions::exposure_ns (0: host rule alone)
  // Optional: one line per hook call ("hook: set-up 3/24 (step1): exit 0").
  std::function<void(const std::string&)> log;
  std::string Validate(bool has_inner) const;  // empty when valid; names field, value, limit
};

// Runs `command` through /bin/sh -c with `input` on its stdin (posix_spawn, own process group).
// Returns the wait status; throws HookFailed when it cannot be started or outlives timeout_ms
// (it is killed then).
int RunHookCommand(const std::string& command, const std::string& input, int timeout_ms);
// "exit status 1" / "killed by signal 9 (Killed)".
std::string DescribeWaitStatus(int status);

class HookOperator : public SetupOperator {
 public:
  // `plan` and `inner` (may be null: lab) must outlive the operator. Throws std::invalid_argument
  // when options.Validate(inner != nullptr) fails.
  HookOperator(const dataset::Recording& plan, HookOperatorOptions options, RigOperator* inner);

  // Sends the truth request for `dir`; throws HookFailed as a set-up does.
  void RequestTruth(const std::filesystem::path& dir);

  int calls() const { return calls_; }  // hook runs that exited 0

 private:
  // Runs the hook with the set-up's JSON; throws HookFailed.
  void Present(const setup::Setup& s) override;
  void Run(const std::string& json, const std::string& what);

  HookOperatorOptions options_;
  int calls_ = 0;
};

}  // namespace msmcal::orchestrator
