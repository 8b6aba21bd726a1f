// The live view without a browser (issue 19): the state model and the one-controller rule
// (LiveView), the web operator's answers and abort path (WebOperator), and the HTTP server's
// endpoints over real loopback HTTP (LiveServer with an httplib client): the page, the state and
// its instruction, the image, the event stream, the buttons, the access token.
#include "sessions/live_view/live_view.h"

#include <gtest/gtest.h>
#include <httplib.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <thread>
#include <vector>

#include "sessions/live_view/live_server.h"
#include "sessions/live_view/web_operator.h"
#include "sessions/orchestrator/console_operator.h"
#include "sessions/setup/setup.h"

namespace msmcal::live_view {
namespace {

using nlohmann::json;
using std::chrono::milliseconds;

dataset::Recording SmallPlan() {
  dataset::Recording p;
  p.world_board = {7, 5, 10.0};
  p.sliding_board = {5, 4, 8.0};
  p.beams = {{1, dataset::BeamRole::kEstimate},
             {2, dataset::BeamRole::kEstimate},
             {3, dataset::BeamRole::kValidate}};
  p.triggers = {{0, 0.010}, {1, 0.0525}};
  p.step1 = {{"step1/0000.png", 0, {1, 2, 3}}, {"step1/0001.png", 1, {2}}};
  // Beam 3 blocked in the scan frame: two step 2 set-ups (a change of drive mode alone is none).
  p.step2 = {{"step2/0000.png", dataset::Step2Kind::kNeutral, {}, {1, 2, 3}},
             {"step2/0001.png", dataset::Step2Kind::kScan, {0, 1}, {1, 2}}};
  return p;
}

// The instruction block of set-up k as the page shows it (without its leading newline).
std::string BlockText(const dataset::Recording& plan, int k) {
  std::string t = setup::PlanSetups(plan, {}).setups.at(static_cast<size_t>(k)).text;
  if (!t.empty() && t.front() == '\n') t.erase(0, 1);
  return t;
}

// A checkerboard of (cols + 1) x (rows + 1) squares of `square` px on a mid-grey background.
cv::Mat Checkerboard(int cols, int rows, int square, int width, int height) {
  cv::Mat m(height, width, CV_8UC1, cv::Scalar(128));  // no pixel at full scale (saturation)
  const int x0 = (width - (cols + 1) * square) / 2, y0 = (height - (rows + 1) * square) / 2;
  cv::rectangle(m, cv::Rect(x0 - square, y0 - square, (cols + 3) * square, (rows + 3) * square),
                cv::Scalar(220), cv::FILLED);
  for (int r = 0; r <= rows; ++r)
    for (int c = 0; c <= cols; ++c)
      if ((r + c) % 2 == 0)
        cv::rectangle(m, cv::Rect(x0 + c * square, y0 + r * square, square, square), cv::Scalar(0),
                      cv::FILLED);
  return m;
}

class FakeRig : public orchestrator::RigOperator {
 public:
  void PrepareStep1Frame(size_t index) override { calls.push_back("s1:" + std::to_string(index)); }
  void PrepareStep2Frame(size_t index) override { calls.push_back("s2:" + std::to_string(index)); }
  bool FrameShowsCurrentSetup(const camera::FrameInfo&) const override { return true; }
  std::string PrepareHallRecording(orchestrator::HallRun run) override {
    calls.push_back(std::string("hall:") + orchestrator::ToString(run));
    return "/dev/fake";
  }
  std::vector<std::string> calls;
};

json State(const LiveView& view) { return json::parse(view.StateJson()); }

// Waits (condition with a deadline, no fixed sleep) until the view's state satisfies `pred`.
template <typename Pred>
bool WaitForState(const LiveView& view, Pred pred, milliseconds timeout = milliseconds(10000)) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  uint64_t v = view.version();
  while (!pred(State(view))) {
    const auto now = std::chrono::steady_clock::now();
    if (now >= deadline) return false;
    v = view.WaitForChange(v, std::chrono::duration_cast<milliseconds>(deadline - now));
  }
  return true;
}

TEST(LiveView, ToStringNamesThePageStates) {
  EXPECT_STREQ(ToString(SessionState::kRunning), "running");
  EXPECT_STREQ(ToString(SessionState::kWaiting), "waiting");
  EXPECT_STREQ(ToString(SessionState::kDone), "done");
  EXPECT_STREQ(ToString(SessionState::kAborted), "aborted");
}

TEST(LiveView, InvalidOptionsAreRefusedNamingTheField) {
  const dataset::Recording plan = SmallPlan();
  LiveViewOptions o;
  o.jpeg_quality = 0;
  EXPECT_NE(o.Validate().find("jpeg_quality"), std::string::npos);
  EXPECT_THROW(LiveView(plan, o), std::invalid_argument);
  o = {};
  o.max_live_fps = 0;
  EXPECT_NE(o.Validate().find("max_live_fps"), std::string::npos);
}

TEST(LiveView, OneControllerAtATimeAndAReloadKeepsControl) {
  const dataset::Recording plan = SmallPlan();
  LiveView view(plan, {});
  const Reply a = view.Claim("");
  ASSERT_EQ(a.http_status, 200);
  ASSERT_FALSE(a.controller_token.empty());
  const Reply b = view.Claim("");
  EXPECT_EQ(b.http_status, 409);
  EXPECT_TRUE(b.controller_token.empty());
  EXPECT_NE(b.error.find("watches"), std::string::npos);
  // A reload of page A presents its token again: control kept, same token.
  const Reply again = view.Claim(a.controller_token);
  EXPECT_EQ(again.http_status, 200);
  EXPECT_EQ(again.controller_token, a.controller_token);
  // A watcher's commands are refused.
  EXPECT_EQ(view.Submit("", Command::kAbort, 0).http_status, 403);
  EXPECT_EQ(view.Submit("not-the-token", Command::kAbort, 0).http_status, 403);
  EXPECT_FALSE(view.AbortRequested());
}

TEST(LiveView, AControllerNotSeenWithinItsLeaseLosesControl) {
  const dataset::Recording plan = SmallPlan();
  LiveViewOptions o;
  o.controller_lease = milliseconds(300);
  LiveView view(plan, o);
  const auto t0 = std::chrono::steady_clock::now();
  const Reply a = view.Claim("");
  ASSERT_EQ(a.http_status, 200);
  ASSERT_EQ(view.Claim("").http_status, 409);
  // Page A is closed (nothing seen from it): after the lease another page may claim.
  Reply b;
  const auto deadline = t0 + std::chrono::seconds(10);
  do {
    b = view.Claim("");
  } while (b.http_status != 200 && std::chrono::steady_clock::now() < deadline);
  ASSERT_EQ(b.http_status, 200);
  EXPECT_GE(std::chrono::steady_clock::now() - t0, milliseconds(300));
  EXPECT_NE(b.controller_token, a.controller_token);
  EXPECT_EQ(view.Submit(a.controller_token, Command::kAbort, 0).http_status, 403);
}

TEST(LiveView, ReadyAnswersOnlyThePromptShownAndRepeatKeepsWaiting) {
  const dataset::Recording plan = SmallPlan();
  LiveView view(plan, {});
  const std::string token = view.Claim("").controller_token;
  // Nothing shown yet: Ready is refused, the session goes on.
  EXPECT_EQ(view.Submit(token, Command::kReady, 0).http_status, 409);
  std::atomic<int> answered{-1};
  std::thread asker([&] {
    Prompt p;
    p.title = "Step 1, frame 1 of 2";
    p.instructions = "=== [1/6] Step 1, frame 1 of 2 ===\n  1. Mount the sliding plate.\n";
    p.number = 1;
    p.total = 6;
    p.step = 1;
    answered = static_cast<int>(view.Ask(p));
  });
  ASSERT_TRUE(WaitForState(view, [](const json& s) { return s["state"] == "waiting"; }));
  const json s = State(view);
  EXPECT_EQ(s["prompt"]["instructions"],
            "=== [1/6] Step 1, frame 1 of 2 ===\n  1. Mount the sliding plate.\n");
  EXPECT_EQ(s["prompt"]["number"], 1);
  EXPECT_EQ(s["prompt"]["total"], 6);
  EXPECT_EQ(s["prompt"]["frame"], 1);
  EXPECT_EQ(s["prompt"]["frames_in_step"], 2);
  const int64_t id = s["prompt"]["id"];
  EXPECT_EQ(view.Submit(token, Command::kReady, id + 1).http_status, 409);  // stale / other prompt
  EXPECT_EQ(view.Submit(token, Command::kRepeat, id).http_status, 200);
  ASSERT_TRUE(WaitForState(view, [](const json& s) { return s["prompt"]["repeats"] == 1; }));
  EXPECT_EQ(State(view)["state"], "waiting");
  EXPECT_EQ(answered.load(), -1);
  EXPECT_EQ(view.Submit(token, Command::kReady, id).http_status, 200);
  asker.join();
  EXPECT_EQ(answered.load(), static_cast<int>(Command::kReady));
  EXPECT_EQ(State(view)["state"], "running");
  // A doubled click reaches no prompt.
  EXPECT_EQ(view.Submit(token, Command::kReady, id).http_status, 409);
}

TEST(LiveView, LiveFramesAreGatedForTheFrameBeingSetUpAndDrawn) {
  dataset::Recording plan = SmallPlan();
  LiveViewOptions o;
  o.max_live_fps = 1000;
  LiveView view(plan, o);
  const cv::Mat board = Checkerboard(7, 5, 30, 400, 300);
  orchestrator::LiveFrame f;
  f.step = 2;
  f.index = 0;  // neutral frame, 3 beams: 3 dots expected, none in this image
  f.image = &board;
  view.MakeLiveFrameObserver()(f);
  const json s = State(view);
  EXPECT_EQ(s["live"]["source"], "live");
  EXPECT_EQ(s["live"]["boards_found"], json::array({true}));
  EXPECT_EQ(s["live"]["dots_expected"], 3);
  EXPECT_EQ(s["live"]["dots_found"], 0);
  EXPECT_EQ(s["live"]["gate_would_accept"], false);
  EXPECT_NE(s["live"]["reason"].get<std::string>().find("expected 3 dots"), std::string::npos);
  uint64_t seq = 0;
  const auto jpeg = view.Image(&seq);
  ASSERT_TRUE(jpeg);
  EXPECT_EQ(seq, 1u);
  const cv::Mat shown =
      cv::imdecode(std::vector<uchar>(jpeg->begin(), jpeg->end()), cv::IMREAD_COLOR);
  ASSERT_FALSE(shown.empty());
  EXPECT_EQ(shown.cols, 400);  // below image_max_width_px: full size
  // The overlay: coloured pixels (the board's outline, the expected-dots region) on a grey image.
  cv::Mat hsv;
  cv::cvtColor(shown, hsv, cv::COLOR_BGR2HSV);
  std::vector<cv::Mat> ch;
  cv::split(hsv, ch);
  EXPECT_GT(cv::countNonZero(ch[1] > 120), 200);
  // Magenta (the region where dots are expected) is drawn.
  cv::Mat magenta;
  cv::inRange(shown, cv::Scalar(180, 0, 180), cv::Scalar(255, 90, 255), magenta);
  EXPECT_GT(cv::countNonZero(magenta), 50);
}

// A live frame the pump streams during a Hall recording says so itself: it is shown as the
// camera image only (no board search) even before the rig's status reports the recording (the
// first frames of the background recording used to get the slow set-up board search, which
// under load could hold the pump for the whole recording: cli.live_view_twin_http).
TEST(LiveView, LiveFramesOfAHallRecordingAreTheImageOnlyFromTheFirst) {
  const dataset::Recording plan = SmallPlan();
  LiveViewOptions o;
  o.max_live_fps = 1000;
  const cv::Mat board = Checkerboard(7, 5, 30, 400, 300);
  orchestrator::LiveFrame f;
  f.step = 0;
  f.image = &board;
  {
    LiveView view(plan, o);
    view.MakeLiveFrameObserver()(f);  // a recording's set-up: the boards searched
    const json s = State(view);
    EXPECT_EQ(s["live"]["caption"], "LIVE (Hall recording set-up)");
    EXPECT_EQ(s["live"]["boards_found"], json::array({true}));
  }
  f.hall_recording = "background";
  LiveView view(plan, o);  // no rig status: the view does not know of the recording
  view.MakeLiveFrameObserver()(f);
  const json s = State(view);
  EXPECT_TRUE(s["rig"]["hall_recording"].get<std::string>().empty());
  EXPECT_EQ(s["live"]["caption"], "LIVE (Hall background recording running: camera image only)");
  EXPECT_EQ(s["live"]["boards_found"], json::array());
}

TEST(LiveView, GateDecisionsGiveTheFiguresProgressAndEta) {
  const dataset::Recording plan = SmallPlan();
  LiveView view(plan, {});
  orchestrator::GateResult g;
  g.accepted = false;
  g.reason = "world board (7x5) not found";
  g.dots_expected = 3;
  const cv::Mat image(120, 160, CV_8UC1, cv::Scalar(90));
  orchestrator::FrameReport r;
  r.step = 1;
  r.index = 0;
  r.count = 2;
  r.file = "step1/0000.png";
  r.gate = &g;
  r.image = &image;
  r.final = false;
  view.MakeFrameObserver()(r);  // retry
  r.attempt = 1;
  r.final = true;
  view.MakeFrameObserver()(r);  // rejected
  const json s = State(view);
  EXPECT_EQ(s["figures"]["rejected"], 1);
  EXPECT_EQ(s["figures"]["retried"], 1);
  EXPECT_EQ(s["figures"]["accepted"], 0);
  EXPECT_EQ(s["figures"]["recent"][0]["decision"], "rejected");
  EXPECT_EQ(s["figures"]["recent"][0]["reason"], "world board (7x5) not found");
  EXPECT_EQ(s["figures"]["recent"][1]["decision"], "retry");
  EXPECT_NE(s["figures"]["last"].get<std::string>().find("REJECTED: world board"),
            std::string::npos);
  EXPECT_EQ(s["progress"]["frames_done"], 1);
  EXPECT_EQ(s["progress"]["frames_total"], 4);
  EXPECT_TRUE(s["progress"]["eta_s"].is_number());
  EXPECT_EQ(s["image"]["sequence"], 2);
}

TEST(LiveView, RigStatusGivesTheHallRateAndTheOutputs) {
  const dataset::Recording plan = SmallPlan();
  LiveView view(plan, {});
  auto rig = view.MakeRigStatusObserver();
  orchestrator::RigStatus st;
  st.outputs_on = true;
  st.reference_locked = true;
  rig(st);
  EXPECT_EQ(State(view)["rig"]["outputs_on"], true);
  EXPECT_EQ(State(view)["rig"]["reference_locked"], true);
  st.hall_recording = "actual";
  st.hall_readings = 100;
  rig(st);
  EXPECT_EQ(State(view)["rig"]["hall_recording"], "actual");
  // A later report: the rate is the readings between the two over the host time between them.
  st.hall_readings = 200;
  st.hall_lost = 2;
  rig(st);
  const json s = State(view);
  EXPECT_GT(s["rig"]["hall_readings_per_s"].get<double>(), 0.0);
  EXPECT_EQ(s["rig"]["hall_readings"], 200);
  EXPECT_EQ(s["rig"]["hall_lost"], 2);
  st = {};
  rig(st);
  EXPECT_EQ(State(view)["rig"]["outputs_on"], false);
}

// The rig's "disk left": the free space of the session folder's file system, as the system
// reports it to this user; null without a folder (nothing invented).
TEST(LiveView, DiskLeftIsTheSessionFoldersFreeSpace) {
  const dataset::Recording plan = SmallPlan();
  EXPECT_TRUE(State(LiveView(plan, {}))["rig"]["disk_free_bytes"].is_null());
  LiveViewOptions options;
  options.disk_path = ::testing::TempDir();
  LiveView view(plan, options);
  const json free_bytes = State(view)["rig"]["disk_free_bytes"];
  ASSERT_TRUE(free_bytes.is_number()) << free_bytes;
  const double available = static_cast<double>(std::filesystem::space(options.disk_path).available);
  ASSERT_GT(available, 0.0);
  // Other processes write meanwhile: equal to within 1 % or 64 MB.
  EXPECT_NEAR(free_bytes.get<double>(), available, std::max(0.01 * available, 64e6));
  options.disk_path = "/nonexistent/session";
  EXPECT_TRUE(State(LiveView(plan, options))["rig"]["disk_free_bytes"].is_null());
}

// --- WebOperator ---

TEST(WebOperator, ReadyConfirmsThenTheInnerOperatorChangesTheRig) {
  const dataset::Recording plan = SmallPlan();
  LiveView view(plan, {});
  FakeRig rig;
  std::vector<std::string> echoed;
  WebOperatorOptions wo;
  wo.echo = [&](const std::string& t) { echoed.push_back(t); };
  WebOperator op(plan, view, wo, &rig);
  const std::string token = view.Claim("").controller_token;
  std::thread session([&] {
    op.PrepareStep1Frame(0);
    op.PrepareStep1Frame(1);
  });
  for (int k = 1; k <= 2; ++k) {
    ASSERT_TRUE(WaitForState(view, [k](const json& s) {
      return s["state"] == "waiting" && s["prompt"]["number"] == k;
    }));
    const json s = State(view);
    EXPECT_EQ(s["prompt"]["instructions"].get<std::string>(),
              BlockText(plan, setup::PlanSetups(plan, {}).step1_setup[k - 1]));
    EXPECT_EQ(rig.calls.size(), static_cast<size_t>(k - 1));  // not before Ready
    ASSERT_EQ(view.Submit(token, Command::kReady, s["prompt"]["id"]).http_status, 200);
  }
  session.join();
  EXPECT_EQ(rig.calls, (std::vector<std::string>{"s1:0", "s1:1"}));
  EXPECT_EQ(op.confirmations(), 2);
  ASSERT_FALSE(echoed.empty());
  EXPECT_NE(echoed[0].find("Step 1, frame 1 of 2"), std::string::npos);
}

TEST(WebOperator, AbortAtAPromptThrowsOperatorAbortAndChangesNothing) {
  const dataset::Recording plan = SmallPlan();
  LiveView view(plan, {});
  FakeRig rig;
  WebOperator op(plan, view, {}, &rig);
  const std::string token = view.Claim("").controller_token;
  std::string error;
  std::thread session([&] {
    try {
      op.PrepareHallRecording(orchestrator::HallRun::kActual);
    } catch (const orchestrator::OperatorAbort& e) {
      error = e.what();
    }
  });
  ASSERT_TRUE(WaitForState(view, [](const json& s) { return s["state"] == "waiting"; }));
  EXPECT_NE(State(view)["prompt"]["title"].get<std::string>().find("Step 2 set-up"),
            std::string::npos);
  ASSERT_EQ(view.Submit(token, Command::kAbort, -1).http_status, 200);
  session.join();
  EXPECT_EQ(error, kWebAbortMessage);
  EXPECT_TRUE(rig.calls.empty());
}

TEST(WebOperator, AbortWhileRunningIsTakenAtTheNextFrameCheck) {
  const dataset::Recording plan = SmallPlan();
  LiveView view(plan, {});
  FakeRig rig;
  WebOperator op(plan, view, {}, &rig);
  const std::string token = view.Claim("").controller_token;
  camera::FrameInfo info;
  EXPECT_TRUE(op.FrameShowsCurrentSetup(info));
  ASSERT_EQ(view.Submit(token, Command::kAbort, -1).http_status, 200);
  EXPECT_THROW(op.FrameShowsCurrentSetup(info), orchestrator::OperatorAbort);
  EXPECT_THROW(op.PrepareStep2Frame(0), orchestrator::OperatorAbort);  // no prompt waits
  EXPECT_TRUE(rig.calls.empty());
}

TEST(WebOperator, LabModeNeedsTheMcuDeviceAndTheHostClock) {
  const dataset::Recording plan = SmallPlan();
  LiveView view(plan, {});
  EXPECT_THROW(WebOperator(plan, view, {}, nullptr), std::invalid_argument);
  WebOperatorOptions wo;
  wo.mcu_device = "/dev/ttyACM0";
  EXPECT_NE(wo.Validate(false).find("host_clock_ns"), std::string::npos);
}

// --- LiveServer over HTTP ---

class ServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    plan_ = SmallPlan();
    LiveViewOptions o;
    o.max_live_fps = 1000;
    view_ = std::make_unique<LiveView>(plan_, o);
    LiveServerOptions so;
    so.port = 0;
    server_ = LiveServer::Start(*view_, so);
    client_ = std::make_unique<httplib::Client>("127.0.0.1", server_->port());
    client_->set_read_timeout(10, 0);
  }
  void TearDown() override {
    view_->Close();
    server_->Stop();
  }
  httplib::Result Post(const std::string& path, bool with_header = true) {
    httplib::Headers h;
    if (with_header) h.emplace("X-Msmcal-Request", "1");
    return client_->Post(path.c_str(), h, "", "text/plain");
  }
  dataset::Recording plan_;
  std::unique_ptr<LiveView> view_;
  std::unique_ptr<LiveServer> server_;
  std::unique_ptr<httplib::Client> client_;
};

