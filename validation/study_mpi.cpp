#include "validation/study_mpi.hpp"

#include <cstdlib>
#include <string>

#include "data/error.hpp"

#if STIFFID_HAVE_MPI
#include <mpi.h>
#endif

namespace stiffid::validation {

bool launched_by_mpirun() {
  return std::getenv("OMPI_COMM_WORLD_SIZE") || std::getenv("PMI_SIZE") || std::getenv("PMIX_RANK");
}

int launcher_world_size() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE"}) {
    if (const char* value = std::getenv(name)) return std::max(1, std::atoi(value));
  }
  return 1;
}

#if STIFFID_HAVE_MPI

MpiWorld::MpiWorld() {
  if (!launched_by_mpirun()) return;
  int already = 0;
  MPI_Initialized(&already);
  if (!already) {
    MPI_Init(nullptr, nullptr);
    initialized_here_ = true;
  }
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
}

MpiWorld::~MpiWorld() {
  if (initialized_here_) MPI_Finalize();
}

void MpiWorld::barrier() const {
  if (size_ > 1) MPI_Barrier(MPI_COMM_WORLD);
}

bool MpiWorld::any(bool flag) const {
  if (size_ == 1) return flag;
  int local = flag ? 1 : 0;
  int global = 0;
  MPI_Allreduce(&local, &global, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  return global != 0;
}

long MpiWorld::sum(long value) const {
  if (size_ == 1) return value;
  long global = 0;
  MPI_Allreduce(&value, &global, 1, MPI_LONG, MPI_SUM, MPI_COMM_WORLD);
  return global;
}

#else

MpiWorld::MpiWorld() {
  if (launcher_world_size() > 1) {
    throw InputError(
        "this stiffid was built without MPI (CMake found no MPI, or STIFFID_WITH_MPI=OFF), so it "
        "cannot share a study among the " +
        std::to_string(launcher_world_size()) +
        " processes mpirun started; run `stiffid study` without mpirun (it uses every core of "
        "the machine), or install openmpi-bin and libopenmpi-dev and rebuild");
  }
}
MpiWorld::~MpiWorld() = default;
void MpiWorld::barrier() const {}
bool MpiWorld::any(bool flag) const { return flag; }
long MpiWorld::sum(long value) const { return value; }

#endif

}  // namespace stiffid::validation
