#include "mocks/generator/scpi_parser.h"

#include <gtest/gtest.h>

namespace msmcal::sim {
namespace {

TEST(ScpiParserTest, MatchesShortLongOptionalAndSuffix) {
  const char* p = "[SOURce#:]FREQuency[:CW]";
  EXPECT_EQ(*MatchHeader(p, {"FREQ"}), std::vector<int>{1});
  EXPECT_EQ(*MatchHeader(p, {"frequency"}), std::vector<int>{1});
  EXPECT_EQ(*MatchHeader(p, {"SOUR2", "FREQ"}), std::vector<int>{2});
  EXPECT_EQ(*MatchHeader(p, {"source1", "Freq", "cw"}), std::vector<int>{1});
  EXPECT_FALSE(MatchHeader(p, {"FRE"}));
  EXPECT_FALSE(MatchHeader(p, {"FREQU"}));  // neither short nor long form
  EXPECT_FALSE(MatchHeader(p, {"SOUR", "VOLT"}));
  EXPECT_EQ(*MatchHeader("OUTPut#[:STATe]", {"OUTP2"}), std::vector<int>{2});
  EXPECT_EQ(*MatchHeader("OUTPut#[:STATe]", {"OUTPUT", "STAT"}), std::vector<int>{1});
}

TEST(ScpiParserTest, CompoundMessageFollowsPathRules) {
  const SplitResult r = SplitProgramMessage("SOUR2:FREQ 1 KHZ;VOLT 0.5;:OUTP2 ON;*OPC?");
  ASSERT_FALSE(r.failure);
  ASSERT_EQ(r.units.size(), 4u);
  std::vector<std::string> path;
  EXPECT_EQ(ResolvePath(r.units[0], path), (std::vector<std::string>{"SOUR2", "FREQ"}));
  EXPECT_EQ(ResolvePath(r.units[1], path), (std::vector<std::string>{"SOUR2", "VOLT"}));
  EXPECT_EQ(ResolvePath(r.units[2], path), (std::vector<std::string>{"OUTP2"}));
  EXPECT_EQ(ResolvePath(r.units[3], path), (std::vector<std::string>{"*OPC"}));
  EXPECT_TRUE(r.units[3].query);
  EXPECT_EQ(r.units[0].params, std::vector<std::string>{"1 KHZ"});
}

TEST(ScpiParserTest, BlocksMayHoldSeparatorsAndNewlines) {
  std::string msg = "DATA:ARB:DAC a,#15;,\n\"x;*IDN?";
  const auto end = FindMessageEnd(msg + "\n");
  ASSERT_TRUE(end);
  EXPECT_EQ(*end, msg.size());
  const SplitResult r = SplitProgramMessage(msg);
  ASSERT_FALSE(r.failure);
  ASSERT_EQ(r.units.size(), 2u);
  ASSERT_EQ(r.units[0].params.size(), 2u);
  EXPECT_EQ(r.units[0].params[1], "#15;,\n\"x");
  // Incomplete block: wait for more bytes.
  EXPECT_FALSE(FindMessageEnd("DATA:ARB:DAC a,#210\n12"));
}

TEST(ScpiParserTest, BlockEndingInWhitespaceBytesKeepsThem) {
  // A last sample 0x200A ends the block in ' ', '\n': data, not whitespace to trim (found with
  // the VXI-11 tests: the mock answered -161 "Invalid block data").
  const SplitResult r = SplitProgramMessage("DATA:ARB:DAC a,#14AB \n  ;:SYST:ERR?");
  ASSERT_FALSE(r.failure);
  ASSERT_EQ(r.units.size(), 2u);
  ASSERT_EQ(r.units[0].params.size(), 2u);
  EXPECT_EQ(r.units[0].params[1], "#14AB \n");
  const SplitResult last = SplitProgramMessage("DATA:ARB:DAC a,#14AB\n\n");
  ASSERT_FALSE(last.failure);
  EXPECT_EQ(last.units.at(0).params.at(1), "#14AB\n\n");
}

TEST(ScpiParserTest, UnitsAndSpecialValues) {
  EXPECT_DOUBLE_EQ(*ParseNumericWithUnit("1 KHZ", "HZ"), 1e3);
  EXPECT_DOUBLE_EQ(*ParseNumericWithUnit("2MHZ", "HZ"), 2e6);  // M before HZ is mega
  EXPECT_DOUBLE_EQ(*ParseNumericWithUnit("100 mV", "VPP|V"), 0.1);
  EXPECT_DOUBLE_EQ(*ParseNumericWithUnit("100 MVPP", "VPP|V"), 0.1);
  EXPECT_DOUBLE_EQ(*ParseNumericWithUnit("1.5e3", "HZ"), 1500.0);
  EXPECT_FALSE(ParseNumericWithUnit("1 FOO", "HZ"));
  EXPECT_FALSE(ParseNumericWithUnit("MAX", "HZ"));
  EXPECT_EQ(ParseBoolean("on"), true);
  EXPECT_EQ(ParseBoolean("0"), false);
  EXPECT_FALSE(ParseBoolean("maybe"));
  EXPECT_EQ(FormatReplyNumber(1000.0), "+1.0000000000000E+03");
  EXPECT_EQ(FormatReplyNumber(-0.25), "-2.5000000000000E-01");
}

TEST(ScpiParserTest, SyntaxErrors) {
  EXPECT_EQ(SplitProgramMessage("FREQ::X 1").failure->code, -102);
  EXPECT_EQ(SplitProgramMessage("DATA:ARB:DAC a,#0abc").failure->code, -161);
}

// The incremental framer ends messages where FindMessageEnd does, however the bytes arrive.
TEST(ScpiParserTest, FramerAgreesWithFindMessageEndForEveryChunking) {
  const std::string stream = std::string("*IDN?\n") + "DISP:TEXT 'a\n" +  // unterminated string
                             "DATA:ARB:DAC X,#210ab\ncd\"ef\n;\n" +       // block with '\n' inside
                             "FREQ 1#0\n" + "A \"q\n\" B\n" + "DATA #3004a\nb\n\n";
  std::vector<size_t> want;
  for (size_t start = 0;;) {
    const auto end = FindMessageEnd(std::string_view(stream).substr(start));
    if (!end) break;
    want.push_back(start + *end);
    start += *end + 1;
  }
  ASSERT_EQ(want.size(), 7u);
  for (size_t chunk : {1u, 2u, 3u, 5u, 7u, 64u}) {
    std::string buffer;
    MessageFramer framer;
    std::vector<size_t> got;
    for (size_t i = 0; i < stream.size(); i += chunk) {
      buffer += stream.substr(i, chunk);
      while (auto end = framer.Next(buffer)) {
        got.push_back(*end);
        framer.Reset(*end + 1);
      }
    }
    EXPECT_EQ(got, want) << "chunk " << chunk;
  }
}

TEST(ScpiParserTest, FramerShiftKeepsItsPlace) {
  MessageFramer framer;
  std::string buffer = "*IDN?\nFREQ #14ab";
  auto end = framer.Next(buffer);
  ASSERT_EQ(end, 5u);
  framer.Reset(6);
  EXPECT_FALSE(framer.Next(buffer));
  buffer.erase(0, 6);
  framer.Shift(6);
  buffer += "\nc\n";  // the block's payload "ab\nc" ends before the terminator
  EXPECT_EQ(framer.Next(buffer), buffer.size() - 1);
}

// Found by the mock_scpi_parser fuzz target in a 10 M-execution run (session 11): a pattern with
// a run of optional nodes of one mnemonic, matched against a header that fits none of the
// alternatives, was searched by plain backtracking in 2^k steps. The search now remembers
// the states that failed: its work stays within (pattern nodes + 1) x (header nodes + 1).
TEST(ScpiParserTest, MatchingARunOfOptionalNodesIsLinearInStates) {
  std::string text;
  for (int i = 0; i < 24; ++i) text += "[:VOLTage]";
  text += ":VOLTage:LEVel";
  const HeaderPattern pattern(text);
  ASSERT_EQ(pattern.max_nodes(), 26u);
  const std::vector<HeaderNode> header =
      SplitHeaderNodes({"VOLT", "VOLT", "VOLT", "VOLT", "VOLT", "VOLT", "FREQ"});
  uint64_t work = 0;
  EXPECT_FALSE(pattern.Match(header, &work));
  EXPECT_LE(work, (pattern.max_nodes() + 1) * (header.size() + 1));  // 2^24 steps before
  // and a header that fits is still matched, with the right number of nodes used.
  work = 0;
  EXPECT_TRUE(pattern.Match(SplitHeaderNodes({"VOLT", "VOLT", "VOLT", "LEV"}), &work));
  EXPECT_LE(work, (pattern.max_nodes() + 1) * 5u);
}

}  // namespace
}  // namespace msmcal::sim
