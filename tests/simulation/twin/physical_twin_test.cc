// Physics through the wires: the twin driven only through the real drivers — SCPI over TCP to
// both mock 33520B units (drivers/generator), GigE Vision to the camera (the Aravis driver), the
// Hall MCU's serial protocol on its pty — and its hands. A frame shows one dot per laser pulse
// of the uploaded arb and per unblocked beam, where the simulator's truth puts them for those
// times; laser off: no dots; a beam blocked: its dots gone; the MCU streams readings and clock
// edges only while the clock output is on; the truth written loads with the truth reader.
// Runs in its own network namespace (the camera serves GigE Vision on 127.0.0.1:3956).
#include "simulation/twin/physical_twin.h"

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <opencv2/core.hpp>

#include "common/units.h"
#include "drivers/camera/open_camera.h"
#include "drivers/generator/function_generator.h"
#include "drivers/generator/rig_generators.h"
#include "drivers/hall_mcu/hall_sensor.h"
#include "mocks/rig/truth_io.h"
#include "processing/vision/dots.h"
#include "sessions/orchestrator/orchestrator.h"
#include "simulation/truth/truth_comparison.h"
#include "simulation/twin/demo_rig.h"

namespace msmcal::twin {
namespace {

namespace fs = std::filesystem;

sim::SimOptions SmallWorld() {
  sim::SimOptions o;
  o.seed = 5;
  o.camera.width = 1224;
  o.camera.height = 1024;
  o.camera.fx = o.camera.fy = 1000;
  o.camera.cx = 611.5;
  o.camera.cy = 511.5;
  o.triggers.max_triggers = 8;
  o.triggers.min_separation_px = 16;
  return o;
}

int64_t SteadyNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

cv::Mat ToMat(const camera::Frame& frame) {
  const auto& info = frame.info();
  cv::Mat view(info.height, info.width, CV_8UC1, const_cast<uint8_t*>(frame.data()),
               frame.stride_bytes());
  return view.clone();
}

class PhysicalTwinTest : public ::testing::Test {
 protected:
  void SetUp() override {
    PhysicalTwinOptions o;
    o.sim = SmallWorld();
    o.camera_address = "127.0.0.1";
    o.camera_frame_rate_hz = 10;
    o.exposure_s = 0.3;  // > one pattern period (0.2 s): every pulse of the pattern shows
    o.clock_ns = SteadyNs;
    twin_ = std::make_unique<PhysicalTwin>(o);
    ref_ = std::make_unique<sim::RigSimulator>(o.sim);  // the truth, computed independently

    const gen::RigGeneratorConfig config =
        DemoGeneratorConfig(o.sim, twin_->generator_port(1), twin_->generator_port(2));
    signals_config_ = config.signals;
    master_ = gen::OpenKeysight33500(config.unit1);
    slave_ = gen::OpenKeysight33500(config.unit2);

    camera::OpenCameraResult opened = camera::OpenCamera("127.0.0.1");
    ASSERT_TRUE(opened.camera) << opened.error;
    camera_ = std::move(opened.camera);
    camera::CameraConfig cc;
    cc.pixel_format = camera::PixelFormat::kMono8;
    cc.frame_rate_hz = 10;
    cc.buffer_count = 4;
    ASSERT_TRUE(camera_->Configure(cc));
    ASSERT_TRUE(camera_->Start());
  }
  void TearDown() override {
    if (camera_) camera_->Stop();
    camera_.reset();
    if (master_) master_->SafeState();
    if (slave_) slave_->SafeState();
    master_.reset();
    slave_.reset();
    twin_.reset();
  }

  // Applies drives, clock and a laser arb firing at `times` (the orchestrator's path).
  void ApplySignals(const std::vector<double>& times) {
    dataset::Recording plan;
    plan.drive.pattern_period_s = ref_->pattern_period_s();
    for (size_t j = 0; j < times.size(); ++j)
      plan.triggers.push_back({static_cast<int>(j), times[j]});
    const gen::RigSignalPlan p = orchestrator::PlanSessionSignals(signals_config_, plan);
    gen::RigGenerators rig(*master_, *slave_);
    rig.Apply(p);
  }

