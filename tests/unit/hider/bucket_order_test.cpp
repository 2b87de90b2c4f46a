// The order workers take a row's buckets in (hider/bucket_scheduler.h):
// every column once, and buckets taken one after another (and so sampled
// at the same time by different workers) far apart.

#include "umbra/hider/bucket_scheduler.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>

using namespace umbra::hider;

TEST(BucketRowOrder, EveryColumnOnceForAnyWidthAndThreads) {
    for (int width = 0; width <= 130; ++width)
        for (int threads = 1; threads <= 9; ++threads) {
            std::vector<int> order = bucketRowOrder(width, threads);
            ASSERT_EQ(order.size(), size_t(width)) << width << " " << threads;
            std::sort(order.begin(), order.end());
            for (int c = 0; c < width; ++c) ASSERT_EQ(order[size_t(c)], c) << width << " " << threads;
        }
}

TEST(BucketRowOrder, OneThreadGoesLeftToRight) {
    std::vector<int> expected(120);
    std::iota(expected.begin(), expected.end(), 0);
    EXPECT_EQ(bucketRowOrder(120, 1), expected);
}

// A 1080p frame's row of 16-pixel buckets: with two workers, the two
// buckets taken together are half the row apart.
TEST(BucketRowOrder, TwoThreadsAlternateBetweenTheRowsHalves) {
    const std::vector<int> order = bucketRowOrder(120, 2);
    for (size_t k = 0; k + 1 < order.size(); k += 2) {
        EXPECT_EQ(order[k], int(k / 2));
        EXPECT_EQ(order[k + 1], 60 + int(k / 2));
    }
    // An odd width: the second stretch is one shorter and ends first.
    EXPECT_EQ(bucketRowOrder(5, 2), (std::vector<int>{0, 3, 1, 4, 2}));
}

// Any `threads` consecutive turns fall in different stretches, each at
// least the stretch's length from the others.
TEST(BucketRowOrder, ConsecutiveTurnsAreAStretchApart) {
    const int width = 128, threads = 4, stretch = 32;
    const std::vector<int> order = bucketRowOrder(width, threads);
    for (size_t k = 0; k + threads <= order.size(); k += threads)
        for (int a = 0; a < threads; ++a)
            for (int b = a + 1; b < threads; ++b)
                EXPECT_GE(std::abs(order[k + size_t(a)] - order[k + size_t(b)]), stretch);
}
