#pragma once
// Safe state on SIGINT, SIGTERM, SIGHUP and SIGQUIT and at scope exit; SIGPIPE ignored while
// a guard is active (a closed stdout must not kill the process before the safe state).
//
// Design (async-signal-safe): the signal handler only write()s the signal number to a self-pipe.
// A watcher thread blocks on the pipe, runs the safe-state actions (ordinary code: sockets,
// mutexes, logging), then restores the default disposition and re-raises the signal, so the
// process ends with the status a shell expects (128 + signo). The actions run before any logging.
// If an action calls ReportUnconfirmed() (outputs not confirmed off), the process says so on
// stderr and exits with kExitSafeStateUnconfirmed instead. The destructor runs the action too
// (normal return and exception unwinding).
//
// Guards nest (a command's OpenGeneratorsGuard around a session's own guard): the outermost
// installs the handlers and the watcher; on a signal every armed guard's action runs, innermost
// first, under one lock, so that a guard being destroyed waits until its action is done. Guards
// are scoped: destroyed in the reverse order of their construction, on the thread that made them.

#include <atomic>
#include <functional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace msmcal::gen {

class FunctionGenerator;

// Exit status of a process whose safe state was not confirmed, by itself nor by its watchdog.
constexpr int kExitSafeStateUnconfirmed = 75;
// Exit status of a process whose own safe state was not confirmed, but whose watchdog, asked to
// act while the process was alive, confirmed every output off (docs/watchdog.md).
constexpr int kExitSafeStateByWatchdog = 76;

// Thrown (by a session) once its own safe state was not confirmed and the watchdog was asked to
// act: the message says what each did; exit_status() is kExitSafeStateByWatchdog or
// kExitSafeStateUnconfirmed, and msmcal's main returns it.
class SafeStateNotConfirmed : public std::runtime_error {
 public:
  SafeStateNotConfirmed(int exit_status, const std::string& message)
      : std::runtime_error(message), exit_status_(exit_status) {}
  int exit_status() const { return exit_status_; }

 private:
  int exit_status_;
};

class SafeStateGuard {
 public:
  // The outermost guard installs handlers for SIGINT, SIGTERM, SIGHUP and SIGQUIT and ignores
  // SIGPIPE. Throws std::runtime_error if the pipe cannot be created.
  explicit SafeStateGuard(std::function<void()> safe_state);
  // Runs the action (unless already run by a signal); the outermost restores the previous
  // handlers.
  ~SafeStateGuard();
  SafeStateGuard(const SafeStateGuard&) = delete;
  SafeStateGuard& operator=(const SafeStateGuard&) = delete;

  // Blocks the calling thread until one of the signals arrives; the process then ends from the
  // watcher after the safe state (this never returns in that case).
  void WaitForSignal();
  // Leaves the outputs as they are at destruction (explicit `--detach`-style use).
  void Disarm() { armed_ = false; }
  // Called by an action when the outputs could not be confirmed off (see above).
  static void ReportUnconfirmed();
  // Called by an action: the words of the process's last line after a signal ("signal 2
  // (SIGINT): <outcome>"); the last call wins. Default: "generator outputs turned off".
  static void ReportOutcome(const std::string& outcome);
  // The signal being handled (0 outside a signal's actions): for an action's own words.
  static int HandlingSignal();
  // Called by an action that handed the safe state over to the watchdog (HandOverToWatchdog):
  // the process then ends with kExitSafeStateByWatchdog when the watchdog confirmed, otherwise
  // as ReportUnconfirmed(); `text` is the outcome line. Later actions see HandedOver() and leave
  // the generators to the watchdog's verdict.
  static void ReportHandedOver(bool watchdog_confirmed, const std::string& text);
  static bool HandedOver();

 private:
  std::function<void()> safe_state_;
  std::atomic<bool> armed_{true};
};

// Every generator connection of this process, from its construction to its destruction: the
// Keysight driver registers each one (before it connects), so that a signal's safe state reaches
// a generator whose open or identify is still in flight (the rig check), on its own connection
// (an instrument serving one connection at a time would not serve a second one).
class OpenGeneratorRegistration {
 public:
  // `who` names it in reports ("unit1 (192.168.1.11:5025)"). The generator must outlive this.
  OpenGeneratorRegistration(FunctionGenerator* generator, std::string who);
  ~OpenGeneratorRegistration();
  OpenGeneratorRegistration(const OpenGeneratorRegistration&) = delete;
  OpenGeneratorRegistration& operator=(const OpenGeneratorRegistration&) = delete;

 private:
  FunctionGenerator* generator_;
};

struct OpenGeneratorOutcome {
  std::string who;
  bool confirmed = false;  // FunctionGenerator::SafeState() confirmed every output off
};
// SafeState() on every registered generator, in registration order (each call waits for the
// exchange in flight on that connection, bounded by its deadline). Thread-safe; a registration
// being destroyed meanwhile waits until this returns.
std::vector<OpenGeneratorOutcome> SafeStateOfOpenGenerators();
// Disconnect() on every registered generator (before the watchdog is asked to act).
void DisconnectOpenGenerators();
// "unit1 (127.0.0.1:15025) off, confirmed; unit2 (...) NOT CONFIRMED OFF"; "" for none.
std::string FormatOpenGeneratorOutcomes(const std::vector<OpenGeneratorOutcome>& outcomes);

// The guard a command that may touch a generator installs first (msmcal demo, session check and
// run, resume, sweep, replay, gen ...): from then on a signal switches every open generator off
// (SafeStateOfOpenGenerators), whatever the command is doing (a rig check, the web page's
// start-up), then closes their connections (the main thread, still running until the process
// ends, cannot switch an output on again), and the process's last line says what happened; an
// output not confirmed off ends the process with kExitSafeStateUnconfirmed. Nested guards (a
// session's) run first.
class OpenGeneratorsGuard {
 public:
  OpenGeneratorsGuard();

 private:
  SafeStateGuard guard_;
};

}  // namespace msmcal::gen
