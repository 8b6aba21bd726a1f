#include "processing/dataset/recording.h"

namespace msmcal::dataset {

const char* ToString(BeamRole role) {
  return role == BeamRole::kEstimate ? "estimate" : "validate";
}

const char* ToString(Step2Kind kind) {
  switch (kind) {
    case Step2Kind::kNeutral:
      return "neutral";
    case Step2Kind::kFastOnly:
      return "fast_only";
    case Step2Kind::kScan:
      return "scan";
  }
  return "?";
}

}  // namespace msmcal::dataset