  // The first frame whose exposure started after `since_ns` (frames in flight are skipped).
  cv::Mat FrameAfter(int64_t since_ns) {
    for (int i = 0; i < 40; ++i) {
      camera::FrameResult fr = camera_->NextFrame(/*timeout_us=*/5'000'000);
      EXPECT_EQ(fr.status, camera::FrameStatus::kOk) << fr.message;
      if (fr.status != camera::FrameStatus::kOk) return {};
      const auto stamp = twin_->FrameStampFor(fr.frame.info().device_timestamp_ns);
      if (stamp && stamp->exposure_start_ns >= since_ns) return ToMat(fr.frame);
    }
    ADD_FAILURE() << "no frame exposed after the change within 40 frames";
    return {};
  }

  // Where the simulator puts beam `id`'s dot for a pulse at generator time t (scan), in C2.
  Eigen::Vector2d TruthPixel(int id, double t) const {
    const auto p =
        ref_->ReflectedDotInWorld(id, ref_->MirrorPlaneInWorld(t, sim::DriveMode::kScan));
    EXPECT_TRUE(p);
    return *ref_->camera().Project(ref_->c2_from_world() * *p);
  }

  static std::vector<vision::Dot> Dots(const cv::Mat& image, const cv::Mat& background) {
    vision::DotOptions d;
    d.min_pixels = 4;
    return vision::DetectDotsOverBackground(image, background, d);
  }

  // Number of expected pixels matched by a detected dot within tol_px, one to one.
  static int Matched(const std::vector<vision::Dot>& dots,
                     const std::vector<Eigen::Vector2d>& expected, double tol_px,
                     double* worst_px) {
    int matched = 0;
    *worst_px = 0;
    std::vector<bool> used(dots.size(), false);
    for (const auto& e : expected) {
      int best = -1;
      double best_d = tol_px;
      for (size_t i = 0; i < dots.size(); ++i) {
        const double d = (dots[i].px - e).norm();
        if (!used[i] && d <= best_d) {
          best_d = d;
          best = static_cast<int>(i);
        }
      }
      if (best >= 0) {
        used[best] = true;
        ++matched;
        *worst_px = std::max(*worst_px, best_d);
      }
    }
    return matched;
  }

