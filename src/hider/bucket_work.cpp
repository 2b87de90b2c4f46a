#include "umbra/hider/bucket_work.h"

#include <algorithm>
#include <cmath>

namespace umbra::hider {

std::vector<double> estimateBucketWork(const BucketLayout& layout, const std::vector<Bound3>& rasterBounds,
                                       double emptyPixelWork) {
    const int nx = std::max(0, layout.bucketsX()), ny = std::max(0, layout.bucketsY());
    std::vector<double> work(size_t(nx) * size_t(ny), 0.0);
    auto bucketEdge = [](int origin, int size, int i, int end) { return std::min(origin + i * size, end); };
    for (int by = 0; by < ny; ++by)
        for (int bx = 0; bx < nx; ++bx) {
            const int w = bucketEdge(layout.x0, layout.bucketWidth, bx + 1, layout.x1) - (layout.x0 + bx * layout.bucketWidth);
            const int h = bucketEdge(layout.y0, layout.bucketHeight, by + 1, layout.y1) - (layout.y0 + by * layout.bucketHeight);
            work[size_t(by) * size_t(nx) + size_t(bx)] = emptyPixelWork * double(w) * double(h);
        }
    for (const Bound3& b : rasterBounds) {
        if (b.empty()) continue;
        // Clamp in float (bounds across the eye plane are infinite) before
        // finding the buckets.
        const double xmin = std::clamp(double(b.min.x), double(layout.x0), double(layout.x1));
        const double xmax = std::clamp(double(b.max.x), double(layout.x0), double(layout.x1));
        const double ymin = std::clamp(double(b.min.y), double(layout.y0), double(layout.y1));
        const double ymax = std::clamp(double(b.max.y), double(layout.y0), double(layout.y1));
        if (!(xmax > xmin && ymax > ymin)) continue;
        const int bx0 = int((xmin - layout.x0) / layout.bucketWidth);
        const int bx1 = std::min(nx - 1, int((xmax - layout.x0) / layout.bucketWidth));
        const int by0 = int((ymin - layout.y0) / layout.bucketHeight);
        const int by1 = std::min(ny - 1, int((ymax - layout.y0) / layout.bucketHeight));
        for (int by = by0; by <= by1; ++by) {
            const double top = std::max(ymin, double(layout.y0 + by * layout.bucketHeight));
            const double bottom = std::min(ymax, double(layout.y0 + (by + 1) * layout.bucketHeight));
            for (int bx = bx0; bx <= bx1; ++bx) {
                const double left = std::max(xmin, double(layout.x0 + bx * layout.bucketWidth));
                const double right = std::min(xmax, double(layout.x0 + (bx + 1) * layout.bucketWidth));
                if (right > left && bottom > top)
                    work[size_t(by) * size_t(nx) + size_t(bx)] += (right - left) * (bottom - top);
            }
        }
    }
    return work;
}

WorkFraction::WorkFraction(const std::vector<double>& bucketWork) {
    // 1/256 of a pixel is finer than the estimate; every bucket counts at
    // least one unit, so a pass of empty buckets still advances.
    m_work.reserve(bucketWork.size());
    for (double w : bucketWork) {
        m_work.push_back(std::max<uint64_t>(1, uint64_t(std::llround(std::max(0.0, w) * 256.0))));
        m_total += m_work.back();
    }
}

double WorkFraction::finish(int b) {
    const uint64_t done = m_done.fetch_add(m_work[size_t(b)], std::memory_order_relaxed) + m_work[size_t(b)];
    return m_total > 0 ? double(done) / double(m_total) : 1.0;
}

double WorkFraction::fraction() const {
    return m_total > 0 ? double(m_done.load(std::memory_order_relaxed)) / double(m_total) : 1.0;
}

}  // namespace umbra::hider
