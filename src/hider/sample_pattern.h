#pragma once
// The stochastic hider's sample pattern and a pixel filter's weights over it
// (internal to the hider; SampleBuffer is the interface).
//
// The jitter is periodic: the offset of sample s inside pixel (px, py) is
// that of pixel (px mod P, py mod P), P = kPatternPeriod, the *pattern
// pixel*. So positions and filter weights are computed once per frame into
// tables, and each bucket copies positions and looks weights up instead of
// hashing and evaluating them for every sample. (Tiling one jittered
// pattern of 32 x 32 pixels is the usual trade: its period is far longer
// than any filter, so the repetition does not show as aliasing.)
//
// Tables are indexed by *pattern stratum*: sample s = j * xs + i of pattern
// pixel (ux, uy) is stratum column tx = ux * xs + i, row ty = uy * ys + j of
// a (P * xs) x (P * ys) grid, row-major. Global stratum (sx, sy) (as in
// sample_buffer.h) maps to (sx mod P * xs, sy mod P * ys), so a row of a
// bucket's strata is a row of the table that wraps at most once.

#include "umbra/hider/sample_buffer.h"
#include "umbra/util/math.h"

#include <cstdint>
#include <vector>

namespace umbra::film {
class PixelFilter;
}

namespace umbra::hider {

/// v mod n in [0, n), also for negative v.
inline int positiveMod(int v, int n) {
    int r = v % n;
    return r < 0 ? r + n : r;
}

/// floor() without a libm call (x86-64 without SSE4.1 has no rounding
/// instruction); exact for the magnitudes of raster coordinates.
inline int floorToInt(float v) {
    int i = int(v);
    return float(i) > v ? i - 1 : i;
}

/// v moved by the fewest ulps so that floor(v * n) == t: a coordinate kept
/// strictly inside stratum t of an axis with n strata per pixel. The
/// rasteriser finds samples by floor(x * xs), and rounding may otherwise
/// push a sample onto its stratum's far edge.
float placeInStratum(float v, int t, int n);

/// What fixes a frame's sample pattern.
struct PatternSettings {
    int xSamples = 1, ySamples = 1;
    bool jitter = true;
    uint32_t frameSeed = 0;
    bool times = false;                  // tabulate each sample's time (motion blur)
    float opening[2] = {0, 1};           // the shutter's shape (scene::Options::shutterOpening)
    bool lens = false;                   // tabulate each sample's lens position (depth of field)
    bool operator==(const PatternSettings& o) const {
        return xSamples == o.xSamples && ySamples == o.ySamples && jitter == o.jitter && frameSeed == o.frameSeed &&
               times == o.times && opening[0] == o.opening[0] && opening[1] == o.opening[1] && lens == o.lens;
    }
};


/// A time drawn uniformly in [0, 1) mapped through the shutter's shape:
/// fully open from a to b, opening and closing linearly before and after
/// (the inverse of the trapezoid's distribution).
float shutterWarp(float u, float a, float b);

/// The time, in [0, 1), of sample s of pattern pixel (ux, uy). Stratified
/// twice: a pixel's n samples take one each of n strata in a hashed order
/// (so time is independent of the sample's place in the pixel), and the
/// kTimeTile^2 pixels of a tile take one each of the n * kTimeTile^2 finer
/// strata inside (so a depth map of one sample a pixel still sees every
/// time across a few texels, which is what percentage-closer filtering
/// averages over).
float sampleTime(int ux, int uy, int s, const PatternSettings& settings);
/// The lens position of sample s of pattern pixel (ux, uy) on the unit
/// disc: strata of an xs x ys grid over the square, taken in a hashed order
/// independent of the time's, mapped onto the disc by Shirley & Chiu's
/// concentric map (which keeps strata compact).
Vec2 sampleLens(int ux, int uy, int s, const PatternSettings& settings);

/// The offsets inside their pixel of one period of samples.
class SamplePattern {
public:
    /// The offset, in [0, 1)^2 and strictly inside its stratum, of sample s
    /// (0 .. xs*ys-1) of pattern pixel (ux, uy) in [0, P)^2: the jitter,
    /// hashed from (frame seed, pattern pixel, sample index), or the
    /// stratum's centre without jitter.
    static Vec2 offset(int ux, int uy, int s, const PatternSettings& settings);

    /// Builds the table unless it already holds these settings.
    void prepare(const PatternSettings& settings);
    const PatternSettings& settings() const { return m_settings; }
    /// Counts rebuilds, so tables derived from this one know when to follow.
    uint64_t generation() const { return m_generation; }