  std::unique_ptr<PhysicalTwin> twin_;
  std::unique_ptr<sim::RigSimulator> ref_;
  gen::RigSignalsConfig signals_config_;
  std::unique_ptr<gen::FunctionGenerator> master_, slave_;
  std::unique_ptr<camera::Camera> camera_;
};

TEST_F(PhysicalTwinTest, FramesFollowTheWiresAndTheHands) {
  // Step 2 set-up by hand: camera at C2, MSM mounted, plate off, every beam.
  TwinSetup s;
  s.camera = 2;
  s.msm_mounted = true;
  s.sliding_plate = SlidingPlateSetup{};  // not mounted
  twin_->Apply(s);
  // Drives and laser off (power-up): the world board alone, no light.
  const cv::Mat background = FrameAfter(twin_->NowNs());
  ASSERT_FALSE(background.empty());
  EXPECT_TRUE(Dots(background, background).empty());

  // Three pulses of the simulator's trigger table (dots apart in C2).
  const std::vector<double> times = {ref_->triggers()[0].t_s, ref_->triggers()[1].t_s,
                                     ref_->triggers()[2].t_s};
  ApplySignals(times);
  // What the twin decoded from the uploaded arb: the three times, to the arb's sample.
  const std::vector<double> decoded = twin_->LaserPatternTimesS();
  ASSERT_EQ(decoded.size(), times.size());
  for (size_t k = 0; k < times.size(); ++k) EXPECT_NEAR(decoded[k], times[k], 1e-6);
  EXPECT_EQ(twin_->Drive().mode, sim::DriveMode::kScan);

  std::vector<Eigen::Vector2d> expected;
  for (double t : times)
    for (int id = 1; id <= 3; ++id) expected.push_back(TruthPixel(id, t));
  {
    const std::vector<vision::Dot> dots = Dots(FrameAfter(twin_->NowNs()), background);
    double worst = 0;
    EXPECT_EQ(dots.size(), times.size() * 3);
    EXPECT_EQ(Matched(dots, expected, /*tol_px=*/1.0, &worst), static_cast<int>(expected.size()))
        << "worst match " << worst << " px";
  }

  // Beam 2 blocked by hand: its three dots gone, the others stay.
  TwinSetup block;
  block.beams_unblocked = std::vector<int>{1, 3};
  twin_->Apply(block);
  {
    const std::vector<vision::Dot> dots = Dots(FrameAfter(twin_->NowNs()), background);
    EXPECT_EQ(dots.size(), times.size() * 2);
    std::vector<Eigen::Vector2d> beam2;
    for (double t : times) beam2.push_back(TruthPixel(2, t));
    double worst = 0;
    EXPECT_EQ(Matched(dots, beam2, /*tol_px=*/3.0, &worst), 0);
  }

  // Drives off (laser still firing): the neutral pose, one dot per unblocked beam.
  ASSERT_TRUE(master_->SetOutput(1, false));
  ASSERT_TRUE(master_->SetOutput(2, false));
  {
    const std::vector<vision::Dot> dots = Dots(FrameAfter(twin_->NowNs()), background);
    EXPECT_EQ(dots.size(), 2u);
    std::vector<Eigen::Vector2d> neutral;
    for (int id : {1, 3}) {
      const auto p =
          ref_->ReflectedDotInWorld(id, ref_->MirrorPlaneInWorld(0, sim::DriveMode::kOff));
      neutral.push_back(*ref_->camera().Project(ref_->c2_from_world() * *p));
    }
    double worst = 0;
    EXPECT_EQ(Matched(dots, neutral, 1.0, &worst), 2) << "worst " << worst;
  }

  // Laser output off: no dots at all.
  ASSERT_TRUE(slave_->SetOutput(1, false));
  EXPECT_TRUE(Dots(FrameAfter(twin_->NowNs()), background).empty());
}

TEST_F(PhysicalTwinTest, Step1DotsLandOnTheSlidingPlate) {
  TwinSetup s;
  s.camera = 1;
  s.msm_mounted = false;
  SlidingPlateSetup plate;
  plate.mounted = true;
  plate.pose = 6;  // the farthest pose of the default design: its dots lie apart in C1
  s.sliding_plate = plate;
  twin_->Apply(s);
  ASSERT_TRUE(slave_->SetOutput(1, false));
  ApplySignals({ref_->triggers()[0].t_s, ref_->triggers()[1].t_s});
  ASSERT_TRUE(slave_->SetOutput(1, false));
  const cv::Mat dark = FrameAfter(twin_->NowNs());
  ASSERT_TRUE(slave_->SetOutput(1, true));
  // No mirror: every pulse lights the same spot, one dot per beam, where the beam meets the plate.
  const std::vector<vision::Dot> dots = Dots(FrameAfter(twin_->NowNs()), dark);
  std::vector<Eigen::Vector2d> expected;
  for (int id = 1; id <= 3; ++id) {
    const auto p = ref_->SlidingDotInWorld(id, 6);
    ASSERT_TRUE(p);
    expected.push_back(*ref_->camera().Project(ref_->c1_from_world() * *p));
  }
  double worst = 0;
  EXPECT_EQ(dots.size(), 3u);
  EXPECT_EQ(Matched(dots, expected, 1.0, &worst), 3) << "worst " << worst;
}

TEST_F(PhysicalTwinTest, ThePlateMovesInTheDarkToo) {
  // Every beam blocked: no dots either way, but the frames show where the plate is.
  TwinSetup s;
  s.camera = 1;
  s.msm_mounted = false;
  SlidingPlateSetup plate;
  plate.mounted = true;
  plate.pose = 0;
  s.sliding_plate = plate;
  s.beams_unblocked = std::vector<int>{};
  twin_->Apply(s);
  const cv::Mat a = FrameAfter(twin_->NowNs());
  s.sliding_plate->pose = 5;
  twin_->Apply(s);
  const cv::Mat b = FrameAfter(twin_->NowNs());
  ASSERT_FALSE(a.empty());
  ASSERT_FALSE(b.empty());
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  EXPECT_GT(cv::countNonZero(diff > 60), 1000) << "the plate did not move in the image";
}

TEST_F(PhysicalTwinTest, HallMcuStreamsAndTimestampsTheClockOnlyWhileItIsOn) {
  ApplySignals({ref_->triggers()[0].t_s});
  hall_mcu::HallMcuOptions link;
  link.device = twin_->hall_device();
  link.stall_timeout_ms = 2000;
  auto mcu = hall_mcu::OpenHallMcu(link);
  hall_mcu::DeviceInfo info;
  ASSERT_TRUE(mcu->Identify(&info).ok);
  ASSERT_TRUE(mcu->StartStreaming().ok);
  // Read until `want` readings arrived; returns the edges seen meanwhile.
  auto read = [&](size_t want, std::vector<hall_mcu::HallSample>* readings) {
    std::vector<hall_mcu::ClockEdge> edges;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (readings->size() < want && std::chrono::steady_clock::now() < deadline) {
      hall_mcu::HallBatch batch;
      const hall_mcu::ReadResult r = mcu->Read(&batch);
      EXPECT_EQ(r.status, hall_mcu::ReadStatus::kOk) << r.message;
      if (r.status != hall_mcu::ReadStatus::kOk) break;
      readings->insert(readings->end(), batch.readings.begin(), batch.readings.end());
      edges.insert(edges.end(), batch.edges.begin(), batch.edges.end());
    }
    return edges;
  };
  std::vector<hall_mcu::HallSample> on_readings;
  const auto on_edges = read(600, &on_readings);  // 0.6 s at 1 kHz: 3 clock periods
  ASSERT_GE(on_readings.size(), 600u);
  // One edge per pattern period (0.2 s, MCU clock +35 ppm) over the readings' span.
  const double span_s =
      static_cast<double>(on_readings.back().mcu_time_us - on_readings.front().mcu_time_us) * 1e-6;
  EXPECT_GE(on_edges.size(), 2u);
  EXPECT_NEAR(static_cast<double>(on_edges.size()), span_s / 0.2, 1.01);
  // Readings every 1 ms of MCU time; edges one pattern period apart (MCU clock: +35 ppm).
  EXPECT_EQ(on_readings[1].mcu_time_us - on_readings[0].mcu_time_us, 1000);
  for (size_t k = 1; k < on_edges.size(); ++k)
    EXPECT_NEAR(on_edges[k].mcu_time_us - on_edges[k - 1].mcu_time_us, 200007, 2);
  // The field moves with the mirror and the coils: readings are not constant.
  double lo = 1e9, hi = -1e9;
  for (const auto& r : on_readings) {
    lo = std::min(lo, r.bx_uT);
    hi = std::max(hi, r.bx_uT);
  }
  EXPECT_GT(hi - lo, 10.0);

  ASSERT_TRUE(slave_->SetOutput(2, false));  // clock output off
  std::vector<hall_mcu::HallSample> skip;
  // What was in flight: the mock MCU hands its output over in blocks of 4 KiB (~170 readings).
  (void)read(400, &skip);
  std::vector<hall_mcu::HallSample> off_readings;
  const auto off_edges = read(600, &off_readings);
  EXPECT_GE(off_readings.size(), 600u);
  EXPECT_TRUE(off_edges.empty()) << off_edges.size() << " edges with the clock off";
  (void)mcu->StopStreaming();
}

TEST_F(PhysicalTwinTest, TruthOfTheLastAppliedDriveLoads) {
  const std::vector<double> times = {ref_->triggers()[0].t_s, ref_->triggers()[2].t_s,
                                     ref_->triggers()[4].t_s};
  ApplySignals(times);
  (void)FrameAfter(twin_->NowNs());
  // The session ends: safe state (every output off). The truth is of what was applied.
  master_->SafeState();
  slave_->SafeState();
  const fs::path dir = fs::path(::testing::TempDir()) / "physical_twin_truth";
  fs::remove_all(dir);
  twin_->WriteTruth(dir / "truth");
  const sim::SimTruth truth = sim::ReadTruth(dir);
  ASSERT_EQ(truth.mirror_planes.size(), times.size());
  for (size_t j = 0; j < times.size(); ++j) {
    EXPECT_NEAR(truth.mirror_planes[j].t_s, times[j], 1e-6);
    const geometry::MirrorPose pose = ref_->motion().PoseAt(times[j], sim::DriveMode::kScan);
    EXPECT_NEAR(truth.mirror_planes[j].alpha_deg, common::RadToDeg(pose.alpha_rad), 1e-3);
    EXPECT_NEAR(truth.mirror_planes[j].beta_deg, common::RadToDeg(pose.beta_rad), 1e-3);
  }
  EXPECT_EQ(truth.beams.size(), 3u);
  EXPECT_TRUE(simulation::OpenSimTruth(dir));
}

}  // namespace
}  // namespace msmcal::twin
