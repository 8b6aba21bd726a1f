#include "mocks/rig/truth_io.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include "common/csv_writer.h"
#include "common/file_text.h"
#include "common/text_io.h"
#include "common/units.h"
#include "common/yaml_fields.h"
#include "mocks/rig/rig_simulator.h"
#include "processing/geometry/mirror_frame.h"

namespace msmcal::sim {
namespace {

namespace fs = std::filesystem;

std::string Y(double x) { return common::YamlDouble(x); }

std::string List(const Eigen::VectorXd& v) {
  std::string s = "[";
  for (int i = 0; i < v.size(); ++i) s += (i ? ", " : "") + Y(v[i]);
  return s + "]";
}

std::string TransformYaml(const geometry::Rigid3d& t) {
  const Eigen::Matrix3d r = t.RotationMatrix();
  Eigen::VectorXd row_major(9);
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) row_major[3 * i + k] = r(i, k);
  return "{R: " + List(row_major) + ", t: " + List(t.translation) + "}";
}

YAML::Node LoadYaml(const fs::path& file) {
  return common::YamlFields(file.string()).Load(common::ReadFileText(file));
}

// node[key], which must exist ("<file>:<line>: <key>: missing").
YAML::Node Need(const YAML::Node& node, const std::string& key, const fs::path& file) {
  return common::YamlFields(file.string()).Required(node, key, key);
}

Eigen::VectorXd NumList(const YAML::Node& n, int size, const fs::path& file,
                        const std::string& key) {
  if (!n.IsSequence() || static_cast<int>(n.size()) != size) {
    common::YamlFields(file.string())
        .Fail(n, key, "expected a list of " + std::to_string(size) + " numbers");
  }
  Eigen::VectorXd v(size);
  for (int i = 0; i < size; ++i) v[i] = n[i].as<double>();
  return v;
}

geometry::Rigid3d ReadTransform(const YAML::Node& n, const fs::path& file, const std::string& key) {
  const Eigen::VectorXd r = NumList(Need(n, "R", file), 9, file, key + ".R");
  const Eigen::VectorXd t = NumList(Need(n, "t", file), 3, file, key + ".t");
  Eigen::Matrix3d m;
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) m(i, k) = r[3 * i + k];
  return geometry::Rigid3d(m, Eigen::Vector3d(t[0], t[1], t[2]));
}

// A CSV file with a fixed header: rows of fields.
std::vector<std::vector<std::string>> ReadCsv(const fs::path& file, const std::string& header) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error(file.string() + ": cannot open");
  std::string line;
  std::getline(in, line);
  if (line != header) {
    throw std::runtime_error(file.string() + ":1: header is '" + line + "' but expected '" +
                             header + "'");
  }
  const size_t columns = std::count(header.begin(), header.end(), ',') + 1;
  std::vector<std::vector<std::string>> rows;
  int line_no = 1;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty()) continue;
    std::vector<std::string> fields;
    std::stringstream s(line);
    std::string f;
    while (std::getline(s, f, ',')) fields.push_back(f);
    if (fields.size() != columns) {
      throw std::runtime_error(file.string() + ":" + std::to_string(line_no) + ": expected " +
                               std::to_string(columns) + " fields, got " +
                               std::to_string(fields.size()));
    }
    rows.push_back(std::move(fields));
  }
  return rows;
}

// The whole cell `s` as a T; otherwise "<file>:<line>: <column>: '<s>' is not <what>".
template <typename T>
T Cell(const std::string& s, const fs::path& file, size_t row, const char* column,
       const char* what) {
  T v = 0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  if (r.ec != std::errc() || r.ptr != s.data() + s.size()) {
    throw std::runtime_error(file.string() + ":" + std::to_string(row + 2) + ": " + column + ": '" +
                             s + "' is not " + what);
  }
  return v;
}

double ToD(const std::string& s, const fs::path& file, size_t row, const char* column) {
  return Cell<double>(s, file, row, column, "a number");
}

int ToI(const std::string& s, const fs::path& file, size_t row, const char* column) {
  return Cell<int>(s, file, row, column, "an integer");
}

constexpr const char* kBeamsHeader = "beam,px,py,pz,vx,vy,vz";
constexpr const char* kPlanesHeader =
    "j,t_s,nx,ny,nz,d_mm,alpha_deg,beta_deg,trans_mm,sigma_alpha_deg,sigma_beta_deg,sigma_trans_mm";
constexpr const char* kDotsHeader = "file,beam,j,u_px,v_px";
constexpr const char* kTrajectoryHeader = "t_s,alpha_deg,beta_deg,trans_mm";

}  // namespace

