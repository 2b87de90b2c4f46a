#include "sample_pattern.h"

#include "umbra/film/pixel_filter.h"
#include "umbra/util/error.h"
#include "umbra/util/rng.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace umbra::hider {

float placeInStratum(float v, int t, int n) {
    const float fn = float(n);
    while (floorToInt(v * fn) > t) v = std::nextafter(v, -kInfinity);
    while (floorToInt(v * fn) < t) v = std::nextafter(v, kInfinity);
    return v;
}

Vec2 SamplePattern::offset(int ux, int uy, int s, const PatternSettings& p) {
    const int xs = p.xSamples, ys = p.ySamples;
    const int i = s % xs, j = s / xs;
    float jx = 0.5f, jy = 0.5f;
    if (p.jitter) {
        uint32_t h = hashKeys(p.frameSeed, uint32_t(ux), uint32_t(uy), uint32_t(s));
        jx = hashToUnit(h);
        jy = hashToUnit(hash32(h ^ 0x68e31da4u));
    }
    return {placeInStratum((float(i) + jx) / float(xs), i, xs), placeInStratum((float(j) + jy) / float(ys), j, ys)};
}

namespace {

/// The ranks of [0, n) in a hashed permutation: rank[i] is the position
/// item i takes when the items are ordered by their hashes (ties by index).
void hashedRanks(int n, uint32_t key, std::vector<int>& rank) {
    std::vector<std::pair<uint32_t, int>> order(static_cast<size_t>(n));
    for (int k = 0; k < n; ++k) order[size_t(k)] = {hashKeys(key, uint32_t(k)), k};
    std::sort(order.begin(), order.end());
    rank.resize(size_t(n));
    for (int k = 0; k < n; ++k) rank[size_t(order[size_t(k)].second)] = k;
}

/// The strata (time or lens) of a pixel's xs x ys samples, rank[s] for
/// sample s = i + xs * j in column i and row j. Square patterns (k x k)
/// get a random Latin square of the k groups of k consecutive strata --
/// every row and every column of the pixel takes one stratum of each group
/// -- and a random order within each group; others a hashed permutation.
///
/// Why: the film's filter weighs a pixel's samples unequally (a Gaussian
/// reaches over half of each neighbour), and under a random permutation a
/// weighted subset, such as a neighbour's two nearest columns, often holds
/// mostly early or mostly late times: a blurred ramp came out with 2-3x
/// the noise of one filtered by a box. With each row and column spread
/// over the whole shutter (or lens), any weighting smooth across the pixel
/// sees the whole shutter. Which stratum a given position takes is still
/// uniformly random from pixel to pixel.
void balancedRanks(int xs, int ys, uint32_t key, std::vector<int>& rank) {
    if (xs != ys || xs < 2) {
        hashedRanks(xs * ys, key, rank);
        return;
    }
    const int k = xs;
    std::vector<int> rows, columns, groups;
    hashedRanks(k, hashKeys(key, 0x1b873593u), rows);
    hashedRanks(k, hashKeys(key, 0xcc9e2d51u), columns);
    hashedRanks(k, hashKeys(key, 0xe6546b64u), groups);
    // Sample (i, j) is in group (row j + column i) mod k, relabelled: a
    // random Latin square. The k samples of a group (one per row) take
    // its k strata in a random order.
    std::vector<std::vector<int>> within(static_cast<size_t>(k));
    for (int g = 0; g < k; ++g) hashedRanks(k, hashKeys(key, 0x85ebca6bu, uint32_t(g)), within[size_t(g)]);
    std::vector<int> taken(size_t(k), 0);
    rank.assign(size_t(k * k), 0);
    for (int s = 0; s < k * k; ++s) {
        const int i = s % k, j = s / k;
        const int g = groups[size_t((rows[size_t(j)] + columns[size_t(i)]) % k)];
        rank[size_t(s)] = g * k + within[size_t(g)][size_t(taken[size_t(g)]++)];
    }
}

uint32_t timePixelKey(int ux, int uy, const PatternSettings& p) {
    return hashKeys(p.frameSeed ^ 0x2545f491u, uint32_t(ux), uint32_t(uy));
}
uint32_t lensPixelKey(int ux, int uy, const PatternSettings& p) {
    return hashKeys(p.frameSeed ^ 0x85ebca6bu, uint32_t(ux), uint32_t(uy));
}

/// The fine time stratum of pattern pixel (ux, uy) within its tile.
int tileRank(int ux, int uy, const PatternSettings& p) {
    std::vector<int> rank;
    // Balanced like a pixel's own samples: each row and column of the tile
    // spans the fine strata, so the pixels a filter blends differ in time.
    balancedRanks(kTimeTile, kTimeTile,
                  hashKeys(p.frameSeed ^ 0x9e3779b9u, uint32_t(ux / kTimeTile), uint32_t(uy / kTimeTile)), rank);
    return rank[size_t((ux % kTimeTile) + kTimeTile * (uy % kTimeTile))];
}

/// sampleTime() given the pixel's coarse stratum of s and its tile rank.
///
/// Within coarse stratum k, the pixel of tile rank r takes fine stratum
/// (r + k T^2 / n) mod T^2 (T = kTimeTile): for each k the tile's pixels
/// still take one fine stratum each, and a pixel's own samples spread over
/// all the fine strata instead of sharing one, so the mean time of a
/// pixel's samples is the shutter's middle to within a fine stratum (with
/// one shared offset it was off by up to half a coarse stratum, which
/// doubled the noise of blurred shading and edges).
float timeOf(int s, int coarse, int tileRank, uint32_t pixelKey, const PatternSettings& p) {
    const int n = p.xSamples * p.ySamples;
    const int fineCount = kTimeTile * kTimeTile;
    const int fine = (tileRank + int(int64_t(coarse) * fineCount / n)) % fineCount;
    const float j = p.jitter ? hashToUnit(hashKeys(pixelKey, uint32_t(s), 0x7f4a7c15u)) : 0.5f;
    const float strata = float(n * fineCount);
    const float u = std::min((float(coarse * fineCount + fine) + j) / strata, 0x1.fffffep-1f);
    return std::min(shutterWarp(u, p.opening[0], p.opening[1]), 0x1.fffffep-1f);
}

/// sampleLens() given the lens stratum of s.
Vec2 lensOf(int s, int stratum, uint32_t pixelKey, const PatternSettings& p) {
    const int xs = p.xSamples, ys = p.ySamples;
    float jx = 0.5f, jy = 0.5f;
    if (p.jitter) {
        const uint32_t h = hashKeys(pixelKey, uint32_t(s), 0xc2b2ae35u);
        jx = hashToUnit(h);
        jy = hashToUnit(hash32(h ^ 0x27d4eb2fu));
    }
    // The square [-1, 1]^2, then Shirley & Chiu's concentric map.
    const float a = 2.0f * (float(stratum % xs) + jx) / float(xs) - 1.0f;
    const float b = 2.0f * (float(stratum / xs) + jy) / float(ys) - 1.0f;
    if (a == 0 && b == 0) return {0, 0};
    float r, phi;
    if (std::abs(a) > std::abs(b)) {
        r = a;
        phi = (kPi / 4) * (b / a);
    } else {
        r = b;
        phi = kPi / 2 - (kPi / 4) * (a / b);
    }
    return {r * std::cos(phi), r * std::sin(phi)};
}

}  // namespace

