#pragma once
// Angle units, defined once. Conversions multiply by the constant (x * kRadPerDeg), so a value
// converted here is bit-identical to the local constants these replace; a division by the
// reciprocal ("deg / kDegPerRad") is written as such where that rounding is what a file holds.

#include <numbers>

namespace msmcal::common {

inline constexpr double kDegPerRad = 180.0 / std::numbers::pi;  // 57.29577951308232
inline constexpr double kRadPerDeg = std::numbers::pi / 180.0;  // 0.017453292519943295

constexpr double DegToRad(double deg) { return deg * kRadPerDeg; }
constexpr double RadToDeg(double rad) { return rad * kDegPerRad; }

}  // namespace msmcal::common
