#pragma once
// The `msmcal mock ...` servers' wait for SIGINT/SIGTERM (one helper for every serving command).

#include <pthread.h>

#include <csignal>

namespace msmcal::app {

// Blocks SIGINT/SIGTERM in this thread and the threads started after it, then waits for one.
class StopSignal {
 public:
  StopSignal() {
    sigemptyset(&set_);
    sigaddset(&set_, SIGINT);
    sigaddset(&set_, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &set_, nullptr);
  }
  int Wait() {
    int signo = 0;
    sigwait(&set_, &signo);
    return signo;
  }

 private:
  sigset_t set_;
};

}  // namespace msmcal::app
