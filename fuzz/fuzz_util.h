#pragma once
// Helpers shared by the libFuzzer targets (fuzz/README in docs/fuzzing.md).
//
// A parser under fuzzing either returns a value or throws the project's documented error type
// (std::runtime_error, which includes the interchange and YAML errors, or std::invalid_argument)
// whose message names the input (file name, "file:line: ..."). Anything else - another exception
// type, a message that does not name the input, a failed property - aborts, which libFuzzer
// reports as a crash together with the input.

#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <string_view>

namespace msmcal::fuzz {

// Aborts with `what` (libFuzzer records the input).
[[noreturn]] inline void Fail(const std::string& what) {
  std::fprintf(stderr, "fuzz property failed: %s\n", what.c_str());
  std::abort();
}

inline void Check(bool ok, const std::string& what) {
  if (!ok) Fail(what);
}

// Runs f(). True when it returned; false when it threw std::invalid_argument or
// std::runtime_error whose message contains `must_name` (when not empty). Other exceptions are
// not caught.
template <typename F>
bool Returns(F&& f, std::string_view must_name = {}) {
  try {
    f();
    return true;
  } catch (const std::invalid_argument& e) {
    if (!must_name.empty() && std::string_view(e.what()).find(must_name) == std::string_view::npos)
      Fail("std::invalid_argument without '" + std::string(must_name) + "': " + e.what());
  } catch (const std::runtime_error& e) {
    if (!must_name.empty() && std::string_view(e.what()).find(must_name) == std::string_view::npos)
      Fail("std::runtime_error without '" + std::string(must_name) + "': " + e.what());
  }
  return false;
}

// Runs f() on text the project wrote itself: it must not throw at all.
template <typename F>
void MustReturn(F&& f, const std::string& what) {
  try {
    f();
  } catch (const std::exception& e) {
    Fail(what + " threw: " + e.what());
  }
}

inline std::string Text(const uint8_t* data, size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

}  // namespace msmcal::fuzz
