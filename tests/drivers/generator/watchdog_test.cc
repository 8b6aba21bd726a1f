// The watchdog (issue 17) against the mock 33520B pair over loopback: a child process drives the
// outputs on through the real driver with the watchdog armed; SIGKILL of the child must leave
// every channel of both units off within 2 s (waited for on the mock's state-change
// notifications, bounded), with the watchdog's report in the log; a clean exit must stand the
// watchdog down without one more connection to either unit. No sleeps: pipes, pidfds and the
// mock's condition variable.
#include "drivers/generator/watchdog.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/prctl.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "drivers/generator/rig_generators.h"
#include "drivers/generator/safe_state.h"
#include "drivers/scpi/scpi_client.h"
#include "test_rig.h"
#include "tests/testing/child_process.h"

namespace msmcal::gen {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

using msmcal::testing::Child;
using msmcal::testing::ReadLine;
using msmcal::testing::Spawn;

int PidfdOpen(pid_t pid) { return static_cast<int>(syscall(SYS_pidfd_open, pid, 0)); }

// Waits (bounded) for `pid`, a child of this process, to exit; returns its exit status, or -1
// (timeout, or ended by a signal).
int WaitExit(pid_t pid, int pidfd, int timeout_ms) {
  pollfd p{pidfd, POLLIN, 0};
  if (poll(&p, 1, timeout_ms) != 1) return -1;
  int status = 0;
  if (waitpid(pid, &status, 0) != pid || !WIFEXITED(status)) return -1;
  return WEXITSTATUS(status);
}

std::string ReadFile(const fs::path& f) {
  std::ifstream in(f);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

bool BothChannelsOff(const sim::Mock33520B& u) {
  return !u.SignalLocked(1).output_on && !u.SignalLocked(2).output_on;
}

class WatchdogTest : public ::testing::Test {
 protected:
  void SetUp() override {
    // The watchdog outlives the SIGKILLed child; as subreaper this test becomes its parent and
    // can read its exit status.
    ASSERT_EQ(prctl(PR_SET_CHILD_SUBREAPER, 1), 0);
    std::string name = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    std::replace(name.begin(), name.end(), '/', '_');  // parameterised: "Test/Param"
    log_ = fs::temp_directory_path() /
           ("watchdog_test_" + std::to_string(getpid()) + "_" + name + ".log");
    fs::remove(log_);
  }
  void TearDown() override { fs::remove(log_); }

  // Starts the driving child; returns the watchdog's pid (from the child's "ready" line).
  pid_t StartDriver() {
    child_ = Spawn({MSMCAL_WATCHDOG_CHILD, "drive", testing::SourceDir() + "/config/rig.yaml",
                    std::to_string(pair_.port(1)), std::to_string(pair_.port(2)), log_.string()});
    const std::string ready = ReadLine(child_.from_child);
    EXPECT_EQ(ready.rfind("ready ", 0), 0u) << ready;
    if (ready.rfind("ready ", 0) != 0) return -1;
    return static_cast<pid_t>(std::stol(ready.substr(6)));
  }

  sim::MockGeneratorPair pair_{sim::GeneratorPairOptions{}};
  fs::path log_;
  Child child_;
};

TEST_F(WatchdogTest, SigkillOfTheDrivingProcessTurnsEveryOutputOffWithinTwoSeconds) {
  const pid_t wd = StartDriver();
  ASSERT_GT(wd, 0);
  const int wd_pidfd = PidfdOpen(wd);
  ASSERT_GE(wd_pidfd, 0);
  for (int u = 1; u <= 2; ++u) {
    EXPECT_TRUE(pair_.unit(u).Signal(1).output_on) << "unit " << u;
    EXPECT_TRUE(pair_.unit(u).Signal(2).output_on) << "unit " << u;
  }
  const uint64_t connections1 = pair_.server(1).ConnectionsAccepted();
  const uint64_t connections2 = pair_.server(2).ConnectionsAccepted();

  const auto killed_at = Clock::now();
  ASSERT_EQ(kill(child_.pid, SIGKILL), 0);
  auto left_ms = [&] {
    return std::max<int64_t>(
        0, 2000 - std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - killed_at)
                      .count());
  };
  EXPECT_TRUE(pair_.unit(1).WaitUntil(BothChannelsOff, left_ms()));
  EXPECT_TRUE(pair_.unit(2).WaitUntil(BothChannelsOff, left_ms()));
  const auto off_after = Clock::now() - killed_at;
  EXPECT_LT(off_after, std::chrono::seconds(2));
  for (int u = 1; u <= 2; ++u) {
    EXPECT_FALSE(pair_.unit(u).Signal(1).output_on) << "unit " << u;
    EXPECT_FALSE(pair_.unit(u).Signal(2).output_on) << "unit " << u;
  }

  int status = 0;
  ASSERT_EQ(waitpid(child_.pid, &status, 0), child_.pid);
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL);
  EXPECT_EQ(WaitExit(wd, wd_pidfd, 5000), kWatchdogFiredConfirmed);
  close(wd_pidfd);
  // One connection per unit: the watchdog's, after the kernel closed the dead child's.
  EXPECT_EQ(pair_.server(1).ConnectionsAccepted(), connections1 + 1);
  EXPECT_EQ(pair_.server(2).ConnectionsAccepted(), connections2 + 1);

