#pragma once
// The command line shared by the two programs of stiffid: `stiffid-full`, with every subcommand,
// and `stiffid`, the front end that runs frf, irf and tfa itself and hands every other command to
// stiffid-full (apps/front/main.cpp).

#include <CLI/CLI.hpp>
#include <functional>

namespace stiffid::apps {

/// Parses argv with the subcommands `add_commands` registers (exactly one required, `--version`)
/// and runs the chosen one, with the solvers' own logging (glog, through Ceres) silenced. Returns
/// the exit code: 0 done, 2 bad input or usage (an InputError or a command-line error, printed as
/// "stiffid: error: ..."), 1 a numerical failure ("stiffid: failed: ...").
int run_cli(int argc, char** argv, const std::function<void(CLI::App&)>& add_commands);

}  // namespace stiffid::apps
