// Safe state on SIGTERM, SIGINT and normal exit, observed through the mock: a child process drives
// the mock units, gets the signal mid-run, and the test waits on the mock's state-change
// notifications until every output is off (no sleeps).
#include "drivers/generator/safe_state.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <string>

#include "drivers/generator/function_generator.h"
#include "mocks/generator/mock_server.h"
#include "test_rig.h"
#include "tests/testing/child_process.h"

namespace msmcal::gen {
namespace {

using msmcal::testing::Child;
using msmcal::testing::ReadAll;
using msmcal::testing::ReadLine;
using msmcal::testing::Spawn;

bool AnyOn(sim::MockGeneratorPair& pair) {
  return pair.unit(1).AnyOutputOn() || pair.unit(2).AnyOutputOn();
}

bool WaitAllOff(sim::MockGeneratorPair& pair) {
  auto off = [](const sim::Mock33520B& u) { return !u.AnyOutputOnLocked(); };
  return pair.unit(1).WaitUntil(off, 10000) && pair.unit(2).WaitUntil(off, 10000);
}

// The signal (0: normal exit); negative: that signal with the child's stdout a closed pipe (Ctrl-C
// on `msmcal ... | tee log` after tee is gone: logging raises SIGPIPE, which must not come before
// the safe state).
class SafeStateTest : public ::testing::TestWithParam<int> {};

TEST_P(SafeStateTest, OutputsGoOffWhenTheDrivingProcessEnds) {
  sim::MockGeneratorPair pair(sim::GeneratorPairOptions{});
  Child c = Spawn({MSMCAL_SAFE_STATE_CHILD, testing::SourceDir() + "/config/rig.yaml",
                   std::to_string(pair.port(1)), std::to_string(pair.port(2))});
  ASSERT_EQ(ReadLine(c.from_child), "ready");
  EXPECT_TRUE(pair.unit(1).AnyOutputOn());
  EXPECT_TRUE(pair.unit(2).AnyOutputOn());
  const int signo = std::abs(GetParam());
  if (GetParam() < 0) {
    close(c.from_child);
    c.from_child = -1;
  }
  if (GetParam() != 0) {
    ASSERT_EQ(kill(c.pid, signo), 0);
  } else {
    close(c.to_child);  // EOF: the child returns from main
    c.to_child = -1;
  }
  EXPECT_TRUE(WaitAllOff(pair));
  EXPECT_FALSE(AnyOn(pair));
  int status = 0;
  ASSERT_EQ(waitpid(c.pid, &status, 0), c.pid);
  if (GetParam() != 0) {
    EXPECT_TRUE(WIFSIGNALED(status));
    EXPECT_EQ(WTERMSIG(status), signo);
  } else {
    EXPECT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 0);
  }
  if (c.to_child >= 0) close(c.to_child);
  if (c.from_child >= 0) close(c.from_child);
}

INSTANTIATE_TEST_SUITE_P(Signals, SafeStateTest,
                         ::testing::Values(SIGTERM, SIGINT, SIGHUP, SIGQUIT, -SIGINT, 0));

// A safe state that cannot be confirmed at signal time is loud and has its own exit status:
// unit 1 drops the connection at its OUTP1 OFF, and again on the driver's new connection, so
// its channel 1 stays on; the process must say so on stderr and exit kExitSafeStateUnconfirmed
// (not die by the signal as if all were well). Unit 2 is still switched off.
TEST(SafeStateUnconfirmedTest, ASignalWhoseSafeStateFailsExitsUnconfirmedAndSaysSo) {
  sim::MockGeneratorPair pair(sim::GeneratorPairOptions{});
  for (int i = 0; i < 2; ++i) pair.server(1).InjectFault(sim::ParseFault("drop,match=OUTP1 OFF"));
  Child c = Spawn({MSMCAL_SAFE_STATE_CHILD, testing::SourceDir() + "/config/rig.yaml",
                   std::to_string(pair.port(1)), std::to_string(pair.port(2))},
                  /*stderr_to_stdout=*/true);
  ASSERT_EQ(ReadLine(c.from_child), "ready");
  ASSERT_EQ(kill(c.pid, SIGTERM), 0);
  const std::string said = ReadAll(c.from_child);
  int status = 0;
  ASSERT_EQ(waitpid(c.pid, &status, 0), c.pid);
  ASSERT_TRUE(WIFEXITED(status)) << "status " << status << "\n" << said;
  EXPECT_EQ(WEXITSTATUS(status), kExitSafeStateUnconfirmed) << said;
  EXPECT_NE(said.find("msmcal: SAFE STATE NOT CONFIRMED after signal 15 (SIGTERM): "),
            std::string::npos)
      << said;
  EXPECT_NE(said.find("check the generators' outputs by hand"), std::string::npos) << said;
  EXPECT_TRUE(pair.unit(1).AnyOutputOn());  // what "not confirmed" is about
  auto off = [](const sim::Mock33520B& u) { return !u.AnyOutputOnLocked(); };
  EXPECT_TRUE(pair.unit(2).WaitUntil(off, 10000));
  close(c.to_child);
  close(c.from_child);
}

TEST(SafeStateGuardTest, DestructorRunsActionAndDisarmSkipsIt) {
  int runs = 0;
  {
    SafeStateGuard g([&] { ++runs; });
  }
  EXPECT_EQ(runs, 1);
  {
    SafeStateGuard g([&] { ++runs; });
    g.Disarm();
  }
  EXPECT_EQ(runs, 1);
}

// A command's guard around a session's: each runs its own action when it leaves its scope.
TEST(SafeStateGuardTest, GuardsNest) {
  std::string order;
  {
    SafeStateGuard outer([&] { order += "outer;"; });
    {
      SafeStateGuard inner([&] { order += "inner;"; });
    }
    EXPECT_EQ(order, "inner;");
    SafeStateGuard again([&] { order += "again;"; });
  }
  EXPECT_EQ(order, "inner;again;outer;");
  EXPECT_EQ(SafeStateGuard::HandlingSignal(), 0);
}

// The driver registers every connection it opens; the registry's safe state reaches it, and a
// closed one is gone from it.
TEST(OpenGeneratorsTest, TheRegistryHoldsEveryOpenGenerator) {
  sim::MockGeneratorPair pair(sim::GeneratorPairOptions{});
  EXPECT_TRUE(SafeStateOfOpenGenerators().empty());
  const RigGeneratorConfig config = testing::RigConfigFor(pair);
  {
    auto g = OpenKeysight33500(config.unit1);
    ASSERT_TRUE(g->SetOutput(1, true));
    ASSERT_TRUE(pair.unit(1).AnyOutputOn());
    const auto outcomes = SafeStateOfOpenGenerators();
    ASSERT_EQ(outcomes.size(), 1u);
    EXPECT_TRUE(outcomes[0].confirmed);
    EXPECT_EQ(outcomes[0].who, "unit1 (127.0.0.1:" + std::to_string(pair.port(1)) + ")");
    EXPECT_FALSE(pair.unit(1).AnyOutputOn());
    EXPECT_EQ(FormatOpenGeneratorOutcomes(outcomes), outcomes[0].who + " off, confirmed");
  }
  EXPECT_TRUE(SafeStateOfOpenGenerators().empty());
}

}  // namespace
}  // namespace msmcal::gen
