// `stiffid`: the program users call. It runs `frf`, `irf` and `tfa` itself and hands every other
// command line (the other subcommands, --help, --version, mistakes) unchanged to `stiffid-full`,
// the program next to it with every subcommand (apps/main.cpp), by exec: same arguments, same
// standard streams, same exit code. Linked with the estimators alone (no Ipopt, NLopt, MPI or
// SQLite; Ceres's own dependencies linked statically where Debian ships their archives,
// CMakeLists.txt), this program loads 12 shared libraries where stiffid-full loads 22 (38 before
// the static link) and starts in ~9 ms (`frf --help`) where stiffid-full takes ~17: a few per
// cent of a 10-minute trial's frf or irf. The modal tfa of a 5 s trial, which used to pay for
// both programs' start, takes a quarter less (docs/tfa_modal.md, "Speed").
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <string>
#include <system_error>

#include "apps/cli.hpp"
#include "apps/commands.hpp"
#include "data/allocator.hpp"

namespace {

// stiffid-full in this program's folder (the build folder, or wherever both are installed).
std::string full_program(const char* argv0) {
  std::error_code ec;
  std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) self = std::filesystem::absolute(argv0, ec);
  return (self.parent_path() / "stiffid-full").string();
}

// `tfa ... --method spectrogram ...` (or --method=spectrogram), the method named once.
bool spectrogram_tfa(int argc, char** argv) {
  if (argc < 2 || std::string(argv[1]) != "tfa") return false;
  int methods = 0;
  bool spectrogram = false;
  for (int i = 2; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--method") {
      ++methods;
      spectrogram = i + 1 < argc && std::string(argv[i + 1]) == "spectrogram";
    } else if (arg.rfind("--method=", 0) == 0) {
      ++methods;
      spectrogram = arg == "--method=spectrogram";
    }
  }
  return methods == 1 && spectrogram;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string command = argc > 1 ? argv[1] : "";
  if (command == "frf" || command == "irf" || command == "tfa") {
    stiffid::data::keep_large_blocks_for_reuse();
    // The modal fit's two damping models run on two threads; one heap for both keeps the second
    // thread's blocks on huge pages too (the spectrogram's FFT tasks, many small blocks on every
    // thread, keep a heap per thread).
    if (command == "tfa" && !spectrogram_tfa(argc, argv)) stiffid::data::one_heap_for_all_threads();
    // Only the command asked for is registered (the others' options are not set up).
    return stiffid::apps::run_cli(argc, argv, [&command](CLI::App& app) {
      if (command == "frf") stiffid::apps::add_frf_command(app);
      if (command == "irf") stiffid::apps::add_irf_command(app);
      if (command == "tfa") stiffid::apps::add_tfa_command(app);
    });
  }
  const std::string full = full_program(argv[0]);
  stiffid::data::ask_huge_pages_after_exec();  // for the threads' heaps too (data/allocator.hpp)
  execv(full.c_str(), argv);                   // argv[0] kept: usage lines name `stiffid` as typed
  std::cerr << "stiffid: error: cannot run " << full << " (" << std::strerror(errno)
            << "): it is built and installed next to stiffid\n";
  return 2;
}
