// The guided console operator: instruction texts, the prompt protocol over a pipe (Enter, r, q,
// EOF, unknown answers), delegation to the inner operator, the lab-mode frame freshness rule and
// the live-figures lines.
#include "sessions/orchestrator/console_operator.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <string>
#include <vector>

namespace msmcal::orchestrator {
namespace {

// A small plan by hand: 3 beams, 2 poses + an identification frame, neutral / fast-only / scan.
dataset::Recording SmallPlan() {
  dataset::Recording p;
  p.beams = {{1, dataset::BeamRole::kEstimate},
             {2, dataset::BeamRole::kEstimate},
             {3, dataset::BeamRole::kValidate}};
  p.triggers = {{0, 0.010}, {1, 0.0525}, {2, 0.125}};
  p.step1 = {{"step1/0000.png", 0, {1, 2, 3}},
             {"step1/0001.png", 1, {1, 2, 3}},
             {"step1/0002.png", 1, {2}}};
  p.step2 = {{"step2/0000.png", dataset::Step2Kind::kNeutral, {}, {1, 2, 3}},
             {"step2/0001.png", dataset::Step2Kind::kFastOnly, {0, 2}, {1, 2, 3}},
             {"step2/0002.png", dataset::Step2Kind::kScan, {1}, {1, 2, 3}}};
  return p;
}

// Records what the orchestrator's calls reached.
class FakeRig : public RigOperator {
 public:
  void PrepareStep1Frame(size_t index) override { calls.push_back("s1:" + std::to_string(index)); }
  void PrepareStep2Frame(size_t index) override { calls.push_back("s2:" + std::to_string(index)); }
  bool FrameShowsCurrentSetup(const camera::FrameInfo& info) const override {
    return info.frame_id == 7;
  }
  std::string PrepareHallRecording(HallRun run) override {
    calls.push_back(std::string("hall:") + ToString(run));
    return std::string("/dev/fake-") + ToString(run);
  }
  std::vector<std::string> calls;
};

// The operator's terminal: answers go into a pipe, output comes out of another.
class Terminal {
 public:
  Terminal() {
    EXPECT_EQ(::pipe(in_), 0);
    EXPECT_EQ(::pipe(out_), 0);
    ::fcntl(out_[0], F_SETFL, O_NONBLOCK);
  }
  ~Terminal() {
    for (int fd : {in_[0], in_[1], out_[0], out_[1]})
      if (fd >= 0) ::close(fd);
  }
  void Type(const std::string& s) {
    ASSERT_EQ(::write(in_[1], s.data(), s.size()), ssize_t(s.size()));
  }
  void CloseInput() {
    ::close(in_[1]);
    in_[1] = -1;
  }
  // Everything written so far.
  std::string Output() {
    char buf[4096];
    for (ssize_t n; (n = ::read(out_[0], buf, sizeof(buf))) > 0;) text_.append(buf, size_t(n));
    return text_;
  }
  ConsoleOperatorOptions Options() const {
    ConsoleOperatorOptions o;
    o.input_fd = in_[0];
    o.output_fd = out_[1];
    return o;
  }