TEST_F(ServerTest, ServesThePageWithTheIdsScriptsDriveItBy) {
  EXPECT_EQ(server_->url(), "http://127.0.0.1:" + std::to_string(server_->port()) + "/");
  auto res = client_->Get("/");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_NE(res->get_header_value("Content-Type").find("text/html"), std::string::npos);
  for (const char* id : kPageIds)
    EXPECT_NE(res->body.find(std::string("id=\"") + id + "\""), std::string::npos) << id;
  EXPECT_EQ(res->body.find("http://"), std::string::npos);  // offline: nothing external
  EXPECT_EQ(res->body.find("https://"), std::string::npos);
  for (const char* path : {"/live.js", "/live.css"}) {
    auto r = client_->Get(path);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200) << path;
    EXPECT_GT(r->body.size(), 100u) << path;
  }
  auto missing = client_->Get("/nothing-here");
  ASSERT_TRUE(missing);
  EXPECT_EQ(missing->status, 404);
}

TEST_F(ServerTest, StateInstructionImageAndButtons) {
  auto state = client_->Get("/api/state");
  ASSERT_TRUE(state);
  EXPECT_EQ(state->status, 200);
  EXPECT_EQ(json::parse(state->body)["state"], "running");
  auto image = client_->Get("/api/image.jpg");
  ASSERT_TRUE(image);
  EXPECT_EQ(image->status, 404);

  // A live frame: the image endpoint serves its JPEG.
  const cv::Mat board = Checkerboard(7, 5, 30, 400, 300);
  orchestrator::LiveFrame f;
  f.step = 2;
  f.image = &board;
  view_->MakeLiveFrameObserver()(f);
  image = client_->Get("/api/image.jpg");
  ASSERT_TRUE(image);
  EXPECT_EQ(image->status, 200);
  EXPECT_EQ(image->get_header_value("Content-Type"), "image/jpeg");
  ASSERT_GT(image->body.size(), 2u);
  EXPECT_EQ(static_cast<unsigned char>(image->body[0]), 0xFF);  // JPEG SOI
  EXPECT_EQ(static_cast<unsigned char>(image->body[1]), 0xD8);
  EXPECT_EQ(image->get_header_value("X-Image-Sequence"), "1");

  FakeRig rig;
  WebOperator op(plan_, *view_, {}, &rig);
  std::string error;
  std::thread session([&] {
    try {
      op.PrepareStep2Frame(1);
      op.PrepareStep2Frame(0);
    } catch (const orchestrator::OperatorAbort& e) {
      error = e.what();
    }
  });
  ASSERT_TRUE(WaitForState(*view_, [](const json& s) { return s["state"] == "waiting"; }));
  state = client_->Get("/api/state");
  ASSERT_TRUE(state);
  const json s = json::parse(state->body);
  EXPECT_EQ(s["state"], "waiting");
  EXPECT_EQ(s["prompt"]["instructions"].get<std::string>(),
            BlockText(plan_, setup::PlanSetups(plan_, {}).step2_setup[1]));
  const std::string id = std::to_string(s["prompt"]["id"].get<int64_t>());

  // Without the header, without control, without a prompt id: refused, nothing happens.
  auto r = Post("/api/claim", /*with_header=*/false);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 403);
  r = Post("/api/ready?controller=x&prompt=" + id);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 403);
  r = Post("/api/claim");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200);
  const std::string token = json::parse(r->body)["controller"];
  r = Post("/api/claim");  // a second page
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 409);
  EXPECT_NE(json::parse(r->body)["error"].get<std::string>().find("another page"),
            std::string::npos);
  r = Post("/api/ready?controller=" + token);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 400);
  r = Post("/api/repeat?controller=" + token + "&prompt=" + id);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_EQ(json::parse(client_->Get("/api/state")->body)["prompt"]["repeats"], 1);
  EXPECT_TRUE(rig.calls.empty());
  r = Post("/api/ready?controller=" + token + "&prompt=" + id);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  ASSERT_TRUE(WaitForState(*view_, [&](const json& s) {
    return s["state"] == "waiting" && std::to_string(s["prompt"]["id"].get<int64_t>()) != id;
  }));
  EXPECT_EQ(rig.calls, (std::vector<std::string>{"s2:1"}));
  r = Post("/api/abort?controller=" + token);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  session.join();
  EXPECT_EQ(error, kWebAbortMessage);
  EXPECT_EQ(rig.calls, (std::vector<std::string>{"s2:1"}));
  view_->SetState(SessionState::kAborted, "aborted");
  EXPECT_EQ(json::parse(client_->Get("/api/state")->body)["state"], "aborted");
  r = Post("/api/abort?controller=" + token);  // ended: nothing more to do
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 409);
}

