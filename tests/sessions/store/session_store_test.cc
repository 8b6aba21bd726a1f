#include "sessions/store/session_store.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <bit>
#include <cmath>
#include <fstream>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <thread>

#include "sessions/interchange/interchange_io.h"
#include "tests/testing/test_files.h"

namespace msmcal::store {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// Per-test folders named msmcal_store_<suite>_<test>_<pid>.
class TempDir : public msmcal::testing::TempDir {
 public:
  TempDir() : msmcal::testing::TempDir("msmcal_store") {}
};

bool Same(double a, double b) { return std::bit_cast<uint64_t>(a) == std::bit_cast<uint64_t>(b); }

SessionMetadata TestMetadata() {
  SessionMetadata m;
  m.rig_id = "rig-A";
  m.mirror_id = "msm-17";
  m.note = "unit test";
  m.config_yaml = "camera: {exposure_us: 1000}\n";
  m.description.camera.width = 640;
  m.description.camera.height = 480;
  m.description.camera.fx = m.description.camera.fy = 800;
  m.description.camera.cx = 320;
  m.description.camera.cy = 240;
  m.description.world_board = {9, 6, 10};
  m.description.sliding_board = {7, 4, 12.5};
  m.description.beams = {{1, dataset::BeamRole::kEstimate}, {2, dataset::BeamRole::kValidate}};
  m.description.drive.fast = {1200, 2.5, 0};
  m.description.drive.slow = {60, 1.25, 90};
  m.description.drive.pattern_period_s = 0.05;
  m.description.clock_frequency_hz = 20;
  return m;
}

// Deterministic Hall reading number i (so a reopened store can be checked value for value).
dataset::HallReading ReadingAt(int64_t i) {
  return {1000.0 * static_cast<double>(i), std::sin(0.001 * i) * 1e3, -std::cos(0.002 * i),
          i % 7 == 0 ? -0.0 : 1e-300 * i};
}

cv::Mat ImageAt(int i) {
  cv::Mat img(48, 64, CV_16UC1);
  for (int r = 0; r < img.rows; ++r) {
    for (int c = 0; c < img.cols; ++c)
      img.at<uint16_t>(r, c) = static_cast<uint16_t>(i * 131 + r * c);
  }
  return img;
}

template <typename Fn>
std::string StoreErrorOf(Fn fn) {
  try {
    fn();
  } catch (const StoreError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no StoreError thrown";
  return "";
}

TEST(SessionStoreTest, EverythingWrittenReadsBackAfterReopen) {
  TempDir tmp;
  FakeClock clock(1'700'000'000'000'000'000, 1000);
  const fs::path dir = tmp.path() / "s1";
  {
    auto store = SessionStore::Create(dir, TestMetadata(), clock);
    store->SetInstrument("generator1", "Keysight,33520B,MY123,4.0");
    store->SetInstrument("camera", "Basler,acA4112,0815");
    store->SetTriggers({{3, 0.001}, {0, -0.0}, {7, std::numeric_limits<double>::denorm_min()}});
    store->AddEvent("info", "started");
    store->AddEvent("step", "step 2 frame", 0.0125);
    FrameRecord f1;
    f1.step = "step1";
    f1.file = "step1/0000.png";
    f1.pose = 3;
    f1.beams = {1};
    f1.quality_json = R"({"dots":1})";
    store->AddFrame(f1, ImageAt(0));
    FrameRecord f2;
    f2.step = "step2";
    f2.file = "step2/0000.png";
    f2.kind = dataset::Step2Kind::kFastOnly;
    f2.triggers = {0, 3};
    f2.beams = {1, 2};
    f2.accepted = false;
    store->AddFrame(f2, ImageAt(1));
    std::vector<dataset::HallReading> batch;
    for (int i = 0; i < 250; ++i) batch.push_back(ReadingAt(i));
    store->AppendHallReadings("actual", {batch.begin(), batch.begin() + 100});
    store->AppendHallReadings("actual", {batch.begin() + 100, batch.end()});
    store->AppendClockEdges("actual", {10, 20});
    store->AppendClockEdges("actual", {30});
    store->PutResult("summary.json", R"({"rms_px": 0.25})");
    store->PutAttachment("marg/validation.csv", "t_s,mx_uT,my_uT,mz_uT\n");
    store->SetStep("step1", StepState::kDone);
    store->SetStep("step2", StepState::kRunning);
    store->SetStep("solve", StepState::kFailed);
    store->SetMeta("custom", "x");
  }
  auto store = SessionStore::Open(dir, clock);
  EXPECT_EQ(store->IntegrityCheck(), "ok");
  EXPECT_EQ(*store->GetMeta("rig_id"), "rig-A");
  EXPECT_EQ(*store->GetMeta("mirror_id"), "msm-17");
  EXPECT_EQ(*store->GetMeta("created_ns"), "1700000000000000000");
  EXPECT_EQ(*store->GetMeta("drive.slow.amplitude_vpp"), "1.25");
  EXPECT_EQ(*store->GetMeta("custom"), "x");
  EXPECT_EQ(store->ConfigYaml(), "camera: {exposure_us: 1000}\n");
  const auto d = store->Description();
  EXPECT_EQ(d.camera.fx, 800);
  EXPECT_EQ(d.sliding_board.square_mm, 12.5);
  EXPECT_EQ(d.beams.size(), 2u);
  EXPECT_EQ(d.drive.slow.phase_deg, 90);
  EXPECT_EQ(store->Instruments().size(), 2u);
  EXPECT_EQ(store->Instruments()[0].first, "camera");

  const auto triggers = store->Triggers();
  ASSERT_EQ(triggers.size(), 3u);
  EXPECT_EQ(triggers[0].j, 3);
  EXPECT_EQ(triggers[1].j, 0);
  EXPECT_TRUE(Same(triggers[1].t_s, -0.0));
  EXPECT_TRUE(Same(triggers[2].t_s, std::numeric_limits<double>::denorm_min()));

  const auto events = store->Events();
  ASSERT_EQ(events.size(), 2u);
  EXPECT_FALSE(events[0].generator_time_s);
  EXPECT_EQ(*events[1].generator_time_s, 0.0125);
  EXPECT_LT(events[0].wall_time_ns, events[1].wall_time_ns);
  EXPECT_EQ(store->Events(1).size(), 1u);
  EXPECT_EQ(store->Events(1)[0].message, "step 2 frame");

  const auto frames = store->Frames();
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].pose, 3);
  EXPECT_EQ(frames[0].quality_json, R"({"dots":1})");
  EXPECT_TRUE(frames[0].accepted);
  EXPECT_EQ(frames[1].kind, dataset::Step2Kind::kFastOnly);
  EXPECT_EQ(frames[1].triggers, (std::vector<int>{0, 3}));
  EXPECT_FALSE(frames[1].accepted);
  const cv::Mat img = cv::imread((dir / "step2/0000.png").string(), cv::IMREAD_UNCHANGED);
  EXPECT_EQ(cv::norm(img, ImageAt(1), cv::NORM_INF), 0);

