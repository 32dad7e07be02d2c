#include "apps/cli.hpp"

#include <glog/logging.h>

#include <iostream>

#include "apps/commands.hpp"
#include "data/error.hpp"

namespace stiffid::apps {

int run_cli(int argc, char** argv, const std::function<void(CLI::App&)>& add_commands) {
  // Ceres logs through glog; its per-step diagnostics (e.g. a rejected start of a multi-start whose
  // model overflows) are not for the user, who gets the fit's status and termination instead.
  FLAGS_logtostderr = true;
  FLAGS_minloglevel = google::GLOG_FATAL;
  google::InitGoogleLogging(argv[0]);
  CLI::App app{"stiffid: stiffness, damping and inertia of human limbs from experimental trials"};
  app.set_version_flag("--version", std::string("stiffid ") + stiffid::version());
  app.require_subcommand(1);
  add_commands(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  } catch (const stiffid::InputError& e) {
    std::cerr << "stiffid: error: " << e.what() << '\n';
    return 2;
  } catch (const NumericalFailure& e) {
    std::cerr << "stiffid: failed: " << e.what() << '\n';
    return 1;
  }
  return 0;
}

}  // namespace stiffid::apps
