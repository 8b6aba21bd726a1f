#pragma once
// One result type for the expected failures of instruments, used by all three driver interfaces
// (gen::FunctionGenerator, camera::Camera, hall_mcu::HallSensor): an instrument that refuses a
// value, a link that drops, a reply that does not come are outcomes a caller decides on (retry,
// report, safe state), so they are returned, never thrown. Broken invariants are MSMCAL_CHECK
// (common/check.h); bad configuration is refused before an instrument is touched (Validate()).
// docs/architecture.md, "Errors: three tiers".
//
//   common::Status s = gen->SetOutput(1, true);
//   if (!s) log(s.message);                       // "'unit1' at 10.0.0.5:5025: OUTP1 ON: ..."
//   common::Result<bool> locked = gen->ReferenceLocked();
//   if (locked.ok() && *locked) ...
//
// Thread safety: value types.

#include <optional>
#include <string>
#include <utility>

namespace msmcal::common {

enum class StatusCode {
  kOk,
  kRefused,      // a value outside the configured limits or the instrument's range (not sent)
  kWrongDevice,  // the instrument is not the one expected (identity, family, firmware)
  kNotLocked,    // a reference or a synchronisation did not take
  kDeviceError,  // the instrument reported an error (its error queue, a rejected command)
  kUnavailable,  // no connection, the device went away, a write failed
  kTimeout,      // no reply within the time allowed
  kProtocol,     // a reply that does not parse (framing, a malformed answer)
};

// "refused", "wrong device", ... (for messages and logs).
const char* StatusCodeName(StatusCode code);

struct Status {
  bool ok = true;
  std::string message;  // what failed, naming the instrument; empty when ok
  StatusCode code = StatusCode::kOk;

  static Status Ok() { return {}; }
  static Status Error(std::string message, StatusCode code = StatusCode::kDeviceError) {
    return {false, std::move(message), code == StatusCode::kOk ? StatusCode::kDeviceError : code};
  }
  explicit operator bool() const { return ok; }
};

// A value, or the Status that says why there is none.
template <typename T>
class Result {
 public:
  Result(T value) : value_(std::move(value)) {}         // NOLINT: implicit, as absl::StatusOr
  Result(Status status) : status_(std::move(status)) {  // NOLINT
    if (status_.ok) status_ = Status::Error("Result made from an ok Status without a value");
  }

  bool ok() const { return value_.has_value(); }
  explicit operator bool() const { return ok(); }
  const Status& status() const { return status_; }
  // The value; only when ok() (MSMCAL_CHECK-like: calling it otherwise is a bug).
  const T& value() const& { return *value_; }
  T& value() & { return *value_; }
  const T& operator*() const& { return *value_; }
  const T* operator->() const { return &*value_; }
  T value_or(T other) const { return value_ ? *value_ : std::move(other); }

 private:
  std::optional<T> value_;
  Status status_;
};

}  // namespace msmcal::common
