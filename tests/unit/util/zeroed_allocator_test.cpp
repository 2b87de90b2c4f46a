#include "umbra/util/zeroed_allocator.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <thread>
#include <vector>

using namespace umbra;

namespace {

bool allZero(const FloatPlane& p) {
    return std::all_of(p.begin(), p.end(), [](float v) { return v == 0.0f; });
}

}  // namespace

// Both sides of the huge-page threshold, and sizes just off a 2 MiB
// multiple: every element starts as zero and keeps what is written.
TEST(ZeroedAllocator, PlanesOfEverySizeStartZeroAndHoldWhatIsWritten) {
    const size_t floats[] = {0, 1, 1000, kLargeZeroedBytes / 4 - 1, kLargeZeroedBytes / 4,
                             (size_t(2) << 20) / 4 + 3, 2048 * 2048, 1920 * 1080 * 4};
    for (size_t n : floats) {
        FloatPlane p(n);
        ASSERT_EQ(p.size(), n);
        EXPECT_TRUE(allZero(p)) << n;
        std::iota(p.begin(), p.end(), 1.0f);
        for (size_t i = 0; i < n; i += std::max<size_t>(1, n / 97)) EXPECT_EQ(p[i], float(i + 1)) << n;
        if (n) {
            EXPECT_EQ(p.back(), float(n));
        }
    }
}

#if defined(__SANITIZE_ADDRESS__)
#define UMBRA_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define UMBRA_TEST_ASAN 1
#endif
#endif
#ifdef UMBRA_TEST_ASAN
#include <sanitizer/asan_interface.h>
#endif

// A large plane starts on a huge page; under AddressSanitizer it comes from
// calloc instead, so that the sanitizer guards its end.
TEST(ZeroedAllocator, LargePlanesAreHugePageAlignedOrGuardedByTheSanitizer) {
    FloatPlane p(size_t(3) << 20);  // 12 MiB
#ifdef UMBRA_TEST_ASAN
    EXPECT_FALSE(__asan_address_is_poisoned(&p.back()));
    EXPECT_TRUE(__asan_address_is_poisoned(p.data() + p.size()));
#else
    EXPECT_EQ(reinterpret_cast<uintptr_t>(p.data()) % (uintptr_t(2) << 20), 0u);
#endif
}

// A plane grown past the threshold and copied: the contents move with it,
// the new part is zero.
TEST(ZeroedAllocator, GrowingAndCopyingKeepContents) {
    FloatPlane p(1000, 5.0f);
    p.resize(kLargeZeroedBytes);  // floats: four times past the threshold
    EXPECT_EQ(p[999], 5.0f);
    EXPECT_EQ(p[1000], 0.0f);
    EXPECT_EQ(p.back(), 0.0f);
    FloatPlane q = p;
    EXPECT_EQ(q[0], 5.0f);
    EXPECT_EQ(q[1000], 0.0f);
    p = FloatPlane(7, 2.0f);  // the large block is given back
    EXPECT_EQ(p.size(), 7u);
    EXPECT_EQ(q.size(), kLargeZeroedBytes);
}

// Pooled blocks: every live block is distinct and whole (two threads take
// and give back thousands, each writing its own pattern over all of its
// block and finding it intact), and other sizes work as malloc's.
TEST(PooledAllocator, BlocksAreDistinctAndKeepWhatIsWrittenAcrossThreads) {
    auto churn = [](uint32_t seed, int* damaged) {
        std::vector<std::vector<float, PooledAllocator<float>>> held;
        for (int round = 0; round < 3000; ++round) {
            std::vector<float, PooledAllocator<float>> tile(kPooledBytes / sizeof(float));
            std::fill(tile.begin(), tile.end(), float(seed + uint32_t(round)));
            held.push_back(std::move(tile));
            if (round % 3 == 2) {  // give back one in three, oldest first after a while
                const size_t k = size_t(round) % held.size();
                const float expected = held[k][0];
                *damaged += !std::all_of(held[k].begin(), held[k].end(), [&](float v) { return v == expected; });
                held.erase(held.begin() + long(k));
            }
        }
        for (const auto& tile : held)
            *damaged += !std::all_of(tile.begin(), tile.end(), [&](float v) { return v == tile[0]; });
    };
    int damagedA = 0, damagedB = 0;
    std::thread a(churn, 1000000u, &damagedA), b(churn, 2000000u, &damagedB);
    a.join();
    b.join();
    EXPECT_EQ(damagedA, 0);
    EXPECT_EQ(damagedB, 0);
    // Other sizes: malloc's, of the size asked.
    std::vector<float, PooledAllocator<float>> odd(1000, 3.0f), none;
    EXPECT_EQ(std::count(odd.begin(), odd.end(), 3.0f), 1000);
    EXPECT_TRUE(none.empty());
}
