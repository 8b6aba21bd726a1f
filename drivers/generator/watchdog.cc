#include "drivers/generator/watchdog.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "drivers/generator/function_generator.h"

extern char** environ;

namespace msmcal::gen {
namespace {

constexpr char kStandDownByte = 'S';
// The parent is alive but its own safe state was not confirmed: act now (Watchdog::ActNow).
constexpr char kActNowByte = 'F';
constexpr char kArmedByte = 'A';
constexpr int kArmTimeoutMs = 5000;
constexpr int kStandDownTimeoutMs = 3000;

int PidfdOpen(pid_t pid) { return static_cast<int>(syscall(SYS_pidfd_open, pid, 0)); }

// poll() on one descriptor, retried on EINTR until `timeout_ms` (-1: forever) has passed.
// Returns the revents (0 on timeout).
short PollOne(int fd, int timeout_ms) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  for (;;) {
    pollfd p{fd, POLLIN, 0};
    int left = -1;
    if (timeout_ms >= 0) {
      left = static_cast<int>(std::max<int64_t>(
          0, std::chrono::duration_cast<std::chrono::milliseconds>(deadline -
                                                                   std::chrono::steady_clock::now())
                 .count()));
    }
    const int n = poll(&p, 1, left);
    if (n > 0) return p.revents;
    if (n == 0) return 0;
    if (errno != EINTR) return POLLERR;
  }
}

int ParseInt(const std::string& flag, const std::string& value, int lo, int hi) {
  size_t used = 0;
  long v = 0;
  try {
    v = std::stol(value, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != value.size() || value.empty() || v < lo || v > hi) {
    throw std::invalid_argument("watchdog: " + flag + " = '" + value +
                                "': expected an integer in [" + std::to_string(lo) + ", " +
                                std::to_string(hi) + "]");
  }
  return static_cast<int>(v);
}

std::string UtcNow() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

void WriteAll(int fd, const std::string& s) {
  size_t off = 0;
  while (off < s.size()) {
    const ssize_t n = write(fd, s.data() + off, s.size() - off);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return;
    off += static_cast<size_t>(n);
  }
}

// write() of one byte that reports a closed read end as false instead of raising SIGPIPE (a
// watchdog that already exited must not kill its parent): SIGPIPE is blocked in this thread for
// the call and a pending one is consumed.
bool WriteByteNoSigpipe(int fd, char b) {
  sigset_t pipe_set, old;
  sigemptyset(&pipe_set);
  sigaddset(&pipe_set, SIGPIPE);
  pthread_sigmask(SIG_BLOCK, &pipe_set, &old);
  ssize_t n;
  do {
    n = write(fd, &b, 1);
  } while (n < 0 && errno == EINTR);
  if (n < 0 && errno == EPIPE) {
    const timespec zero{0, 0};
    while (sigtimedwait(&pipe_set, nullptr, &zero) < 0 && errno == EINTR) {
    }
  }
  pthread_sigmask(SIG_SETMASK, &old, nullptr);
  return n == 1;
}

}  // namespace

std::string WatchdogConfig::Validate() const {
  std::ostringstream os;
  if (generators.empty()) {
    os << "generators: empty: the watchdog needs at least one generator";
  } else if (retry_window_ms <= 0) {
    os << "retry_window_ms = " << retry_window_ms << ": must be > 0";
  } else if (attempt_timeout_ms <= 0 || attempt_timeout_ms > retry_window_ms) {
    os << "attempt_timeout_ms = " << attempt_timeout_ms
       << ": must be in (0, retry_window_ms = " << retry_window_ms << "]";
  } else {
    for (size_t i = 0; i < generators.size(); ++i) {
      const WatchdogGenerator& g = generators[i];
      const std::string field = "generators[" + std::to_string(i) + "]";
      if (g.name.empty() || g.name.find_first_of("=:") != std::string::npos) {
        os << field << ".name = '" << g.name << "': must be non-empty without '=' or ':'";
      } else if (g.host.empty()) {
        os << field << ".host = '': must not be empty";
      } else if (g.port < 1 || g.port > 65535) {
        os << field << ".port = " << g.port << ": must be in [1, 65535]";
      }
      if (os.tellp() > 0) break;
    }
  }
  return os.str();
}

WatchdogConfig WatchdogConfigFor(const RigGeneratorConfig& rig, const std::string& log_path) {
  WatchdogConfig c;
  for (const Keysight33500Options* u : {&rig.unit1, &rig.unit2})
    c.generators.push_back({u->name, u->link.host, u->link.port});
  c.log_path = log_path;
  return c;
}

std::vector<std::string> FormatWatchdogArguments(const WatchdogInvocation& inv) {
  std::vector<std::string> a = {"--control-fd", std::to_string(inv.control_fd),
                                "--ready-fd",   std::to_string(inv.ready_fd),
                                "--parent-pid", std::to_string(inv.parent_pid),
                                "--retry-ms",   std::to_string(inv.config.retry_window_ms),
                                "--attempt-ms", std::to_string(inv.config.attempt_timeout_ms)};
  if (!inv.config.log_path.empty()) {
    a.push_back("--log");
    a.push_back(inv.config.log_path);
  }
  for (const WatchdogGenerator& g : inv.config.generators) {
    a.push_back("--generator");
    a.push_back(g.name + "=" + g.host + ":" + std::to_string(g.port));
  }
  return a;
}

WatchdogInvocation ParseWatchdogArguments(const std::vector<std::string>& args) {
  WatchdogInvocation inv;
  inv.control_fd = inv.ready_fd = -1;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& flag = args[i];
    if (i + 1 >= args.size()) throw std::invalid_argument("watchdog: " + flag + ": missing value");
    const std::string& v = args[++i];
    if (flag == "--control-fd") {
      inv.control_fd = ParseInt(flag, v, 0, 1 << 20);
    } else if (flag == "--ready-fd") {
      inv.ready_fd = ParseInt(flag, v, 0, 1 << 20);
    } else if (flag == "--parent-pid") {
      inv.parent_pid = ParseInt(flag, v, 1, 1 << 30);
    } else if (flag == "--retry-ms") {
      inv.config.retry_window_ms = ParseInt(flag, v, 1, 600000);
    } else if (flag == "--attempt-ms") {
      inv.config.attempt_timeout_ms = ParseInt(flag, v, 1, 600000);
    } else if (flag == "--log") {
      inv.config.log_path = v;
    } else if (flag == "--generator") {
      const size_t eq = v.find('=');
      const size_t colon = v.rfind(':');
      if (eq == std::string::npos || colon == std::string::npos || colon < eq) {
        throw std::invalid_argument("watchdog: --generator = '" + v + "': expected NAME=HOST:PORT");
      }
      WatchdogGenerator g;
      g.name = v.substr(0, eq);
      g.host = v.substr(eq + 1, colon - eq - 1);
      g.port = ParseInt("--generator " + g.name + " port", v.substr(colon + 1), 1, 65535);
      inv.config.generators.push_back(g);
    } else {
      throw std::invalid_argument("watchdog: unknown argument '" + flag +
                                  "' (expected --control-fd, --ready-fd, --parent-pid, "
                                  "--retry-ms, --attempt-ms, --log or --generator)");
    }
  }
  if (inv.control_fd < 0) throw std::invalid_argument("watchdog: --control-fd is required");
  if (inv.ready_fd < 0) throw std::invalid_argument("watchdog: --ready-fd is required");
  if (inv.parent_pid <= 0) throw std::invalid_argument("watchdog: --parent-pid is required");
  if (std::string e = inv.config.Validate(); !e.empty())
    throw std::invalid_argument("watchdog: " + e);
  return inv;
}

