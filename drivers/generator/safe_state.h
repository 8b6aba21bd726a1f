#pragma once
// Safe state on SIGINT, SIGTERM, SIGHUP and SIGQUIT and at scope exit; SIGPIPE ignored while
// a guard is active (a closed stdout must not kill the process before the safe state).
//
// Design (async-signal-safe): the signal handler only write()s the signal number to a self-pipe.
// A watcher thread blocks on the pipe, runs the safe-state action (ordinary code: sockets,
// mutexes, logging), then restores the default disposition and re-raises the signal, so the
// process ends with the status a shell expects (128 + signo). The action runs before any logging.
// If the action calls ReportUnconfirmed() (outputs not confirmed off), the process says so on
// stderr and exits with kExitSafeStateUnconfirmed instead. The destructor runs the action too
// (normal return and exception unwinding). One guard may be active per process.

#include <atomic>
#include <functional>
#include <thread>

namespace msmcal::gen {

// Exit status of a process whose safe state after a signal was not confirmed.
constexpr int kExitSafeStateUnconfirmed = 75;

class SafeStateGuard {
 public:
  // Installs handlers for SIGINT, SIGTERM, SIGHUP and SIGQUIT and ignores SIGPIPE. Throws
  // std::runtime_error if another guard is active or the pipe cannot be created.
  explicit SafeStateGuard(std::function<void()> safe_state);
  // Runs the action (unless already run by a signal), then restores the previous handlers.
  ~SafeStateGuard();
  SafeStateGuard(const SafeStateGuard&) = delete;
  SafeStateGuard& operator=(const SafeStateGuard&) = delete;

  // Blocks the calling thread until one of the signals arrives; the process then ends from the
  // watcher after the safe state (this never returns in that case).
  void WaitForSignal();
  // Leaves the outputs as they are at destruction (explicit `--detach`-style use).
  void Disarm() { armed_ = false; }
  // Called by the action when the outputs could not be confirmed off (see above).
  static void ReportUnconfirmed();

 private:
  std::function<void()> safe_state_;
  std::thread watcher_;
  std::atomic<bool> armed_{true};
};

}  // namespace msmcal::gen
