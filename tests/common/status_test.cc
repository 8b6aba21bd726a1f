#include "common/status.h"

#include <gtest/gtest.h>

#include <string>

namespace msmcal::common {
namespace {

TEST(StatusTest, OkAndErrorsCarryTheirCodeAndMessage) {
  const Status ok = Status::Ok();
  EXPECT_TRUE(ok);
  EXPECT_EQ(ok.code, StatusCode::kOk);
  const Status e = Status::Error("unit1: OUTP1 ON: no reply within 2000 ms", StatusCode::kTimeout);
  EXPECT_FALSE(e);
  EXPECT_EQ(e.code, StatusCode::kTimeout);
  EXPECT_STREQ(StatusCodeName(e.code), "timeout");
  // An error made with kOk is still an error (a device error).
  EXPECT_EQ(Status::Error("x", StatusCode::kOk).code, StatusCode::kDeviceError);
  // Aggregate form of the Hall MCU's replies: {ok, message}.
  const Status agg{false, "identify: rejected"};
  EXPECT_FALSE(agg);
}

TEST(StatusTest, AResultHoldsAValueOrTheStatusThatSaysWhyNot) {
  const Result<std::string> v = std::string("MEM");
  ASSERT_TRUE(v.ok());
  EXPECT_EQ(*v, "MEM");
  EXPECT_EQ(v->size(), 3u);
  EXPECT_TRUE(v.status());
  const Result<bool> none = Status::Error("unit2: garbled reply", StatusCode::kProtocol);
  EXPECT_FALSE(none.ok());
  EXPECT_EQ(none.status().code, StatusCode::kProtocol);
  EXPECT_TRUE(none.value_or(true));
  // An ok Status without a value is not a value.
  const Result<int> odd = Status::Ok();
  EXPECT_FALSE(odd.ok());
  EXPECT_FALSE(odd.status());
}

}  // namespace
}  // namespace msmcal::common
