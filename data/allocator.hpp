#pragma once
// Process-wide memory allocator setting for stiffid's programs (the `stiffid` command and the
// benchmarks); the library never calls it, a program that embeds the library chooses for itself.

#include <string>

namespace stiffid::data {

/// Makes glibc malloc keep freed large blocks for reuse instead of returning them to the kernel:
/// blocks up to 32 MiB come from the heap rather than from a fresh mmap, the heap is not trimmed
/// below 1 GiB, and it grows 64 MiB at a time. Without it every large array (a trial's samples,
/// the truth series of a simulation, FFT buffers: megabytes each) is mapped, page-faulted on first
/// touch and unmapped again on free; on virtual machines, where a page fault costs microseconds,
/// that dominated the run time of a simulated 5 s, 4 kHz trial (31 ms -> 2.3 ms per trial when
/// simulated repeatedly). The heap is grown by those 64 MiB at the call and advised for
/// transparent huge pages (where the kernel offers them on request, as Debian's default "madvise"
/// does), so that what is touched there is faulted in 2 MiB at a time: `stiffid tfa` on a 5 s,
/// 4 kHz trial took 740 instead of 4310 page faults, ~7-10 % of its wall time. Only whole 2 MiB
/// aligned ranges can be huge pages, so the heap's top is then moved to the next 2 MiB boundary
/// by a spacer block (up to 2 MiB of address space, kept and never touched): before, the first
/// blocks carved from a top at a random place below that boundary took up to 512 faults of 4 KiB
/// (the modal `stiffid tfa` of that trial, through the front end: 1670-1790 -> 960 page faults,
/// 0.073-0.084 -> 0.064-0.070 s, `perf stat` means of 25). Call once at the start of main(),
/// before large allocations. Does nothing on other C libraries. Numbers are unaffected: only
/// where memory comes from changes.
void keep_large_blocks_for_reuse();

/// Makes every thread allocate from the main heap (glibc's M_ARENA_MAX = 1), which
/// keep_large_blocks_for_reuse has set up for huge pages, instead of giving each new thread a heap
/// of its own faulted in 4 KiB at a time: for a program that cannot set glibc.malloc.hugetlb
/// (read at start-up only) and runs a few threads that each allocate large blocks. The modal
/// `stiffid tfa` of a 5 s, 4 kHz trial, whose two fits run on two threads: 2840 -> 1020 page
/// faults, 84 -> 69 ms in one program (the same as under the tunable). Call at the start of
/// main(), before other threads allocate. Does nothing on other C libraries.
void one_heap_for_all_threads();

/// GLIBC_TUNABLES for a stiffid program this one starts by exec: `current` (the variable's value,
/// or null when unset) with glibc.malloc.hugetlb=1 added, unless it sets that tunable already.
/// That tunable (glibc >= 2.35; older ones ignore it) makes malloc ask for transparent huge pages
/// on every heap it maps, the heaps of threads other than the main one included, which
/// keep_large_blocks_for_reuse cannot reach from inside a running program: on the modal `stiffid
/// tfa` of a 5 s, 4 kHz trial, whose two fits run on two threads, 1650-1810 page faults instead of
/// 2850 and ~15 % less wall time; runs of a second and more are unchanged.
std::string tunables_with_huge_pages(const char* current);

/// Sets GLIBC_TUNABLES to tunables_with_huge_pages(its value): call just before the exec.
void ask_huge_pages_after_exec();

}  // namespace stiffid::data