TEST_F(ServerTest, EventStreamSendsTheStateOnEveryChange) {
  std::string received;
  int events = 0;
  bool changed = false;
  auto res = client_->Get("/api/events", [&](const char* data, size_t n) {
    received.append(data, n);
    size_t pos;
    while ((pos = received.find("\n\n")) != std::string::npos) {
      const std::string event = received.substr(0, pos);
      received.erase(0, pos + 2);
      const size_t d = event.find("data: ");
      if (d == std::string::npos) continue;  // keepalive
      const json s = json::parse(event.substr(d + 6));
      ++events;
      if (!changed) {
        view_->AddLogLine("the line the stream must bring");
        changed = true;
      } else if (!s["log"].empty() && s["log"].back() == "the line the stream must bring") {
        return false;  // seen: stop reading
      }
    }
    return true;
  });
  EXPECT_GE(events, 2);
  EXPECT_TRUE(changed);
}

TEST_F(ServerTest, EventStreamKeepsTheControllersLease) {
  // Lease of the fixture's view is 5 s; a controller whose stream is open keeps it even when it
  // sends nothing else: checked through a second view with a short lease.
  LiveViewOptions o;
  o.controller_lease = milliseconds(400);
  LiveView view(plan_, o);
  LiveServerOptions so;
  so.port = 0;
  auto server = LiveServer::Start(view, so);
  httplib::Client c("127.0.0.1", server->port());
  c.set_read_timeout(10, 0);
  httplib::Headers h{{"X-Msmcal-Request", "1"}};
  auto r = c.Post("/api/claim", h, "", "text/plain");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200);
  const std::string token = json::parse(r->body)["controller"];
  const auto t0 = std::chrono::steady_clock::now();
  int refused = 0;
  std::thread watcher([&] {
    httplib::Client w("127.0.0.1", server->port());
    // Claims from another page for 1.5 s (several leases): all refused while the stream is open.
    while (std::chrono::steady_clock::now() - t0 < milliseconds(1500)) {
      auto rr = w.Post("/api/claim", h, "", "text/plain");
      if (rr && rr->status == 409) ++refused;
      view.WaitForChange(view.version(), milliseconds(100));
    }
    view.AddLogLine("stop");
  });
  auto stream = c.Get("/api/events?controller=" + token, [&](const char* data, size_t n) {
    return std::string(data, n).find("\"stop\"") == std::string::npos;
  });
  watcher.join();
  EXPECT_GT(refused, 3);
  EXPECT_EQ(view.Submit(token, Command::kAbort, -1).http_status, 200);
  view.Close();
  server->Stop();
}

