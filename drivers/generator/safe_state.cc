#include "drivers/generator/safe_state.h"

#include <fcntl.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <atomic>
#include <cassert>
#include <condition_variable>
#include <iterator>
#include <mutex>
#include <stdexcept>
#include <utility>

#include "drivers/generator/function_generator.h"

namespace msmcal::gen {
namespace {

int g_pipe[2] = {-1, -1};
std::atomic<bool> g_unconfirmed{false};
std::atomic<int> g_signal{0};
std::atomic<bool> g_handed_over{false};
// The signals that end a process by default and that a lab's terminal sends: Ctrl-C, kill,
// a closed terminal (HUP), Ctrl-\ (QUIT).
constexpr int kSignals[] = {SIGINT, SIGTERM, SIGHUP, SIGQUIT};
struct sigaction g_old[4];
struct sigaction g_old_pipe;

// The active guards, outermost first, and the watcher the outermost started. g_mu is held while
// a signal's actions run (and then until the process ends), so a guard leaving its scope waits.
struct GuardEntry {
  const SafeStateGuard* guard;
  const std::function<void()>* action;
  const std::atomic<bool>* armed;
};
std::mutex g_mu;
std::vector<GuardEntry> g_stack;
std::thread g_watcher;

std::mutex g_outcome_mu;
std::string g_outcome;

void OnSignal(int signo) {
  const int saved = errno;
  const unsigned char b = static_cast<unsigned char>(signo);
  [[maybe_unused]] const ssize_t n = write(g_pipe[1], &b, 1);
  errno = saved;
}

const char* SignalName(int signo) {
  switch (signo) {
    case SIGINT:
      return "SIGINT";
    case SIGTERM:
      return "SIGTERM";
    case SIGHUP:
      return "SIGHUP";
    case SIGQUIT:
      return "SIGQUIT";
    default:
      return "signal";
  }
}

std::string Outcome() {
  std::lock_guard<std::mutex> lock(g_outcome_mu);
  return g_outcome.empty() ? "generator outputs turned off" : g_outcome;
}

// Runs on the watcher thread: every armed action, innermost first, then the process ends.
void HandleSignal(int signo) {
  std::unique_lock<std::mutex> lock(g_mu);  // not released: the process ends below
  g_signal = signo;
  for (auto it = g_stack.rbegin(); it != g_stack.rend(); ++it)
    if (*it->armed && *it->action) (*it->action)();
  // Outputs off first (above), then words: logging can fail (a closed pipe, a full disk) and
  // must not stand between the signal and the safe state.
  const std::string head = "signal " + std::to_string(signo) + " (" + SignalName(signo) + ")";
  if (g_unconfirmed) {
    const std::string msg = "msmcal: SAFE STATE NOT CONFIRMED after " + head + ": " + Outcome() +
                            ": check the generators' outputs by hand\n";
    [[maybe_unused]] const ssize_t w = write(2, msg.data(), msg.size());
    _exit(kExitSafeStateUnconfirmed);
  }
  if (g_handed_over) {
    const std::string msg =
        "msmcal: SAFE STATE NOT CONFIRMED by msmcal after " + head + ": " + Outcome() + "\n";
    [[maybe_unused]] const ssize_t w = write(2, msg.data(), msg.size());
    _exit(kExitSafeStateByWatchdog);
  }
  try {
    spdlog::warn("{}: {}", head, Outcome());
  } catch (...) {
  }
  signal(signo, SIG_DFL);
  raise(signo);
}

// WaitForSignal() parks here; the watcher ends the process, so nothing ever notifies it.
std::mutex g_wait_mu;
std::condition_variable g_wait_cv;

// The registry of open generators (OpenGeneratorRegistration).
std::mutex g_registry_mu;
std::vector<std::pair<FunctionGenerator*, std::string>> g_registry;

}  // namespace

SafeStateGuard::SafeStateGuard(std::function<void()> safe_state)
    : safe_state_(std::move(safe_state)) {
  std::lock_guard<std::mutex> lock(g_mu);
  if (g_stack.empty()) {
    if (pipe2(g_pipe, O_CLOEXEC) != 0) throw std::runtime_error("SafeStateGuard: pipe2 failed");
    g_watcher = std::thread([] {
      unsigned char b = 0;
      for (;;) {
        const ssize_t n = read(g_pipe[0], &b, 1);
        if (n < 0 && errno == EINTR) continue;
        if (n != 1 || b == 0) return;  // the outermost guard's destructor stops the watcher
        HandleSignal(b);
        return;
      }
    });
    struct sigaction sa {};
    sa.sa_handler = OnSignal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESTART;
    for (size_t i = 0; i < std::size(kSignals); ++i) sigaction(kSignals[i], &sa, &g_old[i]);
    // A write to a closed pipe (Ctrl-C on `msmcal ... | tee log`) must not kill the process
    // between the signal and the safe state: EPIPE is an ordinary write error.
    struct sigaction ignore {};
    ignore.sa_handler = SIG_IGN;
    sigemptyset(&ignore.sa_mask);
    sigaction(SIGPIPE, &ignore, &g_old_pipe);
  }
  g_stack.push_back({this, &safe_state_, &armed_});
}

void SafeStateGuard::ReportUnconfirmed() { g_unconfirmed = true; }

void SafeStateGuard::ReportOutcome(const std::string& outcome) {
  std::lock_guard<std::mutex> lock(g_outcome_mu);
  g_outcome = outcome;
}

int SafeStateGuard::HandlingSignal() { return g_signal; }

void SafeStateGuard::ReportHandedOver(bool watchdog_confirmed, const std::string& text) {
  g_handed_over = true;
  if (!watchdog_confirmed) g_unconfirmed = true;
  ReportOutcome(text);
}

bool SafeStateGuard::HandedOver() { return g_handed_over; }

SafeStateGuard::~SafeStateGuard() {
  bool outermost = false;
  {
    std::lock_guard<std::mutex> lock(g_mu);
    // Scoped guards leave in reverse order (a broken invariant, not an input error).
    assert(!g_stack.empty() && g_stack.back().guard == this);
    g_stack.pop_back();
    outermost = g_stack.empty();
    if (outermost) {
      for (size_t i = 0; i < std::size(kSignals); ++i) sigaction(kSignals[i], &g_old[i], nullptr);
      sigaction(SIGPIPE, &g_old_pipe, nullptr);
    }
  }
  if (outermost) {
    const unsigned char stop = 0;
    [[maybe_unused]] const ssize_t n = write(g_pipe[1], &stop, 1);
    g_watcher.join();
  }
  if (armed_ && safe_state_) safe_state_();
  if (outermost) {
    close(g_pipe[0]);
    close(g_pipe[1]);
    g_pipe[0] = g_pipe[1] = -1;
    g_unconfirmed = false;
    g_handed_over = false;
    std::lock_guard<std::mutex> lock(g_outcome_mu);
    g_outcome.clear();
  }
}

void SafeStateGuard::WaitForSignal() {
  std::unique_lock lock(g_wait_mu);
  g_wait_cv.wait(lock, [] { return false; });
}

OpenGeneratorRegistration::OpenGeneratorRegistration(FunctionGenerator* generator,
                                                     std::string who) {
  std::lock_guard<std::mutex> lock(g_registry_mu);
  g_registry.emplace_back(generator, std::move(who));
  generator_ = generator;
}

OpenGeneratorRegistration::~OpenGeneratorRegistration() {
  std::lock_guard<std::mutex> lock(g_registry_mu);
  for (auto it = g_registry.begin(); it != g_registry.end(); ++it) {
    if (it->first == generator_) {
      g_registry.erase(it);
      break;
    }
  }
}

std::vector<OpenGeneratorOutcome> SafeStateOfOpenGenerators() {
  std::lock_guard<std::mutex> lock(g_registry_mu);
  std::vector<OpenGeneratorOutcome> outcomes;
  for (const auto& [generator, who] : g_registry) outcomes.push_back({who, generator->SafeState()});
  return outcomes;
}

void DisconnectOpenGenerators() {
  std::lock_guard<std::mutex> lock(g_registry_mu);
  for (const auto& entry : g_registry) entry.first->Disconnect();
}

std::string FormatOpenGeneratorOutcomes(const std::vector<OpenGeneratorOutcome>& outcomes) {
  std::string s;
  for (const auto& o : outcomes)
    s += (s.empty() ? "" : "; ") + o.who + (o.confirmed ? " off, confirmed" : " NOT CONFIRMED OFF");
  return s;
}

OpenGeneratorsGuard::OpenGeneratorsGuard()
    : guard_([] {
        if (SafeStateGuard::HandedOver()) return;  // the watchdog's verdict stands
        const std::vector<OpenGeneratorOutcome> outcomes = SafeStateOfOpenGenerators();
        bool all = true;
        for (const auto& o : outcomes) all = all && o.confirmed;
        if (!all) SafeStateGuard::ReportUnconfirmed();
        if (SafeStateGuard::HandlingSignal() == 0) return;  // scope exit: nothing to say
        // The process ends in a moment: until then the main thread, still running, must not
        // switch anything on again (its next command meets a closed connection).
        DisconnectOpenGenerators();
        SafeStateGuard::ReportOutcome(
            outcomes.empty() ? "no generator connection was open: no output to switch off"
                             : "generator outputs: " + FormatOpenGeneratorOutcomes(outcomes));
      }) {}

}  // namespace msmcal::gen