std::vector<WatchdogOutcome> SwitchOutputsOff(const WatchdogConfig& config) {
  std::vector<WatchdogOutcome> out(config.generators.size());
  const auto start = std::chrono::steady_clock::now();
  const auto deadline = start + std::chrono::milliseconds(config.retry_window_ms);
  auto one = [&](size_t i) {
    WatchdogOutcome& o = out[i];
    o.generator = config.generators[i];
    Keysight33500Options opt;
    opt.name = o.generator.name;
    opt.link.host = o.generator.host;
    opt.link.port = o.generator.port;
    // Back-off between attempts: retry pacing while the port refuses (an instrument freeing the
    // dead process's socket), not synchronisation; doubled per attempt, at most 200 ms.
    int backoff_ms = 20;
    for (;;) {
      const auto now = std::chrono::steady_clock::now();
      const int left = static_cast<int>(
          std::chrono::duration_cast<std::chrono::milliseconds>(deadline - now).count());
      if (left <= 0 && o.attempts > 0) break;
      opt.link.connect_timeout_ms = opt.link.io_timeout_ms =
          std::max(1, std::min(config.attempt_timeout_ms, left));
      ++o.attempts;
      try {
        // The real driver: connect, *IDN? (a connection the instrument does not serve yet fails
        // here), then its SafeState(): OUTP1 OFF;:OUTP2 OFF and OUTP1?;:OUTP2? == 0;0.
        std::unique_ptr<FunctionGenerator> g = OpenKeysight33500(opt);
        if (g->SafeState()) {
          o.confirmed = true;
          o.last_error.clear();
          break;
        }
        o.last_error = "OUTP1?;:OUTP2? did not confirm both outputs off";
      } catch (const std::exception& e) {
        o.last_error = e.what();
      }
      const auto after = std::chrono::steady_clock::now();
      if (after + std::chrono::milliseconds(backoff_ms) >= deadline) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(backoff_ms));
      backoff_ms = std::min(200, backoff_ms * 2);
    }
    o.elapsed_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                       std::chrono::steady_clock::now() - start)
                       .count();
  };
  std::vector<std::thread> threads;
  for (size_t i = 0; i < out.size(); ++i) threads.emplace_back(one, i);
  for (auto& t : threads) t.join();
  return out;
}

