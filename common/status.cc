#include "common/status.h"

namespace msmcal::common {

const char* StatusCodeName(StatusCode code) {
  switch (code) {
    case StatusCode::kOk:
      return "ok";
    case StatusCode::kRefused:
      return "refused";
    case StatusCode::kWrongDevice:
      return "wrong device";
    case StatusCode::kNotLocked:
      return "not locked";
    case StatusCode::kDeviceError:
      return "device error";
    case StatusCode::kUnavailable:
      return "unavailable";
    case StatusCode::kTimeout:
      return "timeout";
    case StatusCode::kProtocol:
      return "protocol";
  }
  return "unknown";
}

}  // namespace msmcal::common
