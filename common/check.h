#pragma once
// The tier for broken invariants (house style 9): a condition that no input can make false, only
// a bug. MSMCAL_CHECK(cond) << "what" prints "<file>:<line>: check failed: <cond>: <what>" to
// stderr and aborts (death-tested in tests/common/check_test.cc). Not for input validation: bad
// input throws at the boundary with its file and line (common/yaml_fields.h); expected
// instrument failures return a result.
//
//   MSMCAL_CHECK(j < frames.size()) << "trigger slot " << j << " of " << frames.size();
//
// The streamed operands are evaluated only when the check fails. Active in every build type.

#include <sstream>

namespace msmcal::common::internal {

// Collects the message of a failed check; its destructor prints and aborts.
class CheckFailure {
 public:
  CheckFailure(const char* file, int line, const char* condition);
  [[noreturn]] ~CheckFailure();
  CheckFailure(const CheckFailure&) = delete;
  CheckFailure& operator=(const CheckFailure&) = delete;
  std::ostream& stream() { return message_; }

 private:
  const char* const file_;
  const int line_;
  const char* const condition_;
  std::ostringstream message_;
};

// Gives the failing branch of MSMCAL_CHECK the type void, so that both branches of ?: agree
// (operator& binds looser than <<, so the whole message is streamed first).
struct CheckVoidify {
  void operator&(std::ostream&) {}
};

}  // namespace msmcal::common::internal

#define MSMCAL_CHECK(condition)                      \
  (condition)                                        \
      ? (void)0                                      \
      : ::msmcal::common::internal::CheckVoidify() & \
            ::msmcal::common::internal::CheckFailure(__FILE__, __LINE__, #condition).stream()