SimTruth MakeTruth(const RigSimulator& sim, double trajectory_rate_hz) {
  SimTruth t;
  t.seed = sim.options().seed;
  t.sim_config_yaml = SimOptionsToYaml(sim.options());
  for (size_t k = 0; k < sim.beams_in_world().size(); ++k) {
    t.beams.push_back(
        {static_cast<int>(k) + 1, sim.beam_sources_in_world()[k], sim.beams_in_world()[k].v});
  }
  double span_sum = 0;
  for (const auto& trig : sim.triggers()) {
    const geometry::MirrorPose pose = sim.motion().PoseAt(trig.t_s, DriveMode::kScan);
    const geometry::Plane plane = geometry::WorldPlaneFromPose(sim.world_from_mirror0(), pose);
    dataset::MirrorPlaneRow row;
    row.j = trig.j;
    row.t_s = trig.t_s;
    row.plane_in_world = plane;
    row.alpha_deg = pose.alpha_rad * common::kDegPerRad;
    row.beta_deg = pose.beta_rad * common::kDegPerRad;
    row.trans_mm = pose.trans_mm;
    t.mirror_planes.push_back(row);
    span_sum += sim.SpanningAngleDeg(plane);
  }
  t.spanning_angle_mean_deg = sim.triggers().empty() ? 0 : span_sum / sim.triggers().size();
  t.world_from_mirror0 = sim.world_from_mirror0();
  const Eigen::Matrix3d r = t.world_from_mirror0.RotationMatrix();
  t.neutral_normal = r.col(2);
  t.fast_axis = r.col(0);
  t.rotation_centre = t.world_from_mirror0.translation;
  t.fan_angle_deg = sim.fan_angle_deg();
  t.spanning_angle_neutral_deg = sim.SpanningAngleDeg(sim.MirrorPlaneInWorld(0, DriveMode::kOff));
  t.c1_from_world = sim.c1_from_world();
  for (size_t l = 0; l < sim.world_from_sliding().size(); ++l) {
    t.c1_from_sliding.push_back(sim.c1_from_sliding(static_cast<int>(l)));
  }
  t.c2_from_world = sim.c2_from_world();
  for (const auto& f : sim.step1_frames()) {
    for (const auto& d : sim.FrameScene(f).labels)
      t.dots.push_back({f.file, d.beam, d.j, d.pixel.x(), d.pixel.y()});
  }
  for (const auto& f : sim.step2_frames()) {
    for (const auto& d : sim.FrameScene(f).labels)
      t.dots.push_back({f.file, d.beam, d.j, d.pixel.x(), d.pixel.y()});
  }
  const auto& h = sim.options().hall;
  t.hall.delta_t_s = h.delta_t_s;
  t.hall.mcu_offset_us = h.mcu_offset_us;
  t.hall.mcu_rate_error_ppm = h.mcu_rate_error_ppm;
  t.hall.noise_uT = h.noise_uT;
  t.hall.sample_rate_hz = h.sample_rate_hz;
  t.hall.background_start_s = sim.hall().RecordingStartS(HallRecordingKind::kBackground, t.seed);
  t.hall.actual_start_s = sim.hall().RecordingStartS(HallRecordingKind::kActual, t.seed);
  t.hall.pattern_period_s = sim.pattern_period_s();
  const int steps = static_cast<int>(std::lround(sim.pattern_period_s() * trajectory_rate_hz));
  for (int i = 0; i < steps; ++i) {
    const double ts = i / trajectory_rate_hz;
    const geometry::MirrorPose p = sim.motion().PoseAt(ts, DriveMode::kScan);
    t.pose_trajectory.push_back(
        {ts, p.alpha_rad * common::kDegPerRad, p.beta_rad * common::kDegPerRad, p.trans_mm});
  }
  return t;
}

