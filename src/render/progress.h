#pragma once
// `--progress`: a live bar with the share of the work done, buckets done,
// elapsed time and ETA when stderr is a terminal; plain lines every 10%
// otherwise (logs, farms). The share and the ETA come from the estimated
// work of the buckets done (hider/bucket_work.h), not from their count.

#include <atomic>
#include <chrono>
#include <mutex>
#include <string>

namespace umbra::render {

class Progress {
public:
    Progress(bool enabled, std::string label);
    /// Called from worker threads after each bucket: buckets done of
    /// `total`, and the share of the pass's estimated work done.
    void update(int done, int total, double workDone);
    /// Ends the bar's line.
    void finish();

private:
    bool m_enabled;
    bool m_terminal;
    std::string m_label;
    std::chrono::steady_clock::time_point m_start;
    std::mutex m_mutex;
    int m_lastDecile = -1;
    double m_workDone = 0;  // the largest share reported: threads report out of order
    double m_lastDraw = -1;
    bool m_drawn = false;
};

}  // namespace umbra::render