float shutterWarp(float u, float a, float b) {
    if (a <= 0 && b >= 1) return u;
    // Density: rising on [0, a], flat on [a, b], falling on [b, 1]; its
    // area is (b - a) + (a + 1 - b) / 2 with a flat height of 1.
    const float area = (b - a) + 0.5f * (a + (1 - b));
    const float target = u * area;
    const float rise = 0.5f * a;
    if (target < rise) return a > 0 ? std::sqrt(2.0f * a * target) : 0.0f;
    if (target < rise + (b - a)) return a + (target - rise);
    const float tail = area - target;  // area left under the falling ramp
    return 1.0f - (1 - b > 0 ? std::sqrt(2.0f * (1 - b) * tail) : 0.0f);
}

float sampleTime(int ux, int uy, int s, const PatternSettings& p) {
    std::vector<int> rank;
    const uint32_t key = timePixelKey(ux, uy, p);
    balancedRanks(p.xSamples, p.ySamples, key, rank);
    return timeOf(s, rank[size_t(s)], tileRank(ux, uy, p), key, p);
}

Vec2 sampleLens(int ux, int uy, int s, const PatternSettings& p) {
    std::vector<int> rank;
    const uint32_t key = lensPixelKey(ux, uy, p);
    balancedRanks(p.xSamples, p.ySamples, key, rank);
    return lensOf(s, rank[size_t(s)], key, p);
}

