// The twin's hands protocol: parsing (unknown fields ignored, wrong types refused naming the
// field), the round trip through the Unix socket, the state in effect before the answer, refusals
// and an unreachable twin. The twin runs without a camera (no network namespace needed).
#include "simulation/twin/hands_protocol.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "simulation/twin/physical_twin.h"

namespace msmcal::twin {
namespace {

namespace fs = std::filesystem;

constexpr const char* kSetup = R"({"msmcal_setup": 1, "kind": "setup", "block": 3, "of": 24,
 "for": {"step": "step1", "frames": ["step1/0003.png"]}, "camera": "C1", "msm_mounted": false,
 "top_frame_mounted": true,
 "sliding_plate": {"mounted": true, "pose": 2, "distance_mm": 41.5, "tilt_deg": 10.0},
 "beams_unblocked": [1, 3], "drive": "off", "changes": ["move the plate"], "text": "...",
 "future_field": {"anything": [1, 2]}})";

std::string ParseError(const std::string& text) {
  try {
    (void)ParseHandsRequest(text);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(accepted)";
}

TEST(HandsProtocol, ParsesTheSetupIgnoringUnknownFields) {
  const HandsRequest r = ParseHandsRequest(kSetup);
  ASSERT_EQ(r.kind, HandsRequest::Kind::kSetup);
  EXPECT_EQ(r.setup.camera, 1);
  EXPECT_EQ(r.setup.msm_mounted, false);
  EXPECT_EQ(r.setup.top_frame_mounted, true);
  ASSERT_TRUE(r.setup.sliding_plate);
  EXPECT_TRUE(r.setup.sliding_plate->mounted);
  EXPECT_EQ(r.setup.sliding_plate->pose, 2);
  EXPECT_EQ(r.setup.sliding_plate->distance_mm, 41.5);
  EXPECT_EQ(r.setup.sliding_plate->tilt_deg, 10.0);
  EXPECT_EQ(r.setup.beams_unblocked, (std::vector<int>{1, 3}));
  EXPECT_EQ(r.setup.for_step, "step1");
  EXPECT_EQ(r.setup.block, 3);
  EXPECT_EQ(r.setup.of, 24);
  // Round trip through the compact form.
  const HandsRequest again = ParseHandsRequest(FormatHandsRequest(r));
  EXPECT_EQ(FormatHandsRequest(again), FormatHandsRequest(r));
  EXPECT_EQ(again.setup.sliding_plate->distance_mm, 41.5);
}

TEST(HandsProtocol, TruthRequest) {
  const HandsRequest r =
      ParseHandsRequest(R"({"msmcal_setup": 1, "kind": "truth_request", "dir": "/tmp/x/truth"})");
  EXPECT_EQ(r.kind, HandsRequest::Kind::kTruthRequest);
  EXPECT_EQ(r.dir, "/tmp/x/truth");
  EXPECT_NE(ParseError(R"({"msmcal_setup": 1, "kind": "truth_request", "dir": "rel"})")
                .find("dir: expected an absolute path"),
            std::string::npos);
}

TEST(HandsProtocol, RefusesMalformedSetupsNamingTheField) {
  EXPECT_NE(ParseError("{not json").find("not valid JSON"), std::string::npos);
  EXPECT_NE(ParseError(R"({"kind": "setup"})").find("msmcal_setup: missing"), std::string::npos);
  EXPECT_NE(ParseError(R"({"msmcal_setup": 2, "kind": "setup"})").find("msmcal_setup"),
            std::string::npos);
  EXPECT_NE(ParseError(R"({"msmcal_setup": 1, "kind": "dance"})").find("kind:"), std::string::npos);
  EXPECT_NE(ParseError(R"({"msmcal_setup": 1, "kind": "setup", "camera": "C3"})").find("camera:"),
            std::string::npos);
  EXPECT_NE(ParseError(R"({"msmcal_setup": 1, "kind": "setup", "msm_mounted": "yes"})")
                .find("msm_mounted: expected true or false"),
            std::string::npos);
  EXPECT_NE(
      ParseError(
          R"({"msmcal_setup": 1, "kind": "setup", "sliding_plate": {"mounted": true, "pose": "2"}})")
          .find("sliding_plate.pose: expected an integer"),
      std::string::npos);
  EXPECT_NE(ParseError(R"({"msmcal_setup": 1, "kind": "setup", "sliding_plate": {"mounted": true,
                "pose": 1, "distance_mm": "near"}})")
                .find("sliding_plate.distance_mm: expected a number"),
            std::string::npos);
  EXPECT_NE(ParseError(R"({"msmcal_setup": 1, "kind": "setup", "beams_unblocked": [1, "2"]})")
                .find("beams_unblocked[1]"),
            std::string::npos);
  EXPECT_NE(ParseError(R"({"msmcal_setup": 1, "kind": "setup", "beams_unblocked": [0]})")
                .find("beams_unblocked[0]: expected a beam id >= 1"),
            std::string::npos);
  EXPECT_NE(
      ParseError(R"({"msmcal_setup": 1, "kind": "setup", "for": {"step": 1}})").find("for.step"),
      std::string::npos);
}