  const auto hall = store->HallReadings("actual");
  ASSERT_EQ(hall.size(), 250u);
  for (int i = 0; i < 250; ++i) {
    const auto want = ReadingAt(i);
    EXPECT_EQ(hall[i].mcu_time_us, want.mcu_time_us);
    EXPECT_TRUE(Same(hall[i].bx_uT, want.bx_uT));
    EXPECT_TRUE(Same(hall[i].by_uT, want.by_uT));
    EXPECT_TRUE(Same(hall[i].bz_uT, want.bz_uT)) << i;
  }
  EXPECT_EQ(store->ClockEdges("actual"), (std::vector<double>{10, 20, 30}));
  EXPECT_EQ(store->HallRecordingNames(), (std::vector<std::string>{"actual"}));
  EXPECT_EQ(*store->GetResult("summary.json"), R"({"rms_px": 0.25})");
  EXPECT_EQ(store->AttachmentPaths(), (std::vector<std::string>{"marg/validation.csv"}));
  const auto steps = store->Steps();
  ASSERT_EQ(steps.size(), 3u);
  EXPECT_EQ(steps[0].first, "step1");
  EXPECT_EQ(steps[1].second, StepState::kRunning);
  EXPECT_EQ(steps[2].second, StepState::kFailed);
  EXPECT_STREQ(ToString(steps[2].second), "failed");
  const auto counts = store->Counts();
  EXPECT_EQ(counts.frames, 2);
  EXPECT_EQ(counts.hall_readings.at("actual"), 250);
  EXPECT_EQ(counts.clock_edges.at("actual"), 3);

