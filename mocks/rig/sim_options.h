#pragma once
// Configuration of the rig simulator (config/sim.yaml documents every field and its default).
//
// Units: millimetres, degrees, seconds, hertz, volts peak-to-peak, microtesla unless a field name
// says otherwise. Frames: {W} world board (Z into the board), {0} mirror home frame
// (interchange-format.md). Every field has a paper-like default; LoadSimOptions overrides the
// fields present in a YAML file and rejects unknown keys.

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace msmcal::sim {

// One resonant mirror axis driven by one sine channel. The axis responds as a second-order
// system: angle amplitude = dc_gain_deg_per_v * (Vpp / 2) * |H(f)| with
// H(f) = 1 / (1 - r^2 + i r / q), r = f / resonance_hz, and lags the drive by arg H (0..180 deg).
struct AxisOptions {
  double frequency_hz = 0;
  double amplitude_vpp = 0;
  double phase_deg = 0;  // generator phase of the sine drive
  double resonance_hz = 0;
  double q = 0;                  // quality factor
  double dc_gain_deg_per_v = 0;  // static angle per volt of drive amplitude
  double harmonic2_ratio = 0;    // 2nd harmonic amplitude / fundamental amplitude
  double harmonic2_phase_deg = 0;
};

struct MirrorOptions {
  AxisOptions fast{205.0, 2.0, 0.0, 210.0, 30.0, 0.126, 0.02, 30.0};
  AxisOptions slow{5.0, 4.0, 0.0, 60.0, 5.0, 4.22, 0.01, -40.0};
  // Out-of-plane translation while the drives are on (drives off: exactly 0):
  // trans = offset + k_beta * beta + k_alpha2 * alpha^2 + k_beta2 * beta^2 (angles in degrees).
  double trans_offset_mm = 0.05;
  double trans_k_beta_mm_per_deg = 0.05;
  double trans_k_alpha2_mm_per_deg2 = 0.01;
  double trans_k_beta2_mm_per_deg2 = 0.004;
};

struct GeometryOptions {
  // Mirror rotation centre X_O at this distance in front of the world board (along -Z_W).
  double mirror_distance_mm = 250.0;
  // Where the neutral central reflected beam meets the board, as a board point (mm in {W}).
  std::array<double, 2> board_aim_mm{110.0, 135.0};
  // Angle of incidence of the central beam on the neutral mirror (beams arrive along +X_W,
  // roughly parallel to the board); 45 deg reflects them straight onto the board.
  double incidence_deg = 45.0;
  // Small rotation of the whole mirror mount (rotation vector, degrees, applied in {W}).
  std::array<double, 3> mount_tilt_deg{1.5, -2.0, 3.0};
};

struct BeamOptions {
  int count = 3;
  // The paper's spanning angle theta: angle between the light-path plane normals of the two
  // outermost beams at the neutral pose. The fan half-angle is solved to give it.
  double spanning_angle_deg = 46.0;
  // Per beam: position in the fan as a fraction of the fan (-0.5 .. 0.5). Size = count.
  std::vector<double> fan_fractions{-0.5, 0.5, 0.0};
  // Per beam: where it crosses the neutral mirror plane, relative to X_O, in {0} x/y (mm). The
  // beams deliberately miss the rotation centre.
  std::vector<std::array<double, 2>> offsets_mm{{1.2, -0.8}, {-1.5, 0.6}, {0.4, 1.3}};
  std::vector<int> validate_ids{3};   // beam ids (1-based) with role validate
  double source_distance_mm = 180.0;  // from the mirror back to each beam's splitter point
};

struct BoardOptions {
  int cols = 0;  // inner corners along X; (cols+1) even
  int rows = 0;  // inner corners along Y; (rows+1) odd
  double square_mm = 10.0;
};

struct CameraOptions {
  int width = 2448;
  int height = 2048;
  double fx = 2000.0, fy = 2000.0, cx = 1223.5, cy = 1023.5;
  std::array<double, 5> distortion{-0.08, 0.05, 0.0004, -0.0003, 0.0};
  // Camera placements: optical centre in {W} (mm) and the {W} point it looks at; the image y
  // axis (down) is kept in the plane of {W}'s Y axis and the viewing direction.
  std::array<double, 3> c1_centre_mm{-330.0, 135.0, -420.0};
  std::array<double, 3> c1_target_mm{0.0, 135.0, -180.0};
  std::array<double, 3> c2_centre_mm{180.0, 140.0, -430.0};
  std::array<double, 3> c2_target_mm{110.0, 135.0, 0.0};
};

struct Step1Options {
  int poses = 7;
  double nearest_mm = 35.0;    // sliding plate distance from X_O along the central beam, first pose
  double farthest_mm = 100.0;  // last pose
  double tilt_deg = 12.0;      // plate tilt about its rows axis, alternating sign per pose
  bool identification_frames = true;  // one frame per beam alone at the first pose
  // After each pose's frame, one with every beam blocked (beams: []): the background under the
  // dots for their fit (docs/solver.md, "Dots"). Not at a pose that has identification frames,
  // whose single-beam frames already show each dot's pixels dot-free. A pose whose dots would
  // lie closer than 20 px in one image gets one frame per beam instead of the all-beams frame
  // (their blobs merge), and its background frame even at the identification pose.
  bool background_frames = true;
  // Every step 1 frame is taken this many times in a row (same pose, same beams): the solver
  // averages repeated exposures, which lowers the noise of the sliding-plane dots that alone
  // carry the held-out beam (docs/solver.md, "Table I").
  int exposures = 3;
};

struct Step2Options {
  int neutral_frames = 2;
  int fast_only_frames = 3;
  int fast_only_triggers_per_frame = 4;
  int scan_triggers_per_frame = 3;
};

struct TriggerOptions {
  int candidates = 1000;            // evenly spaced candidate times over one pattern period
  int max_triggers = 60;            // stop after this many accepted triggers
  double min_separation_px = 25.0;  // minimum distance between any two dots of accepted triggers
  double board_margin_mm = 10.0;    // dots keep this far inside the board's inner-corner area
};

struct HallOptions {
  double sample_rate_hz = 1000.0;  // MCU sampling (exact in MCU time)
  double background_duration_s = 12.0;
  double actual_duration_s = 15.0;
  // Sensing magnet: position on the mirror's back and dipole moment direction in the plate's
  // own frame (moves with the mirror), moment in A*m^2.
  std::array<double, 3> magnet_position_mm{0.0, 0.0, -1.5};
  std::array<double, 3> magnet_direction{0.0, 0.0, -1.0};
  double magnet_moment_am2 = 2.0e-4;
  // Fixed sensor: position in {0} and its axes as a rotation vector (deg) sensor_from_mirror0.
  std::array<double, 3> sensor_position_mm{0.6, -0.4, -5.5};
  std::array<double, 3> sensor_rotation_deg{2.0, -1.0, 4.0};
  std::array<double, 3> earth_uT{21.0, -4.0, 44.0};  // in sensor axes
  // Coil interference at the sensor, per unit of drive signal (sin at the drive's phase).
  std::array<double, 3> coil_fast_uT{30.0, 12.0, -18.0};
  std::array<double, 3> coil_slow_uT{55.0, -14.0, 26.0};
  double coil_harmonic2_ratio = 0.06;
  std::array<double, 3> background_shift_uT{0.8, -0.5, 0.3};  // baseline shift of background
  double noise_uT = 1.5;                                      // per-axis Gaussian sigma
  double delta_t_s = 0.00055;        // sensor delay: a reading shows the field delta_t earlier
  int64_t mcu_offset_us = 3141592;   // MCU time at generator time 0
  double mcu_rate_error_ppm = 35.0;  // MCU clock runs (1 + ppm 1e-6) times the generator's
  double background_start_s =
      40.0;  // generator time of the first background reading (+ seeded jitter)
  double actual_start_s = 130.0;
};

// Image formation (mocks/render): levels are fractions of full scale.
struct RenderOptions {
  double dot_sigma_mm = 0.5;   // 1-sigma radius of a laser spot on the surface it hits
  double dot_peak = 0.7;       // added level at a spot's centre
  double noise_sigma = 0.004;  // read noise
  double shot_noise = 0.01;    // photon noise at full scale
  bool colour = false;         // false: 8-bit mono; true: 8-bit BGR (dots green)
};

struct SimOptions {
  uint64_t seed = 1;
  MirrorOptions mirror;
  GeometryOptions geometry;
  BeamOptions beams;
  BoardOptions world_board{23, 28, 10.0};
  BoardOptions sliding_board{13, 8, 10.0};
  CameraOptions camera;
  Step1Options step1;
  Step2Options step2;
  TriggerOptions triggers;
  HallOptions hall;
  RenderOptions render;
  bool marg = false;  // also write marg/ recordings (when the MARG simulator is available)

  // Empty if usable, else the first problem: names the field, its value and the constraint.
  std::string Validate() const;
  // Pattern period T = 1 / gcd(f_fast, f_slow) (frequencies rounded to mHz).
  double PatternPeriodS() const;
};

// Reads a YAML file (keys as in config/sim.yaml); missing keys keep their defaults. Throws
// std::runtime_error naming the file, line and key for unknown keys, bad types or a failed
// Validate().
SimOptions LoadSimOptions(const std::filesystem::path& file);
SimOptions ParseSimOptions(const std::string& yaml_text, const std::string& source_name);
// The effective configuration as YAML (every field), readable by ParseSimOptions.
std::string SimOptionsToYaml(const SimOptions& options);

}  // namespace msmcal::sim