    int columns() const { return m_columns; }  // P * xs
    int rows() const { return m_rows; }        // P * ys
    /// Offsets of the samples of pattern stratum row ty, by column tx.
    const float* xRow(int ty) const { return &m_x[size_t(ty) * size_t(m_columns)]; }
    const float* yRow(int ty) const { return &m_y[size_t(ty) * size_t(m_columns)]; }
    /// Times and lens positions in the same layout, when the settings ask.
    const float* timeRow(int ty) const { return &m_time[size_t(ty) * size_t(m_columns)]; }
    const float* lensXRow(int ty) const { return &m_lensX[size_t(ty) * size_t(m_columns)]; }
    const float* lensYRow(int ty) const { return &m_lensY[size_t(ty) * size_t(m_columns)]; }
    /// Motion: each sample's time stratum, and the earliest and latest time
    /// that any sample of stratum k takes, so a micropolygon can be bounded
    /// over the part of the shutter a stratum's samples see. Every *cell*
    /// of timeCell() x timeCell() pixels (aligned to multiples of it) has
    /// one sample in each of the timeStrata() strata: with several samples
    /// a pixel, a cell is a pixel and the strata its xs * ys coarse ones;
    /// with one (a depth map), a cell is a kTimeTile x kTimeTile tile and
    /// the strata its pixels' fine ones.
    const uint16_t* timeStratumRow(int ty) const { return &m_timeStratum[size_t(ty) * size_t(m_columns)]; }
    int timeStrata() const { return int(m_stratumStart.size()); }
    int timeCell() const { return m_settings.xSamples * m_settings.ySamples == 1 ? kTimeTile : 1; }
    float stratumStart(int k) const { return m_stratumStart[size_t(k)]; }
    float stratumEnd(int k) const { return m_stratumEnd[size_t(k)]; }
    /// Depth of field likewise: each sample's lens stratum (every pixel has
    /// one sample in each) and the box of lens positions stratum k takes.
    const uint16_t* lensStratumRow(int ty) const { return &m_lensStratum[size_t(ty) * size_t(m_columns)]; }
    /// As x0, y0, x1, y1.
    const float* lensStratumBox(int k) const { return &m_lensBox[4 * size_t(k)]; }

private:
    PatternSettings m_settings;
    bool m_built = false;
    uint64_t m_generation = 0;
    int m_columns = 0, m_rows = 0;
    std::vector<float> m_x, m_y;
    std::vector<float> m_time, m_lensX, m_lensY;
    std::vector<uint16_t> m_timeStratum;
    std::vector<float> m_stratumStart, m_stratumEnd;
    std::vector<uint16_t> m_lensStratum;
    std::vector<float> m_lensBox;
};

/// A separable pixel filter's weights for every sample of a pattern, and
/// the sum of the weights that reach each pattern pixel.
///
/// A sample of pixel q reaches pixel q + d (|d| <= the filter's margin)
/// with weight wx(d.x) * wy(d.y), where wx(dx) = filter.weightX(ox - (dx +
/// 0.5)) for the sample's offset ox inside q (and likewise in y): the
/// weights depend on the sample's offset only, so they repeat with the
/// pattern. Every pixel is reached by all samples of the pixels within the
/// margin (the sample buffer's region covers them), so the sum of weights
/// reaching a pixel repeats with the pattern too and is tabulated, already
/// inverted for normalising.
class PatternFilterWeights {
public:
    /// Pixel offsets from the sample's pixel of the first and last pixel
    /// the sample reaches with a non-zero weight, per axis (x1 < x0 when
    /// none).
    struct Reach {
        int8_t x0, x1, y0, y1;
    };

    /// Builds the tables unless they hold this pattern and filter.
    void prepare(const SamplePattern& pattern, const film::PixelFilter& filter);

    int xMargin() const { return m_mx; }
    int yMargin() const { return m_my; }
    /// Pattern stratum (tx, ty)'s reach and weights: x weights for pixel
    /// offsets -xMargin .. xMargin, then y weights for -yMargin .. yMargin.
    const Reach* reachRow(int ty) const { return &m_reach[size_t(ty) * size_t(m_columns)]; }
    const float* weights(int tx, int ty) const {
        return &m_weights[(size_t(ty) * size_t(m_columns) + size_t(tx)) * size_t(m_stride)];
    }
    /// 1 / (sum of the weights reaching pattern pixel (ux, uy)), 0 if none.
    float inverseWeightSum(int ux, int uy) const {
        return m_inverseSum[size_t(uy) * size_t(kPatternPeriod) + size_t(ux)];
    }

private:
    bool m_built = false;
    uint64_t m_patternGeneration = 0;
    int m_filterKind = -1;
    float m_xWidth = 0, m_yWidth = 0;
    int m_mx = 0, m_my = 0, m_stride = 0, m_columns = 0;
    std::vector<Reach> m_reach;
    std::vector<float> m_weights;
    std::vector<float> m_inverseSum;
};

}  // namespace umbra::hider
