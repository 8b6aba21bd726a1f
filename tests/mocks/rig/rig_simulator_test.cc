// Rig simulator: configuration, motion model, geometry truth, dots, Hall field, determinism.
#include "mocks/rig/rig_simulator.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <sstream>

#include "common/units.h"
#include "mocks/rig/hall_model.h"
#include "mocks/rig/mirror_motion.h"
#include "mocks/rig/sim_options.h"
#include "mocks/rig/truth_io.h"
#include "processing/geometry/mirror_frame.h"

namespace msmcal::sim {
namespace {

namespace fs = std::filesystem;
// The source / binary folders: from the test environment, else as configured at build time.
std::string EnvOr(const char* name, const char* fallback) {
  const char* v = std::getenv(name);
  return v && *v ? v : fallback;
}
constexpr double kPi = std::numbers::pi;

std::string Slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

fs::path TempDir(const std::string& name) {
  const fs::path base =
      fs::temp_directory_path() / ("msmcal_rig_test_" + std::to_string(::getpid()));
  const fs::path dir = base / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// Removes this process's temporary folders at exit.
class TempCleanup : public ::testing::Environment {
 public:
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(fs::temp_directory_path() / ("msmcal_rig_test_" + std::to_string(::getpid())),
                   ec);
  }
};
const auto* const kTempCleanup = ::testing::AddGlobalTestEnvironment(new TempCleanup);

// A quarter-resolution camera: same field of view, fast to render.
SimOptions SmallOptions() {
  SimOptions o;
  o.camera.width = 612;
  o.camera.height = 512;
  o.camera.fx = o.camera.fy = 500.0;
  o.camera.cx = 305.75;
  o.camera.cy = 255.75;
  o.triggers.min_separation_px = 10.0;
  o.render.dot_sigma_mm = 2.0;
  o.hall.background_duration_s = 1.0;
  o.hall.actual_duration_s = 1.2;
  return o;
}

TEST(SimOptionsTest, DefaultsValidateAndYamlRoundTrips) {
  const SimOptions o;
  EXPECT_EQ(o.Validate(), "");
  EXPECT_NEAR(o.PatternPeriodS(), 0.2, 1e-12);  // 205 Hz and 5 Hz: gcd 5 Hz
  const std::string yaml = SimOptionsToYaml(o);
  const SimOptions back = ParseSimOptions(yaml, "mem.yaml");
  EXPECT_EQ(SimOptionsToYaml(back), yaml);
}

TEST(SimOptionsTest, OverridesAndErrorsNameTheField) {
  const SimOptions o = ParseSimOptions("seed: 7\nbeams:\n  spanning_angle_deg: 27\n", "x.yaml");
  EXPECT_EQ(o.seed, 7u);
  EXPECT_EQ(o.beams.spanning_angle_deg, 27.0);
  try {
    ParseSimOptions("mirror:\n  fast:\n    frequncy_hz: 3\n", "bad.yaml");
    FAIL() << "unknown key accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("bad.yaml:3"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("mirror.fast.frequncy_hz"), std::string::npos) << e.what();
  }
  // Fuzz finding (docs/fuzzing.md): a key that is not a name (a null key with an anchor, a list)
  // escaped as yaml-cpp's "bad conversion" without the file.
  for (const char* text : {"beams: {count: 2, &a : [1]}\n", "beams: {[1, 2]: 3}\n"}) {
    try {
      ParseSimOptions(text, "key.yaml");
      FAIL() << "key accepted: " << text;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("key.yaml:1"), std::string::npos) << e.what();
    }
  }
  // Fuzz finding 6 (docs/fuzzing.md): a frequency beyond a long long's mHz reached std::gcd
  // with an overflowed llround (undefined behaviour) before the range check.
  try {
    ParseSimOptions("mirror: {fast: {frequency_hz: 2" + std::string(80, '9') + "}}\n", "f.yaml");
    FAIL() << "huge frequency accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("mirror.fast.frequency_hz"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("(0, 30e6]"), std::string::npos) << e.what();
  }
  try {
    ParseSimOptions("world_board: {cols: 10}\n", "b.yaml");
    FAIL() << "even cols accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("world_board.cols = 10"), std::string::npos) << e.what();
  }
}

TEST(SimOptionsTest, ShippedConfigIsTheDefaults) {
  const SimOptions o = LoadSimOptions(fs::path(EnvOr("MSMCAL_SOURCE_DIR", MSMCAL_TEST_SOURCE_DIR)) /
                                      "config" / "sim.yaml");
  EXPECT_EQ(SimOptionsToYaml(o), SimOptionsToYaml(SimOptions{}));
}

TEST(MirrorMotionTest, ResonanceClosedFormAndModes) {
  AxisOptions a;
  a.frequency_hz = 100;
  a.resonance_hz = 100;
  a.q = 20;
  a.amplitude_vpp = 2;
  a.dc_gain_deg_per_v = 0.1;
  const AxisResponse r = ResonantResponse(a);
  EXPECT_NEAR(r.amplitude_deg, 0.1 * 1.0 * 20, 1e-12);  // |H(f0)| = Q
  EXPECT_NEAR(r.lag_rad, kPi / 2, 1e-12);
  a.frequency_hz = 1e-6;
  EXPECT_NEAR(ResonantResponse(a).amplitude_deg, 0.1, 1e-9);

  const MirrorMotion m(MirrorOptions{});
  for (double t : {0.0, 0.0123, 0.11}) {
    const auto off = m.PoseAt(t, DriveMode::kOff);
    EXPECT_EQ(off.alpha_rad, 0.0);
    EXPECT_EQ(off.beta_rad, 0.0);
    EXPECT_EQ(off.trans_mm, 0.0);
    EXPECT_EQ(m.PoseAt(t, DriveMode::kFastOnly).beta_rad, 0.0);
    EXPECT_EQ(m.PoseAt(t, DriveMode::kFastOnly).alpha_rad, m.PoseAt(t, DriveMode::kScan).alpha_rad);
  }
  // Paper-like ranges over one period: fast ~4.4 deg, slow ~17 deg, trans ~1 mm peak-to-peak.
  double amin = 1e9, amax = -1e9, bmin = 1e9, bmax = -1e9, tmin = 1e9, tmax = -1e9;
  for (int i = 0; i < 20000; ++i) {
    const auto p = m.PoseAt(i * 0.2 / 20000, DriveMode::kScan);
    amin = std::min(amin, p.alpha_rad / common::kRadPerDeg),
    amax = std::max(amax, p.alpha_rad / common::kRadPerDeg);
    bmin = std::min(bmin, p.beta_rad / common::kRadPerDeg),
    bmax = std::max(bmax, p.beta_rad / common::kRadPerDeg);
    tmin = std::min(tmin, p.trans_mm), tmax = std::max(tmax, p.trans_mm);
  }
  EXPECT_NEAR(amax - amin, 4.4, 0.5);
  EXPECT_NEAR(bmax - bmin, 17.0, 1.5);
  EXPECT_NEAR(tmax - tmin, 1.0, 0.25);
  // Periodic with T.
  const auto p0 = m.PoseAt(0.037, DriveMode::kScan), p1 = m.PoseAt(0.237, DriveMode::kScan);
  EXPECT_NEAR(p0.alpha_rad, p1.alpha_rad, 1e-9);
  EXPECT_NEAR(p0.beta_rad, p1.beta_rad, 1e-9);
}

class RigTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { sim_ = new RigSimulator(SimOptions{}); }
  static void TearDownTestSuite() {
    delete sim_;
    sim_ = nullptr;
  }
  static RigSimulator* sim_;
};
RigSimulator* RigTest::sim_ = nullptr;