std::string FormatWatchdogReport(const WatchdogOutcome& o, pid_t parent_pid, bool asked) {
  std::ostringstream os;
  os << "[watchdog " << UtcNow() << "] process " << parent_pid
     << (asked ? " asked the watchdog to act (its own safe state was not confirmed): "
               : " ended without standing the watchdog down: ")
     << o.generator.name << " (" << o.generator.host << ":" << o.generator.port << ") ";
  if (o.confirmed) {
    os << "outputs off, confirmed (OUTP1 OFF;:OUTP2 OFF, OUTP1?;:OUTP2? -> 0;0)";
  } else {
    os << "outputs NOT CONFIRMED OFF: " << o.last_error;
  }
  os << " after " << o.attempts << " attempt(s), " << o.elapsed_ms << " ms";
  return os.str();
}

int RunWatchdog(const WatchdogInvocation& inv) {
  // Terminal signals belong to msmcal (its SafeStateGuard); a closed log pipe must not kill us.
  for (int s : {SIGINT, SIGHUP, SIGQUIT, SIGPIPE}) ::signal(s, SIG_IGN);
  sigset_t none;
  sigemptyset(&none);
  sigprocmask(SIG_SETMASK, &none, nullptr);

  // The parent's pidfd, taken while it is certainly our parent: if getppid() still names it after
  // pidfd_open, the pidfd refers to that process and not to a reused pid.
  int pidfd = PidfdOpen(inv.parent_pid);
  bool gone = getppid() != inv.parent_pid;
  if (pidfd < 0) gone = true;
  fcntl(inv.control_fd, F_SETFL, fcntl(inv.control_fd, F_GETFL) | O_NONBLOCK);
  const char armed = kArmedByte;
  [[maybe_unused]] const ssize_t w = write(inv.ready_fd, &armed, 1);
  close(inv.ready_fd);

  bool asked = false;  // the parent, alive, asked us to act (kActNowByte)
  while (!gone) {
    pollfd p[2] = {{inv.control_fd, POLLIN, 0}, {pidfd, POLLIN, 0}};
    const int n = poll(p, 2, -1);
    if (n < 0) {
      if (errno == EINTR) continue;
      gone = true;  // cannot watch any more: better an extra "outputs off" than none
      break;
    }
    // The pipe first: a stand-down byte written before the parent exited is still there when
    // the pidfd reports the exit.
    char b = 0;
    const ssize_t r = read(inv.control_fd, &b, 1);
    if (r == 1 && b == kStandDownByte) {
      close(inv.control_fd);
      if (pidfd >= 0) close(pidfd);
      return kWatchdogStoodDown;
    }
    if (r == 1 && b == kActNowByte) {
      asked = true;
      break;
    }
    if (r == 0) gone = true;                                               // EOF: write end closed
    if (r < 0 && errno != EAGAIN && errno != EINTR) gone = true;           // broken pipe
    if (r < 0 && errno == EAGAIN && (p[1].revents & POLLIN)) gone = true;  // parent exited
  }
  if (pidfd >= 0) close(pidfd);
  close(inv.control_fd);

  const std::vector<WatchdogOutcome> outcomes = SwitchOutputsOff(inv.config);
  bool all = true;
  std::string report;
  for (const WatchdogOutcome& o : outcomes) {
    all = all && o.confirmed;
    report += FormatWatchdogReport(o, inv.parent_pid, asked) + "\n";
  }
  if (!inv.config.log_path.empty()) {
    const int fd =
        open(inv.config.log_path.c_str(), O_WRONLY | O_APPEND | O_CREAT | O_CLOEXEC, 0644);
    if (fd >= 0) {
      WriteAll(fd, report);  // O_APPEND: whole lines, after whatever the parent wrote
      fsync(fd);
      close(fd);
    } else {
      report +=
          "[watchdog] cannot append to " + inv.config.log_path + ": " + std::strerror(errno) + "\n";
    }
  }
  WriteAll(2, report);
  return all ? kWatchdogFiredConfirmed : kWatchdogFiredUnconfirmed;
}

