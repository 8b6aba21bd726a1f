#include "mocks/rig/hall_model.h"

#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

#include "common/check.h"
#include "common/units.h"
#include "processing/geometry/rigid3.h"

namespace msmcal::sim {
namespace {

Eigen::Vector3d Vec(const std::array<double, 3>& a) { return {a[0], a[1], a[2]}; }

// Uniform in [0, 1) from a seed, independent of the standard library's distributions.
double UnitFromSeed(uint64_t seed) {
  std::mt19937_64 rng(seed);
  return static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

uint64_t StreamSeed(uint64_t seed, HallRecordingKind kind) {
  return seed * 0x9E3779B97F4A7C15ULL + (kind == HallRecordingKind::kActual ? 0xA11 : 0xB66);
}

}  // namespace

const char* ToString(HallRecordingKind kind) {
  return kind == HallRecordingKind::kActual ? "actual" : "background";
}

HallModel::HallModel(const SimOptions& options)
    : options_(options), motion_(options.mirror), period_s_(options.PatternPeriodS()) {
  sensor_from_mirror0_ =
      geometry::So3Exp(Vec(options.hall.sensor_rotation_deg) * common::kRadPerDeg);
  sensor_in_mirror0_mm_ = Vec(options.hall.sensor_position_mm);
}

Eigen::Vector3d HallModel::MagnetFieldUT(const geometry::MirrorPose& pose) const {
  const auto& h = options_.hall;
  const Eigen::Matrix3d r = (Eigen::AngleAxisd(pose.beta_rad, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(pose.alpha_rad, Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  const Eigen::Vector3d n = r.col(2);
  const Eigen::Vector3d magnet_mm = r * Vec(h.magnet_position_mm) + pose.trans_mm * n;
  const Eigen::Vector3d moment = h.magnet_moment_am2 * (r * Vec(h.magnet_direction).normalized());
  const Eigen::Vector3d d = sensor_in_mirror0_mm_ - magnet_mm;  // mm, magnet -> sensor
  const double dist = d.norm();
  const Eigen::Vector3d u = d / dist;
  // mu0 / (4 pi) = 1e-7 T m / A; with r in mm and B in uT: 1e-7 * 1e6 / 1e-9 = 1e8.
  const Eigen::Vector3d b_in_mirror0 =
      1e8 * (3.0 * u * u.dot(moment) - moment) / (dist * dist * dist);
  return sensor_from_mirror0_ * b_in_mirror0;
}

Eigen::Vector3d HallModel::CoilFieldUT(double t_s) const {
  const auto& h = options_.hall;
  auto signal = [&](const AxisOptions& a) {
    const double phi =
        2 * std::numbers::pi * a.frequency_hz * t_s + a.phase_deg * common::kRadPerDeg;
    return std::sin(phi) + h.coil_harmonic2_ratio * std::sin(2 * phi);
  };
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  if (options_.mirror.fast.amplitude_vpp > 0)
    b += Vec(h.coil_fast_uT) * signal(options_.mirror.fast);
  if (options_.mirror.slow.amplitude_vpp > 0)
    b += Vec(h.coil_slow_uT) * signal(options_.mirror.slow);
  return b;
}

Eigen::Vector3d HallModel::FieldUT(double t_s, HallRecordingKind kind) const {
  Eigen::Vector3d b = CoilFieldUT(t_s) + Vec(options_.hall.earth_uT);
  if (kind == HallRecordingKind::kActual) {
    b += MagnetFieldUT(motion_.PoseAt(t_s, DriveMode::kScan));
  } else {
    b += Vec(options_.hall.background_shift_uT);
  }
  return b;
}

double HallModel::GeneratorTimeS(int64_t mcu_time_us) const {
  const double rate = 1.0 + options_.hall.mcu_rate_error_ppm * 1e-6;
  return static_cast<double>(mcu_time_us - options_.hall.mcu_offset_us) * 1e-6 / rate;
}

int64_t HallModel::McuTimeUs(double generator_time_s) const {
  const double rate = 1.0 + options_.hall.mcu_rate_error_ppm * 1e-6;
  return options_.hall.mcu_offset_us + std::llround(generator_time_s * rate * 1e6);
}

double HallModel::RecordingStartS(HallRecordingKind kind, uint64_t seed) const {
  const double base = kind == HallRecordingKind::kActual ? options_.hall.actual_start_s
                                                         : options_.hall.background_start_s;
  return base + period_s_ * UnitFromSeed(StreamSeed(seed, kind) ^ 0x5757);
}

double HallModel::DurationS(HallRecordingKind kind) const {
  return kind == HallRecordingKind::kActual ? options_.hall.actual_duration_s
                                            : options_.hall.background_duration_s;
}

HallSampler::HallSampler(const HallModel& model, HallRecordingKind kind, uint64_t seed,
                         std::optional<double> duration_s)
    : model_(model), kind_(kind), rng_(StreamSeed(seed, kind)), noise_(0.0, 1.0) {
  const double start_s = model.RecordingStartS(kind, seed);
  first_reading_us_ = model.McuTimeUs(start_s);
  sample_period_ns_ = std::llround(1e9 / model.options().hall.sample_rate_hz);
  const double duration = duration_s.value_or(model.DurationS(kind));
  reading_count_ =
      duration > 0
          ? static_cast<int64_t>(std::floor(duration * model.options().hall.sample_rate_hz))
          : std::numeric_limits<int64_t>::max() / 2;
  end_us_ = duration > 0 ? first_reading_us_ + (reading_count_ * sample_period_ns_) / 1000
                         : std::numeric_limits<int64_t>::max();
  // First clock edge at or after the first reading.
  next_edge_k_ = static_cast<int64_t>(std::floor(start_s / model.pattern_period_s()));
  while (model.McuTimeUs(next_edge_k_ * model.pattern_period_s()) < first_reading_us_)
    ++next_edge_k_;
}

std::optional<HallEvent> HallSampler::Next() {
  const int64_t edge_us =
      model_.McuTimeUs(static_cast<double>(next_edge_k_) * model_.pattern_period_s());
  const bool have_reading = next_reading_ < reading_count_;
  const int64_t reading_us = first_reading_us_ + (next_reading_ * sample_period_ns_) / 1000;
  if (edge_us < end_us_ && (!have_reading || edge_us <= reading_us)) {
    ++next_edge_k_;
    HallEvent e;
    e.type = HallEvent::Type::kClockEdge;
    e.mcu_time_us = edge_us;
    return e;
  }
  if (!have_reading) return std::nullopt;
  ++next_reading_;
  const double t_s = model_.GeneratorTimeS(reading_us) - model_.options().hall.delta_t_s;
  const Eigen::Vector3d b = model_.FieldUT(t_s, kind_);
  const double sigma = model_.options().hall.noise_uT;
  HallEvent e;
  e.type = HallEvent::Type::kReading;
  e.mcu_time_us = reading_us;
  e.reading.mcu_time_us = reading_us;
  // Quantised to 0.01 uT like the sensor's output registers (keeps the CSV short).
  auto quantise = [](double x) { return std::round(x * 100.0) / 100.0; };
  e.reading.bx_uT = quantise(b.x() + sigma * noise_(rng_));
  e.reading.by_uT = quantise(b.y() + sigma * noise_(rng_));
  e.reading.bz_uT = quantise(b.z() + sigma * noise_(rng_));
  return e;
}

dataset::HallRecording HallSampler::Collect() {
  dataset::HallRecording rec;
  MSMCAL_CHECK(end_us_ != std::numeric_limits<int64_t>::max())
      << "HallSampler::Collect on an endless sampler";
  rec.readings.reserve(static_cast<size_t>(reading_count_));
  while (auto e = Next()) {
    if (e->type == HallEvent::Type::kClockEdge) {
      rec.clock_edges_us.push_back(e->mcu_time_us);
    } else {
      rec.readings.push_back(e->reading);
    }
  }
  return rec;
}

}  // namespace msmcal::sim
