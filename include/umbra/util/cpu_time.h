#pragma once
// CPU clocks for the statistics: the whole process's, and the calling
// thread's (a pass's workers, a map file's writer).

#include <ctime>

namespace umbra {

inline double cpuSecondsOf(clockid_t clock) {
    timespec ts{};
    clock_gettime(clock, &ts);
    return double(ts.tv_sec) + double(ts.tv_nsec) * 1e-9;
}
/// CPU time of every thread of the process.
inline double processCpuSeconds() { return cpuSecondsOf(CLOCK_PROCESS_CPUTIME_ID); }
/// CPU time of the calling thread.
inline double threadCpuSeconds() { return cpuSecondsOf(CLOCK_THREAD_CPUTIME_ID); }

}  // namespace umbra
