#include "render/progress.h"

#include <fmt/format.h>

#include <unistd.h>

#include <algorithm>

namespace umbra::render {

Progress::Progress(bool enabled, std::string label)
    : m_enabled(enabled), m_terminal(isatty(STDERR_FILENO) != 0), m_label(std::move(label)),
      m_start(std::chrono::steady_clock::now()) {}

void Progress::update(int done, int total, double workDone) {
    if (!m_enabled || total <= 0) return;
    double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - m_start).count();
    std::lock_guard<std::mutex> lock(m_mutex);
    m_workDone = std::max(m_workDone, std::clamp(workDone, 0.0, 1.0));
    const double fraction = m_workDone;
    double eta = fraction > 0 ? elapsed * (1 - fraction) / fraction : 0;
    if (m_terminal) {
        // Redraw at most 20 times a second, and always at the end.
        if (done != total && elapsed - m_lastDraw < 0.05) return;
        m_lastDraw = elapsed;
        constexpr int kWidth = 30;
        int filled = int(fraction * kWidth);
        fmt::print(stderr, "\r{} [{}{}] {:3.0f}%  {}/{} buckets  {:.1f}s elapsed  ETA {:.1f}s ", m_label,
                   std::string(size_t(filled), '#'), std::string(size_t(kWidth - filled), '.'), 100 * fraction, done,
                   total, elapsed, eta);
        m_drawn = true;
    } else {
        int decile = int(fraction * 10);
        if (decile == m_lastDecile) return;
        m_lastDecile = decile;
        fmt::print(stderr, "{}: {}% ({}/{} buckets), {:.1f}s elapsed, ETA {:.1f}s\n", m_label, decile * 10, done,
                   total, elapsed, eta);
    }
}

void Progress::finish() {
    std::lock_guard<std::mutex> lock(m_mutex);
    if (m_enabled && m_terminal && m_drawn) fmt::print(stderr, "\n");
    m_drawn = false;
}

}  // namespace umbra::render
