#include "common/file_text.h"

#include <fstream>
#include <sstream>
#include <stdexcept>

namespace msmcal::common {

std::string ReadFileText(const std::filesystem::path& file, const std::string& cannot_open) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error(file.string() + ": " + cannot_open);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace msmcal::common