  // WAL journal, FULL synchronous on reopen.
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((dir / kSessionDbName).c_str(), &db), SQLITE_OK);
  sqlite3_stmt* st = nullptr;
  sqlite3_prepare_v2(db, "PRAGMA journal_mode", -1, &st, nullptr);
  ASSERT_EQ(sqlite3_step(st), SQLITE_ROW);
  EXPECT_STREQ(reinterpret_cast<const char*>(sqlite3_column_text(st, 0)), "wal");
  sqlite3_finalize(st);
  sqlite3_close(db);
}

TEST(SessionStoreTest, RejectsBadInput) {
  TempDir tmp;
  FakeClock clock;
  const fs::path dir = tmp.path() / "s";
  auto store = SessionStore::Create(dir, TestMetadata(), clock);
  EXPECT_THAT(StoreErrorOf([&] { SessionStore::Create(dir, TestMetadata(), clock); }),
              HasSubstr("already holds a session"));
  store->AppendClockEdges("actual", {10, 20});
  EXPECT_THAT(StoreErrorOf([&] { store->AppendClockEdges("actual", {20}); }),
              HasSubstr("strictly ascending: 20 after 20"));
  EXPECT_EQ(store->ClockEdges("actual").size(), 2u);  // the failed batch left nothing
  FrameRecord f;
  f.step = "step1";
  f.file = "../escape.png";
  EXPECT_THAT(StoreErrorOf([&] { store->AddFrame(f, ImageAt(0)); }),
              HasSubstr("relative path inside the session"));
  f.file = "step1/a.png";
  f.quality_json = "[1]";
  EXPECT_THAT(StoreErrorOf([&] { store->AddFrame(f, ImageAt(0)); }),
              HasSubstr("quality_json must be a JSON object"));
  f.quality_json = "{}";
  store->AddFrame(f, ImageAt(0));
  EXPECT_THAT(StoreErrorOf([&] { store->AddFrame(f, ImageAt(1)); }),
              HasSubstr("'step1/a.png' is already recorded"));
  EXPECT_THAT(StoreErrorOf([&] {
                store->SetTriggers({{1, 0}, {1, 2}});
              }),
              HasSubstr("j=1 appears twice"));
  f.file = "step1/missing.png";
  EXPECT_THAT(StoreErrorOf([&] { store->AddFrameRecord(f); }), HasSubstr("does not exist"));

  EXPECT_THAT(StoreErrorOf([&] { SessionStore::Open(tmp.path() / "nothing", clock); }),
              HasSubstr("not a session folder"));
  store.reset();
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((dir / kSessionDbName).c_str(), &db), SQLITE_OK);
  sqlite3_exec(db, "PRAGMA user_version=99", nullptr, nullptr, nullptr);
  sqlite3_close(db);
  EXPECT_THAT(StoreErrorOf([&] { SessionStore::Open(dir, clock); }),
              HasSubstr("schema version 99, this msmcal reads version 1"));
}

TEST(SessionStoreTest, ReadOnlyRefusesWrites) {
  TempDir tmp;
  FakeClock clock;
  SessionStore::Create(tmp.path() / "s", TestMetadata(), clock);
  auto store = SessionStore::Open(tmp.path() / "s", clock, /*read_only=*/true);
  EXPECT_EQ(*store->GetMeta("mirror_id"), "msm-17");
  EXPECT_THAT(StoreErrorOf([&] { store->AddEvent("info", "x"); }), HasSubstr("read-only"));
}

TEST(SessionStoreTest, ConcurrentWritersAllLand) {
  TempDir tmp;
  FakeClock clock(0, 1);
  auto store = SessionStore::Create(tmp.path() / "s", TestMetadata(), clock);
  constexpr int kBatches = 40;
  std::thread hall([&] {
    for (int b = 0; b < kBatches; ++b) {
      std::vector<dataset::HallReading> batch;
      for (int k = 0; k < 25; ++k) batch.push_back(ReadingAt(b * 25 + k));
      store->AppendHallReadings("actual", batch);
    }
  });
  std::thread frames([&] {
    for (int i = 0; i < 8; ++i) {
      FrameRecord f;
      f.step = "step1";
      f.file = "step1/" + std::to_string(i) + ".png";
      store->AddFrame(f, ImageAt(i));
      store->AddEvent("info", "frame " + std::to_string(i));
    }
  });
  hall.join();
  frames.join();
  const auto readings = store->HallReadings("actual");
  ASSERT_EQ(readings.size(), 25u * kBatches);
  for (size_t i = 0; i < readings.size(); ++i) {
    ASSERT_EQ(readings[i].mcu_time_us, ReadingAt(i).mcu_time_us);
  }
  EXPECT_EQ(store->Frames().size(), 8u);
  EXPECT_EQ(store->Events().size(), 8u);
  EXPECT_EQ(store->IntegrityCheck(), "ok");
}