WatchdogLaunch SelfWatchdogLaunch(const std::string& argv0, const std::string& subcommand) {
  return WatchdogLaunch{"/proc/self/exe", argv0, {subcommand}};
}

std::unique_ptr<Watchdog> Watchdog::Start(const WatchdogLaunch& launch,
                                          const WatchdogConfig& config) {
  if (!launch.enabled()) throw std::invalid_argument("Watchdog::Start: no executable");
  if (std::string e = config.Validate(); !e.empty())
    throw std::invalid_argument("watchdog configuration: " + e);
  const std::string who = "watchdog (" + launch.executable + ")";
  int life[2], ready[2];
  if (pipe2(life, O_CLOEXEC) != 0) throw std::runtime_error(who + ": pipe2 failed");
  if (pipe2(ready, O_CLOEXEC) != 0) {
    close(life[0]);
    close(life[1]);
    throw std::runtime_error(who + ": pipe2 failed");
  }
  // The child's ends above any descriptor the dup2 actions below write to (so that no action's
  // source is also a target).
  const int life_r = fcntl(life[0], F_DUPFD_CLOEXEC, 10);
  const int ready_w = fcntl(ready[1], F_DUPFD_CLOEXEC, 10);
  close(life[0]);
  close(ready[1]);
  auto close_all = [&] {
    for (int fd : {life_r, ready_w, life[1], ready[0]})
      if (fd >= 0) close(fd);
  };
  if (life_r < 0 || ready_w < 0) {
    close_all();
    throw std::runtime_error(who + ": fcntl(F_DUPFD_CLOEXEC) failed");
  }

  WatchdogInvocation inv;
  inv.config = config;
  inv.control_fd = 3;
  inv.ready_fd = 4;
  inv.parent_pid = getpid();
  std::vector<std::string> args = {launch.argv0.empty() ? launch.executable : launch.argv0};
  args.insert(args.end(), launch.args.begin(), launch.args.end());
  for (std::string& a : FormatWatchdogArguments(inv)) args.push_back(std::move(a));
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);

  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_adddup2(&fa, life_r, 3);
  posix_spawn_file_actions_adddup2(&fa, ready_w, 4);
  // Nothing else: the generators' sockets (Asio opens them without close-on-exec) must close
  // with this process, or an instrument serving one connection would never let the watchdog in.
  posix_spawn_file_actions_addclosefrom_np(&fa, 5);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  sigset_t none, defaults;
  sigemptyset(&none);
  sigemptyset(&defaults);
  for (int s : {SIGINT, SIGHUP, SIGQUIT, SIGTERM, SIGPIPE, SIGCHLD}) sigaddset(&defaults, s);
  posix_spawnattr_setsigmask(&attr, &none);
  posix_spawnattr_setsigdefault(&attr, &defaults);
  posix_spawnattr_setflags(&attr,
                           POSIX_SPAWN_SETSID | POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, launch.executable.c_str(), &fa, &attr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  posix_spawnattr_destroy(&attr);
  close(life_r);
  close(ready_w);
  if (rc != 0) {
    close(life[1]);
    close(ready[0]);
    throw std::runtime_error(who + ": cannot start: " + std::strerror(rc));
  }
  const int child_pidfd = PidfdOpen(pid);
  // Armed: one byte on the ready pipe. EOF (bad arguments, exec failure) or silence: refuse.
  char b = 0;
  const short ev = PollOne(ready[0], kArmTimeoutMs);
  const bool ok = (ev & POLLIN) && read(ready[0], &b, 1) == 1 && b == kArmedByte;
  close(ready[0]);
  std::unique_ptr<Watchdog> wd(
      new Watchdog(pid, life[1], child_pidfd, config.retry_window_ms + 2000));
  if (!ok) {
    wd->StandDown();
    std::lock_guard lock(wd->mu_);
    const int status = wd->status_;
    throw std::runtime_error(who + " did not report armed within " + std::to_string(kArmTimeoutMs) +
                             " ms (exit status " + std::to_string(status) +
                             "; its stderr says why)");
  }
  return wd;
}

