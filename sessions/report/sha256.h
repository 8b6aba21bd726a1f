#pragma once
// SHA-256 (FIPS 180-4) of bytes, as lowercase hex: the configuration files' hashes in a report's
// provenance. Pure; no dependency (msmcal links no crypto library).

#include <filesystem>
#include <string>
#include <string_view>

namespace msmcal::report {

std::string Sha256Hex(std::string_view bytes);
// The hash of a file's bytes. Throws std::runtime_error naming the file when it cannot be read.
std::string Sha256HexOfFile(const std::filesystem::path& file);

}  // namespace msmcal::report