 private:
  int in_[2] = {-1, -1};
  int out_[2] = {-1, -1};
  std::string text_;
};

size_t Count(const std::string& s, const std::string& what) {
  size_t n = 0;
  for (size_t p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++n;
  return n;
}

TEST(ConsoleOperator, WholeSessionInOrderWithNumberedInstructions) {
  const dataset::Recording plan = SmallPlan();
  FakeRig rig;
  Terminal term;
  ConsoleOperatorOptions o = term.Options();
  o.poses = {{35, 12}, {100, -12}};
  ConsoleOperator op(plan, o, &rig);
  EXPECT_EQ(op.total_steps(), 6);  // step 2: one set-up (the drives are not physical)
  term.Type(std::string(6, '\n'));  // all answers at once: lines are split correctly

  EXPECT_EQ(op.PrepareHallRecording(HallRun::kBackground), "/dev/fake-background");
  for (size_t i = 0; i < plan.step1.size(); ++i) op.PrepareStep1Frame(i);
  EXPECT_EQ(op.PrepareHallRecording(HallRun::kActual), "/dev/fake-actual");
  for (size_t i = 0; i < plan.step2.size(); ++i) op.PrepareStep2Frame(i);
  EXPECT_EQ(op.confirmations(), 6);
  EXPECT_EQ(rig.calls, (std::vector<std::string>{"hall:background", "s1:0", "s1:1", "s1:2",
                                                 "hall:actual", "s2:0", "s2:1", "s2:2"}));

  const std::string out = term.Output();
  EXPECT_EQ(Count(out, kConsolePrompt), 6u);
  for (int k = 1; k <= 6; ++k)
    EXPECT_NE(out.find("[" + std::to_string(k) + "/6]"), std::string::npos) << k;
  // Order: background (top frame off) before the first sliding plate, top frame on before step 2.
  const size_t remove = out.find("Remove the mirror's top frame");
  const size_t mount1 = out.find("Mount the sliding plate at pose 1 of 2 (about 35 mm");
  const size_t move2 = out.find("Move the sliding plate to pose 2 of 2 (about 100 mm");
  const size_t keep2 = out.find("Leave the sliding plate at pose 2 of 2");
  const size_t top_on = out.find("Mount the mirror's top frame");
  const size_t neutral = out.find("drives off");
  ASSERT_NE(remove, std::string::npos) << out;
  ASSERT_NE(mount1, std::string::npos) << out;
  ASSERT_NE(move2, std::string::npos) << out;
  ASSERT_NE(keep2, std::string::npos) << out;
  ASSERT_NE(top_on, std::string::npos) << out;
  ASSERT_NE(neutral, std::string::npos) << out;
  EXPECT_LT(remove, mount1);
  EXPECT_LT(mount1, move2);
  EXPECT_LT(move2, keep2);
  EXPECT_LT(keep2, top_on);
  EXPECT_LT(top_on, neutral);
  EXPECT_NE(out.find("MSM not mounted"), std::string::npos);
  EXPECT_NE(out.find("Unblock beam 2 only; block beams 1 and 3 (identification frame"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("Unblock beams 1, 2 and 3 (all beams)."), std::string::npos);
  // The drive modes are said, not asked for: the generators switch them per frame.
  EXPECT_NE(out.find("Frames: 1 neutral (drives off), 1 fast-only (fast drive only) and 1 scan "
                     "(both drives); the generators switch the drives for each frame, nothing to "
                     "change at the rig."),
            std::string::npos)
      << out;
  EXPECT_EQ(out.find("Step 2, frame 2 of 3"), std::string::npos) << out;
}

TEST(ConsoleOperator, BackgroundAskedAfterStepOneIsNumberedThere) {
  const dataset::Recording plan = SmallPlan();
  FakeRig rig;
  Terminal term;
  ConsoleOperator op(plan, term.Options(), &rig);
  term.Type(std::string(6, '\n'));
  for (size_t i = 0; i < plan.step1.size(); ++i) op.PrepareStep1Frame(i);
  EXPECT_EQ(op.PrepareHallRecording(HallRun::kBackground), "/dev/fake-background");
  EXPECT_EQ(op.PrepareHallRecording(HallRun::kActual), "/dev/fake-actual");
  for (size_t i = 0; i < plan.step2.size(); ++i) op.PrepareStep2Frame(i);
  const std::string out = term.Output();
  const size_t first = out.find("[1/6] Step 1, frame 1 of 3");
  const size_t last = out.find("[3/6] Step 1, frame 3 of 3");
  const size_t background = out.find("[4/6] Step 1 done: background Hall recording");
  const size_t actual = out.find("[5/6] Step 2 set-up");
  const size_t s2 = out.find("[6/6] Step 2, frame 1 of 3, neutral and 2 more at this set-up");
  ASSERT_NE(first, std::string::npos) << out;
  ASSERT_NE(last, std::string::npos) << out;
  ASSERT_NE(background, std::string::npos) << out;
  ASSERT_NE(actual, std::string::npos) << out;
  ASSERT_NE(s2, std::string::npos) << out;
  EXPECT_LT(last, background);
  EXPECT_LT(out.find("Remove the mirror's top frame", background), actual);
  EXPECT_LT(actual, s2);
}

TEST(ConsoleOperator, RepeatShowsTheSameInstructionsAgainAndUnknownAnswersAskAgain) {
  const dataset::Recording plan = SmallPlan();
  FakeRig rig;
  Terminal term;
  ConsoleOperator op(plan, term.Options(), &rig);
  term.Type("r\nwhat\n  \n");  // repeat, unknown, blank (= Enter)
  op.PrepareStep1Frame(2);
  const std::string out = term.Output();
  EXPECT_EQ(Count(out, "Step 1, frame 3 of 3 (step1/0002.png)"), 2u) << out;
  EXPECT_EQ(Count(out, kConsolePrompt), 3u);
  EXPECT_NE(out.find("unknown answer 'what'"), std::string::npos);
  EXPECT_EQ(rig.calls, std::vector<std::string>{"s1:2"});
}

TEST(ConsoleOperator, QuitAndEndOfInputAbortBeforeTheRigIsTouched) {
  const dataset::Recording plan = SmallPlan();
  {
    FakeRig rig;
    Terminal term;
    ConsoleOperator op(plan, term.Options(), &rig);
    term.Type("q\n");
    try {
      op.PrepareStep2Frame(1);
      FAIL() << "no abort";
    } catch (const OperatorAbort& e) {
      EXPECT_NE(std::string(e.what()).find("operator aborted"), std::string::npos);
    }
    EXPECT_TRUE(rig.calls.empty());
    EXPECT_EQ(op.confirmations(), 0);
  }
  {
    FakeRig rig;
    Terminal term;
    ConsoleOperator op(plan, term.Options(), &rig);
    term.Type("\n");
    term.CloseInput();
    op.PrepareStep1Frame(0);
    EXPECT_THROW(op.PrepareStep1Frame(1), OperatorAbort);
    EXPECT_EQ(rig.calls, std::vector<std::string>{"s1:0"});
  }
}

TEST(ConsoleOperator, DelegatesFreshnessToTheInnerOperator) {
  const dataset::Recording plan = SmallPlan();
  FakeRig rig;
  Terminal term;
  ConsoleOperator op(plan, term.Options(), &rig);
  camera::FrameInfo info;
  info.frame_id = 7;
  EXPECT_TRUE(op.FrameShowsCurrentSetup(info));
  info.frame_id = 8;
  EXPECT_FALSE(op.FrameShowsCurrentSetup(info));
}

TEST(ConsoleOperator, LabModeAcceptsFramesArrivingAfterConfirmationPlusSettle) {
  const dataset::Recording plan = SmallPlan();
  Terminal term;
  ConsoleOperatorOptions o = term.Options();
  EXPECT_NE(o.Validate(false).find("mcu_device"), std::string::npos);
  EXPECT_EQ(o.Validate(true), "");
  o.mcu_device = "/dev/ttyACM0";
  EXPECT_NE(o.Validate(false).find("host_clock_ns"), std::string::npos);
  int64_t now_ns = 5'000'000'000;
  o.host_clock_ns = [&] { return now_ns; };
  o.settle_ns = 100'000'000;
  EXPECT_EQ(o.Validate(false), "");
  o.settle_ns = -1;
  EXPECT_NE(o.Validate(false).find("settle_ns = -1"), std::string::npos);
  o.settle_ns = 100'000'000;
  EXPECT_THROW(ConsoleOperator(plan, term.Options(), nullptr), std::invalid_argument);

  ConsoleOperator op(plan, o, nullptr);
  term.Type("\n\n");
  EXPECT_EQ(op.PrepareHallRecording(HallRun::kBackground), "/dev/ttyACM0");
  now_ns = 9'000'000'000;
  op.PrepareStep1Frame(0);
  camera::FrameInfo info;
  info.host_timestamp_ns = 9'000'000'000 + 99'999'999;  // in flight at the confirmation
  EXPECT_FALSE(op.FrameShowsCurrentSetup(info));
  info.host_timestamp_ns = 9'000'000'000 + 100'000'000;
  EXPECT_TRUE(op.FrameShowsCurrentSetup(info));
  info.host_timestamp_ns = 8'000'000'000;
  EXPECT_FALSE(op.FrameShowsCurrentSetup(info));
}

// A frame delivered late (a loaded host: it arrives long after the settle) but exposed before
// the confirmation on the camera's clock is refused; its device clock is mapped onto the host's
// by the fastest-delivered frame (device = host - 3 s - delivery delay).
TEST(ConsoleOperator, LabModeRefusesALateDeliveredFrameExposedBeforeTheConfirmation) {
  const dataset::Recording plan = SmallPlan();
  Terminal term;
  ConsoleOperatorOptions o = term.Options();
  o.mcu_device = "/dev/ttyACM0";
  int64_t now_ns = 5'000'000'000;
  o.host_clock_ns = [&] { return now_ns; };
  o.settle_ns = 400'000'000;
  o.exposure_ns = 200'000'000;
  ConsoleOperator op(plan, o, nullptr);
  auto frame = [](int64_t exposure_end_host_ns, int64_t delay_ns) {
    camera::FrameInfo f;
    f.device_timestamp_ns = exposure_end_host_ns - 3'000'000'000;
    f.host_timestamp_ns = exposure_end_host_ns + delay_ns;
    return f;
  };
  // Frames before the set-up (nothing confirmed yet), one delivered within 5 ms (the offset).
  (void)op.FrameShowsCurrentSetup(frame(4'000'000'000, 5'000'000));
  (void)op.FrameShowsCurrentSetup(frame(4'250'000'000, 60'000'000));
  term.Type("\n");
  now_ns = 9'000'000'000;
  op.PrepareStep1Frame(0);
  // Exposed 8.95..9.15 s (began before the confirmation at 9 s), delivered 600 ms late: the host
  // rule alone (arrival >= 9.4 s) would take it.
  EXPECT_FALSE(op.FrameShowsCurrentSetup(frame(9'150'000'000, 600'000'000)));
  // Exposed 9.15..9.35 s, delivered as late: counts (began 150 ms after; margin 100 ms + 5 ms).
  EXPECT_TRUE(op.FrameShowsCurrentSetup(frame(9'350'000'000, 600'000'000)));
  // Without a device timestamp the host rule alone decides.
  camera::FrameInfo no_device;
  no_device.host_timestamp_ns = 9'400'000'000;
  EXPECT_TRUE(op.FrameShowsCurrentSetup(no_device));
}

TEST(ConsoleOperator, IndicesOutsideThePlanAreRefused) {
  const dataset::Recording plan = SmallPlan();
  FakeRig rig;
  Terminal term;
  ConsoleOperator op(plan, term.Options(), &rig);
  EXPECT_THROW(op.PrepareStep1Frame(3), std::out_of_range);
  EXPECT_THROW(op.PrepareStep2Frame(3), std::out_of_range);
  EXPECT_TRUE(rig.calls.empty());
}

// Frames repeating the previous set-up (same pose, same beams in any order; step 2 frames that
// differ only in their triggers or their drive mode) run without a prompt; the inner operator still hears of every
// frame. A change of beams at the same pose asks again.
TEST(ConsoleOperator, RepeatedExposuresAndUnchangedSetupsDoNotPrompt) {
  dataset::Recording plan = SmallPlan();
  plan.step1.insert(plan.step1.begin() + 1, {"step1/0000b.png", 0, {3, 2, 1}});
  plan.step2.push_back({"step2/0003.png", dataset::Step2Kind::kScan, {0}, {1, 2, 3}});
  plan.step2.push_back({"step2/0004.png", dataset::Step2Kind::kScan, {2}, {1, 2, 3}});
  FakeRig rig;
  Terminal term;
  ConsoleOperatorOptions o = term.Options();
  o.poses = {{35, 12}, {100, -12}};
  ConsoleOperator op(plan, o, &rig);
  EXPECT_EQ(op.total_steps(), 6);  // 4 step-1 frames in 3, 5 step-2 frames in 1, 2 Hall set-ups
  term.Type(std::string(6, '\n'));
  for (size_t i = 0; i < plan.step1.size(); ++i) op.PrepareStep1Frame(i);
  (void)op.PrepareHallRecording(HallRun::kBackground);
  (void)op.PrepareHallRecording(HallRun::kActual);
  for (size_t i = 0; i < plan.step2.size(); ++i) op.PrepareStep2Frame(i);
  EXPECT_EQ(op.confirmations(), 6);
  EXPECT_EQ(rig.calls.size(), plan.step1.size() + plan.step2.size() + 2);
  const std::string out = term.Output();
  EXPECT_EQ(Count(out, kConsolePrompt), 6u);
  EXPECT_NE(out.find("Step 1, frame 1 of 4 and 1 more at this set-up (step1/0000.png .. "
                     "step1/0000b.png)"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("2 frames are taken at this set-up without another prompt"), std::string::npos)
      << out;
  EXPECT_NE(out.find("Step 2, frame 1 of 5, neutral and 4 more at this set-up"), std::string::npos)
      << out;
  EXPECT_EQ(out.find("Step 1, frame 2 of 4"), std::string::npos) << out;
  EXPECT_NE(out.find("Leave the sliding plate at pose 2 of 2"), std::string::npos) << out;
  // The blocks are the Setups' texts.
  for (const auto& s : op.setups().setups) EXPECT_NE(out.find(s.text), std::string::npos);
}

// Lab mode: a frame of an unchanged set-up counts only once it arrived settle_ns after its own
// Prepare call (no prompt, but frames in flight are still discarded).
TEST(ConsoleOperator, LabModeFreshnessRestartsAtEveryFrameOfASetup) {
  dataset::Recording plan = SmallPlan();
  plan.step1.insert(plan.step1.begin() + 1, {"step1/0000b.png", 0, {1, 2, 3}});
  Terminal term;
  ConsoleOperatorOptions o = term.Options();
  o.mcu_device = "/dev/ttyACM0";
  int64_t now = 1'000'000'000;
  o.host_clock_ns = [&now] { return now; };
  o.settle_ns = 100'000'000;
  ConsoleOperator op(plan, o, nullptr);
  term.Type("\n");
  op.PrepareStep1Frame(0);
  now = 5'000'000'000;
  op.PrepareStep1Frame(1);  // no prompt: only one answer was typed
  EXPECT_EQ(op.confirmations(), 1);
  camera::FrameInfo info;
  info.host_timestamp_ns = 5'000'000'000 + 50'000'000;
  EXPECT_FALSE(op.FrameShowsCurrentSetup(info));
  info.host_timestamp_ns = 5'000'000'000 + 100'000'000;
  EXPECT_TRUE(op.FrameShowsCurrentSetup(info));
}

TEST(LiveFigures, OneLinePerDecisionWithFiguresReasonAndTotals) {
  GateResult g;
  g.accepted = false;
  g.reason = "expected 3 dots, found 2";
  g.dots_found = 2;
  g.dots_expected = 3;
  g.saturated_fraction = 0.0012;
  g.boards = {vision::CheckerboardDetection{}, std::nullopt};
  FrameReport r;
  r.step = 1;
  r.index = 2;
  r.count = 7;
  r.file = "step1/0002.png";
  r.gate = &g;
  std::vector<std::string> lines;
  FrameObserver live = MakeLiveFigures([&](const std::string& l) { lines.push_back(l); });
  live(r);  // attempt 1 rejected, another follows
  r.attempt = 1;
  r.final = true;
  live(r);  // final rejection
  g.accepted = true;
  g.reason.clear();
  g.dots_found = 3;
  g.boards = {vision::CheckerboardDetection{}, vision::CheckerboardDetection{}};
  r.index = 3;
  r.file = "step1/0003.png";
  r.attempt = 0;
  r.accepted = true;
  live(r);
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_NE(lines[0].find("step1/0002.png (step 1, 3/7, attempt 1)"), std::string::npos)
      << lines[0];
  EXPECT_NE(lines[0].find("sliding board found, world board NOT found"), std::string::npos);
  EXPECT_NE(lines[0].find("dots 2/3"), std::string::npos);
  EXPECT_NE(lines[0].find("saturated 0.12%"), std::string::npos) << lines[0];
  EXPECT_NE(lines[0].find("retry: expected 3 dots, found 2"), std::string::npos);
  EXPECT_NE(lines[0].find("totals: 0 accepted, 0 rejected, 1 retried"), std::string::npos);
  EXPECT_NE(lines[1].find("REJECTED: expected 3 dots"), std::string::npos);
  EXPECT_NE(lines[1].find("totals: 0 accepted, 1 rejected, 1 retried"), std::string::npos);
  EXPECT_NE(lines[2].find("dots 3/3"), std::string::npos);
  EXPECT_NE(lines[2].find("ACCEPTED | totals: 1 accepted, 1 rejected, 1 retried"),
            std::string::npos)
      << lines[2];
}

}  // namespace
}  // namespace msmcal::orchestrator
