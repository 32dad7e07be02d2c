#pragma once
// The `stiffid` command: each subcommand lives in its own apps/cmd_NAME.cpp, which defines
// `void add_NAME_command(CLI::App&)`; CMake lists them in generated/commands.inc. A subcommand
// parses flags into a module's options, calls the module and prints or writes the result. No
// numerics here.

#include <CLI/CLI.hpp>
#include <stdexcept>
#include <string>

namespace stiffid::apps {

/// Thrown by a subcommand when a numerical procedure reports failure (tier 2): exit code 1.
class NumericalFailure : public std::runtime_error {
 public:
  explicit NumericalFailure(const std::string& message) : std::runtime_error(message) {}
};

#define STIFFID_COMMAND(name) void add_##name##_command(CLI::App& app);
#include "commands.inc"
#undef STIFFID_COMMAND

}  // namespace stiffid::apps
