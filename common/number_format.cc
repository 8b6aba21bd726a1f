#include "common/number_format.h"

#include <fmt/format.h>

namespace msmcal::common {

std::string FormatSignificant(double value, int digits) {
  return fmt::format("{:.{}g}", value, digits);
}

std::string FormatFixed(double value, int decimals) {
  return fmt::format("{:.{}f}", value, decimals);
}

}  // namespace msmcal::common
