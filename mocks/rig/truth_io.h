#pragma once
// Ground truth of a simulated session: the truth/ folder of an interchange folder (never read by
// the solver). Files (lengths mm, angles deg, times s):
//   truth/sim_config.yaml      effective simulation config, seed included (config/sim.yaml keys)
//   truth/beams.csv            beam,px,py,pz,vx,vy,vz          incident beams in {W} (p = source)
//   truth/mirror_planes.csv    as results/mirror_planes.csv, one row per trigger j (scan), sigmas 0
//   truth/mirror_frame.yaml    world_from_mirror0 {R row-major, t}, neutral_normal, fast_axis,
//                              rotation_centre (in {W}); fan and spanning angles
//   truth/views.yaml           c1_from_world, c1_from_sliding (per pose), c2_from_world {R, t}
//   truth/dots.csv             file,beam,j,u_px,v_px   true dot centres (j = -1: step 1, neutral;
//                              fast_only rows: the fast-only pose at t_j)
//   truth/hall.yaml            delta_t_s, mcu_offset_us, mcu_rate_error_ppm, noise_uT, ...
//   truth/pose_trajectory.csv  t_s,alpha_deg,beta_deg,trans_mm over one pattern period
// Numbers are written in shortest round-trip form, so ReadTruth(WriteTruth(x)) == x.

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "processing/dataset/recording.h"
#include "processing/geometry/rigid3.h"

namespace msmcal::sim {

class RigSimulator;

struct TruthDot {
  std::string file;
  int beam = 0;
  int j = -1;
  double u_px = 0, v_px = 0;
};

struct PoseSample {
  double t_s = 0, alpha_deg = 0, beta_deg = 0, trans_mm = 0;
};

struct HallTruth {
  double delta_t_s = 0;
  int64_t mcu_offset_us = 0;
  double mcu_rate_error_ppm = 0;
  double noise_uT = 0;
  double sample_rate_hz = 0;
  double background_start_s = 0;  // generator time of the first reading
  double actual_start_s = 0;
  double pattern_period_s = 0;
};

struct SimTruth {
  uint64_t seed = 0;
  std::string sim_config_yaml;  // written verbatim
  std::vector<dataset::BeamRow> beams;
  std::vector<dataset::MirrorPlaneRow> mirror_planes;
  geometry::Rigid3d world_from_mirror0;
  Eigen::Vector3d neutral_normal = Eigen::Vector3d::Zero();
  Eigen::Vector3d fast_axis = Eigen::Vector3d::Zero();
  Eigen::Vector3d rotation_centre = Eigen::Vector3d::Zero();
  double fan_angle_deg = 0;
  double spanning_angle_neutral_deg = 0;
  double spanning_angle_mean_deg = 0;  // over the scan triggers
  geometry::Rigid3d c1_from_world;
  std::vector<geometry::Rigid3d> c1_from_sliding;
  geometry::Rigid3d c2_from_world;
  std::vector<TruthDot> dots;
  HallTruth hall;
  std::vector<PoseSample> pose_trajectory;
};

// Truth of a simulator; trajectory sampled at trajectory_rate_hz over one pattern period.
SimTruth MakeTruth(const RigSimulator& sim, double trajectory_rate_hz = 10000.0);

// Writes DIR/truth/... (creates folders; each file written to a temporary and renamed).
void WriteTruth(const std::filesystem::path& dir, const SimTruth& truth);
// Reads DIR/truth/...; throws std::runtime_error naming the file, line and field on bad input.
SimTruth ReadTruth(const std::filesystem::path& dir);


}  // namespace msmcal::sim
