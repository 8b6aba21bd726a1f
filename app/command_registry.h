#pragma once
// Each command family (cmd_*.cc) registers a function that adds its subcommands to the CLI.
// Registration runs at static-initialisation time of the executable's own objects; order is
// given by `order` so that `msmcal --help` lists commands in a stable, meaningful order.

#include <CLI/CLI.hpp>
#include <functional>
#include <string>

namespace msmcal::app {

using CommandRegistrar = std::function<void(CLI::App& app)>;

// Returns true so it can initialise a namespace-scope constant.
bool RegisterCommands(int order, CommandRegistrar registrar);

// Returns the subcommand `name` of `parent`, creating it if absent. Several families share
// parents such as `experiment`, `mock` and `hall`.
CLI::App* GetOrAddSubcommand(CLI::App& parent, const std::string& name,
                             const std::string& description);

// Adds every registered family to `app`, in `order`.
void AddRegisteredCommands(CLI::App& app);

}  // namespace msmcal::app

#define MSMCAL_REGISTER_COMMANDS(order, fn) \
  static const bool msmcal_registered_##fn = ::msmcal::app::RegisterCommands(order, fn)
