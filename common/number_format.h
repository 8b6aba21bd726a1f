#pragma once
// Numbers for people (messages, console tables, notes), through fmt: the same text as printf's
// "%.<digits>g" / "%.<decimals>f" (and as an ostream with precision(digits)), without a buffer
// or stream per call site. Files that are read back use the lossless forms of common/text_io.h
// (ShortestDouble, YamlDouble) instead.

#include <string>

namespace msmcal::common {

// `digits` significant digits, %g style: FormatSignificant(1234.5678, 4) == "1235",
// FormatSignificant(1e-7, 6) == "1e-07".
std::string FormatSignificant(double value, int digits);
// `decimals` digits after the point: FormatFixed(2.0, 3) == "2.000".
std::string FormatFixed(double value, int decimals);

}  // namespace msmcal::common
