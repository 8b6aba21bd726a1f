#pragma once
// Reading a whole text file, for the readers of msmcal's configuration and result files.

#include <filesystem>
#include <string>

namespace msmcal::common {

// The whole contents of `file`. Throws std::runtime_error "<file>: <cannot_open>" when it cannot
// be opened ("cannot open the rig configuration").
std::string ReadFileText(const std::filesystem::path& file,
                         const std::string& cannot_open = "cannot open");

}  // namespace msmcal::common
