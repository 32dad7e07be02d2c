// stiffid-full: the stiffid command line with every subcommand (apps/cmd_*.cpp). Users call
// `stiffid`, which runs frf, irf and tfa itself and hands everything else to this program.
#include "apps/cli.hpp"
#include "apps/commands.hpp"
#include "data/allocator.hpp"

int main(int argc, char** argv) {
  stiffid::data::keep_large_blocks_for_reuse();
  return stiffid::apps::run_cli(argc, argv, [](CLI::App& app) {
#define STIFFID_COMMAND(name) stiffid::apps::add_##name##_command(app);
#include "commands.inc"
#undef STIFFID_COMMAND
  });
}
