// The guided console operator in lab mode (no simulated world behind it): the person at the rig
// is this test's "operator" thread, which reads the instructions from the console's output pipe,
// changes the simulated rig as told (as a person moves the sliding plate) and presses Enter. The
// operator decides which frames show the new setup from the host arrival time alone (the
// Aravis driver's CLOCK_REALTIME stamp), so this checks that rule against the real camera path:
// every frame the session keeps is, pixel for pixel, the render of the setup it was taken for.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <ctime>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <thread>
#include <vector>

#include "sessions/orchestrator/console_operator.h"
#include "sessions/orchestrator/orchestrator.h"
#include "simulation/twin/demo_rig.h"
#include "tests/testing/tiny_sim.h"

namespace msmcal::orchestrator {
namespace {

namespace fs = std::filesystem;
using twin::DemoRig;
using twin::DemoRigOptions;
using twin::SimulatedWorld;

int64_t RealtimeNs() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// The console's RigOperator calls go to the console; the simulated world follows each frame once
// the console returned (the person changed the rig at a prompt; the frame's noise and trigger
// selection, which no person changes, follow every frame), and the Hall device comes from the
// demo rig (it serves each recording from its own mock MCU, where the lab has one device for
// both).
class LabRig : public RigOperator {
 public:
  LabRig(ConsoleOperator& console, SimulatedWorld& world) : console_(console), world_(world) {}
  void PrepareStep1Frame(size_t index) override {
    console_.PrepareStep1Frame(index);
    world_.PrepareStep1Frame(index);
  }
  void PrepareStep2Frame(size_t index) override {
    console_.PrepareStep2Frame(index);
    world_.PrepareStep2Frame(index);
  }
  bool FrameShowsCurrentSetup(const camera::FrameInfo& info) const override {
    return console_.FrameShowsCurrentSetup(info);
  }
  std::string PrepareHallRecording(HallRun run) override {
    (void)console_.PrepareHallRecording(run);
    return world_.PrepareHallRecording(run);
  }

 private:
  ConsoleOperator& console_;
  SimulatedWorld& world_;
};

TEST(LabOperator, AFrameCountsOnlyAfterTheOperatorConfirmedTheSetup) {
  DemoRigOptions ro;
  ro.sim = msmcal::testing::TinySim();
  DemoRig rig(ro);
  const dataset::Recording plan = rig.Plan();
  const fs::path dir = fs::path(::testing::TempDir()) / "lab_operator";
  fs::remove_all(dir);

  int answers[2], console_out[2];
  ASSERT_EQ(::pipe(answers), 0);
  ASSERT_EQ(::pipe(console_out), 0);
  ConsoleOperatorOptions co;
  co.input_fd = answers[0];
  co.output_fd = console_out[1];
  co.mcu_device = "/dev/unused";  // LabRig hands out the demo rig's devices
  co.host_clock_ns = RealtimeNs;
  ConsoleOperator console(plan, co, nullptr);
  LabRig lab(console, rig.world());

  // The set-up changes of the plan, counted here from the frames themselves: a step-1 frame asks
  // when its pose or its beams differ from the previous frame's, a step-2 frame when its beams
  // do (its kind, the drive mode, is the generators' business); plus the two Hall set-ups.
  // Repeated exposures never ask.
  auto sorted = [](std::vector<int> v) {
    std::sort(v.begin(), v.end());
    return v;
  };
  size_t changes = 2;
  for (size_t i = 0; i < plan.step1.size(); ++i)
    changes += i == 0 || plan.step1[i].pose != plan.step1[i - 1].pose ||
               sorted(plan.step1[i].beams) != sorted(plan.step1[i - 1].beams);
  for (size_t i = 0; i < plan.step2.size(); ++i)
    changes += i == 0 || sorted(plan.step2[i].beams) != sorted(plan.step2[i - 1].beams);
  ASSERT_LT(changes, plan.step1.size() + plan.step2.size() + 2);  // the plan repeats exposures
  EXPECT_EQ(static_cast<size_t>(console.total_steps()), changes);

  // The person: Enter at every prompt (the world follows the frames, see LabRig).
  std::string transcript;
  size_t prompts = 0;
  std::thread person([&] {
    std::string pending;
    char buf[4096];
    for (;;) {
      pollfd p{console_out[0], POLLIN, 0};
      if (::poll(&p, 1, 60'000) <= 0) return;  // the session failed; the test below says why
      const ssize_t n = ::read(console_out[0], buf, sizeof(buf));
      if (n <= 0) return;  // the session ended (the console's end closed below)
      pending.append(buf, static_cast<size_t>(n));
      transcript.append(buf, static_cast<size_t>(n));
      size_t at;
      while ((at = pending.find(kConsolePrompt)) != std::string::npos) {
        pending.erase(0, at + std::string(kConsolePrompt).size());
        ++prompts;
        ASSERT_EQ(::write(answers[1], "\n", 1), 1);
      }
    }
  });

  OrchestratorOptions options = rig.MakeOrchestratorOptions(dir);
  options.run_kind = "lab";
  SessionResult result;
  try {
    result = RunSession(options, plan, lab, nullptr);
  } catch (const std::exception& e) {
    ::close(console_out[1]);
    person.join();
    FAIL() << e.what() << "\nconsole:\n" << transcript;
  }
  ::close(console_out[1]);  // the person sees the end of the output
  person.join();
  for (int fd : {answers[0], answers[1], console_out[0]}) ::close(fd);

  EXPECT_EQ(prompts, changes) << transcript;
  EXPECT_EQ(console.confirmations(), static_cast<int>(changes));
  ASSERT_EQ(result.frames.size(), plan.step1.size() + plan.step2.size());
  for (const auto& f : result.frames) EXPECT_TRUE(f.accepted) << f.file << ": " << f.reason;
  for (size_t i = 0; i < plan.step1.size(); ++i) {
    const cv::Mat grabbed = cv::imread((dir / plan.step1[i].file).string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(grabbed.empty()) << plan.step1[i].file;
    EXPECT_EQ(cv::norm(grabbed, rig.sim().RenderStep1Frame(i), cv::NORM_INF), 0.0)
        << plan.step1[i].file << " is not the render of its own setup";
  }
  EXPECT_NE(transcript.find("sliding plate"), std::string::npos) << transcript;
  EXPECT_TRUE(result.safe_state_confirmed);
}

}  // namespace
}  // namespace msmcal::orchestrator