void WriteTruth(const fs::path& dir, const SimTruth& t) {
  const fs::path truth = dir / "truth";
  common::WriteFileAtomically(truth / "sim_config.yaml", t.sim_config_yaml);
  {
    std::string s = std::string(kBeamsHeader) + "\n";
    for (const auto& b : t.beams) {
      common::AppendCsvRow(&s, b.beam, b.p.x(), b.p.y(), b.p.z(), b.v.x(), b.v.y(), b.v.z());
    }
    common::WriteFileAtomically(truth / "beams.csv", s);
  }
  {
    std::string s = std::string(kPlanesHeader) + "\n";
    for (const auto& p : t.mirror_planes) {
      const auto& n = p.plane_in_world.n;
      common::AppendCsvRow(&s, p.j, p.t_s, n.x(), n.y(), n.z(), p.plane_in_world.d, p.alpha_deg,
                           p.beta_deg, p.trans_mm, p.sigma_alpha_deg, p.sigma_beta_deg,
                           p.sigma_trans_mm);
    }
    common::WriteFileAtomically(truth / "mirror_planes.csv", s);
  }
  {
    std::string s = "# Mirror home frame {0} in {W} (ground truth). R row-major, lengths mm.\n";
    s += "world_from_mirror0: " + TransformYaml(t.world_from_mirror0) + "\n";
    s += "neutral_normal: " + List(t.neutral_normal) + "\n";
    s += "fast_axis: " + List(t.fast_axis) + "\n";
    s += "rotation_centre: " + List(t.rotation_centre) + "\n";
    s +=
        "fan_angle_deg: " + Y(t.fan_angle_deg) + "  # angle between the outermost incident beams\n";
    s += "spanning_angle_neutral_deg: " + Y(t.spanning_angle_neutral_deg) +
         "  # light-path plane normals, outer beams\n";
    s += "spanning_angle_mean_deg: " + Y(t.spanning_angle_mean_deg) +
         "  # mean over scan triggers\n";
    common::WriteFileAtomically(truth / "mirror_frame.yaml", s);
  }
  {
    std::string s = "# Camera poses (ground truth): cam_from_board, R row-major, t mm.\n";
    s += "c1_from_world: " + TransformYaml(t.c1_from_world) + "\n";
    s += "c1_from_sliding:\n";
    for (const auto& v : t.c1_from_sliding) s += "  - " + TransformYaml(v) + "\n";
    s += "c2_from_world: " + TransformYaml(t.c2_from_world) + "\n";
    common::WriteFileAtomically(truth / "views.yaml", s);
  }
  {
    std::string s = std::string(kDotsHeader) + "\n";
    for (const auto& d : t.dots) {
      common::AppendCsvRow(&s, d.file, d.beam, d.j, d.u_px, d.v_px);
    }
    common::WriteFileAtomically(truth / "dots.csv", s);
  }
  {
    const auto& h = t.hall;
    std::string s =
        "# Hall timing truth. mcu_time_us = mcu_offset_us + (1 + mcu_rate_error_ppm 1e-6) t 1e6,\n"
        "# t = generator time (s) from the first pattern start; a reading stamped mcu_time_us "
        "shows\n"
        "# the field at t(mcu_time_us) - delta_t_s. Readings quantised to 0.01 uT.\n";
    s += "delta_t_s: " + Y(h.delta_t_s) + "\n";
    s += "mcu_offset_us: " + std::to_string(h.mcu_offset_us) + "\n";
    s += "mcu_rate_error_ppm: " + Y(h.mcu_rate_error_ppm) + "\n";
    s += "noise_uT: " + Y(h.noise_uT) + "\n";
    s += "sample_rate_hz: " + Y(h.sample_rate_hz) + "\n";
    s += "background_start_s: " + Y(h.background_start_s) + "\n";
    s += "actual_start_s: " + Y(h.actual_start_s) + "\n";
    s += "pattern_period_s: " + Y(h.pattern_period_s) + "\n";
    common::WriteFileAtomically(truth / "hall.yaml", s);
  }
  {
    std::string s = std::string(kTrajectoryHeader) + "\n";
    for (const auto& p : t.pose_trajectory) {
      common::AppendCsvRow(&s, p.t_s, p.alpha_deg, p.beta_deg, p.trans_mm);
    }
    common::WriteFileAtomically(truth / "pose_trajectory.csv", s);
  }
}

