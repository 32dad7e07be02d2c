// Benchmark of the study runner: the built-in Perreault 1999 study (or any study file) end to end
// into a temporary store, printing cells, wall time and cells/s. Time the whole process from
// outside (e.g. /usr/bin/time -v bench_study perreault1999 10 2) for whole-process figures.
//   bench_study [SPEC|NAME=perreault1999] [REPLICATES=from the spec] [THREADS=0 (all)]
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "data/allocator.hpp"
#include "validation/study.hpp"

int main(int argc, char** argv) {
  stiffid::data::keep_large_blocks_for_reuse();  // as the stiffid program does
  namespace v = stiffid::validation;
  try {
    v::StudySpec spec = v::load_study(argc > 1 ? argv[1] : "perreault1999");
    if (argc > 2) spec.replicates = std::atoi(argv[2]);
    v::StudyOptions options;
    options.threads = argc > 3 ? std::atoi(argv[3]) : 0;
    options.store_path = (std::filesystem::temp_directory_path() /
                          ("bench_study_" + std::to_string(getpid()) + ".sqlite"))
                             .string();
    const v::StudyResult result = v::run_study(spec, options, v::builtin_evaluators());
    v::ResultStore::remove_files(options.store_path);
    std::printf("%s: %d cells, %d failed, %.3f s wall, %.1f cells/s\n", spec.name.c_str(),
                result.cells_total, result.cells_failed, result.wall_s,
                result.cells_computed / result.wall_s);
    return result.status.ok ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_study: %s\n", e.what());
    return 2;
  }
}
