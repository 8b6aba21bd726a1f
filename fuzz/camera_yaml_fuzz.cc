// libFuzzer target: camera.yaml of the interchange folder (ParseCameraYaml).
//
// Checks: returns or throws std::runtime_error naming "camera.yaml"; FormatCameraYaml of an
// accepted camera parses again to a camera that formats to the same text (round trip).
#include <cstdint>
#include <string>

#include "fuzz/fuzz_util.h"
#include "sessions/interchange/interchange_io.h"

using namespace msmcal;
using fuzz::Check;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  geometry::CameraModel camera;
  if (!fuzz::Returns(
          [&] { camera = interchange::ParseCameraYaml(fuzz::Text(data, size), "camera.yaml"); },
          "camera.yaml"))
    return 0;
  const std::string text = interchange::FormatCameraYaml(camera);
  geometry::CameraModel back;
  fuzz::MustReturn([&] { back = interchange::ParseCameraYaml(text, "written"); },
                   "ParseCameraYaml(FormatCameraYaml)");
  Check(interchange::FormatCameraYaml(back) == text, "camera.yaml round trip differs");
  return 0;
}
