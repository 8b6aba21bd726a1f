#pragma once
// Child processes for tests that talk to tools we did not write (Aravis's fake camera and test
// tool). Each child runs in its own process group; the destructor kills the whole group
// (SIGKILL) and reaps it, so no helper outlives its test.

#include <sys/types.h>

#include <cstdint>
#include <string>
#include <vector>

namespace msmcal::camera::testing {

class Subprocess {
 public:
  // Starts argv[0] (searched in PATH) with stdout and stderr on a pipe. Throws std::runtime_error
  // if fork/pipe fail; a missing program shows as exit status 127.
  explicit Subprocess(const std::vector<std::string>& argv);
  ~Subprocess();
  Subprocess(const Subprocess&) = delete;
  Subprocess& operator=(const Subprocess&) = delete;

  // Reads output until the child closes it or `timeout_ms` passes (then kills the group).
  // Returns the exit status (WEXITSTATUS), or -1 if it had to be killed.
  int WaitWithOutput(int64_t timeout_ms, std::string* output);
  void Kill();
  pid_t pid() const { return pid_; }

 private:
  pid_t pid_ = -1;
  int out_fd_ = -1;
  bool reaped_ = false;
  int status_ = 0;
};

// True if `program` is an executable in PATH.
bool ProgramInPath(const std::string& program);

}  // namespace msmcal::camera::testing
