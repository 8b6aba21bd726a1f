#include "sessions/orchestrator/hook_operator.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <ctime>

extern char** environ;

namespace msmcal::orchestrator {
namespace {

// Writes all of `data` to `fd` with SIGPIPE blocked (a hook that does not read its input and
// exits must not kill msmcal); EPIPE is not an error here.
void WriteAllNoSigpipe(int fd, const std::string& data) {
  sigset_t pipe_set, old;
  sigemptyset(&pipe_set);
  sigaddset(&pipe_set, SIGPIPE);
  pthread_sigmask(SIG_BLOCK, &pipe_set, &old);
  size_t done = 0;
  bool broken = false;
  while (done < data.size()) {
    const ssize_t n = ::write(fd, data.data() + done, data.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      broken = errno == EPIPE;
      break;
    }
    done += static_cast<size_t>(n);
  }
  if (broken) {
    const timespec zero{0, 0};
    while (sigtimedwait(&pipe_set, nullptr, &zero) == SIGPIPE) {
    }
  }
  pthread_sigmask(SIG_SETMASK, &old, nullptr);
}

int64_t MonotonicMs() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1000 + ts.tv_nsec / 1'000'000;
}

}  // namespace

std::string DescribeWaitStatus(int status) {
  if (WIFEXITED(status)) return "exit status " + std::to_string(WEXITSTATUS(status));
  if (WIFSIGNALED(status))
    return "killed by signal " + std::to_string(WTERMSIG(status)) + " (" +
           strsignal(WTERMSIG(status)) + ")";
  return "wait status " + std::to_string(status);
}

int RunHookCommand(const std::string& command, const std::string& input, int timeout_ms) {
  int in[2];
  if (::pipe2(in, O_CLOEXEC) != 0)
    throw HookFailed("operator hook '" + command + "': pipe: " + std::strerror(errno));
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, in[0], STDIN_FILENO);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP | POSIX_SPAWN_SETSIGMASK);
  posix_spawnattr_setpgroup(&attr, 0);  // own group: a timeout kills the hook and its children
  sigset_t none;
  sigemptyset(&none);
  posix_spawnattr_setsigmask(&attr, &none);
  const char* argv[] = {"/bin/sh", "-c", command.c_str(), nullptr};
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, "/bin/sh", &actions, &attr, const_cast<char**>(argv), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attr);
  ::close(in[0]);
  if (rc != 0) {
    ::close(in[1]);
    throw HookFailed("operator hook '" + command + "': cannot start /bin/sh: " + std::strerror(rc));
  }
  WriteAllNoSigpipe(in[1], input);
  ::close(in[1]);
  // Wait with a deadline: a pidfd when the kernel has one, else a short poll of waitpid.
  const int64_t deadline = MonotonicMs() + timeout_ms;
  const int pidfd = static_cast<int>(::syscall(SYS_pidfd_open, pid, 0));
  int status = 0;
  for (;;) {
    const pid_t w = ::waitpid(pid, &status, WNOHANG);
    if (w == pid) break;
    if (w < 0 && errno != EINTR) {
      if (pidfd >= 0) ::close(pidfd);
      throw HookFailed("operator hook '" + command + "': waitpid: " + std::strerror(errno));
    }
    const int64_t left = deadline - MonotonicMs();
    if (left <= 0) {
      ::kill(-pid, SIGKILL);
      while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
      }
      if (pidfd >= 0) ::close(pidfd);
      throw HookFailed("operator hook '" + command + "': no answer within " +
                       std::to_string(timeout_ms) + " ms (killed)");
    }
    if (pidfd >= 0) {
      pollfd p{pidfd, POLLIN, 0};
      (void)::poll(&p, 1, static_cast<int>(std::min<int64_t>(left, 1000)));
    } else {
      const timespec ts{0, 5'000'000};
      nanosleep(&ts, nullptr);
    }
  }
  if (pidfd >= 0) ::close(pidfd);
  return status;
}

std::string HookOperatorOptions::Validate(bool has_inner) const {
  if (command.empty()) return "HookOperatorOptions.command = '': the hook command is empty";
  if (timeout_ms <= 0)
    return "HookOperatorOptions.timeout_ms = " + std::to_string(timeout_ms) + ": must be > 0";
  if (settle_ns < 0)
    return "HookOperatorOptions.settle_ns = " + std::to_string(settle_ns) + ": must be >= 0";
  if (!has_inner) {
    if (mcu_device.empty())
      return "HookOperatorOptions.mcu_device = '': required without an inner operator (lab)";
    if (!host_clock_ns)
      return "HookOperatorOptions.host_clock_ns = (none): required without an inner operator";
  }
  return {};
}

namespace {

SetupWalkOptions WalkOf(const HookOperatorOptions& o, bool has_inner) {
  if (std::string e = o.Validate(has_inner); !e.empty()) throw std::invalid_argument(e);
  return {o.poses, o.mcu_device, o.host_clock_ns, o.settle_ns, o.exposure_ns};
}

}  // namespace

HookOperator::HookOperator(const dataset::Recording& plan, HookOperatorOptions options,
                           RigOperator* inner)
    : SetupOperator(plan, WalkOf(options, inner != nullptr), inner), options_(std::move(options)) {}

void HookOperator::Run(const std::string& json, const std::string& what) {
  const int status = RunHookCommand(options_.command, json + "\n", options_.timeout_ms);
  const bool ok = WIFEXITED(status) && WEXITSTATUS(status) == 0;
  if (options_.log) options_.log("hook: " + what + ": " + DescribeWaitStatus(status));
  if (!ok) {
    throw HookFailed("operator hook '" + options_.command + "' failed at " + what + ": " +
                     DescribeWaitStatus(status) + "; session aborted");
  }
  ++calls_;
}

void HookOperator::Present(const setup::Setup& s) {
  Run(setup::SetupToJson(s), "set-up " + std::to_string(s.block) + "/" + std::to_string(s.of) +
                                 " (" + setup::ToString(s.step) + ")");
}

void HookOperator::RequestTruth(const std::filesystem::path& dir) {
  Run(setup::TruthRequestJson(dir), "truth request");
}

}  // namespace msmcal::orchestrator
