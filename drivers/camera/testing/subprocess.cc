#include "drivers/camera/testing/subprocess.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <sstream>
#include <stdexcept>

namespace msmcal::camera::testing {

Subprocess::Subprocess(const std::vector<std::string>& argv) {
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) throw std::runtime_error("pipe2 failed");
  pid_ = ::fork();
  if (pid_ < 0) throw std::runtime_error("fork failed");
  if (pid_ == 0) {
    ::setpgid(0, 0);
    ::dup2(fds[1], STDOUT_FILENO);
    ::dup2(fds[1], STDERR_FILENO);
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    ::execvp(args[0], args.data());
    ::_exit(127);
  }
  ::setpgid(pid_, pid_);  // also from the parent: no race with the child's own call
  ::close(fds[1]);
  out_fd_ = fds[0];
}

Subprocess::~Subprocess() {
  Kill();
  if (out_fd_ >= 0) ::close(out_fd_);
}

void Subprocess::Kill() {
  if (pid_ <= 0 || reaped_) return;
  ::kill(-pid_, SIGKILL);
  ::waitpid(pid_, &status_, 0);
  reaped_ = true;
}

int Subprocess::WaitWithOutput(int64_t timeout_ms, std::string* output) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  char chunk[4096];
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
                          deadline - std::chrono::steady_clock::now())
                          .count();
    if (left <= 0) {
      Kill();
      return -1;
    }
    pollfd pfd{out_fd_, POLLIN, 0};
    const int n = ::poll(&pfd, 1, static_cast<int>(left));
    if (n < 0) continue;
    if (n == 0) continue;  // deadline check above
    const ssize_t got = ::read(out_fd_, chunk, sizeof(chunk));
    if (got > 0) {
      if (output) output->append(chunk, static_cast<size_t>(got));
      continue;
    }
    break;  // EOF: the child (and its group) closed the pipe
  }
  // Output closed; the child exits now or is killed at the deadline.
  for (;;) {
    const pid_t r = ::waitpid(pid_, &status_, WNOHANG);
    if (r == pid_) {
      reaped_ = true;
      ::kill(-pid_, SIGKILL);  // stray grandchildren, if any
      return WIFEXITED(status_) ? WEXITSTATUS(status_) : -1;
    }
    if (std::chrono::steady_clock::now() >= deadline) {
      Kill();
      return -1;
    }
    // Blocking wait bounded by the deadline: an alarm-free approach is to wait on a pidfd; the
    // child has closed its output, so it is exiting: a blocking waitpid returns promptly.
    const pid_t b = ::waitpid(pid_, &status_, 0);
    if (b == pid_) {
      reaped_ = true;
      return WIFEXITED(status_) ? WEXITSTATUS(status_) : -1;
    }
  }
}

bool ProgramInPath(const std::string& program) {
  const char* path = std::getenv("PATH");
  if (path == nullptr) return false;
  std::stringstream dirs(path);
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    if (!dir.empty() && ::access((dir + "/" + program).c_str(), X_OK) == 0) return true;
  }
  return false;
}

}  // namespace msmcal::camera::testing