  const std::string log = ReadFile(log_);
  for (int u = 1; u <= 2; ++u) {
    const std::string what = "unit" + std::to_string(u) +
                             " (127.0.0.1:" + std::to_string(pair_.port(u)) +
                             ") outputs off, confirmed";
    EXPECT_NE(log.find(what), std::string::npos) << log;
  }
  EXPECT_NE(log.find("process " + std::to_string(child_.pid) +
                     " ended without standing the watchdog down"),
            std::string::npos)
      << log;
  close(child_.to_child);
  close(child_.from_child);
}

TEST_F(WatchdogTest, CleanExitStandsTheWatchdogDownWithoutContactingTheGenerators) {
  const pid_t wd = StartDriver();
  ASSERT_GT(wd, 0);
  const int wd_pidfd = PidfdOpen(wd);
  ASSERT_GE(wd_pidfd, 0);
  // Its own session: the terminal's Ctrl-C and hangup go to msmcal, not to the watchdog; and
  // sent to it anyway they are ignored (a fatal signal would end it before the stand-down and
  // the child would report -1 below).
  EXPECT_EQ(getsid(wd), wd);
  EXPECT_NE(getsid(wd), getsid(0));
  ASSERT_EQ(kill(wd, SIGINT), 0);
  ASSERT_EQ(kill(wd, SIGHUP), 0);
  const uint64_t connections1 = pair_.server(1).ConnectionsAccepted();
  const uint64_t connections2 = pair_.server(2).ConnectionsAccepted();

  close(child_.to_child);  // EOF: the child returns from main
  EXPECT_EQ(ReadLine(child_.from_child), "watchdog exit " + std::to_string(kWatchdogStoodDown));
  int status = 0;
  ASSERT_EQ(waitpid(child_.pid, &status, 0), child_.pid);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  // The child reaped its watchdog before it exited: it did not outlive the run.
  pollfd p{wd_pidfd, POLLIN, 0};
  EXPECT_EQ(poll(&p, 1, 0), 1);
  close(wd_pidfd);

  EXPECT_TRUE(pair_.unit(1).WaitUntil(BothChannelsOff, 0));
  EXPECT_TRUE(pair_.unit(2).WaitUntil(BothChannelsOff, 0));
  EXPECT_EQ(pair_.server(1).ConnectionsAccepted(), connections1);
  EXPECT_EQ(pair_.server(2).ConnectionsAccepted(), connections2);
  EXPECT_FALSE(fs::exists(log_)) << ReadFile(log_);
  close(child_.from_child);
}

