#pragma once
// CPU clocks for the statistics: the whole process's, and the calling
// thread's (a pass's workers, a map file's writer).

#include <algorithm>
#include <cstdint>
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

/// The thread CPU time of one of many short calls (a grid's shading, a
/// shadow() lookup), for a statistic that sums them. Reading the thread's
/// clock is a system call: 1.3 us under these hosts' hypervisor, two per
/// call, 3.5% of the production frame when every lookup was timed. So a
/// thread's first 256 calls are each timed, and after that every 8th is
/// timed and counts 8 times: the sum is exact for small frames and an
/// unbiased estimate for large ones. `callsOnThisThread` is the caller's
/// own thread_local counter.
class SampledCallTime {
public:
    explicit SampledCallTime(uint64_t& callsOnThisThread)
        : m_weight(callsOnThisThread < 256 ? 1 : (callsOnThisThread % 8 == 0 ? 8 : 0)) {
        ++callsOnThisThread;
        if (m_weight) m_start = threadCpuSeconds();
    }
    /// Nanoseconds this call adds to the sum (0 when it was not timed).
    uint64_t nanoseconds() const {
        return m_weight ? m_weight * uint64_t(std::max(0.0, threadCpuSeconds() - m_start) * 1e9) : 0;
    }

private:
    uint64_t m_weight;
    double m_start = 0;
};

}  // namespace umbra