TEST_F(RigTest, DefaultConfigIsSound) {
  for (const auto& w : sim_->warnings()) ADD_FAILURE() << w;
  EXPECT_GE(sim_->triggers().size(), 40u);
  // 7 poses, a background frame (no beam) at the 6 without identification frames, 3 of those;
  // each taken 3 times in a row (step1.exposures).
  EXPECT_EQ(sim_->step1_frames().size(), 3u * (7u + 6u + 3u));
  int background = 0;
  for (size_t i = 0; i < sim_->step1_frames().size(); ++i) {
    const auto& f = sim_->step1_frames()[i];
    const auto& first = sim_->step1_frames()[i - i % 3];
    EXPECT_EQ(f.pose, first.pose) << f.file;
    EXPECT_EQ(f.beams, first.beams) << f.file;
    if (!f.beams.empty()) continue;
    ++background;
    EXPECT_LT(f.pose, 6) << f.file;
  }
  EXPECT_EQ(background, 3 * 6);
  EXPECT_NEAR(sim_->SpanningAngleDeg(sim_->MirrorPlaneInWorld(0, DriveMode::kOff)), 46.0, 1e-6);
  // Every trigger appears in at least one scan frame; kinds present.
  std::map<int, int> seen;
  std::map<dataset::Step2Kind, int> kinds;
  for (const auto& f : sim_->step2_frames()) {
    ++kinds[f.kind];
    if (f.kind == dataset::Step2Kind::kScan)
      for (int j : f.triggers) ++seen[j];
  }
  EXPECT_EQ(seen.size(), sim_->triggers().size());
  EXPECT_EQ(kinds[dataset::Step2Kind::kNeutral], 2);
  EXPECT_EQ(kinds[dataset::Step2Kind::kFastOnly], 3);
  // Triggers ascending in [0, T).
  for (size_t j = 0; j < sim_->triggers().size(); ++j) {
    EXPECT_EQ(sim_->triggers()[j].j, static_cast<int>(j));
    EXPECT_GE(sim_->triggers()[j].t_s, 0.0);
    EXPECT_LT(sim_->triggers()[j].t_s, sim_->pattern_period_s());
    if (j) {
      EXPECT_GT(sim_->triggers()[j].t_s, sim_->triggers()[j - 1].t_s);
    }
  }
}