// The strictest 33500 (docs/watchdog.md): one SCPI connection at a time, a second one queued
// (accepted, served once the first closes) or closed at once. The watchdog connects only after
// the dead process's sockets are closed, and retries a connection turned away, so it still
// switches everything off within 2 s of the SIGKILL; then `OUTP1?;:OUTP2?` on a new connection
// confirms it on each unit.
class WatchdogOneConnectionTest : public WatchdogTest,
                                  public ::testing::WithParamInterface<sim::SecondConnection> {
 protected:
  static sim::GeneratorPairOptions OneAtATime(sim::SecondConnection mode) {
    sim::GeneratorPairOptions o;
    o.limits1.second_connection = o.limits2.second_connection = mode;
    return o;
  }
  WatchdogOneConnectionTest() { strict_.emplace(OneAtATime(GetParam())); }
  std::optional<sim::MockGeneratorPair> strict_;  // instead of the fixture's pair_
};

TEST_P(WatchdogOneConnectionTest, SigkillTurnsEveryOutputOffWithinTwoSeconds) {
  sim::MockGeneratorPair& pair = *strict_;
  child_ = Spawn({MSMCAL_WATCHDOG_CHILD, "drive", testing::SourceDir() + "/config/rig.yaml",
                  std::to_string(pair.port(1)), std::to_string(pair.port(2)), log_.string()});
  const std::string ready = ReadLine(child_.from_child);
  ASSERT_EQ(ready.rfind("ready ", 0), 0u) << ready;
  const pid_t wd = static_cast<pid_t>(std::stol(ready.substr(6)));
  const int wd_pidfd = PidfdOpen(wd);
  ASSERT_GE(wd_pidfd, 0);
  for (int u = 1; u <= 2; ++u) ASSERT_TRUE(pair.unit(u).AnyOutputOn()) << "unit " << u;

  // The mode is in effect: while the driving child holds its connection, another client is not
  // served (queued: no reply within its deadline; closed: the connection is lost).
  {
    scpi::ScpiClientOptions probe_options;
    probe_options.port = pair.port(1);
    probe_options.io_timeout_ms = 300;
    scpi::ScpiClient probe(probe_options);
    probe.Connect();
    try {
      const std::string reply = probe.Query("*IDN?");
      ADD_FAILURE() << "a second connection was served: " << reply;
    } catch (const scpi::ScpiError& e) {
      EXPECT_EQ(e.kind(), GetParam() == sim::SecondConnection::kQueue
                              ? scpi::ErrorKind::kTimeout
                              : scpi::ErrorKind::kConnectionLost)
          << e.what();
    }
  }  // closed: a queued probe is dropped when its turn comes

  const auto killed_at = Clock::now();
  ASSERT_EQ(kill(child_.pid, SIGKILL), 0);
  auto left_ms = [&] {
    return std::max<int64_t>(
        0, 2000 - std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - killed_at)
                      .count());
  };
  EXPECT_TRUE(pair.unit(1).WaitUntil(BothChannelsOff, left_ms()));
  EXPECT_TRUE(pair.unit(2).WaitUntil(BothChannelsOff, left_ms()));
  EXPECT_LT(Clock::now() - killed_at, std::chrono::seconds(2));
  int status = 0;
  ASSERT_EQ(waitpid(child_.pid, &status, 0), child_.pid);
  EXPECT_EQ(WaitExit(wd, wd_pidfd, 5000), kWatchdogFiredConfirmed);
  close(wd_pidfd);

  // Confirmed by the instrument: the watchdog's connection is closed, so this one is served.
  for (int u = 1; u <= 2; ++u) {
    scpi::ScpiClientOptions o;
    o.port = pair.port(u);
    o.io_timeout_ms = 2000;
    scpi::ScpiClient confirm(o);
    confirm.Connect();
    EXPECT_EQ(confirm.Query("OUTP1?;:OUTP2?"), "0;0") << "unit " << u;
  }
  const std::string log = ReadFile(log_);
  for (int u = 1; u <= 2; ++u) {
    EXPECT_NE(log.find("unit" + std::to_string(u) + " (127.0.0.1:" + std::to_string(pair.port(u)) +
                       ") outputs off, confirmed"),
              std::string::npos)
        << log;
  }
  if (GetParam() == sim::SecondConnection::kClose) {
    EXPECT_GE(pair.server(1).Stats().connections_turned_away, 1u);  // the probe
  }
  close(child_.to_child);
  close(child_.from_child);
}

