// msmcal: calibration rig control and solver for soft-hinged micro scanning mirrors.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <exception>
#include <regex>
#include <string>
#include <utility>
#include <vector>

#include "app/command_registry.h"
#include "drivers/generator/safe_state.h"
#include "sessions/report/build_info.h"

namespace msmcal::app {
namespace {
std::vector<std::pair<int, CommandRegistrar>>& Registry() {
  static std::vector<std::pair<int, CommandRegistrar>> registry;
  return registry;
}
}  // namespace

bool RegisterCommands(int order, CommandRegistrar registrar) {
  Registry().emplace_back(order, std::move(registrar));
  return true;
}

CLI::App* GetOrAddSubcommand(CLI::App& parent, const std::string& name,
                             const std::string& description) {
  for (CLI::App* sub : parent.get_subcommands([](CLI::App*) { return true; })) {
    if (sub->get_name() == name) return sub;
  }
  CLI::App* sub = parent.add_subcommand(name, description);
  sub->require_subcommand(1);
  return sub;
}

void AddRegisteredCommands(CLI::App& app) {
  auto& registry = Registry();
  std::stable_sort(registry.begin(), registry.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  for (auto& [order, registrar] : registry) registrar(app);
}

namespace {

// One boundary check for every number on the command line, run before any command does anything:
// CLI11 (2.1) lets "nan" and "inf" through its range checks, reads integers in base 0 ("0100" is
// 64, "0x10" is 16), takes "-1" for an unsigned option as 18446744073709551615 and saturates a
// 64-bit value out of range. A floating-point value must be finite, an integer plain decimal
// within its type (no sign for an unsigned one).
void CheckNumbers(const CLI::App& app) {
  static const std::regex kSigned("[+-]?(0|[1-9][0-9]*)");
  static const std::regex kUnsigned("[+]?(0|[1-9][0-9]*)");
  for (const CLI::Option* option : app.get_options()) {
    if (option->count() == 0) continue;
    // The value type only: CLI11 appends validators' descriptions after it ("INT:INT in [...]").
    const std::string full_type = option->get_type_name();
    const std::string type = full_type.substr(0, full_type.find_first_of(": "));
    const bool floating = type.find("FLOAT") != std::string::npos;
    const bool is_unsigned = type.find("UINT") != std::string::npos;
    const bool integer = is_unsigned || type.find("INT") != std::string::npos;
    if (!floating && !integer) continue;
    for (const std::string& value : option->results()) {
      const auto refuse = [&](const std::string& expected) {
        throw CLI::ValidationError(option->get_name(), "'" + value + "': expected " + expected);
      };
      if (floating) {
        char* end = nullptr;
        const double x = std::strtod(value.c_str(), &end);
        if (end != value.c_str() && *end == '\0' && !std::isfinite(x)) refuse("a finite number");
        continue;
      }
      if (!std::regex_match(value, is_unsigned ? kUnsigned : kSigned))
        refuse(is_unsigned ? "a decimal integer >= 0 (no sign, no leading zeros, no 0x)"
                           : "a decimal integer (no leading zeros, no 0x)");
      errno = 0;
      if (is_unsigned)
        (void)std::strtoull(value.c_str(), nullptr, 10);
      else
        (void)std::strtoll(value.c_str(), nullptr, 10);
      if (errno == ERANGE) refuse("an integer within 64 bits");
    }
  }
  for (const CLI::App* sub : app.get_subcommands()) CheckNumbers(*sub);
}

}  // namespace

}  // namespace msmcal::app

int main(int argc, char** argv) {
  CLI::App app{"msmcal: calibration rig and solver for soft-hinged micro scanning mirrors"};
  app.require_subcommand(1);
  // What a bug report or a lab notebook should quote: the same version and commit as a report's
  // provenance.
  app.set_version_flag("--version", std::string("msmcal ") + msmcal::report::MsmcalVersion() +
                                        " (commit " + msmcal::report::GitCommit() + ", " +
                                        msmcal::report::BuildType() + " build)");
  std::string log_level = "info";
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error"}));
  // Runs after parsing, before any subcommand's callback (the commands themselves).
  app.parse_complete_callback([&] {
    msmcal::app::CheckNumbers(app);
    spdlog::set_level(spdlog::level::from_str(log_level));
  });
  msmcal::app::AddRegisteredCommands(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const msmcal::gen::SafeStateNotConfirmed& e) {
    // Loud, with its own status (docs/watchdog.md): 76 the watchdog confirmed, 75 nobody did.
    spdlog::critical("{}", e.what());
    return e.exit_status();
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}