Watchdog::Watchdog(pid_t pid, int life_fd, int pidfd, int wait_ms)
    : pid_(pid), life_fd_(life_fd), pidfd_(pidfd), fire_wait_ms_(wait_ms) {}

Watchdog::~Watchdog() {
  std::lock_guard lock(mu_);
  if (life_fd_ >= 0) {
    close(life_fd_);  // EOF: the watchdog fires
    life_fd_ = -1;
  }
  Reap(fire_wait_ms_);
  if (pidfd_ >= 0) close(pidfd_);
}

int Watchdog::StandDown() {
  std::lock_guard lock(mu_);
  if (life_fd_ >= 0) {
    WriteByteNoSigpipe(life_fd_, kStandDownByte);
    close(life_fd_);
    life_fd_ = -1;
  }
  return Reap(kStandDownTimeoutMs);
}

int Watchdog::ActNow() {
  std::lock_guard lock(mu_);
  if (life_fd_ >= 0) {
    WriteByteNoSigpipe(life_fd_, kActNowByte);
    close(life_fd_);
    life_fd_ = -1;
  }
  return Reap(fire_wait_ms_);
}

WatchdogHandOver HandOverToWatchdog(Watchdog& watchdog) {
  // Our connections closed first: an instrument serving one connection at a time (the strictest
  // 33500, docs/watchdog.md) would not serve the watchdog's while ours is open.
  DisconnectOpenGenerators();
  WatchdogHandOver h;
  h.watchdog_status = watchdog.ActNow();
  h.confirmed = h.watchdog_status == kWatchdogFiredConfirmed;
  h.exit_status = h.confirmed ? kExitSafeStateByWatchdog : kExitSafeStateUnconfirmed;
  const std::string who = "the watchdog (pid " + std::to_string(watchdog.pid()) + ", exit status " +
                          std::to_string(h.watchdog_status) + ")";
  h.text = h.confirmed ? "safe state NOT CONFIRMED by msmcal itself; " + who +
                             ", asked to act on new connections, confirmed every output off (its "
                             "lines: [watchdog ...] in the log)"
                       : "safe state NOT CONFIRMED by msmcal itself, nor by " + who +
                             ": CHECK THE GENERATORS' OUTPUTS BY HAND";
  return h;
}

int Watchdog::Reap(int timeout_ms) {
  if (reaped_) return status_;
  reaped_ = true;
  bool exited = true;
  if (pidfd_ >= 0) exited = (PollOne(pidfd_, timeout_ms) & POLLIN) != 0;
  if (!exited) kill(pid_, SIGKILL);  // our own child, by its pid: it must not outlive the run
  int status = 0;
  pid_t r;
  do {
    r = waitpid(pid_, &status, 0);
  } while (r < 0 && errno == EINTR);
  if (r == pid_ && WIFEXITED(status) && exited) status_ = WEXITSTATUS(status);
  return status_;
}

}  // namespace msmcal::gen
