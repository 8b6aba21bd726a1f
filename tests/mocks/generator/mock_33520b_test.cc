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

// A compound line of N units costs O(N) parsing steps, whatever its headers: relative headers
// that would nest the path ever deeper ("A:B;C:D;E:F;...", quadratic before) and ordinary ones.
TEST_F(Mock33520BTest, CompoundLineParsesInLinearTime) {
  auto work_for = [this](const std::string& unit_text, int n) {
    std::string line;
    for (int i = 0; i < n; ++i) line += (i ? ";" : "") + unit_text;
    const uint64_t before = unit_.ParseWork();
    const std::string reply = Q(line);
    return std::pair(unit_.ParseWork() - before, reply);
  };
  for (const char* unit_text : {"SOUR1:FREQ 1000", "PHAS:ADJ 1", "VOLT?"}) {
    const auto [small, r1] = work_for(unit_text, 1024);
    const auto [large, r2] = work_for(unit_text, 32768);
    EXPECT_LE(large, 40 * small) << unit_text;  // 32x the units, about 32x the work
    EXPECT_GE(large, 24 * small) << unit_text;
    Q("*CLS");  // the nesting headers are undefined
  }
  // The path rule still holds over a long line, and every query of it is answered.
  const auto [work, reply] = work_for(":SOUR2:FREQ 2000;FREQ?", 32768);
  EXPECT_EQ(reply.size(), 32768 * std::string("+2.0000000000000E+03;").size() - 1);
  EXPECT_EQ(Q("SYST:ERR?"), "+0,\"No error\"");
  EXPECT_LT(work, 40 * 32768 * 32u);
}

TEST_F(Mock33520BTest, OversizedResponseIsDroppedWithQueryDeadlocked) {
  UnitOptions o;
  o.max_response_bytes = 100;
  Mock33520B unit(o, [this] { return now_ns_; });
  std::string line = "*IDN?";
  for (int i = 0; i < 5; ++i) line += ";*IDN?";
  const std::string reply = unit.Process(line);  // six 60-byte replies, one fits
  EXPECT_EQ(reply, o.identity);
  EXPECT_EQ(unit.Process("SYST:ERR?"), "-430,\"Query DEADLOCKED\"");
  EXPECT_EQ(unit.Process("SYST:ERR?"), "+0,\"No error\"");
}

TEST_F(Mock33520BTest, HighLowLevelsAreAmplitudeAndOffset) {
  Q("VOLT 2;VOLT:OFFS 0.5");
  EXPECT_EQ(Q("VOLT:HIGH?;LOW?"), "+1.5000000000000E+00;-5.0000000000000E-01");
  Q("VOLT:HIGH 3");  // keeps the low level
  EXPECT_EQ(Q("VOLT?;VOLT:OFFS?"), "+3.5000000000000E+00;+1.2500000000000E+00");
  Q("SOURCE1:VOLTAGE:LEVEL:IMMEDIATE:LOW -2");
  EXPECT_EQ(Q("VOLT?;VOLT:OFFS?"), "+5.0000000000000E+00;+5.0000000000000E-01");
  Q("VOLT:LOW 4");  // above the high level: refused, nothing changes
  EXPECT_EQ(Q("SYST:ERR?").substr(0, 5), "-221,");
  Q("VOLT:HIGH 6");  // beyond 5 V into 50 ohm: clipped
  EXPECT_EQ(Q("SYST:ERR?").substr(0, 5), "-222,");
  EXPECT_EQ(Q("VOLT:HIGH?;HIGH? MAX"), "+5.0000000000000E+00;+5.0000000000000E+00");
  EXPECT_EQ(Q("SYST:ERR?"), "+0,\"No error\"");
}

TEST_F(Mock33520BTest, VoltageUnitsConvertTheAmplitude) {
  Q("VOLT 2");
  Q("VOLT:UNIT VRMS");
  EXPECT_NEAR(std::stod(Q("VOLT?")), 2 / (2 * std::sqrt(2.0)), 1e-12);
  Q("VOLT 1");  // 1 Vrms sine
  EXPECT_NEAR(unit_.Signal(1).amplitude_vpp, 2 * std::sqrt(2.0), 1e-12);
  Q("VOLT:UNIT DBM;:VOLT 10");  // 10 dBm into 50 ohm: 0.707 Vrms
  EXPECT_NEAR(unit_.Signal(1).amplitude_vpp, std::sqrt(0.01 * 50) * 2 * std::sqrt(2.0), 1e-9);
  Q("VOLT 200 MVPP");  // a suffix overrides the unit
  EXPECT_NEAR(unit_.Signal(1).amplitude_vpp, 0.2, 1e-12);
  Q("OUTP:LOAD INF");  // dBm needs a finite load: back to Vpp
  EXPECT_EQ(Q("VOLT:UNIT?"), "VPP");
  Q("VOLT:UNIT DBM");
  EXPECT_EQ(Q("SYST:ERR?").substr(0, 5), "-221,");
}