// At a small spanning angle the nearest sliding pose brings the dots of two beams within a few
// pixels (9 px apart merged into one blob and lost two frames): there the plan takes one frame
// per beam instead of the all-beams frame (and keeps its background frame: close dots reach
// into each other's fit windows), and no frame shows two dots closer than 20 px.
TEST(RigPlanTest, CloseStep1DotsAreTakenOneBeamAtATime) {
  SimOptions o;
  o.beams.spanning_angle_deg = 18.0;
  o.step1.exposures = 1;
  const RigSimulator sim(o);
  for (const auto& w : sim.warnings()) ADD_FAILURE() << w;
  std::map<int, std::vector<std::vector<int>>> frames_of_pose;
  double closest = 1e9;
  for (const auto& f : sim.step1_frames()) {
    frames_of_pose[f.pose].push_back(f.beams);
    const Scene scene = sim.FrameScene(f);
    for (size_t a = 0; a < scene.labels.size(); ++a)
      for (size_t b = a + 1; b < scene.labels.size(); ++b)
        closest = std::min(closest, (scene.labels[a].pixel - scene.labels[b].pixel).norm());
  }
  EXPECT_GE(closest, 20.0);
  int single_beam_poses = 0;
  for (const auto& [pose, beams] : frames_of_pose) {
    if (pose == o.step1.poses - 1) continue;  // identification frames
    if (beams == std::vector<std::vector<int>>{{1}, {2}, {3}, {}})
      ++single_beam_poses;
    else
      EXPECT_EQ(beams, (std::vector<std::vector<int>>{{1, 2, 3}, {}})) << "pose " << pose;
  }
  EXPECT_GE(single_beam_poses, 1);
  // With all beams at once, that pose's dots would be closer than 20 px.
  bool close = false;
  for (int l = 0; l < o.step1.poses; ++l) {
    const Scene scene = sim.Step1Scene(l, {1, 2, 3});
    for (size_t a = 0; a < scene.labels.size(); ++a)
      for (size_t b = a + 1; b < scene.labels.size(); ++b)
        close |= (scene.labels[a].pixel - scene.labels[b].pixel).norm() < 20.0;
  }
  EXPECT_TRUE(close);
}

