#pragma once
// How far a pass has got, by work rather than by buckets: a frame whose top
// third is empty sky finishes its first third of buckets at once, so
// counting buckets says 30% done when almost none of the work is. Each
// bucket's work is estimated once its top-level primitives are placed
// (before any split or dice), from the raster area they cover there.

#include "umbra/util/math.h"

#include <atomic>
#include <cstdint>
#include <vector>

namespace umbra::hider {

/// The buckets of a pass: the film's crop region cut into bucket-sized
/// rectangles, numbered in scanline order.
struct BucketLayout {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // crop region, raster pixels, [x0, x1) x [y0, y1)
    int bucketWidth = 16, bucketHeight = 16;
    int bucketsX() const { return (x1 - x0 + bucketWidth - 1) / bucketWidth; }
    int bucketsY() const { return (y1 - y0 + bucketHeight - 1) / bucketHeight; }
};

/// What an empty pixel costs against a pixel a primitive covers: an empty
/// bucket still clears and filters its samples, but shades and samples no
/// micropolygon. 0 for depth passes, which skip empty buckets altogether.
inline constexpr double kEmptyPixelWorkColour = 0.1;

/// Expected work of each bucket, in covered-pixel units: the area of each
/// primitive's raster bound (x, y) inside the bucket, summed (micropolygons
/// and samples tested grow with it at a given shading rate), plus
/// `emptyPixelWork` for every pixel of the bucket.
std::vector<double> estimateBucketWork(const BucketLayout& layout, const std::vector<Bound3>& rasterBounds,
                                       double emptyPixelWork);

/// The share of a pass's estimated work done, as buckets finish in any
/// order and on any thread: never decreasing, 1 when every bucket is done.
class WorkFraction {
public:
    explicit WorkFraction(const std::vector<double>& bucketWork);
    /// Records bucket `b` as done; returns the fraction done so far
    /// (including it).
    double finish(int b);
    double fraction() const;

private:
    // Work in fixed point, so concurrent additions are exact and the
    // fraction reaches exactly 1.
    std::vector<uint64_t> m_work;
    uint64_t m_total = 0;
    std::atomic<uint64_t> m_done{0};
};

}  // namespace umbra::hider
