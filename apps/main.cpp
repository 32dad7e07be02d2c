// stiffid-full: the stiffid command line with every subcommand (apps/cmd_*.cpp). Users call
// `stiffid`, which runs frf and irf itself and hands everything else to this program.
#include <glog/logging.h>

#include "apps/cli.hpp"
#include "apps/commands.hpp"
#include "data/allocator.hpp"

int main(int argc, char** argv) {
  stiffid::data::keep_large_blocks_for_reuse();
  // Ceres logs through glog; its per-step diagnostics (e.g. a rejected start of a multi-start whose
  // model overflows) are not for the user, who gets the fit's status and termination instead.
  FLAGS_logtostderr = true;
  FLAGS_minloglevel = google::GLOG_FATAL;
  google::InitGoogleLogging(argv[0]);
  return stiffid::apps::run_cli(argc, argv, [](CLI::App& app) {
#define STIFFID_COMMAND(name) stiffid::apps::add_##name##_command(app);
#include "commands.inc"
#undef STIFFID_COMMAND
  });
}
