#pragma once
// The CSV targets share one shape: parse the text, and for an accepted file check that the
// writer's text parses again to the same rows (compared through the writer's text, which is
// lossless: shortest round-trip doubles).
#include <cstdint>
#include <string>

#include "fuzz/fuzz_util.h"

namespace msmcal::fuzz {

template <typename Parse, typename Format>
void CsvRoundTrip(const uint8_t* data, size_t size, const char* name, Parse parse, Format format) {
  decltype(parse(std::string(), std::string())) value;
  if (!Returns([&] { value = parse(Text(data, size), name); }, name)) return;
  const std::string text = format(value);
  decltype(value) back;
  MustReturn([&] { back = parse(text, "written"); }, std::string(name) + " re-read");
  Check(format(back) == text, std::string(name) + " round trip differs");
}

}  // namespace msmcal::fuzz
