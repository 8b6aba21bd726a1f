#pragma once
// Hall field at the fixed triaxial sensor, and a streaming sampler that produces what the MCU
// reports: readings at the MCU's sample rate and the MCU timestamps of the clock's rising edges
// (pattern phase 0), in MCU-time order.
//
// Model (all in the sensor's axes, microtesla):
//   actual(t)     = dipole(magnet pose at t) + coils(t) + earth
//   background(t) = coils(t) + earth + background_shift        (mirror top frame removed)
// The magnet is a point dipole fixed to the mirror plate: in {0} its position is
// R p_m + trans n and its moment R m_m, with R = Ry(beta) Rx(alpha) and n = R e_z (the mirror
// normal of geometry::PlaneFromPose). Coils: c_f (s_f + h s_f2) + c_s (s_s + h s_s2) where
// s = sin(2 pi f t + phase) is the normalised drive signal and s2 its 2nd harmonic.
//
// Time: the MCU clock maps generator time tau (s) to mcu_us = offset_us + (1 + ppm 1e-6) tau 1e6.
// A reading stamped mcu_us shows the field at generator time tau(mcu_us) - delta_t_s.
// Readings are taken at exact multiples of the sample period in MCU time; clock edges are the
// MCU timestamps (rounded to whole us) of tau = k T. Readings are quantised to 0.01 uT.

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <random>

#include "mocks/rig/mirror_motion.h"
#include "mocks/rig/sim_options.h"
#include "processing/dataset/recording.h"

namespace msmcal::sim {

enum class HallRecordingKind { kBackground, kActual };
const char* ToString(HallRecordingKind kind);

class HallModel {
 public:
  explicit HallModel(const SimOptions& options);

  // Noise-free field in sensor axes at generator time t_s (what the sensor sees at that
  // instant; no delay applied). Actual recordings are taken during a full scan.
  Eigen::Vector3d FieldUT(double t_s, HallRecordingKind kind) const;
  // Parts of the model.
  Eigen::Vector3d MagnetFieldUT(const geometry::MirrorPose& pose) const;
  Eigen::Vector3d CoilFieldUT(double t_s) const;

  // MCU clock mapping (generator time in seconds from the first pattern start).
  double GeneratorTimeS(int64_t mcu_time_us) const;
  int64_t McuTimeUs(double generator_time_s) const;

  // Generator time of the first reading of a recording (configured start + a seeded jitter
  // within one pattern period).
  double RecordingStartS(HallRecordingKind kind, uint64_t seed) const;
  double DurationS(HallRecordingKind kind) const;

  const SimOptions& options() const { return options_; }
  const MirrorMotion& motion() const { return motion_; }
  double pattern_period_s() const { return period_s_; }

 private:
  SimOptions options_;
  MirrorMotion motion_;
  double period_s_ = 0;
  Eigen::Matrix3d sensor_from_mirror0_;
  Eigen::Vector3d sensor_in_mirror0_mm_;
};

// What the MCU emits next: a field reading or a clock edge timestamp.
struct HallEvent {
  enum class Type { kReading, kClockEdge };
  Type type = Type::kReading;
  int64_t mcu_time_us = 0;
  dataset::HallReading reading;  // valid for kReading (mcu_time_us repeated there)
};

// Deterministic stream of one recording (seeded noise). Events come in MCU-time order; an edge
// and a reading with the same timestamp come edge first. Not thread-safe; one per consumer.
class HallSampler {
 public:
  // duration_s: how long the recording runs (default: the configured duration of `kind`);
  // <= 0: endless (for the real-time mock MCU). Starts at RecordingStartS(kind, seed).
  HallSampler(const HallModel& model, HallRecordingKind kind, uint64_t seed,
              std::optional<double> duration_s = std::nullopt);

  // The next event, or empty once the recording's duration is exhausted.
  std::optional<HallEvent> Next();
  // Runs the whole stream into an interchange recording (not for endless samplers).
  dataset::HallRecording Collect();

 private:
  const HallModel& model_;
  HallRecordingKind kind_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> noise_;
  int64_t first_reading_us_ = 0;
  int64_t sample_period_ns_ = 0;
  int64_t reading_count_ = 0;
  int64_t next_reading_ = 0;
  int64_t next_edge_k_ = 0;
  int64_t end_us_ = 0;
};

}  // namespace msmcal::sim