TEST_F(RigTest, MirrorFrameTruthFollowsConventions) {
  const SimTruth t = MakeTruth(*sim_);
  // Neutral plane: normal n_M0 through X_O; pose round trips.
  const geometry::Plane neutral = sim_->MirrorPlaneInWorld(0, DriveMode::kOff);
  EXPECT_NEAR((neutral.n - t.neutral_normal).norm(), 0, 1e-12);
  EXPECT_NEAR(neutral.SignedDistance(t.rotation_centre), 0, 1e-9);
  EXPECT_GT(t.fast_axis.x(), 0.1);  // sign rule of the interchange format
  EXPECT_NEAR(t.fast_axis.dot(t.neutral_normal), 0, 1e-12);
  // Normals face the incoming beams (reflective side) and the board.
  for (const auto& b : sim_->beams_in_world()) EXPECT_LT(b.v.dot(neutral.n), 0);
  for (const auto& row : t.mirror_planes) {
    const auto pose = geometry::PoseFromWorldPlane(t.world_from_mirror0, row.plane_in_world);
    EXPECT_NEAR(pose.alpha_rad / common::kRadPerDeg, row.alpha_deg, 1e-9);
    EXPECT_NEAR(pose.beta_rad / common::kRadPerDeg, row.beta_deg, 1e-9);
    EXPECT_NEAR(pose.trans_mm, row.trans_mm, 1e-9);
  }
  // Fast-only planes contain the fast axis direction (their normals are orthogonal to e_F).
  for (const auto& trig : sim_->triggers()) {
    const auto p = sim_->MirrorPlaneInWorld(trig.t_s, DriveMode::kFastOnly);
    EXPECT_NEAR(p.n.dot(t.fast_axis), 0, 1e-12);
  }
  // Beams miss the rotation centre by about their configured offsets.
  for (size_t k = 0; k < sim_->beams_in_world().size(); ++k) {
    const auto& off = sim_->options().beams.offsets_mm[k];
    const double dist = sim_->beams_in_world()[k].Distance(t.rotation_centre);
    EXPECT_GT(dist, 0.3);
    EXPECT_LE(dist, std::hypot(off[0], off[1]) + 1e-9);
  }
}

// Independent reflection: mirror the world plane, hit it with the incident line, mirror back.
Eigen::Vector3d IndependentDot(const geometry::Line& beam, const geometry::Plane& mirror) {
  const geometry::Plane virtual_board =
      geometry::ReflectPlane(mirror, geometry::Plane{Eigen::Vector3d::UnitZ(), 0});
  const auto x_virtual = geometry::IntersectLinePlane(beam, virtual_board);
  EXPECT_TRUE(x_virtual.has_value());
  return geometry::ReflectPoint(mirror, *x_virtual);
}

TEST_F(RigTest, TruthDotsAreIndependentProjections) {
  const fs::path dir = TempDir("dots");
  WriteTruth(dir, MakeTruth(*sim_));
  const SimTruth t = ReadTruth(dir);
  const geometry::CameraModel& cam = sim_->camera();
  std::map<std::string, const dataset::Step2Frame*> step2;
  for (const auto& f : sim_->step2_frames()) step2[f.file] = &f;
  std::map<std::string, const dataset::Step1Frame*> step1;
  for (const auto& f : sim_->step1_frames()) step1[f.file] = &f;
  std::map<int, geometry::Plane> planes;
  for (const auto& p : t.mirror_planes) planes[p.j] = p.plane_in_world;
  int checked = 0;
  for (const auto& d : t.dots) {
    const geometry::Line beam =
        geometry::Line::FromPointDirection(t.beams.at(d.beam - 1).p, t.beams.at(d.beam - 1).v);
    Eigen::Vector3d p_cam;
    if (step1.count(d.file)) {
      const geometry::Rigid3d& c1_s = t.c1_from_sliding.at(step1[d.file]->pose);
      const geometry::Plane plate_in_world = geometry::TransformPlane(
          t.c1_from_world.Inverse() * c1_s, geometry::Plane{Eigen::Vector3d::UnitZ(), 0});
      p_cam = t.c1_from_world * *geometry::IntersectLinePlane(beam, plate_in_world);
    } else {
      const auto* f = step2.at(d.file);
      geometry::Plane mirror;
      if (f->kind == dataset::Step2Kind::kNeutral) {
        ASSERT_EQ(d.j, -1);
        mirror = geometry::TransformPlane(t.world_from_mirror0,
                                          geometry::Plane{Eigen::Vector3d::UnitZ(), 0});
      } else if (f->kind == dataset::Step2Kind::kScan) {
        mirror = planes.at(d.j);
      } else {
        // Fast-only: alpha from the trajectory model at t_j, beta = 0.
        const auto pose = sim_->motion().PoseAt(sim_->triggers().at(d.j).t_s, DriveMode::kFastOnly);
        EXPECT_EQ(pose.beta_rad, 0.0);
        mirror = geometry::WorldPlaneFromPose(t.world_from_mirror0, pose);
      }
      const Eigen::Vector3d x = IndependentDot(beam, mirror);
      EXPECT_NEAR(x.z(), 0, 1e-9);
      // On the board's inner area.
      EXPECT_GT(x.x(), 0);
      EXPECT_LT(x.x(),
                (sim_->options().world_board.cols - 1) * sim_->options().world_board.square_mm);
      EXPECT_GT(x.y(), 0);
      EXPECT_LT(x.y(),
                (sim_->options().world_board.rows - 1) * sim_->options().world_board.square_mm);
      p_cam = t.c2_from_world * x;
    }
    const auto px = cam.Project(p_cam);
    ASSERT_TRUE(px.has_value());
    EXPECT_NEAR(px->x(), d.u_px, 1e-6) << d.file << " beam " << d.beam << " j " << d.j;
    EXPECT_NEAR(px->y(), d.v_px, 1e-6) << d.file << " beam " << d.beam << " j " << d.j;
    EXPECT_GE(px->x(), 0);
    EXPECT_GE(px->y(), 0);
    EXPECT_LT(px->x(), cam.width);
    EXPECT_LT(px->y(), cam.height);
    ++checked;
  }
  // Every frame's dots: step 1 all-beam frames 3 dots, identification 1, step 2: beams x triggers.
  size_t expected = 0;
  for (const auto& f : sim_->step1_frames()) expected += f.beams.size();
  for (const auto& f : sim_->step2_frames())
    expected += f.beams.size() * (f.kind == dataset::Step2Kind::kNeutral ? 1 : f.triggers.size());
  EXPECT_EQ(static_cast<size_t>(checked), expected);
}