INSTANTIATE_TEST_SUITE_P(SecondConnection, WatchdogOneConnectionTest,
                         ::testing::Values(sim::SecondConnection::kQueue,
                                           sim::SecondConnection::kClose),
                         [](const ::testing::TestParamInfo<sim::SecondConnection>& i) {
                           return std::string(i.param == sim::SecondConnection::kQueue ? "Queued"
                                                                                       : "Closed");
                         });

TEST(WatchdogSwitchOff, GivesUpOnAnUnreachableUnitWithinTheRetryWindowAndSaysWhy) {
  sim::MockGeneratorPair pair{sim::GeneratorPairOptions{}};
  const RigGeneratorConfig rig = testing::RigConfigFor(pair);
  {
    auto g = OpenKeysight33500(rig.unit1);
    ASSERT_TRUE(g->SetOutput(1, true));
    ASSERT_TRUE(g->SetOutput(2, true));
  }
  const int dead_port = pair.port(2);
  pair.server(2).Stop();
  WatchdogConfig c = WatchdogConfigFor(rig, "");
  c.retry_window_ms = 600;
  c.attempt_timeout_ms = 200;
  const auto t0 = Clock::now();
  const std::vector<WatchdogOutcome> out = SwitchOutputsOff(c);
  const auto took = Clock::now() - t0;
  ASSERT_EQ(out.size(), 2u);
  EXPECT_TRUE(out[0].confirmed);
  EXPECT_EQ(out[0].attempts, 1);
  EXPECT_FALSE(pair.unit(1).AnyOutputOn());
  EXPECT_FALSE(out[1].confirmed);
  EXPECT_GT(out[1].attempts, 1);
  EXPECT_NE(out[1].last_error.find("127.0.0.1:" + std::to_string(dead_port)), std::string::npos)
      << out[1].last_error;
  EXPECT_LT(took, std::chrono::milliseconds(600 + 500));
  const std::string line = FormatWatchdogReport(out[1], 1234);
  EXPECT_NE(
      line.find("unit2 (127.0.0.1:" + std::to_string(dead_port) + ") outputs NOT CONFIRMED OFF: "),
      std::string::npos)
      << line;
}

