#pragma once
// What the mock MCU streams: a pull interface over events in MCU-time order, a deterministic
// synthetic source for tests and demos, and a replay source over a recorded session.

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <random>
#include <string>

#include "processing/dataset/recording.h"

namespace msmcal::sim {

// One thing the MCU would observe. time_us is the MCU's clock had it never reset (the mock maps it
// to time since the last boot). Field values are the physical field in uT; the mock quantises them
// with the current gain/resolution.
struct McuEvent {
  enum class Kind { kField, kClockEdge, kMarg };
  Kind kind = Kind::kField;
  int64_t time_us = 0;
  std::array<double, 3> field_uT{};  // kField
  std::array<double, 3> accel_g{};   // kMarg
  std::array<double, 3> gyro_dps{};  // kMarg
  std::array<double, 3> mag_uT{};    // kMarg
};

// Yields events in non-decreasing time_us; nullopt when exhausted (then stays exhausted).
class McuDataSource {
 public:
  virtual ~McuDataSource() = default;
  virtual std::optional<McuEvent> Next() = 0;
};

enum class SyntheticMode { kScan, kBackground, kMarg };
// "scan" | "background" | "marg"; throws std::invalid_argument naming the value otherwise.
SyntheticMode ParseSyntheticMode(const std::string& name);

struct SyntheticSourceOptions {
  SyntheticMode mode = SyntheticMode::kScan;
  double rate_hz = 1000;            // readings per second (divides 1e6 exactly is not required)
  double clock_period_s = 0.5;      // clock edges (pattern phase 0) every period; 0: none
  double clock_first_s = 0.000123;  // first edge time
  double duration_s = 60;           // MCU time covered; 0: endless
  double fast_hz = 97.0, slow_hz = 2.0;  // scan drive frequencies
  double noise_uT = 2.0;                 // white noise sigma per axis
  uint64_t seed = 1;

  std::string Validate() const;  // empty when valid; else field, value, constraint
};

// Deterministic (same options and seed -> same events): a sinusoidal scan field (fast + slow
// components around a static offset), a static background field, or a MARG board rotating slowly
// (accelerometer sees gravity, magnetometer a constant earth field, both rotating).
class SyntheticSource final : public McuDataSource {
 public:
  explicit SyntheticSource(const SyntheticSourceOptions& options);
  std::optional<McuEvent> Next() override;

 private:
  McuEvent MakeSample(int64_t t_us);
  SyntheticSourceOptions options_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> noise_{0.0, 1.0};
  int64_t sample_index_ = 0;
  int64_t edge_index_ = 0;
  int64_t end_us_ = 0;  // 0: endless
};

// Replays a recorded Hall session: readings and clock edges merged by time (edges first on ties).
class ReplaySource final : public McuDataSource {
 public:
  explicit ReplaySource(dataset::HallRecording recording);
  std::optional<McuEvent> Next() override;

 private:
  dataset::HallRecording recording_;
  size_t reading_ = 0;
  size_t edge_ = 0;
};

}  // namespace msmcal::sim
