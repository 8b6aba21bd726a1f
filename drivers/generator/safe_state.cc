#include "drivers/generator/safe_state.h"

#include <fcntl.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <stdexcept>

namespace msmcal::gen {
namespace {

int g_pipe[2] = {-1, -1};
std::atomic<bool> g_active{false};
struct sigaction g_old_int, g_old_term;

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
      spdlog::warn("signal {}: turning generator outputs off", static_cast<int>(b));
      if (armed_ && safe_state_) safe_state_();
      signal(b, SIG_DFL);
      raise(b);
      return;
    }
  });
  struct sigaction sa {};
  sa.sa_handler = OnSignal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESTART;
  sigaction(SIGINT, &sa, &g_old_int);
  sigaction(SIGTERM, &sa, &g_old_term);
}

SafeStateGuard::~SafeStateGuard() {
  sigaction(SIGINT, &g_old_int, nullptr);
  sigaction(SIGTERM, &g_old_term, nullptr);
  const unsigned char stop = 0;
  [[maybe_unused]] const ssize_t n = write(g_pipe[1], &stop, 1);
  watcher_.join();
  if (armed_ && safe_state_) safe_state_();
  close(g_pipe[0]);
  close(g_pipe[1]);
  g_pipe[0] = g_pipe[1] = -1;
  g_active = false;
}

void SafeStateGuard::WaitForSignal() {
  std::unique_lock lock(g_wait_mu);
  g_wait_cv.wait(lock, [] { return false; });
}

}  // namespace msmcal::gen
