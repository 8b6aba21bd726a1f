// The 33500 driver against the mock over loopback.
#include <gtest/gtest.h>

#include <cmath>

#include "drivers/generator/function_generator.h"
#include "mocks/generator/mock_server.h"

namespace msmcal::gen {
namespace {

ChannelLimits CoilLimits() {
  ChannelLimits l;
  l.role = "fast_coil";
  l.max_vpp = 4.0;
  l.max_abs_offset_v = 0.5;
  l.min_frequency_hz = 1000;
  l.max_frequency_hz = 1500;
  return l;
}

class Keysight33500Test : public ::testing::Test {
 protected:
  void Start(const std::string& identity) {
    sim::UnitOptions u;
    u.identity = identity;
    unit_ = std::make_unique<sim::Mock33520B>(u, nullptr);
    server_ = std::make_unique<sim::MockGeneratorServer>(*unit_, 0);
    server_->Start();
  }
  Keysight33500Options Options() {
    Keysight33500Options o;
    o.name = "unit1";
    o.link.port = server_->port();
    o.link.io_timeout_ms = 500;
    o.limits[0] = CoilLimits();
    return o;  // channel 2 keeps zero limits: nothing may be driven there
  }
  std::unique_ptr<sim::Mock33520B> unit_;
  std::unique_ptr<sim::MockGeneratorServer> server_;
};

TEST_F(Keysight33500Test, AcceptsAgilentAndKeysightIdentities) {
  for (const char* id :
       {"Agilent Technologies,33522B,MY1,3.05", "Keysight Technologies,33520B,MY2,4.0",
        "Agilent Technologies,33511B,MY3,1.0"}) {
    Start(id);
    auto g = OpenKeysight33500(Options());
    EXPECT_EQ(g->Identify()->manufacturer, std::string(id).substr(0, std::string(id).find(',')));
  }
}

TEST_F(Keysight33500Test, RefusesOtherInstruments) {
  for (const char* id : {"Rigol Technologies,DG1022Z,DG1,1.0", "Keysight Technologies,34461A,MY,1",
                         "Agilent Technologies,33250A,0,1"}) {
    Start(id);
    try {
      OpenKeysight33500(Options());
      FAIL() << id;
    } catch (const GeneratorError& e) {
      EXPECT_EQ(e.kind(), GeneratorError::Kind::kIdentity);
      EXPECT_NE(std::string(e.what()).find("not an Agilent/Keysight 33500-series"),
                std::string::npos);
    }
  }
}

TEST_F(Keysight33500Test, ConfiguresSineAndReadsBackState) {
  Start("Keysight Technologies,33520B,MY2,4.0");
  auto g = OpenKeysight33500(Options());
  ASSERT_TRUE(g->Reset());
  ChannelSetup s;
  s.frequency_hz = 1234.5;
  s.amplitude_vpp = 2.5;
  s.offset_v = -0.25;
  s.phase_deg = 30;
  ASSERT_TRUE(g->ConfigureChannel(1, s));
  ASSERT_TRUE(g->SetOutput(1, true));
  const sim::ChannelSignal c = unit_->Signal(1);
  EXPECT_EQ(c.function, sim::Function::kSin);
  EXPECT_DOUBLE_EQ(c.frequency_hz, 1234.5);
  EXPECT_DOUBLE_EQ(c.amplitude_vpp, 2.5);
  EXPECT_DOUBLE_EQ(c.offset_v, -0.25);
  EXPECT_DOUBLE_EQ(c.phase_deg, 30);
  EXPECT_DOUBLE_EQ(c.load_ohm, 50);
  EXPECT_TRUE(c.output_on);
  EXPECT_TRUE(g->SafeState());
  EXPECT_FALSE(unit_->AnyOutputOn());
}

// The instrument drops the connection under the safe state's OUTP OFF (fault campaign row
// scpi-drop-safe-state): SafeState() tries again on a new connection and confirms.
TEST_F(Keysight33500Test, SafeStateConfirmsOnANewConnectionWhenTheOpenOneIsDropped) {
  Start("Keysight Technologies,33520B,MY2,4.0");
  auto g = OpenKeysight33500(Options());
  ASSERT_TRUE(g->SetOutput(1, true));
  ASSERT_TRUE(unit_->AnyOutputOn());
  const uint64_t connections = server_->ConnectionsAccepted();
  server_->InjectFault(sim::ParseFault("drop,match=OUTP1 OFF"));
  EXPECT_TRUE(g->SafeState());
  EXPECT_FALSE(unit_->AnyOutputOn());
  EXPECT_EQ(server_->Stats().faults_applied, 1u);
  EXPECT_EQ(server_->ConnectionsAccepted(), connections + 1);
}

TEST_F(Keysight33500Test, LimitsAreRefusedBeforeAnythingIsSent) {
  Start("Keysight Technologies,33520B,MY2,4.0");
  std::vector<std::string> sent;
  auto g = OpenKeysight33500(Options(), [&](const scpi::TranscriptEntry& e) {
    if (e.to_instrument) sent.push_back(e.text);
  });
  const size_t before = sent.size();
  ChannelSetup s;
  s.frequency_hz = 1200;
  s.amplitude_vpp = 4.5;
  const common::Status refused = g->ConfigureChannel(1, s);
  EXPECT_FALSE(refused);
  EXPECT_EQ(refused.code, common::StatusCode::kRefused);
  EXPECT_EQ(refused.message,
            "refused: unit1.ch1 (fast_coil): amplitude_vpp = 4.5 outside the limit [0, 4] Vpp");
  s.amplitude_vpp = 1.0;
  s.frequency_hz = 999;
  EXPECT_EQ(g->ConfigureChannel(1, s).code, common::StatusCode::kRefused);
  s.frequency_hz = 1200;
  s.offset_v = 0.6;
  EXPECT_EQ(g->ConfigureChannel(1, s).code, common::StatusCode::kRefused);
  s.offset_v = 0;
  // Channel 2: no limits configured.
  EXPECT_EQ(g->ConfigureChannel(2, s).code, common::StatusCode::kRefused);
  EXPECT_EQ(sent.size(), before);
  EXPECT_DOUBLE_EQ(unit_->Signal(1).frequency_hz, 1000.0);  // untouched
}

TEST_F(Keysight33500Test, ArbUploadLandsSampleExact) {
  Start("Keysight Technologies,33520B,MY2,4.0");
  Keysight33500Options o = Options();
  o.limits[1] = {"laser_trigger", 5.0, 2.5, 0.01, 1e3, 0.2};
  auto g = OpenKeysight33500(o);
  ASSERT_TRUE(g->Reset());
  ChannelSetup s;
  s.waveform = Waveform::kArb;
  s.arb_name = "TRIG";
  s.arb_samples.assign(1000, -32767);
  for (int k : {10, 0x0A0A % 1000, 500}) s.arb_samples[k] = 32767;
  s.arb_samples[3] = 0x0A0A;  // bytes equal to '\n' in the block
  s.arb_sample_rate_sps = 100e3;
  s.amplitude_vpp = 5;
  s.offset_v = 2.5;
  s.load_ohm = kHighZ;
  ASSERT_TRUE(g->ConfigureChannel(2, s));
  const sim::ChannelSignal c = unit_->Signal(2);
  EXPECT_EQ(c.function, sim::Function::kArb);
  ASSERT_TRUE(c.arb_samples);
  EXPECT_EQ(*c.arb_samples, s.arb_samples);
  EXPECT_DOUBLE_EQ(c.arb_sample_rate_sps, 100e3);
  EXPECT_DOUBLE_EQ(c.arb_ptpeak_v, 5);
  EXPECT_DOUBLE_EQ(c.offset_v, 2.5);
  EXPECT_TRUE(std::isinf(c.load_ohm));
  // A duty above the laser limit is refused.
  s.arb_samples.assign(1000, 32767);
  EXPECT_EQ(g->ConfigureChannel(2, s).code, common::StatusCode::kRefused);
}

// An infinite limit never reaches the wire: the driver refuses it before connecting, so no
// `SOUR1:VOLT 1000` is ever sent for the instrument to clip.
TEST_F(Keysight33500Test, AnInfiniteLimitIsRefusedBeforeAnyCommand) {
  Start("Keysight Technologies,33520B,MY2,4.0");
  Keysight33500Options o = Options();
  o.limits[0].max_vpp = kHighZ;
  try {
    OpenKeysight33500(o);
    FAIL() << "an infinite limit must be refused";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("unit1.channels.1.limits.max_vpp = inf: must be finite"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(server_->ConnectionsAccepted(), 0u);
}

// The wire's failures come back as the Status of the call that met them, with their code: a
// garbled reply (kProtocol), a connection dropped under a command (kUnavailable), and the
// instrument's error queue (kDeviceError: a command the 33520B does not know).
TEST_F(Keysight33500Test, WireAndInstrumentFailuresAreStatusesWithTheirCode) {
  Start("Keysight Technologies,33520B,MY2,4.0");
  auto g = OpenKeysight33500(Options());
  server_->InjectFault(sim::ParseFault("garbage,match=ROSC:SOUR:CURR?"));
  const common::Result<bool> locked = g->ReferenceLocked();
  ASSERT_FALSE(locked.ok());
  EXPECT_EQ(locked.status().code, common::StatusCode::kProtocol) << locked.status().message;
  EXPECT_TRUE(g->SafeState());  // reconnects

  server_->InjectFault(sim::ParseFault("drop,match=OUTP1 ON"));
  const common::Status dropped = g->SetOutput(1, true);
  EXPECT_FALSE(dropped);
  EXPECT_EQ(dropped.code, common::StatusCode::kUnavailable) << dropped.message;
  EXPECT_NE(dropped.message.find("127.0.0.1"), std::string::npos) << dropped.message;
  EXPECT_FALSE(unit_->AnyOutputOn());
  EXPECT_TRUE(g->SafeState());
  ASSERT_TRUE(g->Reset());
  ASSERT_TRUE(g->SynchronizePhase());
}

}  // namespace
}  // namespace msmcal::gen