TEST(LiveServer, AnotherAddressNeedsTheExplicitOptionAndTheToken) {
  const dataset::Recording plan = SmallPlan();
  LiveView view(plan, {});
  LiveServerOptions so;
  so.bind_address = "127.0.0.2";  // not 127.0.0.1: treated like a lab-network address
  so.port = 0;
  EXPECT_NE(so.Validate().find("allow_remote"), std::string::npos);
  EXPECT_THROW(LiveServer::Start(view, so), std::invalid_argument);
  so.allow_remote = true;
  auto server = LiveServer::Start(view, so);
  const std::string token = server->access_token();
  EXPECT_EQ(token.size(), 32u);
  EXPECT_EQ(server->url(),
            "http://127.0.0.2:" + std::to_string(server->port()) + "/?token=" + token);
  httplib::Client c("127.0.0.2", server->port());
  auto r = c.Get("/api/state");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 403);
  r = c.Get("/?token=wrong");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 403);
  r = c.Get("/?token=" + token);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  const std::string cookie = r->get_header_value("Set-Cookie");
  EXPECT_NE(cookie.find("msmcal_token=" + token), std::string::npos);
  // The page's own requests carry the cookie.
  r = c.Get("/api/state", {{"Cookie", "msmcal_token=" + token}});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  server->Stop();
}

TEST(LiveServer, ParsesTheUiOptionAndRefusesABusyPort) {
  EXPECT_EQ(ParseUiWebOption("web"), kDefaultLivePort);
  EXPECT_EQ(ParseUiWebOption("web:0"), 0);
  EXPECT_EQ(ParseUiWebOption("web:9000"), 9000);
  for (const char* bad : {"", "web:", "web:x", "web:70000", "console", "web:-1"})
    EXPECT_THROW(ParseUiWebOption(bad), std::invalid_argument) << bad;
  const dataset::Recording plan = SmallPlan();
  LiveView view(plan, {});
  LiveServerOptions so;
  so.port = 0;
  auto first = LiveServer::Start(view, so);
  so.port = first->port();
  try {
    LiveServer::Start(view, so);
    ADD_FAILURE() << "a second server bound the same port";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot bind"), std::string::npos);
  }
}

}  // namespace
}  // namespace msmcal::live_view
