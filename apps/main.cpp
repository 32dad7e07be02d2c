#include <iostream>

#include "apps/commands.hpp"
#include "data/error.hpp"

int main(int argc, char** argv) {
  CLI::App app{"stiffid: stiffness, damping and inertia of human limbs from experimental trials"};
  app.set_version_flag("--version", std::string("stiffid ") + stiffid::version());
  app.require_subcommand(1);
#define STIFFID_COMMAND(name) stiffid::apps::add_##name##_command(app);
#include "commands.inc"
#undef STIFFID_COMMAND
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  } catch (const stiffid::InputError& e) {
    std::cerr << "stiffid: error: " << e.what() << '\n';
    return 2;
  } catch (const stiffid::apps::NumericalFailure& e) {
    std::cerr << "stiffid: failed: " << e.what() << '\n';
    return 1;
  }
  return 0;
}
