#include "mocks/rig/rig_simulator.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <numeric>
#include <stdexcept>

#include "common/units.h"
#include "processing/plan/frame_design.h"

namespace msmcal::sim {
namespace {

// Step 1 dots closer than this in one image are taken one beam at a time: their blobs merge
// (9 px apart did, at an 18 deg spanning angle) or reach into each other's fit windows.
constexpr double kMinStep1SeparationPx = 20.0;

Eigen::Vector3d Vec(const std::array<double, 3>& a) { return {a[0], a[1], a[2]}; }

// cam_from_world for a camera at `centre` looking at `target`, image y (down) in the plane of
// Y_W and the viewing direction.
geometry::Rigid3d LookAt(const Eigen::Vector3d& centre, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - centre).normalized();
  Eigen::Vector3d x = Eigen::Vector3d::UnitY().cross(z);
  if (x.norm() < 1e-6) throw std::runtime_error("camera looks along Y_W: choose another target");
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d world_from_cam;
  world_from_cam.col(0) = x;
  world_from_cam.col(1) = y;
  world_from_cam.col(2) = z;
  return geometry::Rigid3d(world_from_cam, centre).Inverse();
}

std::string Fmt(const char* format, double a, double b = 0, double c = 0) {
  char buf[256];
  std::snprintf(buf, sizeof(buf), format, a, b, c);
  return buf;
}

bool OnBoard(const BoardOptions& b, const Eigen::Vector3d& p_in_board, double margin_mm) {
  return p_in_board.x() >= margin_mm && p_in_board.x() <= (b.cols - 1) * b.square_mm - margin_mm &&
         p_in_board.y() >= margin_mm && p_in_board.y() <= (b.rows - 1) * b.square_mm - margin_mm &&
         std::abs(p_in_board.z()) < 1e-6;
}

render::BoardSpec ToRenderBoard(const BoardOptions& b) {
  render::BoardSpec spec;
  spec.cols = b.cols;
  spec.rows = b.rows;
  spec.square_mm = b.square_mm;
  return spec;
}

uint64_t Mix(uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

}  // namespace

RigSimulator::RigSimulator(const SimOptions& options)
    : options_(options),
      motion_(options.mirror),
      hall_(options),
      period_s_(options.PatternPeriodS()) {
  Build(nullptr);
}

RigSimulator::RigSimulator(const SimOptions& options, const std::vector<double>& trigger_times_s)
    : options_(options),
      motion_(options.mirror),
      hall_(options),
      period_s_(options.PatternPeriodS()) {
  if (trigger_times_s.empty())
    throw std::invalid_argument("RigSimulator: the given trigger table is empty");
  Build(&trigger_times_s);
}

void RigSimulator::Build(const std::vector<double>* trigger_times_s) {
  const SimOptions& options = options_;
  if (const std::string err = options.Validate(); !err.empty()) throw std::invalid_argument(err);
  const auto& c = options.camera;
  camera_.width = c.width;
  camera_.height = c.height;
  camera_.fx = c.fx;
  camera_.fy = c.fy;
  camera_.cx = c.cx;
  camera_.cy = c.cy;
  camera_.distortion = c.distortion;
  if (const std::string err = camera_.Validate(); !err.empty()) {
    throw std::invalid_argument("camera: " + err);
  }
  BuildGeometry();
  BuildFrames(trigger_times_s);
}

void RigSimulator::BuildGeometry() {
  const auto& g = options_.geometry;
  const double theta = g.incidence_deg * common::kRadPerDeg;
  // Nominal: reflected central beam +Z_W; incident central direction in the X_W-Z_W plane.
  const Eigen::Vector3d r_c = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d v_c(std::sin(2 * theta), 0.0, -std::cos(2 * theta));
  const Eigen::Vector3d n_nominal = (r_c - v_c).normalized();
  const Eigen::Matrix3d tilt = geometry::So3Exp(Vec(g.mount_tilt_deg) * common::kRadPerDeg);
  const Eigen::Vector3d n0 = tilt * n_nominal;
  const Eigen::Vector3d fast = tilt * Eigen::Vector3d::UnitY().cross(n_nominal).normalized();
  const Eigen::Vector3d x_o(g.board_aim_mm[0], g.board_aim_mm[1], -g.mirror_distance_mm);
  world_from_mirror0_ = geometry::MirrorHomeFrame(n0, fast, x_o);
  const geometry::Plane neutral = MirrorPlaneInWorld(0.0, DriveMode::kOff);

  // Beam fan: rotation about the axis normal to the plane spanned by v_c and Y_W.
  const Eigen::Vector3d fan_axis = v_c.cross(Eigen::Vector3d::UnitY()).normalized();
  const Eigen::Matrix3d r_w0 = world_from_mirror0_.RotationMatrix();
  const auto& b = options_.beams;
  auto build_beams = [&](double fan_rad) {
    beams_.clear();
    sources_.clear();
    for (int k = 0; k < b.count; ++k) {
      const Eigen::Vector3d v =
          Eigen::AngleAxisd(b.fan_fractions[k] * fan_rad, fan_axis).toRotationMatrix() * v_c;
      const Eigen::Vector3d hit =
          x_o + b.offsets_mm[k][0] * r_w0.col(0) + b.offsets_mm[k][1] * r_w0.col(1);
      const Eigen::Vector3d source = hit - b.source_distance_mm * v;
      sources_.push_back(source);
      beams_.push_back(geometry::Line::FromPointDirection(source, v));
    }
  };
  // Bisection on the fan angle for the requested spanning angle (monotone over (0, 150) deg for
  // these geometries; checked).
  double lo = 1e-4, hi = 150.0 * common::kRadPerDeg;
  build_beams(hi);
  if (SpanningAngleDeg(neutral) < b.spanning_angle_deg) {
    throw std::runtime_error(Fmt("beams.spanning_angle_deg = %g cannot be reached (max %g deg)",
                                 b.spanning_angle_deg, SpanningAngleDeg(neutral)));
  }
  for (int it = 0; it < 80; ++it) {
    const double mid = 0.5 * (lo + hi);
    build_beams(mid);
    (SpanningAngleDeg(neutral) < b.spanning_angle_deg ? lo : hi) = mid;
  }
  build_beams(0.5 * (lo + hi));
  fan_angle_deg_ = 0.5 * (lo + hi) * common::kDegPerRad;

  // Cameras.
  const auto& c = options_.camera;
  c1_from_world_ = LookAt(Vec(c.c1_centre_mm), Vec(c.c1_target_mm));
  c2_from_world_ = LookAt(Vec(c.c2_centre_mm), Vec(c.c2_target_mm));

  // Sliding board poses: centred on the central incident line, facing the source.
  central_incident_ = v_c;
  world_from_sliding_.clear();
  for (int l = 0; l < options_.step1.poses; ++l) world_from_sliding_.push_back(SlidingPose(l));
}

geometry::Rigid3d RigSimulator::SlidingPose(int l, std::optional<double> distance_mm,
                                            std::optional<double> tilt_deg) const {
  const auto& s1 = options_.step1;
  const auto& sb = options_.sliding_board;
  const auto& g = options_.geometry;
  const Eigen::Vector3d x_o(g.board_aim_mm[0], g.board_aim_mm[1], -g.mirror_distance_mm);
  const Eigen::Vector3d& v_c = central_incident_;
  const double s = distance_mm.value_or(
      s1.poses > 1 ? s1.nearest_mm + l * (s1.farthest_mm - s1.nearest_mm) / (s1.poses - 1)
                   : s1.nearest_mm);
  const Eigen::Vector3d centre = x_o - s * v_c;
  const Eigen::Vector3d z = v_c;
  const Eigen::Vector3d x =
      (Eigen::Vector3d::UnitY() - Eigen::Vector3d::UnitY().dot(z) * z).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d r;
  r.col(0) = x;
  r.col(1) = y;
  r.col(2) = z;
  // The design alternates the tilt's sign per pose; a given tilt is the signed one.
  const double sign = (l % 2 == 0) ? 1.0 : -1.0;
  const double signed_tilt_rad = (tilt_deg ? *tilt_deg : sign * s1.tilt_deg) * common::kRadPerDeg;
  const double tilt_rad = std::abs(signed_tilt_rad);
  const int m = ((l % 3) + 3) % 3;
  r = Eigen::AngleAxisd(signed_tilt_rad, y).toRotationMatrix() *
      Eigen::AngleAxisd(0.5 * tilt_rad * (m - 1), x).toRotationMatrix() * r;
  const Eigen::Vector3d origin =
      centre - r * Eigen::Vector3d(0.5 * (sb.cols - 1) * sb.square_mm,
                                   0.5 * (sb.rows - 1) * sb.square_mm, 0);
  return geometry::Rigid3d(r, origin);
}

geometry::Rigid3d RigSimulator::c1_from_sliding(int pose) const {
  return c1_from_world_ * world_from_sliding_.at(pose);
}

double RigSimulator::SpanningAngleDeg(const geometry::Plane& mirror) const {
  const auto& f = options_.beams.fan_fractions;
  const int lo = static_cast<int>(std::min_element(f.begin(), f.end()) - f.begin());
  const int hi = static_cast<int>(std::max_element(f.begin(), f.end()) - f.begin());
  auto normal = [&](int k) {
    const Eigen::Vector3d r = geometry::ReflectDirection(mirror, beams_[k].v);
    return beams_[k].v.cross(r).normalized();
  };
  return geometry::AngleBetween(normal(lo), normal(hi)) * common::kDegPerRad;
}

geometry::Plane RigSimulator::MirrorPlaneInWorld(double t_s, DriveMode mode) const {
  return geometry::WorldPlaneFromPose(world_from_mirror0_, motion_.PoseAt(t_s, mode));
}

std::optional<Eigen::Vector3d> RigSimulator::ReflectedDotInWorld(
    int beam_id, const geometry::Plane& mirror) const {
  const geometry::Line& beam = beams_.at(beam_id - 1);
  const auto hit = geometry::IntersectRayPlane(sources_.at(beam_id - 1), beam.v, mirror);
  if (!hit) return std::nullopt;
  const Eigen::Vector3d r = geometry::ReflectDirection(mirror, beam.v);
  return geometry::IntersectRayPlane(*hit, r, WorldBoardPlane());
}

std::optional<Eigen::Vector3d> RigSimulator::SlidingDotInWorld(int beam_id, int pose) const {
  const geometry::Rigid3d& w_s = world_from_sliding_.at(pose);
  const geometry::Plane plate =
      geometry::Plane::FromPointNormal(w_s.translation, w_s.RotationMatrix().col(2));
  return geometry::IntersectRayPlane(sources_.at(beam_id - 1), beams_.at(beam_id - 1).v, plate);
}

bool RigSimulator::InImage(const Eigen::Vector2d& px, double margin_px) const {
  return px.x() >= margin_px && px.y() >= margin_px && px.x() <= camera_.width - 1 - margin_px &&
         px.y() <= camera_.height - 1 - margin_px;
}

bool RigSimulator::OnWorldBoardInC2(const Eigen::Vector3d& p, double margin_mm,
                                    double margin_px) const {
  if (!OnBoard(options_.world_board, p, margin_mm)) return false;
  const auto px = camera_.Project(c2_from_world_ * p);
  return px && InImage(*px, margin_px);
}

Scene RigSimulator::Step1Scene(int pose, const std::vector<int>& beam_ids) const {
  Scene scene;
  scene.camera = camera_;
  const geometry::Rigid3d c1_from_sliding = this->c1_from_sliding(pose);
  scene.boards.push_back({ToRenderBoard(options_.world_board), c1_from_world_});
  scene.boards.push_back({ToRenderBoard(options_.sliding_board), c1_from_sliding});
  const Eigen::Vector3d normal_in_cam = c1_from_sliding.RotationMatrix().col(2);
  for (int id : beam_ids) {
    const auto p = SlidingDotInWorld(id, pose);
    if (!p) continue;
    const Eigen::Vector3d p_cam = c1_from_world_ * *p;
    const auto px = camera_.Project(p_cam);
    if (!px) continue;
    render::SceneDot dot;
    dot.p_in_cam = p_cam;
    dot.sigma_mm = options_.render.dot_sigma_mm;
    dot.normal_in_cam = normal_in_cam;
    scene.dots.push_back(dot);
    scene.labels.push_back({id, -1, *p, *px});
  }
  return scene;
}

Scene RigSimulator::Step2Scene(DriveMode mode, const std::vector<int>& trigger_indices,
                               const std::vector<int>& beam_ids) const {
  Scene scene;
  scene.camera = camera_;
  scene.boards.push_back({ToRenderBoard(options_.world_board), c2_from_world_});
  const Eigen::Vector3d normal_in_cam = c2_from_world_.RotationMatrix().col(2);
  auto add = [&](const geometry::Plane& mirror, int j) {
    for (int id : beam_ids) {
      const auto p = ReflectedDotInWorld(id, mirror);
      if (!p) continue;
      const Eigen::Vector3d p_cam = c2_from_world_ * *p;
      const auto px = camera_.Project(p_cam);
      if (!px) continue;
      render::SceneDot dot;
      dot.p_in_cam = p_cam;
      dot.sigma_mm = options_.render.dot_sigma_mm;
      dot.normal_in_cam = normal_in_cam;
      scene.dots.push_back(dot);
      scene.labels.push_back({id, j, *p, *px});
    }
  };
  if (mode == DriveMode::kOff) {
    add(MirrorPlaneInWorld(0.0, DriveMode::kOff), -1);
  } else {
    for (int j : trigger_indices) add(MirrorPlaneInWorld(triggers_.at(j).t_s, mode), j);
  }
  return scene;
}

Scene RigSimulator::FrameScene(const dataset::Step1Frame& frame) const {
  return Step1Scene(frame.pose, frame.beams);
}

Scene RigSimulator::FrameScene(const dataset::Step2Frame& frame) const {
  const DriveMode mode = frame.kind == dataset::Step2Kind::kNeutral    ? DriveMode::kOff
                         : frame.kind == dataset::Step2Kind::kFastOnly ? DriveMode::kFastOnly
                                                                       : DriveMode::kScan;
  return Step2Scene(mode, frame.triggers, frame.beams);
}

Scene RigSimulator::StateScene(const RigState& state,
                               const std::vector<PulseAtPose>& pulses) const {
  Scene scene;
  scene.camera = camera_;
  const geometry::Rigid3d& cam_from_world = state.camera == 1 ? c1_from_world_ : c2_from_world_;
  scene.boards.push_back({ToRenderBoard(options_.world_board), cam_from_world});
  std::optional<geometry::Plane> plate;
  if (state.world_from_sliding) {
    const geometry::Rigid3d& w_s = *state.world_from_sliding;
    scene.boards.push_back({ToRenderBoard(options_.sliding_board), cam_from_world * w_s});
    plate = geometry::Plane::FromPointNormal(w_s.translation, w_s.RotationMatrix().col(2));
  }
  const geometry::Plane board = WorldBoardPlane();
  // Nearest surface a ray meets: (point, normal, is_mirror).
  struct Hit {
    Eigen::Vector3d p;
    Eigen::Vector3d n;
    bool mirror = false;
  };
  auto nearest = [](const Eigen::Vector3d& o, const Eigen::Vector3d& v,
                    const std::vector<std::pair<geometry::Plane, bool>>& surfaces) {
    std::optional<Hit> best;
    double best_s = 1e300;
    for (const auto& [plane, is_mirror] : surfaces) {
      const auto p = geometry::IntersectRayPlane(o, v, plane);
      if (!p) continue;
      const double s = (*p - o).dot(v);
      if (s > 1e-9 && s < best_s) {
        best_s = s;
        best = Hit{*p, plane.n, is_mirror};
      }
    }
    return best;
  };
  auto add_dot = [&](int beam, int j, const Hit& hit) {
    const Eigen::Vector3d p_cam = cam_from_world * hit.p;
    const auto px = camera_.Project(p_cam);
    if (!px) return;
    for (const auto& l : scene.labels)
      if (l.beam == beam && (l.p_in_world - hit.p).norm() < 1e-6) return;  // same spot again
    render::SceneDot dot;
    dot.p_in_cam = p_cam;
    dot.sigma_mm = options_.render.dot_sigma_mm;
    dot.normal_in_cam = cam_from_world.RotationMatrix() * hit.n;
    scene.dots.push_back(dot);
    scene.labels.push_back({beam, j, hit.p, *px});
  };
  for (const PulseAtPose& pulse : pulses) {
    std::vector<std::pair<geometry::Plane, bool>> first;
    if (plate) first.emplace_back(*plate, false);
    geometry::Plane mirror;
    if (state.msm_mounted) {
      mirror = geometry::WorldPlaneFromPose(world_from_mirror0_, pulse.pose);
      first.emplace_back(mirror, true);
    }
    first.emplace_back(board, false);
    for (int id : state.unblocked_beams) {
      if (id < 1 || id > static_cast<int>(beams_.size())) continue;
      const Eigen::Vector3d& src = sources_[id - 1];
      const Eigen::Vector3d& v = beams_[id - 1].v;
      const auto hit = nearest(src, v, first);
      if (!hit) continue;
      if (!hit->mirror) {
        add_dot(id, -1, *hit);
        continue;
      }
      std::vector<std::pair<geometry::Plane, bool>> after;
      if (plate) after.emplace_back(*plate, false);
      after.emplace_back(board, false);
      const auto landed = nearest(hit->p, geometry::ReflectDirection(mirror, v), after);
      if (landed) add_dot(id, pulse.j, *landed);
    }
  }
  return scene;
}

std::vector<double> SimpleTriggerTimes(const RigSimulator& sim) {
  const auto& opt = sim.options().triggers;
  const int n = opt.candidates;
  const double period = sim.pattern_period_s();
  // Scrambled visiting order: stride coprime with n near the golden ratio.
  int stride = std::max(1, static_cast<int>(std::lround(n * 0.6180339887)));
  while (std::gcd(stride, n) != 1) ++stride;
  const int beams = sim.options().beams.count;
  std::vector<Eigen::Vector2d> accepted_px;
  std::vector<double> times;
  for (int i = 0; i < n && static_cast<int>(times.size()) < opt.max_triggers; ++i) {
    const int k = static_cast<int>((static_cast<int64_t>(i) * stride) % n);
    // Whole nanoseconds (the generator's waveform resolution is far coarser anyway).
    const double t = std::round((k + 0.5) * period / n * 1e9) / 1e9;
    const geometry::Plane mirror = sim.MirrorPlaneInWorld(t, DriveMode::kScan);
    std::vector<Eigen::Vector2d> px;
    bool ok = true;
    for (int id = 1; id <= beams && ok; ++id) {
      const auto p = sim.ReflectedDotInWorld(id, mirror);
      if (!p || !sim.OnWorldBoardInC2(*p, opt.board_margin_mm, 20.0)) {
        ok = false;
        break;
      }
      px.push_back(*sim.camera().Project(sim.c2_from_world() * *p));
    }
    for (size_t a = 0; a < px.size() && ok; ++a) {
      for (size_t b = a + 1; b < px.size() && ok; ++b)
        ok = (px[a] - px[b]).norm() >= opt.min_separation_px;
      for (const auto& q : accepted_px) {
        if ((px[a] - q).norm() < opt.min_separation_px) {
          ok = false;
          break;
        }
      }
    }
    if (!ok) continue;
    times.push_back(t);
    accepted_px.insert(accepted_px.end(), px.begin(), px.end());
  }
  std::sort(times.begin(), times.end());
  return times;
}

void RigSimulator::BuildFrames(const std::vector<double>* trigger_times_s) {
  const auto& s1 = options_.step1;
  const auto& s2 = options_.step2;
  const int beams = options_.beams.count;
  std::vector<int> all_beams(beams);
  std::iota(all_beams.begin(), all_beams.end(), 1);
  const double margin_mm = options_.triggers.board_margin_mm;

  // Board visibility: every inner corner of each board in its camera's image.
  auto check_board = [&](const std::string& what, const BoardOptions& b,
                         const geometry::Rigid3d& cam_from_board) {
    for (int r = 0; r < b.rows; r += b.rows - 1) {
      for (int c = 0; c < b.cols; c += b.cols - 1) {
        const auto px =
            camera_.Project(cam_from_board * Eigen::Vector3d(c * b.square_mm, r * b.square_mm, 0));
        if (!px || !InImage(*px, 5.0)) {
          warnings_.push_back(what + ": corner (" + std::to_string(c) + ", " + std::to_string(r) +
                              ") is outside the image");
          return;
        }
      }
    }
  };
  check_board("world board in C1", options_.world_board, c1_from_world_);
  check_board("world board in C2", options_.world_board, c2_from_world_);

  // Step 1: per pose a frame with all beams and a background frame with none; where two of the
  // pose's dots would lie closer than kMinStep1SeparationPx, one frame per beam instead of the
  // all-beams frame. Identification frames (one per beam) at the last pose.
  // (processing/plan: the frame list; here the geometry says which poses are close.)
  std::vector<bool> close_pose;
  for (int l = 0; l < s1.poses; ++l) {
    check_board("sliding board pose " + std::to_string(l) + " in C1", options_.sliding_board,
                c1_from_sliding(l));
    for (int id : all_beams) {
      const auto p = SlidingDotInWorld(id, l);
      const Eigen::Vector3d p_board =
          world_from_sliding_[l].Inverse() * p.value_or(Eigen::Vector3d::Zero());
      if (!p || !OnBoard(options_.sliding_board, p_board, 1.0)) {
        warnings_.push_back("step1 pose " + std::to_string(l) + ": beam " + std::to_string(id) +
                            " misses the sliding board's inner area");
      }
    }
    const Scene scene = Step1Scene(l, all_beams);
    bool close = false;
    for (size_t a = 0; a < scene.labels.size(); ++a)
      for (size_t b = a + 1; b < scene.labels.size(); ++b)
        close |= (scene.labels[a].pixel - scene.labels[b].pixel).norm() < kMinStep1SeparationPx;
    close_pose.push_back(close);
  }
  plan::Step1FrameOptions fo;
  fo.poses = s1.poses;
  fo.beams = beams;
  fo.identification_frames = s1.identification_frames;
  fo.background_frames = s1.background_frames;
  fo.exposures = std::max(1, s1.exposures);
  fo.close_pose = close_pose;
  step1_ = plan::DesignStep1Frames(fo);
  auto file = [](const char* step, size_t i) { return plan::FrameFile(step, i); };

  // Triggers.
  const std::vector<double> times = trigger_times_s ? *trigger_times_s : SimpleTriggerTimes(*this);
  for (size_t j = 0; j < times.size(); ++j) triggers_.push_back({static_cast<int>(j), times[j]});
  if (!trigger_times_s && triggers_.size() < 3) {
    throw std::runtime_error("only " + std::to_string(triggers_.size()) +
                             " trigger times keep all dots on the board and apart; check geometry, "
                             "triggers.min_separation_px and the drive amplitudes");
  }

  // Step 2: neutral frames.
  for (int i = 0; i < s2.neutral_frames; ++i) {
    step2_.push_back({file("step2", step2_.size()), dataset::Step2Kind::kNeutral, {}, all_beams});
  }
  for (int id : all_beams) {
    const auto p = ReflectedDotInWorld(id, MirrorPlaneInWorld(0, DriveMode::kOff));
    if (!p || !OnWorldBoardInC2(*p, margin_mm, 20.0)) {
      warnings_.push_back("neutral: beam " + std::to_string(id) + " dot is off the visible board");
    }
  }
  // Fast-only frames: greedy per frame over the trigger table from a rotating start.
  const int n = static_cast<int>(triggers_.size());
  for (int f = 0; f < s2.fast_only_frames; ++f) {
    std::vector<int> chosen;
    std::vector<Eigen::Vector2d> px_chosen;
    for (int i = 0; i < n && static_cast<int>(chosen.size()) < s2.fast_only_triggers_per_frame;
         ++i) {
      const int j = (i + f * n / s2.fast_only_frames) % n;
      const geometry::Plane mirror = MirrorPlaneInWorld(triggers_[j].t_s, DriveMode::kFastOnly);
      std::vector<Eigen::Vector2d> px;
      bool ok = true;
      for (int id : all_beams) {
        const auto p = ReflectedDotInWorld(id, mirror);
        if (!p || !OnWorldBoardInC2(*p, margin_mm, 20.0)) {
          ok = false;
          break;
        }
        px.push_back(*camera_.Project(c2_from_world_ * *p));
      }
      for (size_t a = 0; a < px.size() && ok; ++a)
        for (const auto& q : px_chosen)
          ok = ok && (px[a] - q).norm() >= options_.triggers.min_separation_px;
      if (!ok) continue;
      chosen.push_back(j);
      px_chosen.insert(px_chosen.end(), px.begin(), px.end());
    }
    if (chosen.empty()) {
      warnings_.push_back("fast_only frame " + std::to_string(f) +
                          ": no trigger keeps its dots on the board");
      continue;
    }
    std::sort(chosen.begin(), chosen.end());
    step2_.push_back(
        {file("step2", step2_.size()), dataset::Step2Kind::kFastOnly, chosen, all_beams});
  }
  // Scan frames: consecutive groups of the table, so every j appears exactly once.
  for (int j0 = 0; j0 < n; j0 += s2.scan_triggers_per_frame) {
    std::vector<int> group;
    for (int j = j0; j < std::min(n, j0 + s2.scan_triggers_per_frame); ++j) group.push_back(j);
    step2_.push_back({file("step2", step2_.size()), dataset::Step2Kind::kScan, group, all_beams});
  }

  // C1: the sliding board must not hide the world board (bounding boxes of the projections).
  auto bbox = [&](const BoardOptions& b, const geometry::Rigid3d& cam_from_board) {
    Eigen::Vector4d box(1e18, 1e18, -1e18, -1e18);
    for (double r : {-1.0, static_cast<double>(b.rows)}) {
      for (double c : {-1.0, static_cast<double>(b.cols)}) {
        const auto px =
            camera_.Project(cam_from_board * Eigen::Vector3d(c * b.square_mm, r * b.square_mm, 0));
        if (!px) continue;
        box = Eigen::Vector4d(std::min(box[0], px->x()), std::min(box[1], px->y()),
                              std::max(box[2], px->x()), std::max(box[3], px->y()));
      }
    }
    return box;
  };
  const Eigen::Vector4d world_box = bbox(options_.world_board, c1_from_world_);
  for (int l = 0; l < s1.poses; ++l) {
    const Eigen::Vector4d s = bbox(options_.sliding_board, c1_from_sliding(l));
    const bool overlap =
        s[0] < world_box[2] && world_box[0] < s[2] && s[1] < world_box[3] && world_box[1] < s[3];
    if (overlap) {
      warnings_.push_back("step1 pose " + std::to_string(l) +
                          ": the sliding board overlaps the world board in C1's image");
    }
  }
}

dataset::Recording RigSimulator::MakeRecording(bool with_hall) const {
  dataset::Recording rec;
  rec.camera = camera_;
  rec.world_board = {options_.world_board.cols, options_.world_board.rows,
                     options_.world_board.square_mm};
  rec.sliding_board = {options_.sliding_board.cols, options_.sliding_board.rows,
                       options_.sliding_board.square_mm};
  for (int id = 1; id <= options_.beams.count; ++id) {
    const auto& v = options_.beams.validate_ids;
    const bool validate = std::find(v.begin(), v.end(), id) != v.end();
    rec.beams.push_back(
        {id, validate ? dataset::BeamRole::kValidate : dataset::BeamRole::kEstimate});
  }
  const auto& m = options_.mirror;
  rec.drive.fast = {m.fast.frequency_hz, m.fast.amplitude_vpp, m.fast.phase_deg};
  rec.drive.slow = {m.slow.frequency_hz, m.slow.amplitude_vpp, m.slow.phase_deg};
  rec.drive.pattern_period_s = period_s_;
  rec.clock_frequency_hz = 1.0 / period_s_;
  rec.triggers = triggers_;
  rec.step1 = step1_;
  rec.step2 = step2_;
  if (with_hall) {
    rec.hall_background =
        HallSampler(hall_, HallRecordingKind::kBackground, options_.seed).Collect();
    rec.hall_actual = HallSampler(hall_, HallRecordingKind::kActual, options_.seed).Collect();
  }
  return rec;
}

cv::Mat RigSimulator::RenderScene(const Scene& scene, uint64_t frame_index) const {
  return render::Render(scene.camera, scene.boards, scene.dots, RenderOptionsFor(frame_index));
}

cv::Mat RigSimulator::RenderStep1Frame(size_t i) const {
  const Scene scene = FrameScene(step1_.at(i));
  return render::Render(scene.camera, scene.boards, scene.dots, RenderOptionsFor(i));
}

cv::Mat RigSimulator::RenderStep2Frame(size_t i) const {
  const Scene scene = FrameScene(step2_.at(i));
  return render::Render(scene.camera, scene.boards, scene.dots, RenderOptionsFor(100000 + i));
}

render::RenderOptions RigSimulator::RenderOptionsFor(uint64_t frame_index) const {
  render::RenderOptions opt;
  opt.format = options_.render.colour ? render::PixelFormat::kBgr8 : render::PixelFormat::kMono8;
  opt.dot_peak = options_.render.dot_peak;
  opt.noise_sigma = options_.render.noise_sigma;
  opt.shot_noise = options_.render.shot_noise;
  opt.seed = Mix(options_.seed * 1000003ULL + frame_index);
  return opt;
}

}  // namespace msmcal::sim