void SamplePattern::prepare(const PatternSettings& settings) {
    if (m_built && settings == m_settings) return;
    UMBRA_CHECK(settings.xSamples >= 1 && settings.ySamples >= 1, "bad sample pattern {} x {}", settings.xSamples,
                settings.ySamples);
    m_settings = settings;
    m_built = true;
    ++m_generation;
    const int xs = settings.xSamples, ys = settings.ySamples;
    m_columns = kPatternPeriod * xs;
    m_rows = kPatternPeriod * ys;
    m_x.resize(size_t(m_columns) * size_t(m_rows));
    m_y.resize(m_x.size());
    m_time.assign(settings.times ? m_x.size() : 0, 0.0f);
    m_timeStratum.assign(settings.times ? m_x.size() : 0, 0);
    const size_t timeStrata = xs * ys == 1 ? size_t(kTimeTile * kTimeTile) : size_t(xs * ys);
    m_stratumStart.assign(settings.times ? timeStrata : 0, 1.0f);
    m_stratumEnd.assign(settings.times ? timeStrata : 0, 0.0f);
    m_lensStratum.assign(settings.lens ? m_x.size() : 0, 0);
    m_lensBox.clear();
    for (int k = 0; settings.lens && k < xs * ys; ++k) m_lensBox.insert(m_lensBox.end(), {kInfinity, kInfinity, -kInfinity, -kInfinity});
    m_lensX.assign(settings.lens ? m_x.size() : 0, 0.0f);
    m_lensY.assign(settings.lens ? m_x.size() : 0, 0.0f);
    std::vector<int> timeRank, lensRank;
    for (int uy = 0; uy < kPatternPeriod; ++uy)
        for (int ux = 0; ux < kPatternPeriod; ++ux) {
            const uint32_t timeKey = timePixelKey(ux, uy, settings), lensKey = lensPixelKey(ux, uy, settings);
            int fine = 0;
            if (settings.times) {
                balancedRanks(xs, ys, timeKey, timeRank);
                fine = tileRank(ux, uy, settings);
            }
            if (settings.lens) balancedRanks(xs, ys, lensKey, lensRank);
            for (int s = 0; s < xs * ys; ++s) {
                const Vec2 o = offset(ux, uy, s, settings);
                const size_t k = size_t(uy * ys + s / xs) * size_t(m_columns) + size_t(ux * xs + s % xs);
                m_x[k] = o.x;
                m_y[k] = o.y;
                if (settings.times) {
                    const float t = timeOf(s, timeRank[size_t(s)], fine, timeKey, settings);
                    // One sample a pixel: its tile's fine strata (timeCell).
                    const int stratum = xs * ys == 1 ? fine : timeRank[size_t(s)];
                    m_time[k] = t;
                    m_timeStratum[k] = uint16_t(stratum);
                    m_stratumStart[size_t(stratum)] = std::min(m_stratumStart[size_t(stratum)], t);
                    m_stratumEnd[size_t(stratum)] = std::max(m_stratumEnd[size_t(stratum)], t);
                }
                if (settings.lens) {
                    const int stratum = lensRank[size_t(s)];
                    const Vec2 l = lensOf(s, stratum, lensKey, settings);
                    m_lensX[k] = l.x;
                    m_lensY[k] = l.y;
                    m_lensStratum[k] = uint16_t(stratum);
                    float* box = &m_lensBox[4 * size_t(stratum)];
                    box[0] = std::min(box[0], l.x);
                    box[1] = std::min(box[1], l.y);
                    box[2] = std::max(box[2], l.x);
                    box[3] = std::max(box[3], l.y);
                }
            }
        }
}