TEST_F(RigTest, TruthRoundTripsThroughFiles) {
  const fs::path dir = TempDir("truth_rt");
  const SimTruth a = MakeTruth(*sim_);
  WriteTruth(dir, a);
  const SimTruth b = ReadTruth(dir);
  EXPECT_EQ(a.seed, b.seed);
  ASSERT_EQ(a.mirror_planes.size(), b.mirror_planes.size());
  for (size_t i = 0; i < a.mirror_planes.size(); ++i) {
    EXPECT_EQ(a.mirror_planes[i].plane_in_world.n, b.mirror_planes[i].plane_in_world.n);
    EXPECT_EQ(a.mirror_planes[i].trans_mm, b.mirror_planes[i].trans_mm);
  }
  EXPECT_EQ(a.rotation_centre, b.rotation_centre);
  EXPECT_EQ(a.c2_from_world.translation, b.c2_from_world.translation);
  EXPECT_EQ(a.pose_trajectory.size(), b.pose_trajectory.size());
  EXPECT_EQ(a.hall.mcu_offset_us, b.hall.mcu_offset_us);
  EXPECT_EQ(a.dots.size(), b.dots.size());
  EXPECT_EQ(a.pose_trajectory.size(), 2000u);  // 0.2 s at 10 kHz
}

