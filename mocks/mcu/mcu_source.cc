#include "mocks/mcu/mcu_source.h"

#include <cmath>
#include <numbers>
#include <stdexcept>

#include "common/units.h"

namespace msmcal::sim {

SyntheticMode ParseSyntheticMode(const std::string& name) {
  if (name == "scan") return SyntheticMode::kScan;
  if (name == "background") return SyntheticMode::kBackground;
  if (name == "marg") return SyntheticMode::kMarg;
  throw std::invalid_argument("mode '" + name + "' is not one of scan|background|marg");
}

std::string SyntheticSourceOptions::Validate() const {
  auto bad = [](const char* field, double value, const char* constraint) {
    return std::string("SyntheticSourceOptions.") + field + " = " + std::to_string(value) +
           ": violated constraint " + constraint;
  };
  if (!(rate_hz > 0 && rate_hz <= 100000)) return bad("rate_hz", rate_hz, "0 < rate_hz <= 1e5");
  if (!(clock_period_s >= 0)) return bad("clock_period_s", clock_period_s, "clock_period_s >= 0");
  if (!(clock_first_s >= 0)) return bad("clock_first_s", clock_first_s, "clock_first_s >= 0");
  if (!(duration_s >= 0)) return bad("duration_s", duration_s, "duration_s >= 0");
  if (!(noise_uT >= 0)) return bad("noise_uT", noise_uT, "noise_uT >= 0");
  return {};
}

SyntheticSource::SyntheticSource(const SyntheticSourceOptions& options)
    : options_(options), rng_(options.seed) {
  if (std::string msg = options.Validate(); !msg.empty()) throw std::invalid_argument(msg);
  end_us_ = static_cast<int64_t>(std::llround(options.duration_s * 1e6));
}

McuEvent SyntheticSource::MakeSample(int64_t t_us) {
  const double t = t_us * 1e-6;
  constexpr double kTwoPi = 2 * std::numbers::pi;
  McuEvent e;
  e.time_us = t_us;
  if (options_.mode == SyntheticMode::kMarg) {
    e.kind = McuEvent::Kind::kMarg;
    const double yaw = 0.5 * t;  // rad, slow turn about Z
    const double c = std::cos(yaw), s = std::sin(yaw);
    e.accel_g = {0.1 * c, -0.1 * s, 0.995};
    e.gyro_dps = {0.0, 0.0, common::RadToDeg(0.5)};
    e.mag_uT = {20.0 * c, -20.0 * s, -43.0};
    for (int i = 0; i < 3; ++i) {
      e.accel_g[i] += 0.001 * options_.noise_uT * noise_(rng_);
      e.gyro_dps[i] += 0.01 * options_.noise_uT * noise_(rng_);
      e.mag_uT[i] += options_.noise_uT * noise_(rng_);
    }
    return e;
  }
  e.kind = McuEvent::Kind::kField;
  const double fast = std::sin(kTwoPi * options_.fast_hz * t);
  const double slow = std::sin(kTwoPi * options_.slow_hz * t);
  const bool scan = options_.mode == SyntheticMode::kScan;
  const double a = scan ? 1.0 : 0.0;
  e.field_uT = {120.0 + a * 800.0 * fast, -60.0 + a * 600.0 * slow,
                2500.0 + a * (150.0 * fast * slow)};
  for (double& v : e.field_uT) v += options_.noise_uT * noise_(rng_);
  return e;
}

std::optional<McuEvent> SyntheticSource::Next() {
  const int64_t sample_t =
      static_cast<int64_t>(std::llround(sample_index_ * 1e6 / options_.rate_hz));
  std::optional<int64_t> edge_t;
  if (options_.clock_period_s > 0 && options_.mode != SyntheticMode::kMarg) {
    edge_t = static_cast<int64_t>(
        std::llround((options_.clock_first_s + edge_index_ * options_.clock_period_s) * 1e6));
  }
  const bool sample_ok = end_us_ == 0 || sample_t < end_us_;
  const bool edge_ok = edge_t && (end_us_ == 0 || *edge_t < end_us_);
  if (edge_ok && (!sample_ok || *edge_t <= sample_t)) {
    ++edge_index_;
    McuEvent e;
    e.kind = McuEvent::Kind::kClockEdge;
    e.time_us = *edge_t;
    return e;
  }
  if (!sample_ok) return std::nullopt;
  ++sample_index_;
  return MakeSample(sample_t);
}

ReplaySource::ReplaySource(dataset::HallRecording recording) : recording_(std::move(recording)) {}

std::optional<McuEvent> ReplaySource::Next() {
  const bool have_r = reading_ < recording_.readings.size();
  const bool have_e = edge_ < recording_.clock_edges_us.size();
  if (!have_r && !have_e) return std::nullopt;
  McuEvent e;
  if (have_e &&
      (!have_r || recording_.clock_edges_us[edge_] <= recording_.readings[reading_].mcu_time_us)) {
    e.kind = McuEvent::Kind::kClockEdge;
    e.time_us = recording_.clock_edges_us[edge_++];
    return e;
  }
  const dataset::HallReading& r = recording_.readings[reading_++];
  e.kind = McuEvent::Kind::kField;
  e.time_us = r.mcu_time_us;
  e.field_uT = {r.bx_uT, r.by_uT, r.bz_uT};
  return e;
}

}  // namespace msmcal::sim
