#pragma once
// The watchdog: a separate process that switches the generators' outputs off when the process
// driving them ends without saying so (SIGKILL, an OOM kill, a crash), which no in-process guard
// (SafeStateGuard) can do. docs/watchdog.md has the design and the 33500's connection behaviour.
//
// Parent side: Watchdog::Start() spawns `launch.executable launch.args... <watchdog arguments>`
// (msmcal: itself with the hidden subcommand `watchdog`) before the first OUTP ON, in its own
// session (setsid: the terminal's Ctrl-C and hangup go to msmcal, whose SafeStateGuard handles
// them), with exactly these descriptors: 0 and 1 on /dev/null, 2 inherited, 3 the read end of the
// life pipe, 4 the write end of the ready pipe; every other descriptor of the parent (the
// generators' sockets included) is closed in the child, so the kernel closes the dead parent's
// connections and the watchdog can connect. The life pipe's write end exists only in the parent
// and is close-on-exec, so no other child holds it.
//
// Child side: RunWatchdog() waits, without polling, on the life pipe and on a pidfd of the
// parent. A stand-down byte on the pipe ends it without a word to any generator; EOF on the pipe
// or the parent's exit without that byte fires it: it connects to every generator (in parallel,
// retrying while the port refuses or the old connection is still held, bounded by
// retry_window_ms), runs the driver's safe state (OUTP1 OFF;:OUTP2 OFF, confirmed with
// OUTP1?;:OUTP2?), appends one line per generator to the log file and exits with a status that
// says whether every generator confirmed.

#include <sys/types.h>

#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "drivers/generator/rig_config.h"
#include "drivers/generator/safe_state.h"

