// `--operator hook:CMD`: the hook program gets one set-up JSON per physical change on stdin and
// the session goes on when it exits 0; a failing hook aborts with the generator outputs off, the
// error naming the hook and its status. Sessions run on the demo rig (its SimulatedWorld is the
// inner operator that actually changes the rig after the hook confirmed).
#include "sessions/orchestrator/hook_operator.h"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "mocks/generator/mock_server.h"
#include "sessions/orchestrator/orchestrator.h"
#include "simulation/twin/demo_rig.h"
#include "tests/testing/tiny_sim.h"

namespace msmcal::orchestrator {
namespace {

namespace fs = std::filesystem;
using twin::DemoRig;
using twin::DemoRigOptions;

fs::path FreshDir(const std::string& name) {
  const fs::path d = fs::path(::testing::TempDir()) / ("hook_operator_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::vector<std::string> Lines(const fs::path& file) {
  std::ifstream in(file);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  return lines;
}

std::string Quote(const fs::path& p) { return "'" + p.string() + "'"; }

TEST(HookCommand, StatusTimeoutAndInput) {
  const fs::path dir = FreshDir("command");
  int status = RunHookCommand("cat > " + Quote(dir / "in.txt"), "{\"a\": 1}\n", 5000);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  EXPECT_EQ(Lines(dir / "in.txt"), std::vector<std::string>{"{\"a\": 1}"});
  status = RunHookCommand("exit 3", "", 5000);
  EXPECT_EQ(DescribeWaitStatus(status), "exit status 3");
  status = RunHookCommand("kill -9 $$", "", 5000);
  EXPECT_EQ(DescribeWaitStatus(status).rfind("killed by signal 9", 0), 0u)
      << DescribeWaitStatus(status);
  // A hook that does not read its input is not an error of msmcal (no SIGPIPE).
  status = RunHookCommand("true", std::string(1 << 20, 'x'), 5000);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  try {
    RunHookCommand("exec sleep 30", "", 200);
    FAIL() << "no timeout";
  } catch (const HookFailed& e) {
    EXPECT_NE(std::string(e.what()).find("'exec sleep 30': no answer within 200 ms (killed)"),
              std::string::npos)
        << e.what();
  }
}

// A hook that records what it gets and exits 0: one call per set-up (not per frame), in the
// orchestrator's order, each the Setup's JSON; then the truth request.
TEST(HookOperator, TheSessionCompletesWithOneCallPerSetup) {
  DemoRigOptions ro;
  ro.sim = msmcal::testing::TinySim();
  DemoRig rig(ro);
  const fs::path dir = FreshDir("complete");
  const fs::path log = dir.parent_path() / "hook_operator_complete.jsonl";
  fs::remove(log);
  const dataset::Recording plan = rig.Plan();
  HookOperatorOptions ho;
  ho.command = "cat >> " + Quote(log);
  ho.timeout_ms = 20000;
  HookOperator op(plan, ho, &rig.world());
  const size_t setups = op.setups().setups.size();
  ASSERT_LT(setups, plan.step1.size() + plan.step2.size() + 2);  // exposures share a set-up
  OrchestratorOptions options = rig.MakeOrchestratorOptions(dir / "session");
  const SessionResult result = RunSession(options, plan, op, nullptr);
  ASSERT_EQ(result.frames.size(), plan.step1.size() + plan.step2.size());
  EXPECT_TRUE(result.safe_state_confirmed);
  EXPECT_EQ(op.calls(), static_cast<int>(setups));
  op.RequestTruth(dir / "session" / "truth");
  const std::vector<std::string> lines = Lines(log);
  ASSERT_EQ(lines.size(), setups + 1);
  std::vector<std::string> frames;
  for (size_t k = 0; k < setups; ++k) {
    const setup::Setup s = setup::SetupFromJson(lines[k]);
    EXPECT_EQ(s.block, static_cast<int>(k) + 1);
    EXPECT_EQ(s.of, static_cast<int>(setups));
    EXPECT_EQ(s.text, op.setups().setups[k].text);
    frames.insert(frames.end(), s.frames.begin(), s.frames.end());
  }
  EXPECT_EQ(frames.size(), plan.step1.size() + plan.step2.size());
  const nlohmann::json truth = nlohmann::json::parse(lines.back());
  EXPECT_EQ(truth["kind"], "truth_request");
  EXPECT_EQ(truth["dir"], (dir / "session" / "truth").lexically_normal().string());
}

// The hook fails at its third call: the session aborts, generator outputs off, the error names
// the hook and its exit status.
TEST(HookOperator, AFailingHookAbortsWithTheSafeState) {
  DemoRigOptions ro;
  ro.sim = msmcal::testing::TinySim();
  DemoRig rig(ro);
  const fs::path dir = FreshDir("fail");
  const fs::path count = dir / "calls";
  const dataset::Recording plan = rig.Plan();
  HookOperatorOptions ho;
  ho.command = "echo x >> " + Quote(count) + "; test $(wc -l < " + Quote(count) + ") -lt 3";
  HookOperator op(plan, ho, &rig.world());
  OrchestratorOptions options = rig.MakeOrchestratorOptions(dir / "session");
  bool outputs_were_on = false;
  try {
    RunSession(options, plan, op, [&](const std::string& line) {
      // Step 1 (MSM not mounted): the laser and the clock on, the drives off.
      if (line.find("step 1: frame 1/") != std::string::npos)
        outputs_were_on =
            !rig.generators().unit(1).AnyOutputOn() && rig.generators().unit(2).AnyOutputOn();
    });
    FAIL() << "expected the hook's failure to abort the session";
  } catch (const HookFailed& e) {
    EXPECT_NE(std::string(e.what()).find("operator hook 'echo x >> "), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("failed at set-up 3/"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("exit status 1"), std::string::npos) << e.what();
  }
  EXPECT_EQ(op.calls(), 2);
  EXPECT_TRUE(outputs_were_on);
  EXPECT_FALSE(rig.generators().unit(1).AnyOutputOn());
  EXPECT_FALSE(rig.generators().unit(2).AnyOutputOn());
  std::ifstream in(dir / "session" / "session_log.txt");
  std::stringstream log;
  log << in.rdbuf();
  EXPECT_NE(log.str().find("safe state: generator outputs off"), std::string::npos) << log.str();
  EXPECT_FALSE(fs::exists(dir / "session" / "session.yaml"));
}

}  // namespace
}  // namespace msmcal::orchestrator