TEST(WatchdogArguments, RoundTripAndErrorsNameTheArgument) {
  WatchdogInvocation inv;
  inv.config.generators = {{"unit1", "10.0.0.5", 5025}, {"unit2", "::1", 5026}};
  inv.config.log_path = "/tmp/a b/session_log.txt";
  inv.config.retry_window_ms = 1200;
  inv.config.attempt_timeout_ms = 300;
  inv.parent_pid = 4242;
  const WatchdogInvocation back = ParseWatchdogArguments(FormatWatchdogArguments(inv));
  EXPECT_EQ(back.control_fd, 3);
  EXPECT_EQ(back.ready_fd, 4);
  EXPECT_EQ(back.parent_pid, 4242);
  EXPECT_EQ(back.config.log_path, inv.config.log_path);
  EXPECT_EQ(back.config.retry_window_ms, 1200);
  EXPECT_EQ(back.config.attempt_timeout_ms, 300);
  ASSERT_EQ(back.config.generators.size(), 2u);
  EXPECT_EQ(back.config.generators[1].name, "unit2");
  EXPECT_EQ(back.config.generators[1].host, "::1");
  EXPECT_EQ(back.config.generators[1].port, 5026);

  auto error = [](std::vector<std::string> a) {
    try {
      ParseWatchdogArguments(a);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::vector<std::string> base = {"--control-fd", "3", "--ready-fd", "4",
                                         "--parent-pid", "7"};
  auto with = [&](std::vector<std::string> more) {
    std::vector<std::string> a = base;
    a.insert(a.end(), more.begin(), more.end());
    return a;
  };
  EXPECT_NE(error(with({"--generator", "unit1=host:99999"})).find("port = '99999'"),
            std::string::npos);
  EXPECT_NE(error(with({"--generator", "unit1"})).find("expected NAME=HOST:PORT"),
            std::string::npos);
  EXPECT_NE(error(with({})).find("generators: empty"), std::string::npos);
  EXPECT_NE(error(with({"--bogus", "1"})).find("unknown argument '--bogus'"), std::string::npos);
  EXPECT_NE(error({"--ready-fd", "4", "--parent-pid", "7", "--generator", "u=h:1"})
                .find("--control-fd is required"),
            std::string::npos);
  EXPECT_NE(error(with({"--retry-ms", "100", "--attempt-ms", "400", "--generator", "u=h:1"}))
                .find("attempt_timeout_ms = 400"),
            std::string::npos);
}

// This process's own safe state unconfirmed, the process alive: HandOverToWatchdog closes this
// process's connections (the units serve one at a time) and the watchdog, asked to act, switches
// every output off on its own connections and says so; the verdict comes back (exit 76).
TEST_F(WatchdogTest, AskedToActWhileTheParentLivesSwitchesEveryOutputOff) {
  sim::GeneratorPairOptions one_at_a_time;
  one_at_a_time.limits1.second_connection = one_at_a_time.limits2.second_connection =
      sim::SecondConnection::kQueue;
  sim::MockGeneratorPair pair(one_at_a_time);
  const RigGeneratorConfig config = testing::RigConfigFor(pair);
  auto master = OpenKeysight33500(config.unit1);
  auto slave = OpenKeysight33500(config.unit2);
  RigGenerators rig(*master, *slave);
  rig.Apply(PlanRigSignals(config.signals));
  for (int u = 1; u <= 2; ++u) ASSERT_TRUE(pair.unit(u).AnyOutputOn()) << "unit " << u;
  std::unique_ptr<Watchdog> wd = Watchdog::Start(
      WatchdogLaunch{MSMCAL_WATCHDOG_CHILD, "", {"watchdog"}}, WatchdogConfigFor(config, log_));

  const WatchdogHandOver h = HandOverToWatchdog(*wd);
  EXPECT_TRUE(h.confirmed) << h.text;
  EXPECT_EQ(h.watchdog_status, kWatchdogFiredConfirmed);
  EXPECT_EQ(h.exit_status, kExitSafeStateByWatchdog);
  EXPECT_NE(h.text.find("confirmed every output off"), std::string::npos) << h.text;
  for (int u = 1; u <= 2; ++u) EXPECT_TRUE(BothChannelsOff(pair.unit(u))) << "unit " << u;
  const std::string log = ReadFile(log_);
  for (int u = 1; u <= 2; ++u) {
    EXPECT_NE(log.find("asked the watchdog to act (its own safe state was not confirmed): unit" +
                       std::to_string(u) + " (127.0.0.1:" + std::to_string(pair.port(u)) +
                       ") outputs off, confirmed"),
              std::string::npos)
        << log;
  }
  // Ours are closed.
  EXPECT_EQ(master->SetOutput(1, true).code, common::StatusCode::kUnavailable);
  EXPECT_EQ(wd->StandDown(), kWatchdogFiredConfirmed);  // reaped once, idempotent
}

TEST(WatchdogStart, RefusesWhenTheWatchdogCannotArm) {
  WatchdogConfig c;
  c.generators = {{"unit1", "127.0.0.1", 5025}};
  WatchdogLaunch bad{MSMCAL_WATCHDOG_CHILD, "", {"not-a-role"}};  // exits 2 at once
  try {
    Watchdog::Start(bad, c);
    ADD_FAILURE() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("did not report armed"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace msmcal::gen