class TwinHands : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) / ("twin_hands_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    PhysicalTwinOptions o;
    o.camera_address.clear();  // no camera: the hands only
    o.hands_socket = (dir_ / "hands.sock").string();
    twin_ = std::make_unique<PhysicalTwin>(o);
  }
  void TearDown() override {
    twin_.reset();
    fs::remove_all(dir_);
  }
  std::string socket() const { return (dir_ / "hands.sock").string(); }
  fs::path dir_;
  std::unique_ptr<PhysicalTwin> twin_;
};

TEST_F(TwinHands, SetupIsInEffectWhenTheAnswerComes) {
  const TwinState before = twin_->State();
  EXPECT_EQ(before.beams_unblocked, (std::vector<int>{1, 2, 3}));
  EXPECT_FALSE(before.sliding_plate);
  const uint64_t generation = twin_->generation();
  const HandsReply reply = SendHandsRequest(socket(), kSetup, /*timeout_ms=*/5000);
  ASSERT_TRUE(reply.ok) << reply.error;
  EXPECT_EQ(reply.generation, generation + 1);
  // No waiting: the answer means the state is in effect.
  const TwinState s = twin_->State();
  EXPECT_EQ(s.camera, 1);
  EXPECT_FALSE(s.msm_mounted);
  ASSERT_TRUE(s.sliding_plate);
  EXPECT_EQ(s.sliding_plate->pose, 2);
  EXPECT_EQ(s.beams_unblocked, (std::vector<int>{1, 3}));
  EXPECT_EQ(twin_->generation(), reply.generation);

  // A partial set-up changes only what it names.
  const HandsReply r2 = SendHandsRequest(
      socket(), R"({"msmcal_setup": 1, "kind": "setup", "sliding_plate": {"mounted": false}})",
      5000);
  ASSERT_TRUE(r2.ok) << r2.error;
  EXPECT_FALSE(twin_->State().sliding_plate);
  EXPECT_EQ(twin_->State().beams_unblocked, (std::vector<int>{1, 3}));
}

TEST_F(TwinHands, RefusalsComeBackWithTheReason) {
  const HandsReply bad = SendHandsRequest(socket(), R"({"msmcal_setup": 1, "kind": "setup",
      "beams_unblocked": [1, 7]})",
                                          5000);
  EXPECT_FALSE(bad.ok);
  EXPECT_NE(bad.error.find("beam 7 does not exist"), std::string::npos) << bad.error;
  const HandsReply malformed = SendHandsRequest(socket(), R"({"msmcal_setup": 1})", 5000);
  EXPECT_FALSE(malformed.ok);
  EXPECT_NE(malformed.error.find("kind: missing"), std::string::npos) << malformed.error;
  // Nothing was applied.
  EXPECT_EQ(twin_->State().beams_unblocked, (std::vector<int>{1, 2, 3}));
  // Truth before any drive was applied: refused with the reason.
  const HandsReply truth = SendHandsRequest(
      socket(),
      R"({"msmcal_setup": 1, "kind": "truth_request", "dir": ")" + (dir_ / "t").string() + R"("})",
      5000);
  EXPECT_FALSE(truth.ok);
  EXPECT_NE(truth.error.find("no drive and trigger table applied"), std::string::npos)
      << truth.error;
}

TEST(TwinHandsClient, UnreachableTwinIsAClearError) {
  const std::string path = (fs::path(::testing::TempDir()) / "no_twin_here.sock").string();
  try {
    (void)SendHandsRequest(path, kSetup, 1000);
    FAIL() << "connected to nothing";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot connect"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace msmcal::twin
