// Progress by work (hider/bucket_work.h): a 1080p frame whose top third is
// empty sky is not a third done when its sky buckets are. The fractions are
// checked against the areas computed by hand; no clock is read.

#include "umbra/hider/bucket_work.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>

using namespace umbra;
using namespace umbra::hider;

namespace {

constexpr BucketLayout k1080p{0, 0, 1920, 1080, 16, 16};

Bound3 rect(float x0, float y0, float x1, float y1) { return {{x0, y0, 1}, {x1, y1, 2}}; }

}  // namespace

TEST(BucketWork, AreaOfEachBoundInsideEachBucket) {
    const BucketLayout layout{0, 0, 40, 20, 16, 16};  // 3 x 2 buckets, the last column and row cut short
    ASSERT_EQ(layout.bucketsX(), 3);
    ASSERT_EQ(layout.bucketsY(), 2);
    // 10..30 x 4..12 spans buckets 0 and 1 of the top row; the second bound
    // reaches past the film and is clipped to it.
    const std::vector<double> work = estimateBucketWork(layout, {rect(10, 4, 30, 12), rect(35, 18, 90, 50)}, 0.5);
    const std::vector<double> expected = {
        0.5 * 16 * 16 + 6 * 8, 0.5 * 16 * 16 + 14 * 8, 0.5 * 8 * 16,  // top row
        0.5 * 16 * 4,          0.5 * 16 * 4,           0.5 * 8 * 4 + 5 * 2,
    };
    ASSERT_EQ(work.size(), expected.size());
    for (size_t i = 0; i < work.size(); ++i) EXPECT_DOUBLE_EQ(work[i], expected[i]) << i;
}

TEST(BucketWork, BoundsAcrossTheEyePlaneCoverTheFilm) {
    const BucketLayout layout{0, 0, 32, 32, 16, 16};
    const Bound3 infinite{{-kInfinity, -kInfinity, 0}, {kInfinity, kInfinity, 1}};
    const std::vector<double> work = estimateBucketWork(layout, {infinite, Bound3()}, 0.0);
    for (double w : work) EXPECT_DOUBLE_EQ(w, 256.0);
}

TEST(WorkFraction, EmptySkyIsNotAThirdOfTheFrame) {
    // The lower two thirds hold a ground plane and two objects on it; the
    // top third (y < 360) is empty.
    const std::vector<Bound3> bounds = {rect(0, 360, 1920, 1080), rect(200, 500, 600, 900), rect(1200, 400, 1500, 700)};
    const std::vector<double> work = estimateBucketWork(k1080p, bounds, kEmptyPixelWorkColour);
    const double empty = kEmptyPixelWorkColour * 1920 * 1080;
    const double total = empty + 1920 * 720 + 400 * 400 + 300 * 300;
    EXPECT_NEAR(std::accumulate(work.begin(), work.end(), 0.0), total, 1e-6 * total);

    WorkFraction fraction(work);
    const int bucketsX = k1080p.bucketsX(), bucketsY = k1080p.bucketsY();
    double last = 0;
    for (int b = 0; b < bucketsX * bucketsY; ++b) {
        const double f = fraction.finish(b);
        EXPECT_GE(f, last) << b;  // in scanline order, as the workers take them
        last = f;
        const int rowsDone = b / bucketsX + 1;
        if (b % bucketsX != bucketsX - 1) continue;
        if (rowsDone == 22) {
            // The sky's 22 rows (352 pixels): a third of the buckets, 4% of the work.
            const double sky = kEmptyPixelWorkColour * 1920 * 352;
            EXPECT_NEAR(f, sky / total, 1e-5);
            EXPECT_LT(f, 0.05);
            EXPECT_GT(double(rowsDone) / bucketsY, 0.32);
        }
        if (rowsDone == 45) {
            // Down to y = 720: the sky, half the plane, the first object whole
            // and the second's part above 720 (all of it).
            const double upTo720 = kEmptyPixelWorkColour * 1920 * 720 + 1920 * 360 + 400 * 220 + 300 * 300;
            EXPECT_NEAR(f, upTo720 / total, 1e-5);
        }
    }
    EXPECT_DOUBLE_EQ(last, 1.0);
}

TEST(WorkFraction, AnyOrderEndsAtOneAndNeverGoesBack) {
    const std::vector<Bound3> bounds = {rect(0, 360, 1920, 1080)};
    const std::vector<double> work = estimateBucketWork(k1080p, bounds, 0.0);  // a depth pass: empty is free
    std::vector<int> order(work.size());
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), std::mt19937(7));
    WorkFraction fraction(work);
    double last = 0;
    for (int b : order) {
        const double f = fraction.finish(b);
        EXPECT_GE(f, last);
        last = f;
    }
    EXPECT_DOUBLE_EQ(fraction.fraction(), 1.0);
    // Every bucket counts a little: an all-empty depth pass still advances.
    WorkFraction nothing(std::vector<double>(4, 0.0));
    EXPECT_DOUBLE_EQ(nothing.finish(0), 0.25);
}