// The crash test: a child process records Hall batches and frames, reporting each committed
// call through a pipe; the parent kills it with SIGKILL at a chosen point; the reopened session
// must be consistent and hold every reported row.
constexpr int kBatch = 100;

[[noreturn]] void RecordUntilKilled(const fs::path& dir, int progress_fd) {
  FakeClock clock(0, 1);
  auto store = SessionStore::Open(dir, clock);
  for (int32_t i = 0; i < 1'000'000; ++i) {
    std::vector<dataset::HallReading> batch;
    for (int k = 0; k < kBatch; ++k) batch.push_back(ReadingAt(int64_t{i} * kBatch + k));
    store->AppendHallReadings("actual", batch);
    store->AppendClockEdges("actual", {i * 50000.0});
    if (i % 3 == 0) {
      FrameRecord f;
      f.step = "step2";
      char name[32];
      std::snprintf(name, sizeof(name), "step2/%06d.png", i);
      f.file = name;
      f.kind = dataset::Step2Kind::kScan;
      f.beams = {1};
      store->AddFrame(f, ImageAt(i));
    }
    if (::write(progress_fd, &i, sizeof(i)) != sizeof(i)) _exit(2);
  }
  _exit(0);
}

TEST(SessionStoreCrashTest, ReopensConsistentAfterSigkill) {
  TempDir tmp;
  FakeClock clock;
  // Kill points (in committed iterations): early, mid-frame-writing, later.
  for (int32_t kill_after : {0, 4, 11}) {
    const fs::path dir = tmp.path() / ("s" + std::to_string(kill_after));
    SessionStore::Create(dir, TestMetadata(), clock);
    int fds[2];
    ASSERT_EQ(::pipe(fds), 0);
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      ::close(fds[0]);
      try {
        RecordUntilKilled(dir, fds[1]);
      } catch (...) {
        _exit(3);
      }
    }
    ::close(fds[1]);
    int32_t reported = -1, got = 0;
    while (reported < kill_after &&
           ::read(fds[0], &got, sizeof(got)) == static_cast<ssize_t>(sizeof(got))) {
      reported = got;
    }
    ASSERT_EQ(::kill(pid, SIGKILL), 0);
    int status = 0;
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(WIFSIGNALED(status)) << "child exited with status " << status;
    // Iterations reported after our last read were committed too.
    while (::read(fds[0], &got, sizeof(got)) == static_cast<ssize_t>(sizeof(got))) reported = got;
    ::close(fds[0]);
    ASSERT_GE(reported, kill_after);

    auto store = SessionStore::Open(dir, clock);
    EXPECT_EQ(store->IntegrityCheck(), "ok");
    const auto hall = store->HallReadings("actual");
    // Every reported batch is there; batches are all-or-nothing.
    EXPECT_GE(hall.size(), static_cast<size_t>(reported + 1) * kBatch);
    EXPECT_EQ(hall.size() % kBatch, 0u);
    for (size_t i = 0; i < hall.size(); ++i) {
      ASSERT_EQ(hall[i].mcu_time_us, ReadingAt(i).mcu_time_us);
      ASSERT_TRUE(Same(hall[i].bx_uT, ReadingAt(i).bx_uT));
    }
    EXPECT_GE(store->ClockEdges("actual").size(), static_cast<size_t>(reported + 1));
    const auto frames = store->Frames();
    EXPECT_GE(frames.size(), static_cast<size_t>(reported / 3 + 1));
    for (const auto& f : frames) {
      const int i = std::stoi(f.file.substr(6, 6));
      const cv::Mat img = cv::imread((dir / f.file).string(), cv::IMREAD_UNCHANGED);
      ASSERT_FALSE(img.empty()) << f.file;
      EXPECT_EQ(cv::norm(img, ImageAt(i), cv::NORM_INF), 0) << f.file;
    }
    // Open removed the temporaries of an interrupted image write.
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
      EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
    }
    // The session keeps recording after the crash.
    store->AppendHallReadings("actual", {ReadingAt(static_cast<int64_t>(hall.size()))});
    EXPECT_EQ(store->HallReadings("actual").size(), hall.size() + 1);
  }
}

}  // namespace
}  // namespace msmcal::store