TEST_F(Mock33520BTest, PulseHoldsWidthOrDutyCycleAndStaysRealisable) {
  Q("FUNC PULS;FREQ 1000;:FUNC:PULS:WIDT 200 US;TRAN 50 NS");
  EXPECT_EQ(Q("FUNC:PULS:DCYC?;PER?;TRAN?;TRAN:TRA?"),
            "+2.0000000000000E+01;+1.0000000000000E-03;+5.0000000000000E-08;"
            "+5.0000000000000E-08");
  Q("FUNC:PULS:PER 2E-3");  // HOLD WIDTh: the width stays, the duty cycle halves
  EXPECT_EQ(Q("FREQ?;:FUNC:PULS:WIDT?;DCYC?"),
            "+5.0000000000000E+02;+2.0000000000000E-04;+1.0000000000000E+01");
  Q("FUNC:PULS:HOLD DCYCLE;:FREQ 1000");  // HOLD DCYCle: the duty cycle stays
  EXPECT_EQ(Q("FUNC:PULS:HOLD?;WIDT?;DCYC?"), "DCYC;+1.0000000000000E-04;+1.0000000000000E+01");
  Q("FUNC:PULS:WIDT 2E-3");  // wider than the period: adjusted, -221
  EXPECT_EQ(Q("SYST:ERR?").substr(0, 5), "-221,");
  EXPECT_NEAR(std::stod(Q("FUNC:PULS:WIDT?")), 1e-3 - 16e-9, 1e-15);
  Q("FUNC:PULS:WIDT 20 NS;TRAN:LEAD 1 US");  // edges give way to a narrow pulse
  EXPECT_EQ(Q("SYST:ERR?").substr(0, 5), "-221,");
  EXPECT_NEAR(std::stod(Q("FUNC:PULS:TRAN:LEAD?")), 0.625 * 20e-9, 1e-18);
  Q("FUNC:PULS:TRAN 5 US");
  EXPECT_EQ(Q("SYST:ERR?"), "-222,\"Data out of range;value clipped to upper limit\"");
  Q("*CLS");
  // The waveform: high for the width.
  Q("*RST;:FUNC PULS;FREQ 1000;:FUNC:PULS:WIDT 250 US;:OUTP1 ON;:VOLT 2");
  EXPECT_NEAR(unit_.SignalAt(1, now_ns_ + 100'000), 1.0, 1e-12);
  EXPECT_NEAR(unit_.SignalAt(1, now_ns_ + 300'000), -1.0, 1e-12);
}

TEST_F(Mock33520BTest, FiniteBurstRunsNCyclesThenIdles) {
  Q("FREQ 1000;VOLT 2;:BURS:MODE TRIG;NCYC 3;STAT ON;:TRIG:SOUR BUS;:OUTP ON");
  EXPECT_EQ(Q("BURS:NCYC?;MODE?;INT:PER?"), "+3.0000000000000E+00;TRIG;+1.0000000000000E-02");
  now_ns_ += 1'000'000;
  Q("*TRG");
  EXPECT_NEAR(unit_.SignalAt(1, now_ns_ + 2'250'000), 1.0, 1e-9);  // third cycle's peak
  EXPECT_NEAR(unit_.SignalAt(1, now_ns_ + 3'250'000), 0.0, 1e-9);  // done: idle level
  // Internal trigger: the burst repeats every burst period; a period too short is raised.
  Q("BURS:INT:PER 2 MS");
  EXPECT_EQ(Q("SYST:ERR?").substr(0, 5), "-221,");
  EXPECT_NEAR(std::stod(Q("BURS:INT:PER?")), 3e-3 + 1e-6, 1e-15);
  Q("BURS:INT:PER 10 MS;:TRIG:SOUR IMM;:BURS:STAT OFF;STAT ON");
  EXPECT_NEAR(unit_.SignalAt(1, now_ns_ + 10'250'000), 1.0, 1e-9);
  EXPECT_NEAR(unit_.SignalAt(1, now_ns_ + 15'250'000), 0.0, 1e-9);
  Q("BURS:NCYC INF");
  EXPECT_EQ(Q("BURS:NCYC?"), "+9.9000000000000E+37");
  Q("BURS:MODE GAT;:BURS:NCYC 0");
  EXPECT_EQ(Q("SYST:ERR?").substr(0, 5), "-222,");
  EXPECT_EQ(Q("BURS:MODE?;NCYC?"), "GAT;+1.0000000000000E+00");
  Q("FUNC DC");  // no DC in burst mode
  EXPECT_EQ(Q("SYST:ERR?").substr(0, 5), "-221,");
}

TEST_F(Mock33520BTest, AngleUnitsAndInformationQueries) {
  Q("FREQ 1000;:UNIT:ANGL RAD;:PHAS 1.5707963267948966");
  EXPECT_NEAR(unit_.Signal(1).phase_deg, 90.0, 1e-9);
  Q("UNIT:ANGLE SECOND;:BURS:PHAS 0.5 MS");  // half a period
  EXPECT_NEAR(unit_.Signal(1).burst_phase_deg, 180.0, 1e-9);
  EXPECT_EQ(Q("UNIT:ANGL?;:BURS:PHAS?"), "SEC;+5.0000000000000E-04");
  Q("UNIT:ANGL DEF;:PHAS 90 DEG");
  EXPECT_EQ(Q("UNIT:ANGL?;:PHAS?"), "DEG;+9.0000000000000E+01");
  EXPECT_EQ(Q("SYST:VERS?;:*TST?"), "1999.0;+0");
  Q("DISP:TEXT \"HELLO; WORLD\";:*ESE 36");
  EXPECT_EQ(Q("DISP:TEXT?;:*ESE?"), "\"HELLO; WORLD\";+36");
  Q("FUNC TRIANGLE;:FREQ 1 MHZ");  // triangles stop at 200 kHz
  EXPECT_EQ(Q("SYST:ERR?"), "-222,\"Data out of range;value clipped to upper limit\"");
  EXPECT_EQ(Q("FUNC?;FREQ?"), "TRI;+2.0000000000000E+05");
  EXPECT_EQ(Q("SYST:ERR?"), "+0,\"No error\"");
}

}  // namespace
}  // namespace msmcal::sim