SimTruth ReadTruth(const fs::path& dir) {
  const fs::path truth = dir / "truth";
  SimTruth t;
  t.sim_config_yaml = common::ReadFileText(truth / "sim_config.yaml");
  {
    const YAML::Node cfg = LoadYaml(truth / "sim_config.yaml");
    t.seed = Need(cfg, "seed", truth / "sim_config.yaml").as<uint64_t>();
  }
  {
    const fs::path f = truth / "beams.csv";
    const auto rows = ReadCsv(f, kBeamsHeader);
    for (size_t i = 0; i < rows.size(); ++i) {
      const auto& r = rows[i];
      dataset::BeamRow b;
      b.beam = ToI(r[0], f, i, "beam");
      b.p = {ToD(r[1], f, i, "px"), ToD(r[2], f, i, "py"), ToD(r[3], f, i, "pz")};
      b.v = {ToD(r[4], f, i, "vx"), ToD(r[5], f, i, "vy"), ToD(r[6], f, i, "vz")};
      t.beams.push_back(b);
    }
  }
  {
    const fs::path f = truth / "mirror_planes.csv";
    const auto rows = ReadCsv(f, kPlanesHeader);
    static const char* kCols[] = {"j",
                                  "t_s",
                                  "nx",
                                  "ny",
                                  "nz",
                                  "d_mm",
                                  "alpha_deg",
                                  "beta_deg",
                                  "trans_mm",
                                  "sigma_alpha_deg",
                                  "sigma_beta_deg",
                                  "sigma_trans_mm"};
    for (size_t i = 0; i < rows.size(); ++i) {
      const auto& r = rows[i];
      double v[12];
      for (int c = 1; c < 12; ++c) v[c] = ToD(r[c], f, i, kCols[c]);
      dataset::MirrorPlaneRow p;
      p.j = ToI(r[0], f, i, "j");
      p.t_s = v[1];
      p.plane_in_world = {Eigen::Vector3d(v[2], v[3], v[4]), v[5]};
      p.alpha_deg = v[6];
      p.beta_deg = v[7];
      p.trans_mm = v[8];
      p.sigma_alpha_deg = v[9];
      p.sigma_beta_deg = v[10];
      p.sigma_trans_mm = v[11];
      t.mirror_planes.push_back(p);
    }
  }
  {
    const fs::path f = truth / "mirror_frame.yaml";
    const YAML::Node y = LoadYaml(f);
    t.world_from_mirror0 = ReadTransform(Need(y, "world_from_mirror0", f), f, "world_from_mirror0");
    t.neutral_normal = NumList(Need(y, "neutral_normal", f), 3, f, "neutral_normal");
    t.fast_axis = NumList(Need(y, "fast_axis", f), 3, f, "fast_axis");
    t.rotation_centre = NumList(Need(y, "rotation_centre", f), 3, f, "rotation_centre");
    t.fan_angle_deg = Need(y, "fan_angle_deg", f).as<double>();
    t.spanning_angle_neutral_deg = Need(y, "spanning_angle_neutral_deg", f).as<double>();
    t.spanning_angle_mean_deg = Need(y, "spanning_angle_mean_deg", f).as<double>();
  }
  {
    const fs::path f = truth / "views.yaml";
    const YAML::Node y = LoadYaml(f);
    t.c1_from_world = ReadTransform(Need(y, "c1_from_world", f), f, "c1_from_world");
    for (const auto& n : Need(y, "c1_from_sliding", f)) {
      t.c1_from_sliding.push_back(ReadTransform(n, f, "c1_from_sliding[]"));
    }
    t.c2_from_world = ReadTransform(Need(y, "c2_from_world", f), f, "c2_from_world");
  }
  {
    const fs::path f = truth / "dots.csv";
    const auto rows = ReadCsv(f, kDotsHeader);
    for (size_t i = 0; i < rows.size(); ++i) {
      const auto& r = rows[i];
      t.dots.push_back({r[0], ToI(r[1], f, i, "beam"), ToI(r[2], f, i, "j"),
                        ToD(r[3], f, i, "u_px"), ToD(r[4], f, i, "v_px")});
    }
  }
  {
    const fs::path f = truth / "hall.yaml";
    const YAML::Node y = LoadYaml(f);
    t.hall.delta_t_s = Need(y, "delta_t_s", f).as<double>();
    t.hall.mcu_offset_us = Need(y, "mcu_offset_us", f).as<int64_t>();
    t.hall.mcu_rate_error_ppm = Need(y, "mcu_rate_error_ppm", f).as<double>();
    t.hall.noise_uT = Need(y, "noise_uT", f).as<double>();
    t.hall.sample_rate_hz = Need(y, "sample_rate_hz", f).as<double>();
    t.hall.background_start_s = Need(y, "background_start_s", f).as<double>();
    t.hall.actual_start_s = Need(y, "actual_start_s", f).as<double>();
    t.hall.pattern_period_s = Need(y, "pattern_period_s", f).as<double>();
  }
  {
    const fs::path f = truth / "pose_trajectory.csv";
    const auto rows = ReadCsv(f, kTrajectoryHeader);
    for (size_t i = 0; i < rows.size(); ++i) {
      const auto& r = rows[i];
      t.pose_trajectory.push_back({ToD(r[0], f, i, "t_s"), ToD(r[1], f, i, "alpha_deg"),
                                   ToD(r[2], f, i, "beta_deg"), ToD(r[3], f, i, "trans_mm")});
    }
  }
  return t;
}

}  // namespace msmcal::sim
