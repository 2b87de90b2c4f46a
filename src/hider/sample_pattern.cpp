#include "sample_pattern.h"

#include "umbra/film/pixel_filter.h"
#include "umbra/util/error.h"
#include "umbra/util/rng.h"

#include <cmath>

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
    for (int uy = 0; uy < kPatternPeriod; ++uy)
        for (int ux = 0; ux < kPatternPeriod; ++ux)
            for (int s = 0; s < xs * ys; ++s) {
                const Vec2 o = offset(ux, uy, s, settings);
                const size_t k = size_t(uy * ys + s / xs) * size_t(m_columns) + size_t(ux * xs + s % xs);
                m_x[k] = o.x;
                m_y[k] = o.y;
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
