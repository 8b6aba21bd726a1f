#include "drivers/scpi/scpi_text.h"

#include <gtest/gtest.h>

namespace msmcal::scpi {
namespace {

TEST(ScpiTextTest, NumbersRoundTrip) {
  EXPECT_EQ(FormatNumber(1000.0), "1000");
  EXPECT_EQ(FormatNumber(0.25), "0.25");
  EXPECT_EQ(ParseNumber(FormatNumber(1.0 / 3.0)), 1.0 / 3.0);
  EXPECT_EQ(FormatNumber(1.5e-7), "1.5e-07");
  EXPECT_DOUBLE_EQ(ParseNumber("+1.0000000000000E+03"), 1000.0);
  EXPECT_DOUBLE_EQ(ParseNumber(" -2.5E-01\r"), -0.25);
  EXPECT_THROW(ParseNumber("1.0 V"), std::invalid_argument);
}

TEST(ScpiTextTest, DefiniteBlocks) {
  const std::string payload("a\nb;\0c", 6);
  const std::string block = FormatDefiniteBlock(payload);
  EXPECT_EQ(block.substr(0, 3), "#16");
  const auto h = ParseBlockHeader(block);
  ASSERT_TRUE(h);
  EXPECT_EQ(h->header_size, 3u);
  EXPECT_EQ(h->payload_size, 6u);
  EXPECT_EQ(block.substr(h->header_size), payload);
  EXPECT_FALSE(ParseBlockHeader("#"));
  EXPECT_FALSE(ParseBlockHeader("#41"));
  EXPECT_THROW(ParseBlockHeader("#0"), std::invalid_argument);
  EXPECT_THROW(ParseBlockHeader("X"), std::invalid_argument);
  EXPECT_EQ(FormatDefiniteBlock(std::string(1234, 'x')).substr(0, 6), "#41234");
}

TEST(ScpiTextTest, Int16PayloadByteOrder) {
  EXPECT_EQ(Int16Payload({0x0102, -2}, true), std::string("\x01\x02\xff\xfe", 4));
  EXPECT_EQ(Int16Payload({0x0102, -2}, false), std::string("\x02\x01\xfe\xff", 4));
}

TEST(ScpiTextTest, ErrorEntriesAndIdentity) {
  EXPECT_EQ(ParseErrorEntry("+0,\"No error\"").code, 0);
  const ErrorEntry e = ParseErrorEntry("-222,\"Data out of range;value clipped\"");
  EXPECT_EQ(e.code, -222);
  EXPECT_EQ(e.message, "Data out of range;value clipped");
  EXPECT_THROW(ParseErrorEntry("garbage"), std::invalid_argument);
  const Identity id = ParseIdentity("Agilent Technologies,33522B,MY5200,3.05-1.19");
  EXPECT_EQ(id.manufacturer, "Agilent Technologies");
  EXPECT_EQ(id.model, "33522B");
  EXPECT_THROW(ParseIdentity("only,three,fields"), std::invalid_argument);
}

TEST(ScpiTextTest, ResponsesAndPrintable) {
  EXPECT_EQ(SplitResponses("1;\"a;b\";+2.0E+00"),
            (std::vector<std::string>{"1", "\"a;b\"", "+2.0E+00"}));
  EXPECT_TRUE(IsPrintable("+0,\"No error\""));
  EXPECT_FALSE(IsPrintable(std::string("\x01\xfe", 2)));
  EXPECT_TRUE(ParseBool("1"));
  EXPECT_FALSE(ParseBool("OFF"));
}

}  // namespace
}  // namespace msmcal::scpi