namespace msmcal::gen {

// Exit status of the watchdog process.
enum WatchdogExit : int {
  kWatchdogStoodDown = 0,        // told to stand down: no generator was contacted
  kWatchdogUsage = 2,            // bad arguments (message on stderr)
  kWatchdogFiredConfirmed = 10,  // parent gone; every generator confirmed its outputs off
  kWatchdogFiredUnconfirmed = kExitSafeStateUnconfirmed,  // parent gone; some did not confirm
};

struct WatchdogGenerator {
  std::string name;  // as in the rig configuration ("unit1")
  std::string host;
  int port = 5025;
};

struct WatchdogConfig {
  std::vector<WatchdogGenerator> generators;
  // File the watchdog appends its report to when it fires (opened O_APPEND, one write per line;
  // the session's session_log.txt). Empty: the report goes to stderr only.
  std::string log_path;
  // How long the watchdog keeps trying one generator (connect refused, connection not served
  // because the instrument still holds the dead process's socket, no reply), and the deadline of
  // one connect or reply within that window.
  int retry_window_ms = 1500;
  int attempt_timeout_ms = 400;
  std::string Validate() const;  // empty when valid; names the field, its value, the constraint
};

// The watchdog configuration for the rig's two units (addresses only: the watchdog never
// configures anything, it only switches outputs off).
WatchdogConfig WatchdogConfigFor(const RigGeneratorConfig& rig, const std::string& log_path);

// What the parent hands the watchdog process on its command line.
struct WatchdogInvocation {
  WatchdogConfig config;
  int control_fd = 3;  // life pipe, read end
  int ready_fd = 4;    // the watchdog writes one byte here once it is armed
  pid_t parent_pid = 0;
};

// The watchdog's arguments (after the launcher's own): --control-fd N --ready-fd N --parent-pid P
// --retry-ms MS --attempt-ms MS [--log FILE] --generator NAME=HOST:PORT ...
std::vector<std::string> FormatWatchdogArguments(const WatchdogInvocation& invocation);
// Inverse of FormatWatchdogArguments. Throws std::invalid_argument naming the argument, its value
// and what was expected; validates the configuration.
WatchdogInvocation ParseWatchdogArguments(const std::vector<std::string>& args);

// What the watchdog did with one generator when it fired.
struct WatchdogOutcome {
  WatchdogGenerator generator;
  bool confirmed = false;  // OUTP1?;:OUTP2? replied 0;0
  int attempts = 0;
  int64_t elapsed_ms = 0;  // from firing to confirmation (or to giving up)
  std::string last_error;  // why the last attempt failed (empty when confirmed)
};

// Connects to every generator in parallel and runs the Keysight driver's safe state, retrying
// within config.retry_window_ms. Never throws.
std::vector<WatchdogOutcome> SwitchOutputsOff(const WatchdogConfig& config);
// One report line per outcome, as the watchdog appends it to the log; `asked`: the parent was
// alive and asked the watchdog to act (Watchdog::ActNow), else it ended without a stand-down.
std::string FormatWatchdogReport(const WatchdogOutcome& outcome, pid_t parent_pid,
                                 bool asked = false);

// The watchdog process's main (a WatchdogExit value). Ignores SIGINT, SIGHUP, SIGQUIT and
// SIGPIPE; SIGTERM and SIGKILL still end it.
int RunWatchdog(const WatchdogInvocation& invocation);

class Watchdog;

// What became of a safe state handed over to the watchdog.
struct WatchdogHandOver {
  bool confirmed = false;  // the watchdog confirmed every output of every generator off
  int watchdog_status = -1;
  int exit_status = kExitSafeStateUnconfirmed;  // kExitSafeStateByWatchdog when confirmed
  std::string text;                             // one line, loud, for the log and stderr
};
// This process's own safe state was not confirmed: closes every generator connection of this
// process (DisconnectOpenGenerators), asks the watchdog to act (Watchdog::ActNow) and waits for
// its verdict. The generators are the watchdog's from then on: this process must not drive them.
WatchdogHandOver HandOverToWatchdog(Watchdog& watchdog);

// How to start the watchdog process. An empty executable means no watchdog.
struct WatchdogLaunch {
  std::string executable;
  std::string argv0;              // argv[0] (defaults to executable)
  std::vector<std::string> args;  // before the watchdog arguments (e.g. the subcommand)
  bool enabled() const { return !executable.empty(); }
};

// This executable (/proc/self/exe, valid even if the file was replaced since) with the hidden
// subcommand `subcommand`, which must call RunWatchdog(ParseWatchdogArguments(rest)).
WatchdogLaunch SelfWatchdogLaunch(const std::string& argv0, const std::string& subcommand);

// The parent's handle on a running watchdog. Thread-safe (StandDown may run from the safe-state
// watcher thread of SafeStateGuard).
class Watchdog {
 public:
  // Spawns the watchdog and returns once it is armed (it has its pidfd on this process and
  // ignores terminal signals). Throws std::runtime_error naming the executable and what went wrong
  // when it cannot be started or does not report armed within 5 s.
  static std::unique_ptr<Watchdog> Start(const WatchdogLaunch& launch,
                                         const WatchdogConfig& config);
  // Without StandDown(): closes the life pipe, so the watchdog fires (nobody confirmed the safe
  // state), and waits for it to finish (bounded by the retry window + 2 s).
  ~Watchdog();
  Watchdog(const Watchdog&) = delete;
  Watchdog& operator=(const Watchdog&) = delete;

  // Call once this process has confirmed every output off: the watchdog exits without
  // contacting any generator. Returns its exit status (kWatchdogStoodDown), or -1 if it had to
  // be killed or could not be reaped. Idempotent (later calls return the first status).
  int StandDown();
  // Call when this process's own safe state was not confirmed (it is alive, the watchdog would
  // otherwise wait for its end): the watchdog fires now, as on the parent's death, and this
  // waits for its verdict (bounded by the retry window + 2 s). Returns its exit status
  // (kWatchdogFiredConfirmed, kWatchdogFiredUnconfirmed; kWatchdogStoodDown if it had been stood
  // down already; -1 if it had to be killed). Close this process's generator connections first
  // (HandOverToWatchdog does both).
  int ActNow();
  pid_t pid() const { return pid_; }

 private:
  Watchdog(pid_t pid, int life_fd, int pidfd, int wait_ms);
  int Reap(int timeout_ms);  // with mu_ held

  std::mutex mu_;
  pid_t pid_;
  int life_fd_;  // write end of the life pipe (-1 once closed)
  int pidfd_;
  int fire_wait_ms_;
  bool reaped_ = false;
  int status_ = -1;
};

}  // namespace msmcal::gen
