#pragma once
// The few text and file primitives every writer of msmcal's files shares: the lossless number
// format and the atomic file write. Below every module (no msmcal dependencies), so mocks,
// acquisition and sessions write numbers and files the same way.

#include <filesystem>
#include <string>

namespace msmcal::common {

// Shortest text that reads back to the same double (std::to_chars): "0.1", "1e-07", "-0".
std::string ShortestDouble(double value);
void AppendShortestDouble(std::string* out, double value);

// The same for YAML: ".0" before a bare exponent so that YAML 1.1 readers (PyYAML) read a float
// ("4e-04" -> "4.0e-04"), and YAML's .inf / -.inf / .nan.
std::string YamlDouble(double value);

// Writes `contents` to `file` atomically: a temporary in the same folder, fsync, rename, fsync
// of the folder; creates parent folders. Throws std::runtime_error naming the file and the
// failing step; on failure the previous file, if any, is untouched and no temporary is left.
void WriteFileAtomically(const std::filesystem::path& file, const std::string& contents);

}  // namespace msmcal::common