// Independent dipole: B = mu0/(4 pi) (3 r^(r^.m) - m) / r^3 in SI units, mirror plate rotated by
// Rx(alpha) then Ry(beta), translated by trans along its normal.
Eigen::Vector3d IndependentHall(const SimOptions& o, const geometry::MirrorPose& pose, bool magnet,
                                double t, bool background) {
  const auto& h = o.hall;
  const double ca = std::cos(pose.alpha_rad), sa = std::sin(pose.alpha_rad);
  const double cb = std::cos(pose.beta_rad), sb = std::sin(pose.beta_rad);
  Eigen::Matrix3d rx, ry;
  rx << 1, 0, 0, 0, ca, -sa, 0, sa, ca;
  ry << cb, 0, sb, 0, 1, 0, -sb, 0, cb;
  const Eigen::Matrix3d r = ry * rx;
  const Eigen::Vector3d normal = geometry::PlaneFromPose(pose).n;
  EXPECT_NEAR((normal - r.col(2)).norm(), 0, 1e-12);
  const Eigen::Vector3d pm =
      Eigen::Vector3d(h.magnet_position_mm[0], h.magnet_position_mm[1], h.magnet_position_mm[2]);
  const Eigen::Vector3d mpos_m = (r * pm + pose.trans_mm * normal) * 1e-3;
  const Eigen::Vector3d dir =
      Eigen::Vector3d(h.magnet_direction[0], h.magnet_direction[1], h.magnet_direction[2])
          .normalized();
  const Eigen::Vector3d m = h.magnet_moment_am2 * (r * dir);
  const Eigen::Vector3d s_m =
      Eigen::Vector3d(h.sensor_position_mm[0], h.sensor_position_mm[1], h.sensor_position_mm[2]) *
      1e-3;
  const Eigen::Vector3d rv = s_m - mpos_m;
  const double rn = rv.norm();
  const Eigen::Vector3d rh = rv / rn;
  const double mu0_4pi = 4e-7 * kPi / (4 * kPi);
  Eigen::Vector3d b_tesla = mu0_4pi * (3 * rh * rh.dot(m) - m) / std::pow(rn, 3);
  const Eigen::Vector3d rot_vec =
      Eigen::Vector3d(h.sensor_rotation_deg[0], h.sensor_rotation_deg[1],
                      h.sensor_rotation_deg[2]) *
      common::kRadPerDeg;
  const Eigen::Matrix3d sensor_from_0 =
      Eigen::AngleAxisd(rot_vec.norm(), rot_vec.normalized()).toRotationMatrix();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  if (magnet) b = sensor_from_0 * b_tesla * 1e6;
  auto coil = [&](const AxisOptions& a, const std::array<double, 3>& c) -> Eigen::Vector3d {
    const double phi = 2 * kPi * a.frequency_hz * t + a.phase_deg * common::kRadPerDeg;
    const double s = std::sin(phi) + h.coil_harmonic2_ratio * std::sin(2 * phi);
    const Eigen::Vector3d amplitude(c[0], c[1], c[2]);
    return amplitude * s;
  };
  b += coil(o.mirror.fast, h.coil_fast_uT) + coil(o.mirror.slow, h.coil_slow_uT);
  b += Eigen::Vector3d(h.earth_uT[0], h.earth_uT[1], h.earth_uT[2]);
  if (background)
    b += Eigen::Vector3d(h.background_shift_uT[0], h.background_shift_uT[1],
                         h.background_shift_uT[2]);
  return b;
}

TEST(HallModelTest, FieldMatchesIndependentDipole) {
  const SimOptions o;
  const HallModel model(o);
  double span = 0;
  for (double t : {0.0, 0.0131, 0.05, 0.0977, 0.1503}) {
    const auto pose = model.motion().PoseAt(t, DriveMode::kScan);
    const Eigen::Vector3d expect = IndependentHall(o, pose, true, t, false);
    const Eigen::Vector3d got = model.FieldUT(t, HallRecordingKind::kActual);
    EXPECT_NEAR((got - expect).norm(), 0, 1e-9 * expect.norm()) << "t=" << t;
    const Eigen::Vector3d bg = IndependentHall(o, pose, false, t, true);
    EXPECT_NEAR((model.FieldUT(t, HallRecordingKind::kBackground) - bg).norm(), 0, 1e-9);
    span = std::max(span, (got - bg).norm());
  }
  EXPECT_GT(span, 50.0);  // the magnet dominates the foreground
}

