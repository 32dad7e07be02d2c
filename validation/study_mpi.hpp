#pragma once
// The MPI side of the study runner (internal): who am I among the processes that mpirun started.
// Built as a stub when the build has no MPI (STIFFID_HAVE_MPI=0): a process started by mpirun with
// more than one rank then gets an InputError that explains why and what to do.

namespace stiffid::validation {

/// True when the environment says this process was started by mpirun/mpiexec (Open MPI's
/// OMPI_COMM_WORLD_SIZE, or PMI_SIZE / PMIX_RANK of other launchers).
bool launched_by_mpirun();
/// The number of processes mpirun started, from the environment (1 when not launched by it).
int launcher_world_size();

/// MPI_COMM_WORLD for the duration of a study: initializes MPI when launched by mpirun and
/// finalizes it on destruction; a single process otherwise.
class MpiWorld {
 public:
  MpiWorld();
  ~MpiWorld();
  MpiWorld(const MpiWorld&) = delete;
  MpiWorld& operator=(const MpiWorld&) = delete;

  int rank() const { return rank_; }
  int size() const { return size_; }
  void barrier() const;
  /// True on every rank when `flag` is true on any rank (collective).
  bool any(bool flag) const;
  /// Sum of `value` over ranks, on every rank (collective).
  long sum(long value) const;

 private:
  int rank_ = 0;
  int size_ = 1;
  bool initialized_here_ = false;
};

}  // namespace stiffid::validation
