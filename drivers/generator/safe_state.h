#pragma once
// Safe state on SIGINT/SIGTERM and at scope exit.
//
// Design (async-signal-safe): the signal handler only write()s the signal number to a self-pipe.
// A watcher thread blocks on the pipe, runs the safe-state action (ordinary code: sockets,
// mutexes, logging), then restores the default disposition and re-raises the signal, so the
// process ends with the status a shell expects (128 + signo). The destructor runs the action too
// (normal return and exception unwinding). One guard may be active per process.

#include <atomic>
#include <functional>
#include <thread>

namespace msmcal::gen {

class SafeStateGuard {
 public:
  // Installs handlers for SIGINT and SIGTERM. Throws std::runtime_error if another guard is
  // active or the pipe cannot be created.
  explicit SafeStateGuard(std::function<void()> safe_state);
  // Runs the action (unless already run by a signal), then restores the previous handlers.
  ~SafeStateGuard();
  SafeStateGuard(const SafeStateGuard&) = delete;
  SafeStateGuard& operator=(const SafeStateGuard&) = delete;

  // Blocks the calling thread until SIGINT/SIGTERM arrives; the process then ends from the
  // watcher after the safe state (this never returns in that case).
  void WaitForSignal();
  // Leaves the outputs as they are at destruction (explicit `--detach`-style use).
  void Disarm() { armed_ = false; }

 private:
  std::function<void()> safe_state_;
  std::thread watcher_;
  std::atomic<bool> armed_{true};
};

}  // namespace msmcal::gen
