#include "common/number_format.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <limits>
#include <sstream>

namespace msmcal::common {
namespace {

std::string Printf(const char* format, int n, double v) {
  char buf[512];  // DBL_MAX in %f has 309 digits
  std::snprintf(buf, sizeof(buf), format, n, v);
  return buf;
}

std::string Stream(double v, int precision) {
  std::ostringstream os;
  os.precision(precision);
  os << v;
  return os.str();
}

// The formatters replaced printf / ostream code whose text reaches messages and plans: the text
// must stay the same.
TEST(NumberFormatTest, SameTextAsPrintfAndOstream) {
  const double values[] = {0.0,
                           -0.0,
                           1.0,
                           -2.5,
                           0.1,
                           1.0 / 3.0,
                           1234.5678,
                           1e-7,
                           1e6,
                           123456789.0,
                           2e15,
                           -7.25e-300,
                           205.0,
                           0.0001,
                           99999.95,
                           1e21,
                           std::numeric_limits<double>::max(),
                           std::numeric_limits<double>::infinity(),
                           -std::numeric_limits<double>::infinity()};
  for (double v : values) {
    for (int n : {1, 3, 4, 6, 12, 17}) {
      EXPECT_EQ(FormatSignificant(v, n), Printf("%.*g", n, v)) << v << " " << n;
      EXPECT_EQ(FormatSignificant(v, n), Stream(v, n)) << v << " " << n;
    }
    for (int n : {0, 1, 3, 6}) EXPECT_EQ(FormatFixed(v, n), Printf("%.*f", n, v)) << v << " " << n;
  }
  EXPECT_EQ(FormatSignificant(1234.5678, 4), "1235");
  EXPECT_EQ(FormatSignificant(1e-7, 6), "1e-07");
  EXPECT_EQ(FormatFixed(2.0, 3), "2.000");
}

}  // namespace
}  // namespace msmcal::common
