#include "drivers/generator/safe_state.h"

#include <fcntl.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <atomic>
#include <condition_variable>
#include <iterator>
#include <mutex>
#include <stdexcept>

namespace msmcal::gen {
namespace {

int g_pipe[2] = {-1, -1};
std::atomic<bool> g_active{false};
std::atomic<bool> g_unconfirmed{false};
// The signals that end a process by default and that a lab's terminal sends: Ctrl-C, kill,
// a closed terminal (HUP), Ctrl-\ (QUIT).
constexpr int kSignals[] = {SIGINT, SIGTERM, SIGHUP, SIGQUIT};
struct sigaction g_old[4];
struct sigaction g_old_pipe;

void OnSignal(int signo) {
  const int saved = errno;
  const unsigned char b = static_cast<unsigned char>(signo);
  [[maybe_unused]] const ssize_t n = write(g_pipe[1], &b, 1);
  errno = saved;
}

// WaitForSignal() parks here; the watcher ends the process, so nothing ever notifies it.
std::mutex g_wait_mu;
std::condition_variable g_wait_cv;

}  // namespace

SafeStateGuard::SafeStateGuard(std::function<void()> safe_state)
    : safe_state_(std::move(safe_state)) {
  if (g_active.exchange(true)) throw std::runtime_error("SafeStateGuard: one is already active");
  if (pipe2(g_pipe, O_CLOEXEC) != 0) {
    g_active = false;
    throw std::runtime_error("SafeStateGuard: pipe2 failed");
  }
  watcher_ = std::thread([this] {
    unsigned char b = 0;
    for (;;) {
      const ssize_t n = read(g_pipe[0], &b, 1);
      if (n < 0 && errno == EINTR) continue;
      if (n != 1 || b == 0) return;  // destructor asks the watcher to stop
      // Outputs off first, then words: logging can fail (a closed pipe, a full disk) and must
      // not stand between the signal and the safe state.
      if (armed_ && safe_state_) safe_state_();
      if (g_unconfirmed) {
        static const char kMsg[] =
            "msmcal: SAFE STATE NOT CONFIRMED after a signal: check the generators' outputs by "
            "hand\n";
        [[maybe_unused]] const ssize_t w = write(2, kMsg, sizeof(kMsg) - 1);
        _exit(kExitSafeStateUnconfirmed);
      }
      try {
        spdlog::warn("signal {}: generator outputs turned off", static_cast<int>(b));
      } catch (...) {
      }
      signal(b, SIG_DFL);
      raise(b);
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

void SafeStateGuard::ReportUnconfirmed() { g_unconfirmed = true; }

SafeStateGuard::~SafeStateGuard() {
  for (size_t i = 0; i < std::size(kSignals); ++i) sigaction(kSignals[i], &g_old[i], nullptr);
  sigaction(SIGPIPE, &g_old_pipe, nullptr);
  const unsigned char stop = 0;
  [[maybe_unused]] const ssize_t n = write(g_pipe[1], &stop, 1);
  watcher_.join();
  if (armed_ && safe_state_) safe_state_();
  close(g_pipe[0]);
  close(g_pipe[1]);
  g_pipe[0] = g_pipe[1] = -1;
  g_unconfirmed = false;
  g_active = false;
}

void SafeStateGuard::WaitForSignal() {
  std::unique_lock lock(g_wait_mu);
  g_wait_cv.wait(lock, [] { return false; });
}

}  // namespace msmcal::gen
