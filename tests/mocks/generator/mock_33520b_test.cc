#include "mocks/generator/mock_33520b.h"

#include <gtest/gtest.h>

#include <cmath>

namespace msmcal::sim {
namespace {

class Mock33520BTest : public ::testing::Test {
 protected:
  int64_t now_ns_ = 1'000'000'000;
  Mock33520B unit_{UnitOptions{}, [this] { return now_ns_; }};
  std::string Q(const std::string& m) { return unit_.Process(m); }
};

TEST_F(Mock33520BTest, IdentityAndEmptyErrorQueue) {
  EXPECT_EQ(Q("*IDN?"), "Agilent Technologies,33522B,MY52000001,3.05-1.19-2.00-52-00");
  EXPECT_EQ(Q("SYST:ERR?"), "+0,\"No error\"");
  EXPECT_EQ(Q("*idn?;*opc?"), "Agilent Technologies,33522B,MY52000001,3.05-1.19-2.00-52-00;1");
}

TEST_F(Mock33520BTest, ErrorQueueFifoOverflowAndClear) {
  Q("BOGUS");
  Q("FREQ 1 FOO");
  EXPECT_EQ(Q("SYST:ERR?"), "-113,\"Undefined header\"");
  EXPECT_EQ(Q("SYSTEM:ERROR:NEXT?"), "-131,\"Invalid suffix\"");
  EXPECT_EQ(Q("SYST:ERR?"), "+0,\"No error\"");
  for (int i = 0; i < 25; ++i) Q("BOGUS");
  EXPECT_EQ(unit_.ErrorCount(), 20u);
  for (int i = 0; i < 19; ++i) EXPECT_EQ(Q("SYST:ERR?"), "-113,\"Undefined header\"");
  EXPECT_EQ(Q("SYST:ERR?"), "-350,\"Queue overflow\"");
  Q("BOGUS");
  Q("*RST");
  EXPECT_EQ(unit_.ErrorCount(), 1u);  // *RST keeps the queue
  Q("*CLS");
  EXPECT_EQ(unit_.ErrorCount(), 0u);
}

TEST_F(Mock33520BTest, ChannelStateUnitsAndRanges) {
  Q("SOUR2:FUNC SQU;FREQ 2 KHZ;VOLT 500 MV;VOLT:OFFS 0.1;:OUTP2:LOAD INF");
  EXPECT_EQ(Q("SOUR2:FUNC?"), "SQU");
  EXPECT_EQ(Q("SOURCE2:FREQUENCY?"), "+2.0000000000000E+03");
  EXPECT_EQ(Q("SOUR2:VOLT?;VOLT:OFFS?"), "+5.0000000000000E-01;+1.0000000000000E-01");
  EXPECT_EQ(Q("OUTP2:LOAD?"), "+9.9000000000000E+37");
  EXPECT_EQ(Q("FREQ?"), "+1.0000000000000E+03");  // channel 1 untouched
  Q("FREQ 40 MHZ");
  EXPECT_EQ(Q("SYST:ERR?"), "-222,\"Data out of range;value clipped to upper limit\"");
  EXPECT_EQ(Q("FREQ?"), "+3.0000000000000E+07");
  Q("FREQ MIN");
  EXPECT_EQ(Q("FREQ?"), "+1.0000000000000E-06");
  Q("SOUR3:FREQ 1");
  EXPECT_EQ(Q("SYST:ERR?"), "-114,\"Header suffix out of range\"");
  Q("VOLT 9;VOLT:OFFS 3");  // 4.5 + 3 > 5 V into 50 ohm
  EXPECT_EQ(Q("SYST:ERR?").substr(0, 4), "-221");
  Q("*RST");
  EXPECT_EQ(Q("SOUR2:FUNC?;:OUTP2?"), "SIN;0");
}

TEST_F(Mock33520BTest, ArbUploadBigAndLittleEndianAndBadBlock) {
  std::string payload;
  for (int16_t v : {0, 32767, -32767, 256, 0, 1, 2, 3}) {
    payload.push_back(static_cast<char>((static_cast<uint16_t>(v) >> 8) & 0xFF));
    payload.push_back(static_cast<char>(static_cast<uint16_t>(v) & 0xFF));
  }
  Q("DATA:VOL:CLE;:FORM:BORD NORM;:DATA:ARB:DAC TRIG,#216" + payload);
  EXPECT_EQ(Q("SYST:ERR?"), "+0,\"No error\"");
  EXPECT_EQ(Q("DATA:ATTR:POIN? TRIG"), "+8");
  Q("FUNC ARB;:FUNC:ARB TRIG;:FUNC:ARB:SRAT 8;PTP 2;:OUTP1 ON");
  EXPECT_EQ(Q("SYST:ERR?"), "+0,\"No error\"");
  EXPECT_EQ(Q("FUNC:ARB?"), "\"TRIG\"");
  // At 8 Sa/s sample k plays over [k/8, (k+1)/8) s.
  EXPECT_NEAR(unit_.SignalAt(1, now_ns_ + 125'000'000 + 1), 1.0, 1e-12);
  EXPECT_NEAR(unit_.SignalAt(1, now_ns_ + 250'000'000 + 1), -1.0, 1e-12);
  Q("DATA:ARB:DAC BAD,#213abc");
  EXPECT_EQ(Q("SYST:ERR?"), "-161,\"Invalid block data\"");
  Q("FUNC:ARB NOPE");
  EXPECT_EQ(Q("SYST:ERR?").substr(0, 4), "-224");
}

TEST_F(Mock33520BTest, BurstWaitsForBusTriggerAndForwardsTriggerOut) {
  Mock33520B slave(UnitOptions{}, [this] { return now_ns_; });
  unit_.AddTriggerOutTarget(&slave);
  slave.Process("BURS:STAT ON;:TRIG1:SOUR EXT;:OUTP1 ON");
  Q("BURS:STAT ON;:TRIG1:SOUR BUS;:OUTP:TRIG ON;:OUTP1 ON");
  EXPECT_FALSE(unit_.Signal(1).running);
  EXPECT_FALSE(slave.Signal(1).running);
  now_ns_ += 5'000'000;
  Q("*TRG");
  EXPECT_TRUE(unit_.Signal(1).running);
  EXPECT_TRUE(slave.Signal(1).running);
  EXPECT_EQ(unit_.Signal(1).start_time_ns, now_ns_);
  EXPECT_EQ(slave.Signal(1).start_time_ns, now_ns_);
  // 1 kHz, 0.1 Vpp sine: a quarter period after the trigger it peaks.
  EXPECT_NEAR(unit_.SignalAt(1, now_ns_ + 250'000), 0.05, 1e-9);
}

TEST_F(Mock33520BTest, ExternalReferenceNeedsWiring) {
  bool wired = false;
  unit_.SetReferenceInput([&] { return wired; });
  Q("ROSC:SOUR EXT");
  EXPECT_EQ(Q("ROSC:SOUR?;:ROSC:SOUR:CURR?"), "EXT;INT");
  wired = true;
  EXPECT_EQ(Q("ROSC:SOUR:CURR?"), "EXT");
}

}  // namespace
}  // namespace msmcal::sim
