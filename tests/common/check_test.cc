#include "common/check.h"

#include <gtest/gtest.h>

#include <vector>

namespace msmcal::common {
namespace {

TEST(CheckTest, TrueConditionDoesNothingAndDoesNotEvaluateTheMessage) {
  int evaluated = 0;
  auto count = [&] { return ++evaluated; };
  MSMCAL_CHECK(1 + 1 == 2) << "never " << count();
  EXPECT_EQ(evaluated, 0);
}

TEST(CheckDeathTest, FalseConditionPrintsFileLineConditionAndMessageAndAborts) {
  const std::vector<int> v(3);
  const size_t j = 5;
  EXPECT_DEATH(MSMCAL_CHECK(j < v.size()) << "slot " << j << " of " << v.size(),
               "check_test\\.cc:[0-9]+: check failed: j < v\\.size\\(\\): slot 5 of 3");
}

TEST(CheckDeathTest, WithoutAMessage) {
  const bool ready = false;
  EXPECT_DEATH(MSMCAL_CHECK(ready), "check failed: ready\n");
}

TEST(CheckDeathTest, UsableAsAStatementInAnUnbracedIf) {
  const int n = -1;
  auto run = [&] {
    if (n < 0)
      MSMCAL_CHECK(n >= 0) << "n = " << n;
    else
      MSMCAL_CHECK(false) << "the else branch";
  };
  EXPECT_DEATH(run(), "check failed: n >= 0: n = -1");
}

}  // namespace
}  // namespace msmcal::common