TEST(HallModelTest, SamplerTimingDelayAndNoise) {
  SimOptions o;
  o.hall.actual_duration_s = 2.0;
  const HallModel model(o);
  HallSampler sampler(model, HallRecordingKind::kActual, 42);
  const dataset::HallRecording rec = sampler.Collect();
  ASSERT_EQ(rec.readings.size(), 2000u);
  for (size_t i = 1; i < rec.readings.size(); ++i) {
    EXPECT_EQ(rec.readings[i].mcu_time_us - rec.readings[i - 1].mcu_time_us, 1000);
  }
  // Edges: pattern phase 0 in generator time, mapped through offset and rate.
  ASSERT_GE(rec.clock_edges_us.size(), 9u);
  for (int64_t e : rec.clock_edges_us) {
    const double t = model.GeneratorTimeS(e);
    const double phase = t / model.pattern_period_s() - std::round(t / model.pattern_period_s());
    EXPECT_NEAR(phase * model.pattern_period_s(), 0, 1.1e-6);
    EXPECT_GE(e, rec.readings.front().mcu_time_us);
    EXPECT_LE(e, rec.readings.back().mcu_time_us + 1000);
  }
  const double rate = 1 + o.hall.mcu_rate_error_ppm * 1e-6;
  EXPECT_NEAR(static_cast<double>(rec.clock_edges_us[1] - rec.clock_edges_us[0]), 0.2 * rate * 1e6,
              1.0);
  // Residuals against the model at the true delay: zero mean, sigma = noise (quantisation adds
  // 0.01/sqrt(12)); the wrong delay (0) gives much larger residuals.
  auto rms = [&](double delay) {
    double sum = 0;
    for (const auto& r : rec.readings) {
      const Eigen::Vector3d b =
          model.FieldUT(model.GeneratorTimeS(r.mcu_time_us) - delay, HallRecordingKind::kActual);
      sum += (Eigen::Vector3d(r.bx_uT, r.by_uT, r.bz_uT) - b).squaredNorm();
    }
    return std::sqrt(sum / (3.0 * rec.readings.size()));
  };
  EXPECT_NEAR(rms(o.hall.delta_t_s), o.hall.noise_uT, 0.1);
  EXPECT_GT(rms(0.0), 3 * o.hall.noise_uT);
  // Deterministic per seed, different across seeds.
  const dataset::HallRecording again = HallSampler(model, HallRecordingKind::kActual, 42).Collect();
  EXPECT_EQ(again.readings.back().bx_uT, rec.readings.back().bx_uT);
  EXPECT_EQ(again.clock_edges_us, rec.clock_edges_us);
  const dataset::HallRecording other = HallSampler(model, HallRecordingKind::kActual, 43).Collect();
  EXPECT_NE(other.readings.front().mcu_time_us, rec.readings.front().mcu_time_us);
}

TEST(RigDeterminismTest, SameSeedSameBytesOtherSeedDiffers) {
  SimOptions o = SmallOptions();
  o.seed = 5;
  const fs::path a = TempDir("det_a"), b = TempDir("det_b"), c = TempDir("det_c");
  {
    const RigSimulator sim(o);
    WriteTruth(a, MakeTruth(sim));
  }
  {
    const RigSimulator sim(o);
    WriteTruth(b, MakeTruth(sim));
  }
  for (const char* f : {"sim_config.yaml", "beams.csv", "mirror_planes.csv", "mirror_frame.yaml",
                        "views.yaml", "dots.csv", "hall.yaml", "pose_trajectory.csv"}) {
    EXPECT_EQ(Slurp(a / "truth" / f), Slurp(b / "truth" / f)) << f;
    EXPECT_FALSE(Slurp(a / "truth" / f).empty()) << f;
  }
  o.seed = 6;
  const RigSimulator sim6(o);
  WriteTruth(c, MakeTruth(sim6));
  EXPECT_NE(Slurp(a / "truth" / "hall.yaml"), Slurp(c / "truth" / "hall.yaml"));

  // Images: identical for the same seed, different noise for another seed, dots where truth says.
  o.seed = 5;
  const RigSimulator s1(o), s2(o);
  const cv::Mat img1 = s1.RenderStep2Frame(s1.step2_frames().size() - 1);
  const cv::Mat img2 = s2.RenderStep2Frame(s2.step2_frames().size() - 1);
  ASSERT_EQ(img1.size(), cv::Size(612, 512));
  EXPECT_EQ(cv::norm(img1, img2, cv::NORM_INF), 0.0);
  const cv::Mat img6 = sim6.RenderStep2Frame(sim6.step2_frames().size() - 1);
  EXPECT_GT(cv::norm(img1, img6, cv::NORM_INF), 0.0);
  const Scene scene = s1.FrameScene(s1.step2_frames().back());
  ASSERT_FALSE(scene.labels.empty());
  for (const auto& l : scene.labels) {
    const int u = static_cast<int>(std::lround(l.pixel.x())),
              v = static_cast<int>(std::lround(l.pixel.y()));
    EXPECT_GT(img1.at<uint8_t>(v, u), 150) << "no bright dot at beam " << l.beam << " j " << l.j;
  }
  const cv::Mat step1 = s1.RenderStep1Frame(0);
  EXPECT_EQ(step1.type(), CV_8UC1);
}

}  // namespace
}  // namespace msmcal::sim