void PatternFilterWeights::prepare(const SamplePattern& pattern, const film::PixelFilter& filter) {
    UMBRA_CHECK(filter.separable(), "tabulated weights need a separable filter, not {}", filter.name());
    if (m_built && m_patternGeneration == pattern.generation() && m_filterKind == int(filter.kind()) &&
        m_xWidth == filter.xWidth() && m_yWidth == filter.yWidth())
        return;
    m_built = true;
    m_patternGeneration = pattern.generation();
    m_filterKind = int(filter.kind());
    m_xWidth = filter.xWidth();
    m_yWidth = filter.yWidth();
    m_mx = filter.xMargin();
    m_my = filter.yMargin();
    UMBRA_CHECK(m_mx <= 100 && m_my <= 100, "pixel filter too wide ({} x {})", filter.xWidth(), filter.yWidth());
    const int xTaps = 2 * m_mx + 1, yTaps = 2 * m_my + 1;
    m_stride = xTaps + yTaps;
    m_columns = pattern.columns();
    const int rows = pattern.rows();
    const size_t strata = size_t(m_columns) * size_t(rows);
    m_reach.resize(strata);
    m_weights.resize(strata * size_t(m_stride));

    // One axis: the weights of the pixels at offsets -margin .. margin and
    // the first and last non-zero one (closed support, as PixelFilter).
    auto tabulate = [](float offset, int margin, float* w, int8_t* first, int8_t* last, auto weightAt) {
        *first = int8_t(margin + 1);
        *last = int8_t(-margin - 1);
        for (int d = -margin; d <= margin; ++d) {
            const float v = weightAt(offset - (float(d) + 0.5f));
            w[d + margin] = v;
            if (v == 0.0f) continue;
            if (*first > d) *first = int8_t(d);
            *last = int8_t(d);
        }
    };
    for (int ty = 0; ty < rows; ++ty) {
        const float* ox = pattern.xRow(ty);
        const float* oy = pattern.yRow(ty);
        for (int tx = 0; tx < m_columns; ++tx) {
            const size_t k = size_t(ty) * size_t(m_columns) + size_t(tx);
            Reach& r = m_reach[k];
            float* w = &m_weights[k * size_t(m_stride)];
            tabulate(ox[tx], m_mx, w, &r.x0, &r.x1, [&](float t) { return filter.weightX(t); });
            tabulate(oy[tx], m_my, w + xTaps, &r.y0, &r.y1, [&](float t) { return filter.weightY(t); });
        }
    }

    // The sums, over the samples of the pixels within the margin in
    // stratum order (rows, then columns), of the weights a resolve uses.
    const int xs = pattern.settings().xSamples, ys = pattern.settings().ySamples;
    m_inverseSum.resize(size_t(kPatternPeriod) * size_t(kPatternPeriod));
    for (int uy = 0; uy < kPatternPeriod; ++uy)
        for (int ux = 0; ux < kPatternPeriod; ++ux) {
            float sum = 0.0f;
            for (int dy = -m_my; dy <= m_my; ++dy)
                for (int j = 0; j < ys; ++j) {
                    const int ty = positiveMod(uy + dy, kPatternPeriod) * ys + j;
                    for (int dx = -m_mx; dx <= m_mx; ++dx)
                        for (int i = 0; i < xs; ++i) {
                            const int tx = positiveMod(ux + dx, kPatternPeriod) * xs + i;
                            // This pixel lies at offset -d from the sample's.
                            const float* w = weights(tx, ty);
                            sum += w[m_mx - dx] * w[xTaps + m_my - dy];
                        }
                }
            m_inverseSum[size_t(uy) * size_t(kPatternPeriod) + size_t(ux)] = sum != 0.0f ? 1.0f / sum : 0.0f;
        }
}

}  // namespace umbra::hider
