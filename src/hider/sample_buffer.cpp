#include "umbra/hider/sample_buffer.h"

#include "sample_pattern.h"

#include "umbra/film/film.h"
#include "umbra/util/error.h"
#include "umbra/util/lanes.h"
#include "umbra/util/rng.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <cstring>

#include <emmintrin.h>

namespace umbra::hider {

namespace {

/// Bit k set when lane k of a comparison's result is true.
inline int laneMask(I4 m) { return _mm_movemask_ps(__m128(m)); }

/// The total order on hits: nearer first, then grid id, then triangle.
inline bool keyLess(float z, uint64_t id, uint32_t sub, float z2, uint64_t id2, uint32_t sub2) {
    if (z != z2) return z < z2;
    if (id != id2) return id < id2;
    return sub < sub2;
}

/// One triangle edge as an edge function evaluated in a canonical direction
/// (from the endpoint that is smaller by (y, x) to the larger), so the two
/// triangles sharing an edge compute bit-identical values of opposite sign.
/// A sample exactly on the edge belongs to the triangle that runs along the
/// edge in the canonical direction: exactly one of the two (a top-left
/// rule), so shared edges are neither missed nor hit twice. Evaluated for
/// four samples at once; each lane computes exactly what scalar code would.
struct Edge {
    // The edge function's constants, with the sign of the direction folded
    // into dx, dy (negation is exact, so the values are unchanged) and
    // spread over four lanes.
    F4 bx, by, dx, dy;
    I4 inclusive;  // all ones when samples exactly on the edge are inside

    void setup(const Vec3& u, const Vec3& v) {
        bool canonical = u.y < v.y || (u.y == v.y && u.x < v.x);
        const Vec3& a = canonical ? u : v;
        const Vec3& b = canonical ? v : u;
        const float sign = canonical ? 1.0f : -1.0f;
        bx = F4{} + a.x;
        by = F4{} + a.y;
        dx = F4{} + sign * (b.x - a.x);
        dy = F4{} + sign * (b.y - a.y);
        inclusive = I4{} - int32_t(canonical);
    }
    /// Positive inside (for a triangle of positive orientation).
    F4 eval(F4 x, F4 y) const { return dx * (y - by) - dy * (x - bx); }
    I4 inside(F4 e) const { return (e > 0.0f) | ((e == 0.0f) & inclusive); }
};

inline float mean3(const Color& c) { return (c.x + c.y + c.z) * (1.0f / 3.0f); }

}  // namespace

/// One triangle of a micropolygon, set up for sampling: its vertices in
/// positive orientation, their grid indices, its edges, and its index
/// (2 * micropolygon + half) for tie-breaking.
struct SampleBuffer::Tri {
    Vec3 p0, p1, p2;
    int i0, i1, i2;
    uint32_t sub;
    Edge e0, e1, e2;  // e0 is opposite p0 (its barycentric weight), and so on
    float invArea;    // 1 / (e0 + e1 + e2), the edge functions' sum (twice the area) at every point
    float d0, d1, d2; // what depth is interpolated from: z, or 1/z under perspective
    bool valid;
    bool reversed;    // wound clockwise in raster space as the grid gave it

    /// `depthOf` (may be null: z itself) gives the per-vertex quantity
    /// that is linear in raster space.
    void setup(const MicroGrid& g, const float* depthOf, int a, int b, int c, uint32_t subIndex) {
        i0 = a;
        i1 = b;
        i2 = c;
        p0 = g.P[a];
        p1 = g.P[b];
        p2 = g.P[c];
        sub = subIndex;
        float area = (p1.x - p0.x) * (p2.y - p0.y) - (p1.y - p0.y) * (p2.x - p0.x);
        invArea = 1.0f / std::fabs(area);
        // Degenerate (or NaN, or too small to invert) triangles cover nothing.
        valid = area != 0.0f && std::isfinite(area) && std::isfinite(invArea);
        if (!valid) return;
        reversed = area < 0;
        if (area < 0) {
            std::swap(p1, p2);
            std::swap(i1, i2);
        }
        e0.setup(p1, p2);
        e1.setup(p2, p0);
        e2.setup(p0, p1);
        d0 = depthOf ? depthOf[i0] : p0.z;
        d1 = depthOf ? depthOf[i1] : p1.z;
        d2 = depthOf ? depthOf[i2] : p2.z;
    }
    /// Which of four samples the triangle covers (bit k for lane k), and
    /// their barycentric weights of p1 and p2.
    int cover(F4 x, F4 y, F4* b1, F4* b2) const {
        const F4 w0 = e0.eval(x, y), w1 = e1.eval(x, y), w2 = e2.eval(x, y);
        const int covered = laneMask(e0.inside(w0) & e1.inside(w1) & e2.inside(w2));
        *b1 = w1 * invArea;
        *b2 = w2 * invArea;
        return covered;
    }
};

/// Per-grid constants of sample().
struct SampleBuffer::HitContext {
    bool depthMode;
    bool gridOpaque;  // no Oi, or every Oi >= 1
    /// Per sample, a depth beyond which no hit changes anything: the opaque
    /// depth (depth mode: the second depth, or the first with one layer).
    const float* farthestUseful;
    /// Perspective passes: 1/z per vertex, the quantity that is linear in
    /// raster space across a planar micropolygon; null: z itself is.
    const float* inverseDepth;
};

namespace {

inline bool opaqueColor(const Color& o) { return o.x >= 1.0f && o.y >= 1.0f && o.z >= 1.0f; }

}  // namespace

SampleBuffer::SampleBuffer()
    : m_pattern(std::make_unique<SamplePattern>()), m_weights() {}
SampleBuffer::~SampleBuffer() = default;
SampleBuffer::SampleBuffer(SampleBuffer&&) noexcept = default;
SampleBuffer& SampleBuffer::operator=(SampleBuffer&&) noexcept = default;

Vec2 SampleBuffer::samplePosition(int px, int py, int s, int xs, int ys, bool jitter, uint32_t frameSeed) {
    const Vec2 o = SamplePattern::offset(positiveMod(px, kPatternPeriod), positiveMod(py, kPatternPeriod), s,
                                         PatternSettings{xs, ys, jitter, frameSeed});
    return {placeInStratum(float(px) + o.x, px * xs + s % xs, xs),
            placeInStratum(float(py) + o.y, py * ys + s / xs, ys)};
}

namespace {

PatternSettings patternSettings(const SampleBufferConfig& c) {
    PatternSettings p{c.xSamples, c.ySamples, c.jitter, c.frameSeed};
    p.times = c.motion;
    p.opening[0] = c.shutterOpening[0];
    p.opening[1] = c.shutterOpening[1];
    p.lens = c.lens;
    return p;
}

}  // namespace

float SampleBuffer::sampleTime(int px, int py, int s, const SampleBufferConfig& c) {
    return hider::sampleTime(positiveMod(px, kPatternPeriod), positiveMod(py, kPatternPeriod), s, patternSettings(c));
}

Vec2 SampleBuffer::sampleLens(int px, int py, int s, const SampleBufferConfig& c) {
    return hider::sampleLens(positiveMod(px, kPatternPeriod), positiveMod(py, kPatternPeriod), s, patternSettings(c));
}

std::vector<float> SampleBuffer::periodTimes(const SampleBufferConfig& c) {
    UMBRA_CHECK(c.xSamples == 1 && c.ySamples == 1, "periodTimes: {} x {} samples a pixel, expected one", c.xSamples,
                c.ySamples);
    std::vector<float> times(size_t(kPatternPeriod) * size_t(kPatternPeriod));
    for (int y = 0; y < kPatternPeriod; ++y)
        for (int x = 0; x < kPatternPeriod; ++x)
            times[size_t(y) * size_t(kPatternPeriod) + size_t(x)] = hider::sampleTime(x, y, 0, patternSettings(c));
    return times;
}

void SampleBuffer::reset(const SampleBufferConfig& c) {
    UMBRA_CHECK(c.x1 > c.x0 && c.y1 > c.y0, "empty bucket [{},{})x[{},{})", c.x0, c.x1, c.y0, c.y1);
    UMBRA_CHECK(c.xSamples >= 1 && c.ySamples >= 1 && c.margin >= 0 && c.aovCount >= 0, "bad sample buffer settings");
    m_cfg = c;
    const int xs = c.xSamples, ys = c.ySamples;
    m_rx0 = c.x0 - c.margin;
    m_ry0 = c.y0 - c.margin;
    m_rw = c.x1 - c.x0 + 2 * c.margin;
    m_rh = c.y1 - c.y0 + 2 * c.margin;
    m_sw = m_rw * xs;
    m_sh = m_rh * ys;
    m_sx0 = m_rx0 * xs;
    m_sy0 = m_ry0 * ys;
    m_fx0 = float(m_rx0);
    m_fy0 = float(m_ry0);
    m_fx1 = float(m_rx0 + m_rw);
    m_fy1 = float(m_ry0 + m_rh);

    const size_t n = size_t(m_sw) * size_t(m_sh);
    m_px.resize(n + 3);  // rasterizeQuad reads groups of four
    m_py.resize(n + 3);
    // Positions as samplePosition(): pixel + tabulated offset, kept inside
    // the stratum (rounding of the sum rarely needs it; checking is cheap).
    m_pattern->prepare(patternSettings(c));
    const int columns = m_pattern->columns(), rows = m_pattern->rows();
    const float fxs = float(xs), fys = float(ys);
    m_columnPixel.resize(size_t(m_sw));
    for (int sx = 0; sx < m_sw; ++sx) m_columnPixel[size_t(sx)] = float(m_rx0 + sx / xs);
    for (int sy = 0; sy < m_sh; ++sy) {
        const int gy = m_sy0 + sy;  // global stratum row
        const int ty = positiveMod(gy, rows);
        const float pixelY = float(m_ry0 + sy / ys);
        float* x = &m_px[size_t(sy) * size_t(m_sw)];
        float* y = &m_py[size_t(sy) * size_t(m_sw)];
        // The row of the table wraps at most once across the region's row.
        bool outside = false;
        for (int sx = 0; sx < m_sw;) {
            const int tx = positiveMod(m_sx0 + sx, columns);
            const int count = std::min(m_sw - sx, columns - tx);
            const float* __restrict ox = m_pattern->xRow(ty) + tx;
            const float* __restrict oy = m_pattern->yRow(ty) + tx;
            const float* __restrict pixelX = &m_columnPixel[size_t(sx)];
            float* __restrict xk = x + sx;
            float* __restrict yk = y + sx;
            const int gx = m_sx0 + sx;
            int misplaced = 0;
            for (int k = 0; k < count; ++k) {
                const float xv = pixelX[k] + ox[k], yv = pixelY + oy[k];
                xk[k] = xv;
                yk[k] = yv;
                misplaced |= (floorToInt(xv * fxs) - gx - k) | (floorToInt(yv * fys) - gy);
            }
            outside |= misplaced != 0;
            sx += count;
        }
        if (!outside) continue;
        for (int sx = 0; sx < m_sw; ++sx) {
            x[sx] = placeInStratum(x[sx], m_sx0 + sx, xs);
            y[sx] = placeInStratum(y[sx], gy, ys);
        }
    }
    // Times and lens positions, copied from the pattern's tables likewise.
    m_time.resize(c.motion ? n : 0);
    m_lensX.resize(c.lens ? n : 0);
    m_lensY.resize(c.lens ? n : 0);
    if (c.motion || c.lens)
        for (int sy = 0; sy < m_sh; ++sy) {
            const int ty = positiveMod(m_sy0 + sy, rows);
            const float* timeRow = c.motion ? m_pattern->timeRow(ty) : nullptr;
            const float* lensXRow = c.lens ? m_pattern->lensXRow(ty) : nullptr;
            const float* lensYRow = c.lens ? m_pattern->lensYRow(ty) : nullptr;
            // The table's column, wrapped by counting (a modulo a sample
            // was a noticeable part of a blurred bucket's setup).
            int tx = positiveMod(m_sx0, columns);
            for (int sx = 0; sx < m_sw; ++sx) {
                const size_t k = size_t(sy) * size_t(m_sw) + size_t(sx);
                if (timeRow) m_time[k] = timeRow[tx];
                if (lensXRow) {
                    m_lensX[k] = lensXRow[tx];
                    m_lensY[k] = lensYRow[tx];
                }
                tx = tx + 1 == columns ? 0 : tx + 1;
            }
        }
    // The part of the shutter the region's samples cover (boundMotion).
    m_timeMin = 0;
    m_timeMax = 1;
    if (c.motion && n > 0) {
        const auto [least, greatest] = std::minmax_element(m_time.begin(), m_time.end());
        m_timeMin = *least;
        m_timeMax = *greatest;
    }
    // Motion and depth of field: which sample of each pixel sees each
    // stratum of the shutter, and of the lens.
    const int perPixel = xs * ys;
    m_strataSample.clear();
    m_strataStart.clear();
    m_strataEnd.clear();
    m_lensStrataSample.clear();
    m_lensStrataBox.clear();
    // One sample a pixel (a depth map) has its strata across a tile of
    // pixels: without them a micropolygon was tested against every sample
    // it sweeps over (a fast caster near a light, against most of the map).
    if (c.motion && c.sampleStrata) {
        const int strata = m_pattern->timeStrata();
        m_strataGrid = strataGrid(m_pattern->timeCell());
        tabulateStrata(&SamplePattern::timeStratumRow, strata, m_strataGrid, m_strataSample, m_strataX, m_strataY,
                       &m_strataTime);
        for (int k = 0; k < strata; ++k) {
            m_strataStart.push_back(m_pattern->stratumStart(k));
            m_strataEnd.push_back(m_pattern->stratumEnd(k));
        }
    }
    if (c.lens && c.sampleStrata && perPixel > 1) {
        m_lensStrataGrid = strataGrid(1);
        tabulateStrata(&SamplePattern::lensStratumRow, perPixel, m_lensStrataGrid, m_lensStrataSample, m_lensStrataX,
                       m_lensStrataY);
        for (int k = 0; k < perPixel; ++k)
            m_lensStrataBox.insert(m_lensStrataBox.end(), m_pattern->lensStratumBox(k), m_pattern->lensStratumBox(k) + 4);
    }
    // Only the depths (and fragment lists) need clearing: a sample's id,
    // colour, alpha and AOVs are read only once its depth is finite, and
    // every write of a finite depth writes them too. That keeps the reset
    // of a bucket at 8 bytes a sample instead of 40.
    m_z.assign(n + 3, kInfinity);  // rasterizeQuad reads groups of four
    m_id.resize(n);
    m_sub.resize(n);
    if (c.mode == HiderMode::Colour) {
        m_ci.resize(n);
        m_alpha.resize(n);
        m_aov.resize(n * size_t(c.aovCount));
        m_fragHead.assign(n, -1);
        m_z2.clear();
        m_id2.clear();
        m_sub2.clear();
        m_wind.clear();
    } else {
        // The second layer only when it is kept.
        m_z2.assign(c.depthLayers > 1 ? n + 3 : 0, kInfinity);
        m_id2.resize(c.depthLayers > 1 ? n : 0);
        m_sub2.resize(c.depthLayers > 1 ? n : 0);
        m_wind.resize(c.depthLayers > 1 ? n : 0);
        m_ci.clear();
        m_alpha.clear();
        m_aov.clear();
        if (c.csg)
            m_fragHead.assign(n, -1);
        else
            m_fragHead.clear();
    }
    m_frags.clear();
    m_fragAov.clear();
    m_csgFragments = 0;
    m_dissolveReady = false;
    m_csgRay.reset(c.csg ? size_t(c.csg->size()) : 0);
    m_csgNext.assign(c.csg ? size_t(c.csg->size()) : 0, 0);
    m_pixelMax.assign(size_t(m_rw) * size_t(m_rh), kInfinity);
    m_pixelDirty.assign(size_t(m_rw) * size_t(m_rh), 0);
}

float SampleBuffer::dissolveValue(int sx, int sy, uint32_t frameSeed) {
    return hashToUnit(hashKeys(uint32_t(sx), uint32_t(sy), frameSeed, 0x10dU));
}

void SampleBuffer::prepareDissolve() {
    if (m_dissolveReady) return;
    m_dissolve.resize(size_t(m_sw) * size_t(m_sh) + 3);  // read in groups of four
    for (int sy = 0; sy < m_sh; ++sy)
        for (int sx = 0; sx < m_sw; ++sx)
            m_dissolve[size_t(sy) * size_t(m_sw) + size_t(sx)] = dissolveValue(m_sx0 + sx, m_sy0 + sy, m_cfg.frameSeed);
    m_dissolveReady = true;
}

int SampleBuffer::sampleIndex(int px, int py, int s) const {
    const int xs = m_cfg.xSamples, ys = m_cfg.ySamples;
    UMBRA_CHECK(px >= m_rx0 && py >= m_ry0 && px < m_rx0 + m_rw && py < m_ry0 + m_rh && s >= 0 && s < xs * ys,
                "sample ({},{},{}) outside the buffer", px, py, s);
    return ((py - m_ry0) * ys + s / xs) * m_sw + (px - m_rx0) * xs + s % xs;
}

Vec2 SampleBuffer::position(int px, int py, int s) const {
    int k = sampleIndex(px, py, s);
    return {m_px[size_t(k)], m_py[size_t(k)]};
}
float SampleBuffer::depth(int px, int py, int s) const { return m_z[size_t(sampleIndex(px, py, s))]; }
float SampleBuffer::secondDepth(int px, int py, int s) const {
    return m_cfg.mode == HiderMode::Depth && m_cfg.depthLayers > 1 ? m_z2[size_t(sampleIndex(px, py, s))] : kInfinity;
}
int SampleBuffer::fragmentCount(int px, int py, int s) const {
    if (m_cfg.mode != HiderMode::Colour) return 0;
    int count = 0;
    for (int32_t f = m_fragHead[size_t(sampleIndex(px, py, s))]; f >= 0; f = m_frags[size_t(f)].next) ++count;
    return count;
}

void SampleBuffer::sample(const MicroGrid& g) {
    if (g.nu <= 0 || g.nv <= 0 || !g.P) return;
    UMBRA_CHECK(!g.aov || g.aovCount == m_cfg.aovCount, "grid has {} AOV floats, the buffer {}", g.aovCount,
                m_cfg.aovCount);
    if (g.dissolves()) prepareDissolve();
    if (g.keyCount > 1 || m_cfg.lens) {
        sampleBlurred(g);
        return;
    }
    const int nu1 = g.nu + 1;
    const int nverts = nu1 * (g.nv + 1);
    const float nearZ = m_cfg.nearClip, farZ = m_cfg.farClip;

    // Whole-grid reject: a grid is handed to every bucket it overlaps.
    float gx0 = kInfinity, gy0 = kInfinity, gz0 = kInfinity, gx1 = -kInfinity, gy1 = -kInfinity, gz1 = -kInfinity;
    for (int k = 0; k < nverts; ++k) {
        const Vec3& p = g.P[k];
        gx0 = std::min(gx0, p.x);
        gx1 = std::max(gx1, p.x);
        gy0 = std::min(gy0, p.y);
        gy1 = std::max(gy1, p.y);
        gz0 = std::min(gz0, p.z);
        gz1 = std::max(gz1, p.z);
    }
    if (!(gx1 >= m_fx0 && gx0 < m_fx1 && gy1 >= m_fy0 && gy0 < m_fy1 && gz1 >= nearZ && gz0 <= farZ)) return;

    HitContext ctx;
    ctx.depthMode = m_cfg.mode == HiderMode::Depth;
    ctx.gridOpaque = true;
    if (g.Oi && !ctx.depthMode)
        for (int k = 0; k < nverts && ctx.gridOpaque; ++k) ctx.gridOpaque = opaqueColor(g.Oi[k]);
    ctx.farthestUseful = ctx.depthMode && m_cfg.depthLayers > 1 ? m_z2.data() : m_z.data();
    ctx.inverseDepth = nullptr;
    if (m_cfg.perspective) {
        // Vertices at or behind the eye have no 1/z: NaN fails every depth
        // test downstream, as their z did before.
        m_inverseDepth.resize(size_t(nverts));
        for (int k = 0; k < nverts; ++k) {
            const float z = g.P[k].z;
            m_inverseDepth[size_t(k)] = z > 0 && z < kInfinity ? 1.0f / z : std::numeric_limits<float>::quiet_NaN();
        }
        ctx.inverseDepth = m_inverseDepth.data();
    }

    for (int j = 0; j < g.nv; ++j) {
        const Vec3* row0 = g.P + j * nu1;
        const Vec3* row1 = row0 + nu1;
        const uint8_t* culledRow = g.culled ? g.culled + j * g.nu : nullptr;
        for (int i = 0; i < g.nu; ++i) {
            if (culledRow && culledRow[i]) continue;
            if (g.discs && (i & 1)) continue;
            const Vec3 &a = row0[i], &b = row0[i + 1], &c = row1[i], &d = row1[i + 1];
            float minx = std::min(std::min(a.x, b.x), std::min(c.x, d.x));
            float maxx = std::max(std::max(a.x, b.x), std::max(c.x, d.x));
            float miny = std::min(std::min(a.y, b.y), std::min(c.y, d.y));
            float maxy = std::max(std::max(a.y, b.y), std::max(c.y, d.y));
            // NaN coordinates fail these tests and are skipped.
            if (!(maxx >= m_fx0 && minx < m_fx1 && maxy >= m_fy0 && miny < m_fy1)) continue;
            float minz = std::min(std::min(a.z, b.z), std::min(c.z, d.z));
            float maxz = std::max(std::max(a.z, b.z), std::max(c.z, d.z));
            if (!(maxz >= nearZ && minz <= farZ)) continue;
            rasterizeQuad(g, ctx, i, j, minx, miny, maxx, maxy, minz, maxz);
        }
    }
}

int SampleBuffer::trimKept(const MicroGrid& g, const Tri& t, const float b1[4], const float b2[4], int lanes) {
    const float* a = g.uv + 2 * t.i0;
    const float* b = g.uv + 2 * t.i1;
    const float* c = g.uv + 2 * t.i2;
    int kept = 0;
    for (int k = 0; k < 4; ++k) {
        if (!(lanes & (1 << k))) continue;
        const float u = a[0] + b1[k] * (b[0] - a[0]) + b2[k] * (c[0] - a[0]);
        const float v = a[1] + b1[k] * (b[1] - a[1]) + b2[k] * (c[1] - a[1]);
        if (g.trim->keeps(u, v)) kept |= 1 << k;
    }
    return kept;
}

inline bool SampleBuffer::takeNearest(size_t s, float z, uint64_t gid, uint32_t sub) {
    if (!keyLess(z, gid, sub, m_z[s], m_id[s], m_sub[s])) return false;
    m_z[s] = z;
    m_id[s] = gid;
    m_sub[s] = sub;
    return true;
}

void SampleBuffer::rasterizeQuad(const MicroGrid& g, const HitContext& ctx, int i, int j, float minx, float miny,
                                 float maxx, float maxy, float minz, float maxz) {
    // Every depth interpolated across the micropolygon is at least its
    // nearest vertex's, less the interpolation's rounding (a few 1e-6 of
    // the largest depth; the margin is far wider). Samples holding a useful
    // depth nearer than that cannot take a hit: groups of four such samples
    // are skipped, and a micropolygon hidden at every sample (two fifths of
    // the shop's depth-map micropolygons) is never set up. Depths that are not numbers
    // skip nothing.
    float nearest = minz - 1e-4f * std::max(std::abs(minz), std::abs(maxz));
    if (!(nearest >= -kInfinity)) nearest = -kInfinity;
    const int nu1 = g.nu + 1;
    const int v00 = j * nu1 + i, v10 = v00 + 1, v01 = v00 + nu1, v11 = v01 + 1;
    const uint32_t mp = uint32_t(j * g.nu + i);
    Tri ta, tb;
    bool setUp = false;

    const int xs = m_cfg.xSamples, ys = m_cfg.ySamples;
    minx = std::max(minx, m_fx0);
    maxx = std::min(maxx, m_fx1);
    miny = std::max(miny, m_fy0);
    maxy = std::min(maxy, m_fy1);
    // Samples of stratum column sx satisfy floor(x * xs) == sx (see samplePosition).
    const int sx0 = std::max(0, floorToInt(minx * float(xs)) - m_sx0);
    const int sx1 = std::min(m_sw - 1, floorToInt(maxx * float(xs)) - m_sx0);
    const int sy0 = std::max(0, floorToInt(miny * float(ys)) - m_sy0);
    const int sy1 = std::min(m_sh - 1, floorToInt(maxy * float(ys)) - m_sy0);
    if (sx0 > sx1 || sy0 > sy1) return;

    // A point's disc: the sample must also lie within it (MicroGrid::discs).
    float discX = 0, discY = 0, discR2 = 0;
    if (g.discs) {
        const Vec3 &a = g.P[v00], &b = g.P[v10], &c = g.P[v01], &d = g.P[v11];
        discX = 0.25f * (a.x + b.x + c.x + d.x);
        discY = 0.25f * (a.y + b.y + c.y + d.y);
        auto dist = [](float x0, float y0, float x1, float y1) { return std::hypot(x1 - x0, y1 - y0); };
        // Midpoints of the u edges (a-c, b-d) and the v edges (a-b, c-d).
        const float across = dist(0.5f * (a.x + c.x), 0.5f * (a.y + c.y), 0.5f * (b.x + d.x), 0.5f * (b.y + d.y));
        const float along = dist(0.5f * (a.x + b.x), 0.5f * (a.y + b.y), 0.5f * (c.x + d.x), 0.5f * (c.y + d.y));
        const float r = 0.25f * (across + along);
        discR2 = r * r;
    }

    // Four samples of a row at a time (positions are padded so the last
    // group may read past the end); lanes past sx1 are masked off.
    bool wrote = false;
    const bool nearestOnly = ctx.depthMode && m_cfg.depthLayers == 1 && g.csgLeaf < 0;  // CSG hits go to record()
    for (int sy = sy0; sy <= sy1; ++sy) {
        const size_t row = size_t(sy) * size_t(m_sw);
        for (int sx = sx0; sx <= sx1; sx += 4) {
            const size_t s = row + size_t(sx);
            const F4 x = load4(&m_px[s]), y = load4(&m_py[s]);
            const int lanes = sx1 - sx >= 3 ? 0xf : (1 << (sx1 - sx + 1)) - 1;
            const F4 useful = load4(&ctx.farthestUseful[s]);
            if (!(laneMask(useful >= nearest) & lanes)) continue;
            if (!setUp) {
                ta.setup(g, ctx.inverseDepth, v00, v10, v11, 2 * mp);
                tb.setup(g, ctx.inverseDepth, v00, v11, v01, 2 * mp + 1);
                if (!ta.valid && !tb.valid) return;
                setUp = true;
            }
            // Both halves are tested: a bow-tie's triangles may overlap.
            for (const Tri* t : {&ta, &tb}) {
                if (!t->valid) continue;
                F4 b1, b2;
                int hits = t->cover(x, y, &b1, &b2) & lanes;
                if (!hits) continue;
                // Interpolated as v0 + b1 (v1 - v0) + b2 (v2 - v0): exact
                // where the values are equal (flat surfaces, constant colours).
                // Under perspective 1/z is what is linear in raster space, so
                // a planar micropolygon gets its plane's exact depth (the
                // depth maps' virtual samples rely on it).
                const F4 d = t->d0 + b1 * (t->d1 - t->d0) + b2 * (t->d2 - t->d0);
                const F4 z = ctx.inverseDepth ? 1.0f / d : d;
                // Hits behind what the sample holds, or clipped, change
                // nothing; record() decides ties by the full key.
                hits &= laneMask((z <= useful) & (z >= m_cfg.nearClip) & (z <= m_cfg.farClip));
                if (g.discs && hits) {
                    const F4 dx = x - discX, dy = y - discY;
                    hits &= laneMask(dx * dx + dy * dy <= discR2);
                }
                if (g.dissolves() && hits) {
                    const F4 u = load4(&m_dissolve[s]);
                    hits &= laneMask((u >= g.dissolveFrom) & (u < g.dissolveBelow));
                }
                if (g.trim && hits) {
                    float w1[4], w2[4];
                    for (int k = 0; k < 4; ++k) {
                        w1[k] = b1[k];
                        w2[k] = b2[k];
                    }
                    hits &= trimKept(g, *t, w1, w2, hits);
                }
                while (hits) {
                    const int k = __builtin_ctz(unsigned(hits));
                    // A depth pass of one layer keeps the nearest hit: inline,
                    // the common case of a depth map.
                    if (nearestOnly)
                        wrote |= takeNearest(s + size_t(k), z[k], g.id, t->sub);
                    else
                        wrote |= record(g, ctx, *t, s + size_t(k), z[k], b1[k], b2[k]);
                    hits &= hits - 1;
                }
            }
        }
    }
    if (wrote) markDirty(sx0, sy0, sx1, sy1);
}

namespace {

/// Edge's scalar twin for the blurred path: the same canonical direction,
/// the same arithmetic, so a micropolygon that does not move (an in-focus
/// surface under a lens) covers exactly the samples the static path gives.
struct ScalarEdge {
    float bx, by, dx, dy;
    bool inclusive;
    void setup(float ux, float uy, float vx, float vy) {
        const bool canonical = uy < vy || (uy == vy && ux < vx);
        const float sign = canonical ? 1.0f : -1.0f;
        bx = canonical ? ux : vx;
        by = canonical ? uy : vy;
        dx = sign * ((canonical ? vx : ux) - bx);
        dy = sign * ((canonical ? vy : uy) - by);
        inclusive = canonical;
    }
    float eval(float x, float y) const { return dx * (y - by) - dy * (x - bx); }
    bool inside(float e) const { return e > 0.0f || (e == 0.0f && inclusive); }
};

/// A micropolygon corner at one sample's time and lens position.
struct Corner {
    float x, y, d;  // raster x, y; z, or 1/z under perspective
};

/// Two motion keys: the least and greatest first-key coordinate of a
/// micropolygon's four corners (lo, hi) and of their motions to the second
/// key (dlo, dhi). At weight f >= 0 every corner lies inside [lo + f * dlo,
/// hi + f * dhi]: exactly for a micropolygon that translates, a deforming
/// one's few ulps more only cost a test.
template <class Index>
void boundKeyMotion(const MicroGrid& g, const Index (&corner)[4], size_t nverts, float lo[2], float hi[2],
                    float dlo[2], float dhi[2]) {
    for (int axis = 0; axis < 2; ++axis) {
        lo[axis] = dlo[axis] = kInfinity;
        hi[axis] = dhi[axis] = -kInfinity;
    }
    for (Index c : corner) {
        const Vec3& a = g.P[size_t(c)];
        const Vec3& b = g.P[nverts + size_t(c)];
        const float ax[2] = {a.x, a.y}, d[2] = {b.x - a.x, b.y - a.y};
        for (int axis = 0; axis < 2; ++axis) {
            lo[axis] = std::min(lo[axis], ax[axis]);
            hi[axis] = std::max(hi[axis], ax[axis]);
            dlo[axis] = std::min(dlo[axis], d[axis]);
            dhi[axis] = std::max(dhi[axis], d[axis]);
        }
    }
}

/// What such a bound is widened by on one axis: the ulps of testSample's
/// interpolation, and `pad`, the lens's reach.
/// The key segment a time falls in, between keys k and k + 1 of `keys`
/// (the first before the keys, the last after them; testSample's rule,
/// which every bound of a stratum or a queue of samples follows).
int keySegment(const MicroGrid& g, int keys, float t) {
    int k = 0;
    while (k + 2 < keys && t >= g.keyTimes[k + 1]) ++k;
    return k;
}

/// The weight of key k + 1 at time t in segment k, held at 0 and 1 outside.
float segmentWeight(const MicroGrid& g, int k, float t) {
    const float span = g.keyTimes[k + 1] - g.keyTimes[k];
    return span > 0 ? std::clamp((t - g.keyTimes[k]) / span, 0.0f, 1.0f) : 0.0f;
}

float keyMotionMargin(float lo, float hi, float dlo, float dhi, float pad) {
    return 1e-3f + pad + 1e-5f * std::max({std::abs(lo), std::abs(hi), std::abs(lo + dlo), std::abs(hi + dhi)});
}

/// Narrows [first, last] to the weights f at which [lo + f * dlo, hi + f *
/// dhi] can meet [r0, r1]: lo + f * dlo <= r1 and hi + f * dhi >= r0.
void clipKeyMotion(float lo, float hi, float dlo, float dhi, float r0, float r1, float& first, float& last) {
    if (dlo > 0) last = std::min(last, (r1 - lo) / dlo);
    if (dlo < 0) first = std::max(first, (r1 - lo) / dlo);
    if (dhi > 0) first = std::max(first, (r0 - hi) / dhi);
    if (dhi < 0) last = std::min(last, (r0 - hi) / dhi);
}

}  // namespace

SampleBuffer::StrataGrid SampleBuffer::strataGrid(int cell) const {
    StrataGrid grid;
    while ((1 << grid.cellShift) < cell) ++grid.cellShift;
    grid.x0 = m_rx0 >> grid.cellShift;
    grid.y0 = m_ry0 >> grid.cellShift;
    grid.w = ((m_rx0 + m_rw - 1) >> grid.cellShift) - grid.x0 + 1;
    grid.h = ((m_ry0 + m_rh - 1) >> grid.cellShift) - grid.y0 + 1;
    return grid;
}

void SampleBuffer::tabulateStrata(const uint16_t* (SamplePattern::*row)(int) const, int strata,
                                  const StrataGrid& grid, std::vector<int32_t>& table, std::vector<float>& tableX,
                                  std::vector<float>& tableY, std::vector<float>* tableTime) const {
    const int xs = m_cfg.xSamples, ys = m_cfg.ySamples;
    const int columns = m_pattern->columns(), rows = m_pattern->rows();
    const size_t plane = grid.plane();
    table.assign(size_t(strata) * plane + 3, -1);  // read in groups of four
    tableX.assign(size_t(strata) * plane + 3, std::numeric_limits<float>::quiet_NaN());
    tableY.assign(size_t(strata) * plane + 3, std::numeric_limits<float>::quiet_NaN());
    if (tableTime) tableTime->assign(size_t(strata) * plane + 3, 0.0f);
    for (int sy = 0; sy < m_sh; ++sy) {
        const uint16_t* stratum = (m_pattern.get()->*row)(positiveMod(m_sy0 + sy, rows));
        const size_t cellRow = size_t(grid.cellY(m_ry0 + sy / ys)) * size_t(grid.w);
        // The table's column and the pixel, counted rather than divided.
        int tx = positiveMod(m_sx0, columns);
        int pixel = m_rx0;
        for (int sx = 0, i = 0; sx < m_sw; ++sx) {
            const size_t at = size_t(stratum[tx]) * plane + cellRow + size_t(grid.cellX(pixel));
            tx = tx + 1 == columns ? 0 : tx + 1;
            if (++i == xs) {
                i = 0;
                ++pixel;
            }
            const int s = sy * m_sw + sx;
            table[at] = s;
            tableX[at] = m_px[size_t(s)];
            tableY[at] = m_py[size_t(s)];
            if (tableTime) (*tableTime)[at] = m_time[size_t(s)];
        }
    }
}

void SampleBuffer::sampleBlurred(const MicroGrid& g) {
    const int nverts = g.vertexCount();
    const int keys = std::max(1, g.keyCount);
    const float nearZ = m_cfg.nearClip, farZ = m_cfg.farClip;
    const bool lens = m_cfg.lens && m_cfg.perspective;
    // The grid's bound over every key, widened by its largest circle of
    // confusion under a lens.
    float gx0 = kInfinity, gy0 = kInfinity, gz0 = kInfinity, gx1 = -kInfinity, gy1 = -kInfinity, gz1 = -kInfinity;
    float coc = 0;
    for (int k = 0; k < nverts * keys; ++k) {
        const Vec3& p = g.P[k];
        gx0 = std::min(gx0, p.x);
        gx1 = std::max(gx1, p.x);
        gy0 = std::min(gy0, p.y);
        gy1 = std::max(gy1, p.y);
        gz0 = std::min(gz0, p.z);
        gz1 = std::max(gz1, p.z);
        if (lens && p.z > 0) coc = std::max(coc, std::abs(m_cfg.inverseFocalDistance - 1.0f / p.z));
    }
    const float padX = coc * std::abs(m_cfg.lensScaleX), padY = coc * std::abs(m_cfg.lensScaleY);
    if (!(gx1 + padX >= m_fx0 && gx0 - padX < m_fx1 && gy1 + padY >= m_fy0 && gy0 - padY < m_fy1 && gz1 >= nearZ &&
          gz0 <= farZ))
        return;

    HitContext ctx;
    ctx.depthMode = m_cfg.mode == HiderMode::Depth;
    ctx.gridOpaque = true;
    if (g.Oi && !ctx.depthMode)
        for (int k = 0; k < nverts && ctx.gridOpaque; ++k) ctx.gridOpaque = opaqueColor(g.Oi[k]);
    ctx.farthestUseful = ctx.depthMode && m_cfg.depthLayers > 1 ? m_z2.data() : m_z.data();
    ctx.inverseDepth = nullptr;
    if (m_cfg.perspective) {
        m_inverseDepth.resize(size_t(nverts) * size_t(keys));
        for (int k = 0; k < nverts * keys; ++k) {
            const float z = g.P[k].z;
            m_inverseDepth[size_t(k)] = z > 0 && z < kInfinity ? 1.0f / z : std::numeric_limits<float>::quiet_NaN();
        }
        ctx.inverseDepth = m_inverseDepth.data();
    }
    // Two keys: every corner moves linearly, so the weight of the second
    // key at the strata's edges is the same for the whole grid.
    m_strataWeight.clear();
    if (keys == 2 && !m_strataStart.empty()) {
        const float span = g.keyTimes[1] - g.keyTimes[0];
        auto weight = [&](float t) { return span > 0 ? std::clamp((t - g.keyTimes[0]) / span, 0.0f, 1.0f) : 0.0f; };
        for (size_t k = 0; k < m_strataStart.size(); ++k) m_strataWeight.push_back(weight(m_strataStart[k]));
        m_strataWeight.push_back(weight(m_strataEnd.back()));
        // The same, four strata a lane group: a stratum's first and next
        // weight, and whether it is a stratum (start <= end).
        const size_t strata = m_strataStart.size(), padded = (strata + 3) & ~size_t(3);
        m_strataW0.assign(padded, 0.0f);
        m_strataW1.assign(padded, 0.0f);
        m_strataLive.assign(padded / 4, 0);
        for (size_t k = 0; k < strata; ++k) {
            m_strataW0[k] = m_strataWeight[k];
            m_strataW1[k] = m_strataWeight[k + 1];
            if (!(m_strataStart[k] > m_strataEnd[k])) m_strataLive[k / 4] |= 1 << (k % 4);
        }
    }
    // Two keys without a lens: every micropolygon's motion bound at once,
    // and only those that can reach the region at some sample's time are
    // rasterized.
    const bool perGrid = keys == 2 && !m_strataWeight.empty() && !lens;
    if (perGrid && !boundMotion(g)) return;
    for (int j = 0; j < g.nv; ++j)
        for (int i = 0; i < g.nu; ++i) {
            if (g.culled && g.culled[j * g.nu + i] == MicroGrid::kCulled) continue;
            if (g.discs && (i & 1)) continue;
            if (!perGrid) {
                rasterizeBlurred(g, ctx, i, j, nullptr);
                continue;
            }
            const MotionBound& b = m_motion[size_t(j) * size_t(g.nu) + size_t(i)];
            if (b.first <= b.last) rasterizeBlurred(g, ctx, i, j, &b);
        }
}

bool SampleBuffer::boundMotion(const MicroGrid& g) {
    const int nu1 = g.nu + 1;
    const size_t nverts = size_t(g.vertexCount());
    const float span = g.keyTimes[1] - g.keyTimes[0];
    // testSample's weight of the second key at time t: monotonic in t, so
    // every sample of the region has one in [shutterFirst, shutterLast].
    auto weight = [&](float t) { return span > 0 ? std::clamp((t - g.keyTimes[0]) / span, 0.0f, 1.0f) : 0.0f; };
    const float shutterFirst = weight(m_timeMin), shutterLast = weight(m_timeMax);
    const float region0[2] = {m_fx0, m_fy0}, region1[2] = {m_fx1, m_fy1};
    const float nearZ = m_cfg.nearClip, farZ = m_cfg.farClip;
    m_motion.resize(size_t(g.nu) * size_t(g.nv));
    bool any = false;
    for (int j = 0; j < g.nv; ++j)
        for (int i = 0; i < g.nu; ++i) {
            MotionBound& b = m_motion[size_t(j) * size_t(g.nu) + size_t(i)];
            b.first = 1;
            b.last = 0;
            // Not drawn: culled (back-facing), or a disc's odd neighbour.
            if ((g.culled && g.culled[j * g.nu + i] == MicroGrid::kCulled) || (g.discs && (i & 1))) continue;
            const size_t corner[4] = {size_t(j * nu1 + i), size_t(j * nu1 + i + 1), size_t((j + 1) * nu1 + i),
                                      size_t((j + 1) * nu1 + i + 1)};
            // rasterizeBlurred's bound over both keys, in its order.
            float minx = kInfinity, miny = kInfinity, maxx = -kInfinity, maxy = -kInfinity, minz = kInfinity,
                  maxz = -kInfinity;
            for (size_t k = 0; k < 2; ++k)
                for (size_t c : corner) {
                    const Vec3& p = g.P[k * nverts + c];
                    minx = std::min(minx, p.x);
                    maxx = std::max(maxx, p.x);
                    miny = std::min(miny, p.y);
                    maxy = std::max(maxy, p.y);
                    minz = std::min(minz, p.z);
                    maxz = std::max(maxz, p.z);
                }
            b.swept0[0] = minx;
            b.swept0[1] = miny;
            b.swept1[0] = maxx;
            b.swept1[1] = maxy;
            b.minz = minz;
            b.maxz = maxz;
            // NaN coordinates fail these tests and are skipped.
            if (!(maxx >= m_fx0 && minx < m_fx1 && maxy >= m_fy0 && miny < m_fy1)) continue;
            if (!(maxz >= nearZ && minz <= farZ)) continue;
            // The first key's bound and the motion's, as rasterizeBlurred
            // finds them.
            float lo[2], hi[2], dlo[2], dhi[2];
            boundKeyMotion(g, corner, nverts, lo, hi, dlo, dhi);
            float fFirst = 0.0f, fLast = 1.0f;
            bool finite = true;
            for (int axis = 0; axis < 2; ++axis) {
                const float margin = keyMotionMargin(lo[axis], hi[axis], dlo[axis], dhi[axis], 0.0f);
                clipKeyMotion(lo[axis], hi[axis], dlo[axis], dhi[axis], region0[axis] - margin,
                              region1[axis] + margin, fFirst, fLast);
                finite = finite && std::isfinite(lo[axis]) && std::isfinite(hi[axis]) && std::isfinite(dlo[axis]) &&
                         std::isfinite(dhi[axis]) && std::isfinite(margin);
                b.lo[axis] = lo[axis];
                b.hi[axis] = hi[axis];
                b.dlo[axis] = dlo[axis];
                b.dhi[axis] = dhi[axis];
                b.margin[axis] = margin;
            }
            if (finite) {
                // At a weight outside [fFirst, fLast] its bound (with the
                // margin) misses the region, so the region's samples of
                // that weight are outside it; the slack covers the
                // quotients' rounding.
                b.first = std::max(fFirst - 1e-4f, shutterFirst);
                b.last = std::min(fLast + 1e-4f, shutterLast);
            } else {
                b.first = 0.0f;  // rasterizeBlurred tests every stratum's box
                b.last = 1.0f;
            }
            any |= b.first <= b.last;
        }
    return any;
}

void SampleBuffer::rasterizeBlurred(const MicroGrid& g, const HitContext& ctx, int i, int j,
                                    const MotionBound* bound) {
    const int nverts = g.vertexCount();
    const int keys = std::max(1, g.keyCount);
    const int nu1 = g.nu + 1;
    const int corner[4] = {j * nu1 + i, j * nu1 + i + 1, (j + 1) * nu1 + i, (j + 1) * nu1 + i + 1};  // 00 10 01 11
    const bool lens = m_cfg.lens && m_cfg.perspective;
    float minx = kInfinity, miny = kInfinity, maxx = -kInfinity, maxy = -kInfinity, minz = kInfinity,
          maxz = -kInfinity, coc = 0;
    float blur0 = kInfinity, blur1 = -kInfinity;  // range of 1/focaldistance - 1/z over the corners
    if (bound) {
        // boundMotion's (two keys, no lens): the same bound.
        minx = bound->swept0[0];
        miny = bound->swept0[1];
        maxx = bound->swept1[0];
        maxy = bound->swept1[1];
        minz = bound->minz;
        maxz = bound->maxz;
    } else
    for (int k = 0; k < keys; ++k)
        for (int c : corner) {
            const Vec3& p = g.P[size_t(k) * size_t(nverts) + size_t(c)];
            minx = std::min(minx, p.x);
            maxx = std::max(maxx, p.x);
            miny = std::min(miny, p.y);
            maxy = std::max(maxy, p.y);
            minz = std::min(minz, p.z);
            maxz = std::max(maxz, p.z);
            if (lens) {
                const float blur = m_cfg.inverseFocalDistance - 1.0f / p.z;
                coc = std::max(coc, std::abs(blur));
                blur0 = std::min(blur0, blur);
                blur1 = std::max(blur1, blur);
            }
        }
    // The lens moves a corner by at most its circle of confusion; between
    // keys a corner stays inside the keys' bound (and 1/z between theirs).
    const float padX = coc * std::abs(m_cfg.lensScaleX), padY = coc * std::abs(m_cfg.lensScaleY);
    const float sharpX0 = minx, sharpX1 = maxx, sharpY0 = miny, sharpY1 = maxy;  // before the lens
    minx -= padX;
    maxx += padX;
    miny -= padY;
    maxy += padY;
    // NaN coordinates fail these tests and are skipped.
    if (!(maxx >= m_fx0 && minx < m_fx1 && maxy >= m_fy0 && miny < m_fy1)) return;
    if (!(maxz >= m_cfg.nearClip && minz <= m_cfg.farClip)) return;
    float nearest = minz - 1e-4f * std::max(std::abs(minz), std::abs(maxz));
    if (!(nearest >= -kInfinity)) nearest = -kInfinity;

    const int xs = m_cfg.xSamples, ys = m_cfg.ySamples;
    minx = std::max(minx, m_fx0);
    maxx = std::min(maxx, m_fx1);
    miny = std::max(miny, m_fy0);
    maxy = std::min(maxy, m_fy1);
    const int sx0 = std::max(0, floorToInt(minx * float(xs)) - m_sx0);
    const int sx1 = std::min(m_sw - 1, floorToInt(maxx * float(xs)) - m_sx0);
    const int sy0 = std::max(0, floorToInt(miny * float(ys)) - m_sy0);
    const int sy1 = std::min(m_sh - 1, floorToInt(maxy * float(ys)) - m_sy0);
    if (sx0 > sx1 || sy0 > sy1) return;
    ++m_blur.micropolygons;

    const uint32_t mp = uint32_t(j * g.nu + i);
    // A micropolygon that turns its back during the shutter (Facing) is
    // kept at a sample's time only where its winding in raster space is the
    // one it has at the opening key (its diagonals' cross there), or the
    // other one: +1 or -1, the sign a half's area must have; 0: any.
    int facingSign = 0;
    if (g.culled && g.culled[mp] >= MicroGrid::kKeepAsOpening) {
        const Vec3 &a = g.P[corner[0]], &b = g.P[corner[1]], &c = g.P[corner[2]], &d = g.P[corner[3]];
        const float cross = (d.x - a.x) * (c.y - b.y) - (d.y - a.y) * (c.x - b.x);
        const int opening = cross > 0 ? 1 : cross < 0 ? -1 : 0;
        facingSign = g.culled[mp] == MicroGrid::kKeepAsOpening ? opening : -opening;
    }
    const bool nearestOnly = ctx.depthMode && m_cfg.depthLayers == 1 && g.csgLeaf < 0;  // CSG hits go to record()
    const float* depthOf = ctx.inverseDepth;
    auto depthAt = [&](size_t v) { return depthOf ? depthOf[v] : g.P[v].z; };
    bool wrote = false;
    // The last steps for a sample inside a half, the scalar and the
    // four-wide tests alike: the trim curves, then the record.
    auto keepHit = [&](size_t s, const Tri& t, float z, float b1, float b2) {
        if (g.trim) {
            const float w1s[4] = {b1, 0, 0, 0}, w2s[4] = {b2, 0, 0, 0};
            if (!trimKept(g, t, w1s, w2s, 1)) return;
        }
        ++m_blur.sampleHits;
        if (nearestOnly)
            wrote |= takeNearest(s, z, g.id, t.sub);
        else
            wrote |= record(g, ctx, t, s, z, b1, b2);
    };
    // One sample, at its own time and lens position.
    auto testSample = [&](const size_t s) {
            const float useful = ctx.farthestUseful[s];
            if (!(useful >= nearest)) return;
            ++m_blur.sampleTests;
            // The corners at this sample's time: between keys k and k + 1.
            Corner q[4];
            int k = 0;
            float f = 0;
            if (keys > 1) {
                const float t = m_time.empty() ? 0.0f : m_time[s];
                k = keySegment(g, keys, t);
                f = segmentWeight(g, k, t);
            }
            for (int c = 0; c < 4; ++c) {
                const size_t v0 = size_t(k) * size_t(nverts) + size_t(corner[c]);
                const Vec3& a = g.P[v0];
                q[c] = {a.x, a.y, depthAt(v0)};
                if (keys > 1) {
                    const size_t v1 = v0 + size_t(nverts);
                    const Vec3& b = g.P[v1];
                    q[c].x += f * (b.x - a.x);
                    q[c].y += f * (b.y - a.y);
                    q[c].d += f * (depthAt(v1) - q[c].d);
                }
                if (lens) {
                    const float blur = m_cfg.inverseFocalDistance - q[c].d;  // d is 1/z
                    q[c].x += m_lensX[s] * m_cfg.lensScaleX * blur;
                    q[c].y += m_lensY[s] * m_cfg.lensScaleY * blur;
                }
            }
            const float x = m_px[s], y = m_py[s];
            if (g.discs) {
                const float cx = 0.25f * (q[0].x + q[1].x + q[2].x + q[3].x);
                const float cy = 0.25f * (q[0].y + q[1].y + q[2].y + q[3].y);
                auto dist = [](float x0, float y0, float x1, float y1) { return std::hypot(x1 - x0, y1 - y0); };
                const float across = dist(0.5f * (q[0].x + q[2].x), 0.5f * (q[0].y + q[2].y),
                                          0.5f * (q[1].x + q[3].x), 0.5f * (q[1].y + q[3].y));
                const float along = dist(0.5f * (q[0].x + q[1].x), 0.5f * (q[0].y + q[1].y),
                                         0.5f * (q[2].x + q[3].x), 0.5f * (q[2].y + q[3].y));
                const float r = 0.25f * (across + along);
                if ((x - cx) * (x - cx) + (y - cy) * (y - cy) > r * r) return;
            }
            // The two triangles (00, 10, 11) and (00, 11, 01), as Tri::setup.
            static constexpr int kHalves[2][3] = {{0, 1, 3}, {0, 3, 2}};
            for (int h = 0; h < 2; ++h) {
                int a = kHalves[h][0], b = kHalves[h][1], c = kHalves[h][2];
                const float area = (q[b].x - q[a].x) * (q[c].y - q[a].y) - (q[b].y - q[a].y) * (q[c].x - q[a].x);
                if (!(area != 0.0f && std::isfinite(area))) continue;
                if (facingSign && (area > 0 ? 1 : -1) != facingSign) continue;
                if (area < 0) std::swap(b, c);
                ScalarEdge e0, e1, e2;
                e0.setup(q[b].x, q[b].y, q[c].x, q[c].y);
                e1.setup(q[c].x, q[c].y, q[a].x, q[a].y);
                e2.setup(q[a].x, q[a].y, q[b].x, q[b].y);
                const float w0 = e0.eval(x, y), w1 = e1.eval(x, y), w2 = e2.eval(x, y);
                if (!(e0.inside(w0) && e1.inside(w1) && e2.inside(w2))) continue;
                // Divided only for a sample inside (most tests miss).
                const float invArea = 1.0f / std::fabs(area);
                if (!std::isfinite(invArea)) continue;
                const float b1 = w1 * invArea, b2 = w2 * invArea;
                const float d = q[a].d + b1 * (q[b].d - q[a].d) + b2 * (q[c].d - q[a].d);
                const float z = depthOf ? 1.0f / d : d;
                if (!(z <= useful && z >= m_cfg.nearClip && z <= m_cfg.farClip)) continue;
                Tri t;
                t.i0 = corner[a];
                t.i1 = corner[b];
                t.i2 = corner[c];
                t.sub = 2 * mp + uint32_t(h);
                if (g.dissolves() && !(m_dissolve[s] >= g.dissolveFrom && m_dissolve[s] < g.dissolveBelow)) continue;
                t.reversed = area < 0;
                keepHit(s, t, z, b1, b2);
            }
    };

    // Samples are queued four at a time and their corners, edges,
    // barycentrics and depths found four-wide, with testSample's arithmetic
    // lane by lane (so the same bits): most samples in a stratum's box miss
    // the micropolygon, and only those inside a half go on to the rest of
    // testSample (depth, clipping, dissolve, trim, record). Samples are distinct,
    // and a hit writes only its own sample, so the order of the tests, and
    // the pictures, are those of testing each in turn.
    // Three keys or more: the samples queued together share a key segment
    // (pendingSegment), whose two keys they are interpolated between.
    const bool batched = !g.discs;
    size_t pending[4];
    int pendingCount = 0, pendingSegment = 0;
    auto select = [](I4 m, F4 a, F4 b) { return F4((I4(a) & m) | (I4(b) & ~m)); };
    auto flush = [&]() {
        if (!pendingCount) return;
        for (int k = pendingCount; k < 4; ++k) pending[k] = pending[0];
        F4 f = {0, 0, 0, 0};
        if (keys > 1) {
            const F4 t = m_time.empty() ? F4{0, 0, 0, 0}
                                        : F4{m_time[pending[0]], m_time[pending[1]], m_time[pending[2]],
                                             m_time[pending[3]]};
            const float span = g.keyTimes[pendingSegment + 1] - g.keyTimes[pendingSegment];
            if (span > 0) {
                const F4 u = (t - g.keyTimes[pendingSegment]) / span;
                const F4 zero = {0, 0, 0, 0}, one = {1, 1, 1, 1};
                f = select(u < zero, zero, select(one < u, one, u));  // std::clamp
            }
        }
        F4 lensX = {0, 0, 0, 0}, lensY = {0, 0, 0, 0};
        if (lens) {
            lensX = F4{m_lensX[pending[0]], m_lensX[pending[1]], m_lensX[pending[2]], m_lensX[pending[3]]} *
                    m_cfg.lensScaleX;
            lensY = F4{m_lensY[pending[0]], m_lensY[pending[1]], m_lensY[pending[2]], m_lensY[pending[3]]} *
                    m_cfg.lensScaleY;
        }
        F4 qx[4], qy[4], qd[4];
        for (int c = 0; c < 4; ++c) {
            const size_t v0 = size_t(pendingSegment) * size_t(nverts) + size_t(corner[c]);
            const Vec3& a = g.P[v0];
            const float d0 = depthAt(v0);
            F4 x = {a.x, a.x, a.x, a.x}, y = {a.y, a.y, a.y, a.y}, d = {d0, d0, d0, d0};
            if (keys > 1) {
                const size_t v1 = v0 + size_t(nverts);
                const Vec3& b = g.P[v1];
                x += f * (b.x - a.x);
                y += f * (b.y - a.y);
                d += f * (depthAt(v1) - d);
            }
            if (lens) {
                const F4 blur = m_cfg.inverseFocalDistance - d;
                x += lensX * blur;
                y += lensY * blur;
            }
            qx[c] = x;
            qy[c] = y;
            qd[c] = d;
        }
        const F4 x = {m_px[pending[0]], m_px[pending[1]], m_px[pending[2]], m_px[pending[3]]};
        const F4 y = {m_py[pending[0]], m_py[pending[1]], m_py[pending[2]], m_py[pending[3]]};
        // Per half: the lanes inside, and testSample's barycentrics and
        // depth for them (its arithmetic lane by lane, so the same bits).
        int inHalf[2];
        F4 hitB1[2] = {}, hitB2[2] = {}, hitZ[2] = {}, hitArea[2] = {};
        static constexpr int kHalves[2][3] = {{0, 1, 3}, {0, 3, 2}};
        for (int h = 0; h < 2; ++h) {
            const int a = kHalves[h][0], b = kHalves[h][1], c = kHalves[h][2];
            const F4 area = (qx[b] - qx[a]) * (qy[c] - qy[a]) - (qy[b] - qy[a]) * (qx[c] - qx[a]);
            I4 valid = (area != 0.0f) & finite4(area);
            if (facingSign) valid &= facingSign > 0 ? area > 0.0f : area < 0.0f;
            const I4 flip = area < 0.0f;
            const F4 bx = select(flip, qx[c], qx[b]), by = select(flip, qy[c], qy[b]);
            const F4 cx = select(flip, qx[b], qx[c]), cy = select(flip, qy[b], qy[c]);
            // ScalarEdge::setup, eval and inside, lane by lane.
            auto edge = [&](F4 ux, F4 uy, F4 vx, F4 vy, I4& in) {
                const I4 canonical = (uy < vy) | ((uy == vy) & (ux < vx));
                const F4 ox = select(canonical, ux, vx), oy = select(canonical, uy, vy);
                const F4 dx = select(canonical, vx - ox, -(ux - ox));
                const F4 dy = select(canonical, vy - oy, -(uy - oy));
                const F4 e = dx * (y - oy) - dy * (x - ox);
                in = (e > 0.0f) | ((e == 0.0f) & canonical);
                return e;
            };
            I4 in0, in1, in2;
            edge(bx, by, cx, cy, in0);
            const F4 w1 = edge(cx, cy, qx[a], qy[a], in1);
            const F4 w2 = edge(qx[a], qy[a], bx, by, in2);
            inHalf[h] = laneMask(valid & in0 & in1 & in2);
            if (!inHalf[h]) continue;
            const F4 invArea = 1.0f / abs4(area);
            inHalf[h] &= laneMask(finite4(invArea));
            const F4 b1 = w1 * invArea, b2 = w2 * invArea;
            const F4 db = select(flip, qd[c], qd[b]), dc = select(flip, qd[b], qd[c]);
            const F4 d = qd[a] + b1 * (db - qd[a]) + b2 * (dc - qd[a]);
            hitB1[h] = b1;
            hitB2[h] = b2;
            hitZ[h] = depthOf ? 1.0f / d : d;
            hitArea[h] = area;
        }
        m_blur.sampleTests += uint64_t(pendingCount);
        const int hit = inHalf[0] | inHalf[1];
        for (int k = 0; k < pendingCount; ++k) {
            if (!(hit & (1 << k))) continue;
            const size_t s = pending[k];
            const float useful = ctx.farthestUseful[s];
            // testSample's tail, half by half.
            for (int h = 0; h < 2; ++h) {
                if (!(inHalf[h] & (1 << k))) continue;
                const float z = hitZ[h][k];
                if (!(z <= useful && z >= m_cfg.nearClip && z <= m_cfg.farClip)) continue;
                if (g.dissolves() && !(m_dissolve[s] >= g.dissolveFrom && m_dissolve[s] < g.dissolveBelow)) continue;
                const bool reversed = hitArea[h][k] < 0;
                int b = kHalves[h][1], c = kHalves[h][2];
                if (reversed) std::swap(b, c);
                Tri t;
                t.i0 = corner[kHalves[h][0]];
                t.i1 = corner[b];
                t.i2 = corner[c];
                t.sub = 2 * mp + uint32_t(h);
                t.reversed = reversed;
                const float b1 = hitB1[h][k], b2 = hitB2[h][k];
                keepHit(s, t, z, b1, b2);
            }
        }
        pendingCount = 0;
    };
    // A sample to test: at once, or queued for the four-wide test.
    auto candidate = [&](const size_t s) {
        if (!batched) return testSample(s);
        if (keys > 2) {
            const int k = keySegment(g, keys, m_time.empty() ? 0.0f : m_time[s]);
            if (k != pendingSegment) {
                flush();
                pendingSegment = k;
            }
        }
        pending[pendingCount] = s;  // kept only if not hidden (no branch)
        pendingCount += ctx.farthestUseful[s] >= nearest;
        if (pendingCount == 4) flush();
    };

    // The samples of one stratum (one a pixel, from `table`) inside the
    // raster box [x0, x1] x [y0, y1], clipped to the micropolygon's bound.
    // Two keys (or a stratum inside one key segment of more): each sample
    // is also tested against the micropolygon's bound at its own time, [lo + f * dlo, hi + f * dhi] widened by a
    // margin (set below; see there), f its weight as testSample finds it.
    bool timeBox = false;
    float boxLo[2] = {}, boxHi[2] = {}, boxDlo[2] = {}, boxDhi[2] = {};
    float boxTime0 = 0, boxTimeScale = 0;  // f = (t - boxTime0) * boxTimeScale, clamped to [0, 1]
    // Four pixels of a row at a time are tested against the box [x0, x1] x
    // [y0, y1] (pixels [px0, px1] x [py0, py1] of the region), by their
    // sample's position in that stratum (NaN, never inside, for none). The
    // samples inside are appended to a short list without a branch (most
    // groups hold one or two of them, in lanes no predictor guesses: the
    // branches on them were most of this loop's time), then handed to
    // candidate() in the same order.
    constexpr int kListed = 256;
    int32_t listed[kListed];
    auto visitPixels = [&](size_t offset, const StrataGrid& grid, const std::vector<int32_t>& tableS,
                           const std::vector<float>& tableX, const std::vector<float>& tableY, float x0, float y0,
                           float x1, float y1, int px0, int py0, int px1, int py1) {
        int n = 0;
        const F4 zero = {0, 0, 0, 0}, one = {1, 1, 1, 1};
        for (int py = py0; py <= py1; ++py) {
            const size_t rowAt = offset + size_t(py) * size_t(grid.w);
            for (int px = px0; px <= px1; px += 4) {
                const size_t at = rowAt + size_t(px);
                const F4 sx = load4(&tableX[at]), sy = load4(&tableY[at]);
                I4 in = (sx >= x0) & (sx <= x1) & (sy >= y0) & (sy <= y1);
                if (timeBox) {
                    // The weight to within an ulp or two (a product for
                    // testSample's quotient): the margin covers it.
                    const F4 u = (load4(&m_strataTime[at]) - boxTime0) * boxTimeScale;
                    const F4 f = select(u < zero, zero, select(one < u, one, u));
                    in &= (sx >= boxLo[0] + f * boxDlo[0]) & (sx <= boxHi[0] + f * boxDhi[0]) &
                          (sy >= boxLo[1] + f * boxDlo[1]) & (sy <= boxHi[1] + f * boxDhi[1]);
                }
                const int inside = laneMask(in) & (px1 - px >= 3 ? 0xf : (1 << (px1 - px + 1)) - 1);
                const int32_t* s = &tableS[at];  // padded: four may be read at the last pixel
                listed[n] = s[0];
                n += inside & 1;
                listed[n] = s[1];
                n += (inside >> 1) & 1;
                listed[n] = s[2];
                n += (inside >> 2) & 1;
                listed[n] = s[3];
                n += (inside >> 3) & 1;
                if (n > kListed - 4) {
                    for (int k = 0; k < n; ++k) candidate(size_t(listed[k]));
                    n = 0;
                }
            }
        }
        for (int k = 0; k < n; ++k) candidate(size_t(listed[k]));
    };
    // The samples of one stratum inside [x0, x1] x [y0, y1], clipped to the
    // micropolygon's bound: those of the cells the box reaches.
    auto visitStratum = [&](size_t offset, const StrataGrid& grid, const std::vector<int32_t>& tableS,
                            const std::vector<float>& tableX, const std::vector<float>& tableY, float x0, float y0,
                            float x1, float y1) {
        x0 = std::max(x0, minx);
        x1 = std::min(x1, maxx);
        y0 = std::max(y0, miny);
        y1 = std::min(y1, maxy);
        if (!(x0 <= x1 && y0 <= y1)) return;
        const int px0 = std::max(0, grid.cellX(floorToInt(x0))), px1 = std::min(grid.w - 1, grid.cellX(floorToInt(x1)));
        const int py0 = std::max(0, grid.cellY(floorToInt(y0))), py1 = std::min(grid.h - 1, grid.cellY(floorToInt(y1)));
        visitPixels(offset, grid, tableS, tableX, tableY, x0, y0, x1, y1, px0, py0, px1, py1);
    };
    // A moving micropolygon seen through a lens: the lens strata bound it
    // by its whole sweep plus a stratum's share of the circle of
    // confusion, the time strata by a stratum's share of the sweep plus the
    // whole circle. The lens strata when the circle is the larger: a
    // defocused edge moving a little was tested against every sample its
    // circle reaches in every time stratum (20 times the time of either
    // effect alone). Either way the same samples hit.
    bool lensFirst = keys < 2;
    if (!lensFirst && lens) {
        float x0 = kInfinity, x1 = -kInfinity, y0 = kInfinity, y1 = -kInfinity;
        for (int c : corner) {
            const Vec3& p = g.P[size_t(c)];
            x0 = std::min(x0, p.x), x1 = std::max(x1, p.x), y0 = std::min(y0, p.y), y1 = std::max(y1, p.y);
        }
        const float sweep = (sharpX1 - sharpX0) - (x1 - x0) + (sharpY1 - sharpY0) - (y1 - y0);
        lensFirst = padX + padY > sweep;
    }
    // One sample a pixel: a micropolygon whose bound holds at most four
    // samples a stratum is cheaper to test sample by sample than to walk
    // the tile's 16 strata (which took twice the depth pass's time for
    // casters moving a texel or two; docs/performance.md, "Depth maps of
    // moving casters").
    const bool sweepsFewSamples =
        m_strataGrid.cellShift > 0 && size_t(sx1 - sx0 + 1) * size_t(sy1 - sy0 + 1) <= 4 * m_strataStart.size();
    const bool lensStrata = lens && lensFirst && !m_lensStrataSample.empty() && std::isfinite(blur0) &&
                            std::isfinite(blur1);
    if (lensStrata) {
        // Each pixel has one sample in each stratum of the lens: a corner
        // seen through stratum k moves by lens * scale * blur, the lens
        // inside the stratum's box and blur in [blur0, blur1], so its
        // bound there is the sharp bound widened by about the circle of
        // confusion over the number of strata along an axis, not by all of it.
        auto range = [](float l0, float l1, float scale, float b0, float b1, float& lo, float& hi) {
            const float a = l0 * scale, b = l1 * scale;
            const float p[4] = {a * b0, a * b1, b * b0, b * b1};
            lo = std::min({p[0], p[1], p[2], p[3]});
            hi = std::max({p[0], p[1], p[2], p[3]});
        };
        const int strata = int(m_lensStrataBox.size() / 4);
        for (int k = 0; k < strata; ++k) {
            const float* box = &m_lensStrataBox[4 * size_t(k)];
            if (box[0] > box[2]) continue;
            float ox0, ox1, oy0, oy1;
            range(box[0], box[2], m_cfg.lensScaleX, blur0, blur1, ox0, ox1);
            range(box[1], box[3], m_cfg.lensScaleY, blur0, blur1, oy0, oy1);
            // Margins for the ulps of interpolating and scaling per sample.
            const float ex = 1e-5f * (std::max(std::abs(sharpX0), std::abs(sharpX1)) + std::abs(ox0) + std::abs(ox1)) + 1e-3f;
            const float ey = 1e-5f * (std::max(std::abs(sharpY0), std::abs(sharpY1)) + std::abs(oy0) + std::abs(oy1)) + 1e-3f;
            visitStratum(size_t(k) * m_lensStrataGrid.plane(), m_lensStrataGrid, m_lensStrataSample, m_lensStrataX,
                         m_lensStrataY, sharpX0 + ox0 - ex, sharpY0 + oy0 - ey,
                         sharpX1 + ox1 + ex, sharpY1 + oy1 + ey);
        }
    } else if (m_strataSample.empty() || keys < 2 || sweepsFewSamples) {
        for (int sy = sy0; sy <= sy1; ++sy)
            for (int sx = sx0; sx <= sx1; ++sx) candidate(size_t(sy) * size_t(m_sw) + size_t(sx));
    } else {
        // Each pixel has one sample in each coarse stratum of the shutter:
        // bound the micropolygon over the part of the shutter a stratum's
        // samples see and test only that stratum's samples there. A fast
        // micropolygon sweeps many pixels over the shutter but only a few
        // in one stratum, so this tests about 1/n of the samples the whole
        // swept bound holds (n samples a pixel). Which samples are tested
        // changes, not how: the pictures are those of testing every one.
        const int strata = int(m_strataStart.size());
        auto cornerAt = [&](int c, float t, float& x, float& y) {
            const int k = keySegment(g, keys, t);
            const float f = segmentWeight(g, k, t);
            const Vec3& a = g.P[size_t(k) * size_t(nverts) + size_t(corner[c])];
            const Vec3& b = g.P[size_t(k + 1) * size_t(nverts) + size_t(corner[c])];
            x = a.x + f * (b.x - a.x);
            y = a.y + f * (b.y - a.y);
        };
        // Two keys: the corners' bound at weight f lies inside [lo + f *
        // dlo, hi + f * dhi], lo and hi the least and greatest first-key
        // coordinate, dlo and dhi those of the motion (exact for a
        // micropolygon that translates; a deforming one's few ulps more
        // only cost a test). Strata are consecutive, so each stratum's
        // bound is that of its first time and the next one's.
        const bool linear = !m_strataWeight.empty();
        float lo[2] = {kInfinity, kInfinity}, hi[2] = {-kInfinity, -kInfinity};
        float dlo[2] = {kInfinity, kInfinity}, dhi[2] = {-kInfinity, -kInfinity};
        if (bound)
            for (int axis = 0; axis < 2; ++axis) {
                lo[axis] = bound->lo[axis];
                hi[axis] = bound->hi[axis];
                dlo[axis] = bound->dlo[axis];
                dhi[axis] = bound->dhi[axis];
            }
        else if (linear)
            boundKeyMotion(g, corner, size_t(nverts), lo, hi, dlo, dhi);
        // Two keys: the weights at which the micropolygon's bound overlaps
        // this bucket's region (it often crosses a region in a few strata).
        float fFirst = 0.0f, fLast = 1.0f;
        if (bound) {
            // boundMotion's window, clipped to the samples' times, and the
            // time box as below.
            fFirst = bound->first;
            fLast = bound->last;
            bool finite = true;
            for (int axis = 0; axis < 2; ++axis) {
                finite = finite && std::isfinite(lo[axis]) && std::isfinite(hi[axis]) &&
                         std::isfinite(dlo[axis]) && std::isfinite(dhi[axis]);
                boxLo[axis] = lo[axis] - bound->margin[axis];
                boxHi[axis] = hi[axis] + bound->margin[axis];
                boxDlo[axis] = dlo[axis];
                boxDhi[axis] = dhi[axis];
            }
            const float span = g.keyTimes[1] - g.keyTimes[0];
            boxTime0 = g.keyTimes[0];
            boxTimeScale = span > 0 ? 1.0f / span : 0.0f;
            timeBox = finite && std::isfinite(boxTimeScale) && !m_strataTime.empty();
        } else if (linear) {
            // Between the strata's times, a corner at weight f lies in
            // [lo + f * dlo, hi + f * dhi] (f >= 0); the margin covers the
            // ulps of testSample's interpolation and the lens (the inside
            // test is within the corners' bound). Coordinates that are not
            // finite leave the samples to testSample.
            const float region0[2] = {m_fx0, m_fy0}, region1[2] = {m_fx1, m_fy1}, pad[2] = {padX, padY};
            bool finite = true;
            for (int axis = 0; axis < 2; ++axis) {
                const float margin = keyMotionMargin(lo[axis], hi[axis], dlo[axis], dhi[axis], pad[axis]);
                clipKeyMotion(lo[axis], hi[axis], dlo[axis], dhi[axis], region0[axis] - margin,
                              region1[axis] + margin, fFirst, fLast);
                finite = finite && std::isfinite(lo[axis]) && std::isfinite(hi[axis]) &&
                         std::isfinite(dlo[axis]) && std::isfinite(dhi[axis]);
                boxLo[axis] = lo[axis] - margin;
                boxHi[axis] = hi[axis] + margin;
                boxDlo[axis] = dlo[axis];
                boxDhi[axis] = dhi[axis];
            }
            const float span = g.keyTimes[1] - g.keyTimes[0];
            boxTime0 = g.keyTimes[0];
            boxTimeScale = span > 0 ? 1.0f / span : 0.0f;
            timeBox = finite && std::isfinite(boxTimeScale) && !m_strataTime.empty();
            fFirst -= 1e-4f;
            fLast += 1e-4f;
        }
        // Two keys: four strata's bounds at a time, each lane the scalar
        // loop's arithmetic below (std::min and std::max as selects, NaN
        // handled alike), so the same boxes and the same samples in the
        // same order.
        if (linear) {
            auto splat = [](float v) { return F4{} + v; };
            auto vmin = [&](F4 a, F4 b) { return select(b < a, b, a); };  // std::min(a, b)
            auto vmax = [&](F4 a, F4 b) { return select(a < b, b, a); };  // std::max(a, b)
            const F4 first = splat(fFirst), last = splat(fLast);
            const F4 clipX0 = splat(minx), clipX1 = splat(maxx), clipY0 = splat(miny), clipY1 = splat(maxy);
            for (int k = 0; k < strata; k += 4) {
                const F4 f0 = load4(&m_strataW0[size_t(k)]), f1 = load4(&m_strataW1[size_t(k)]);
                int live = m_strataLive[size_t(k / 4)] & laneMask(~((f1 < first) | (last < f0)));
                if (!live) continue;
                F4 x0 = splat(kInfinity), y0 = splat(kInfinity), x1 = splat(-kInfinity), y1 = splat(-kInfinity);
                auto include = [&](F4 x, F4 y) {
                    x0 = vmin(x0, x);
                    x1 = vmax(x1, x);
                    y0 = vmin(y0, y);
                    y1 = vmax(y1, y);
                };
                // Only the part of the stratum within [fFirst, fLast]: at
                // other weights the bound misses the region.
                for (const F4 f : {vmax(f0, first), vmin(f1, last)}) {
                    include(lo[0] + f * dlo[0], lo[1] + f * dlo[1]);
                    include(hi[0] + f * dhi[0], hi[1] + f * dhi[1]);
                }
                const F4 ex = 1e-5f * vmax(abs4(x0), abs4(x1)) + 1e-3f + padX;
                const F4 ey = 1e-5f * vmax(abs4(y0), abs4(y1)) + 1e-3f + padY;
                // visitStratum's clip and pixel range.
                const F4 bx0 = vmax(x0 - ex, clipX0), bx1 = vmin(x1 + ex, clipX1);
                const F4 by0 = vmax(y0 - ey, clipY0), by1 = vmin(y1 + ey, clipY1);
                const I4 nonEmpty = (bx0 <= bx1) & (by0 <= by1);
                live &= laneMask(nonEmpty);
                if (!live) continue;
                // Empty lanes (perhaps not numbers) are not converted.
                const F4 zero = {0, 0, 0, 0};
                const I4 ix0 = floorX4(select(nonEmpty, bx0, zero)), ix1 = floorX4(select(nonEmpty, bx1, zero));
                const I4 iy0 = floorX4(select(nonEmpty, by0, zero)), iy1 = floorX4(select(nonEmpty, by1, zero));
                while (live) {
                    const int l = __builtin_ctz(unsigned(live));
                    live &= live - 1;
                    const StrataGrid& grid = m_strataGrid;
                    visitPixels(size_t(k + l) * grid.plane(), grid, m_strataSample, m_strataX, m_strataY, bx0[l],
                                by0[l], bx1[l], by1[l], std::max(0, grid.cellX(ix0[l])),
                                std::max(0, grid.cellY(iy0[l])), std::min(grid.w - 1, grid.cellX(ix1[l])),
                                std::min(grid.h - 1, grid.cellY(iy1[l])));
                }
            }
        } else {
            // Three keys or more (up to nine): each key segment's bound as two
            // keys' above, which bounds the strata lying inside that segment
            // and checks their samples at their own times. The same motion
            // given as three keys tested 2.5 times the samples of two.
            struct SegmentBox {
                float lo[2], hi[2], dlo[2], dhi[2];
                bool finite;
            };
            SegmentBox segments[8];
            const int boxedSegments = !linear && keys > 2 && keys - 1 <= 8 && !m_strataTime.empty() ? keys - 1 : 0;
            for (int seg = 0; seg < boxedSegments; ++seg) {
                SegmentBox& b = segments[seg];
                const size_t shifted[4] = {size_t(seg) * size_t(nverts) + size_t(corner[0]),
                                           size_t(seg) * size_t(nverts) + size_t(corner[1]),
                                           size_t(seg) * size_t(nverts) + size_t(corner[2]),
                                           size_t(seg) * size_t(nverts) + size_t(corner[3])};
                boundKeyMotion(g, shifted, size_t(nverts), b.lo, b.hi, b.dlo, b.dhi);
                const float pad[2] = {padX, padY};
                b.finite = g.keyTimes[seg + 1] - g.keyTimes[seg] > 0;
                for (int axis = 0; axis < 2; ++axis) {
                    const float margin = keyMotionMargin(b.lo[axis], b.hi[axis], b.dlo[axis], b.dhi[axis], pad[axis]);
                    b.finite = b.finite && std::isfinite(b.lo[axis]) && std::isfinite(b.hi[axis]) &&
                               std::isfinite(b.dlo[axis]) && std::isfinite(b.dhi[axis]) && std::isfinite(margin);
                    b.lo[axis] -= margin;
                    b.hi[axis] += margin;
                }
            }
            for (int k = 0; k < strata; ++k) {
                const float t0 = m_strataStart[size_t(k)], t1 = m_strataEnd[size_t(k)];
                if (t0 > t1) continue;
                if (boxedSegments) {
                    // The segment of the stratum's first time, if its last
                    // time falls in the same one.
                    const int seg = keySegment(g, keys, t0);
                    const SegmentBox& b = segments[seg];
                    timeBox = b.finite && keySegment(g, keys, t1) == seg;
                    if (timeBox) {
                        for (int axis = 0; axis < 2; ++axis) {
                            boxLo[axis] = b.lo[axis];
                            boxHi[axis] = b.hi[axis];
                            boxDlo[axis] = b.dlo[axis];
                            boxDhi[axis] = b.dhi[axis];
                        }
                        boxTime0 = g.keyTimes[seg];
                        boxTimeScale = 1.0f / (g.keyTimes[seg + 1] - g.keyTimes[seg]);
                        timeBox = std::isfinite(boxTimeScale);
                    }
                }
                if (linear && (m_strataWeight[size_t(k) + 1] < fFirst || m_strataWeight[size_t(k)] > fLast)) continue;
                float x0 = kInfinity, y0 = kInfinity, x1 = -kInfinity, y1 = -kInfinity;
                auto include = [&](float x, float y) {
                    x0 = std::min(x0, x);
                    x1 = std::max(x1, x);
                    y0 = std::min(y0, y);
                    y1 = std::max(y1, y);
                };
                if (linear) {
                    for (const float f : {m_strataWeight[size_t(k)], m_strataWeight[size_t(k) + 1]}) {
                        include(lo[0] + f * dlo[0], lo[1] + f * dlo[1]);
                        include(hi[0] + f * dhi[0], hi[1] + f * dhi[1]);
                    }
                } else if (boxedSegments && timeBox) {
                    // Inside one key segment: its bound at the stratum's first
                    // and last weights (margins included).
                    for (const float t : {t0, t1}) {
                        const float f = std::clamp((t - boxTime0) * boxTimeScale, 0.0f, 1.0f);
                        include(boxLo[0] + f * boxDlo[0], boxLo[1] + f * boxDlo[1]);
                        include(boxHi[0] + f * boxDhi[0], boxHi[1] + f * boxDhi[1]);
                    }
                } else {
                    for (int c = 0; c < 4; ++c) {
                        float x, y;
                        cornerAt(c, t0, x, y);
                        include(x, y);
                        cornerAt(c, t1, x, y);
                        include(x, y);
                        for (int m = 1; m + 1 < keys; ++m)
                            if (g.keyTimes[m] > t0 && g.keyTimes[m] < t1) {
                                const Vec3& p = g.P[size_t(m) * size_t(nverts) + size_t(corner[c])];
                                include(p.x, p.y);
                            }
                    }
                }
                // Interpolation rounds monotonically within a key segment; the
                // margin covers the last ulps where segments meet, and the lens.
                const float ex = 1e-5f * std::max(std::abs(x0), std::abs(x1)) + 1e-3f + padX;
                const float ey = 1e-5f * std::max(std::abs(y0), std::abs(y1)) + 1e-3f + padY;
                visitStratum(size_t(k) * m_strataGrid.plane(), m_strataGrid, m_strataSample, m_strataX, m_strataY, x0 - ex,
                             y0 - ey, x1 + ex, y1 + ey);
            }
        }
    }
    flush();
    if (wrote) markDirty(sx0, sy0, sx1, sy1);
}

inline bool SampleBuffer::recordDepth(size_t s, float z, uint64_t gid, uint32_t sub, bool reversed,
                                      bool ownSecondLayer) {
    // Hits of one grid are one layer, except where the grid folds over the
    // light's silhouette (a quadric's rim inside one grid): there a
    // micropolygon wound the other way in raster space is the surface's far
    // side, the second layer the map needs (else the floor behind the rim
    // becomes it and the shadow's outline leaks).
    const bool layers = m_cfg.depthLayers > 1;
    auto otherLayer = [&](uint64_t id, uint32_t otherSub, bool otherReversed) {
        return id != gid || (otherReversed != reversed && otherSub / 2 != sub / 2);
    };
    if (keyLess(z, gid, sub, m_z[s], m_id[s], m_sub[s])) {
        // The nearest hit from another layer than the new nearest is the
        // old nearest (it was nearer than everything else); a surface that
        // is its own second layer is nearer still.
        if (layers && ownSecondLayer) {
            m_z2[s] = z;
            m_id2[s] = gid;
            m_sub2[s] = sub;
        } else if (layers && m_z[s] != kInfinity && otherLayer(m_id[s], m_sub[s], m_wind[s] != 0)) {
            m_z2[s] = m_z[s];
            m_id2[s] = m_id[s];
            m_sub2[s] = m_sub[s];
        }
        m_z[s] = z;
        m_id[s] = gid;
        m_sub[s] = sub;
        if (layers) m_wind[s] = reversed;
        return true;
    }
    if (layers && (otherLayer(m_id[s], m_sub[s], m_wind[s] != 0) || ownSecondLayer) &&
        keyLess(z, gid, sub, m_z2[s], m_id2[s], m_sub2[s])) {
        m_z2[s] = z;
        m_id2[s] = gid;
        m_sub2[s] = sub;
        return true;
    }
    return false;
}

bool SampleBuffer::record(const MicroGrid& g, const HitContext& ctx, const Tri& t, size_t s, float z, float b1,
                          float b2) {
    const uint64_t gid = g.id;
    const uint32_t sub = t.sub;

    if (ctx.depthMode) {
        if (g.csgLeaf >= 0) {
            recordCsgDepth(g, t, s, z);
            return false;
        }
        return recordDepth(s, z, gid, sub, t.reversed, g.ownSecondLayer);
    }

    if (!keyLess(z, gid, sub, m_z[s], m_id[s], m_sub[s])) return false;  // behind the opaque hit
    const Color kBlack(0.0f), kWhite(1.0f);
    Color oi = kWhite;
    bool isOpaque = true;
    if (!ctx.gridOpaque) {
        const Color &o0 = g.Oi[t.i0], &o1 = g.Oi[t.i1], &o2 = g.Oi[t.i2];
        oi = o0 + (o1 - o0) * b1 + (o2 - o0) * b2;
        isOpaque = opaqueColor(oi);
    }
    Color ci = kBlack;
    if (g.Ci && !g.matte) {
        const Color &c0 = g.Ci[t.i0], &c1 = g.Ci[t.i1], &c2 = g.Ci[t.i2];
        ci = c0 + (c1 - c0) * b1 + (c2 - c0) * b2;
    }
    const int aovN = m_cfg.aovCount;
    const bool hasAov = g.aov && aovN > 0 && !g.matte;
    auto interpolateAov = [&](float* dst) {
        const float* a0 = g.aov + size_t(t.i0) * size_t(aovN);
        const float* a1 = g.aov + size_t(t.i1) * size_t(aovN);
        const float* a2 = g.aov + size_t(t.i2) * size_t(aovN);
        for (int k = 0; k < aovN; ++k) dst[k] = a0[k] + b1 * (a1[k] - a0[k]) + b2 * (a2[k] - a0[k]);
    };
    if (isOpaque && g.csgLeaf < 0) {
        m_z[s] = z;
        m_id[s] = gid;
        m_sub[s] = sub;
        m_ci[s] = ci;
        m_alpha[s] = g.matte ? 0.0f : 1.0f;
        if (aovN > 0) {
            float* dst = &m_aov[s * size_t(aovN)];
            if (hasAov)
                interpolateAov(dst);
            else
                std::fill_n(dst, aovN, 0.0f);
        }
        return true;
    }
    Fragment f;
    f.z = z;
    f.sub = sub;
    f.id = gid;
    f.matte = g.matte;
    f.ci = ci;
    f.oi = oi;
    f.next = m_fragHead[s];
    f.aovBase = -1;
    f.opaque = isOpaque;
    f.leaving = g.leaving && g.leaving[sub / 2];
    f.csgLeaf = g.csgLeaf;
    m_csgFragments += g.csgLeaf >= 0;
    if (hasAov) {
        f.aovBase = int32_t(m_fragAov.size());
        m_fragAov.resize(m_fragAov.size() + size_t(aovN));
        interpolateAov(&m_fragAov[size_t(f.aovBase)]);
    }
    m_fragHead[s] = int32_t(m_frags.size());
    m_frags.push_back(f);
    return false;  // transparent fragments and CSG hits do not change the occlusion bound
}

void SampleBuffer::recordCsgDepth(const MicroGrid& g, const Tri& t, size_t s, float z) {
    // Nothing behind the farthest depth kept can change the map.
    const bool twoLayers = m_cfg.depthLayers > 1;
    if (!keyLess(z, g.id, t.sub, twoLayers ? m_z2[s] : m_z[s], twoLayers ? m_id2[s] : m_id[s],
                 twoLayers ? m_sub2[s] : m_sub[s]))
        return;
    Fragment f{};
    f.z = z;
    f.sub = t.sub;
    f.id = g.id;
    f.next = m_fragHead[s];
    f.aovBase = -1;
    f.opaque = true;
    f.leaving = g.leaving && g.leaving[t.sub / 2];
    f.csgLeaf = g.csgLeaf;
    m_fragHead[s] = int32_t(m_frags.size());
    m_frags.push_back(f);
    ++m_csgFragments;
}

void SampleBuffer::resolveCsg(size_t s) {
    const CsgForest& forest = *m_cfg.csg;
    const bool depthMode = m_cfg.mode == HiderMode::Depth;
    // Every CSG hit (those behind the opaque hit still tell which leaves the
    // ray is in) and the ordinary fragments in front of the opaque hit, in
    // the total key order.
    m_order.clear();
    for (int32_t f = m_fragHead[s]; f >= 0; f = m_frags[size_t(f)].next) {
        const Fragment& fr = m_frags[size_t(f)];
        if (fr.csgLeaf >= 0 || keyLess(fr.z, fr.id, fr.sub, m_z[s], m_id[s], m_sub[s])) m_order.push_back(f);
    }
    std::sort(m_order.begin(), m_order.end(), [&](int32_t a, int32_t b) {
        const Fragment &fa = m_frags[size_t(a)], &fb = m_frags[size_t(b)];
        return keyLess(fa.z, fa.id, fa.sub, fb.z, fb.id, fb.sub);
    });
    // Whether the ray is inside a leaf just after one of its hits: inside
    // when the leaf's next hit leaves it, else (no later hit) when this one
    // enters. Counting entries and exits instead would let one sample that
    // slips through a crack between grids, or hits a shared edge twice, turn
    // a whole solid inside out along the rest of the ray; looking ahead only
    // misjudges the stretch before the missed hit. Before its first hit the
    // ray is inside a leaf that its first hit leaves (the eye inside it).
    // m_csgNext, walking back: 0 no later hit, 1 it enters, 2 it leaves.
    m_csgAfter.resize(m_order.size());
    for (size_t k = m_order.size(); k-- > 0;) {
        const Fragment& fr = m_frags[size_t(m_order[k])];
        if (fr.csgLeaf < 0) continue;
        uint8_t& next = m_csgNext[size_t(fr.csgLeaf)];
        m_csgAfter[k] = next != 0 ? next == 2 : !fr.leaving;
        next = fr.leaving ? 2 : 1;
    }
    for (int32_t f : m_order) {
        const int leaf = m_frags[size_t(f)].csgLeaf;
        if (leaf < 0 || m_csgNext[size_t(leaf)] == 0) continue;
        if (m_csgNext[size_t(leaf)] == 2) forest.setLeaf(leaf, true, m_csgRay);  // the eye is inside it
        m_csgNext[size_t(leaf)] = 0;
    }
    size_t kept = 0;
    for (size_t k = 0; k < m_order.size(); ++k) {
        const int32_t f = m_order[k];
        const Fragment& fr = m_frags[size_t(f)];
        if (fr.csgLeaf < 0) {
            m_order[kept++] = f;
            continue;
        }
        if (!depthMode && !keyLess(fr.z, fr.id, fr.sub, m_z[s], m_id[s], m_sub[s])) break;  // behind the opaque hit
        if (!forest.setLeaf(fr.csgLeaf, m_csgAfter[k], m_csgRay)) continue;  // not on the result's boundary
        if (depthMode) {
            recordDepth(s, fr.z, fr.id, fr.sub, fr.leaving, false);
            continue;
        }
        if (!fr.opaque) {
            m_order[kept++] = f;
            continue;
        }
        // The first opaque boundary hides everything behind it: it becomes
        // the sample's opaque hit.
        m_z[s] = fr.z;
        m_id[s] = fr.id;
        m_sub[s] = fr.sub;
        m_ci[s] = fr.ci;
        m_alpha[s] = fr.matte ? 0.0f : 1.0f;
        const int aovN = m_cfg.aovCount;
        if (aovN > 0) {
            float* dst = &m_aov[s * size_t(aovN)];
            if (fr.aovBase >= 0)
                std::copy_n(&m_fragAov[size_t(fr.aovBase)], aovN, dst);
            else
                std::fill_n(dst, aovN, 0.0f);
        }
        break;
    }
    // Ordinary fragments after the break lie behind the new opaque hit.
    m_order.resize(kept);
    for (int32_t f = m_fragHead[s]; f >= 0; f = m_frags[size_t(f)].next)
        if (m_frags[size_t(f)].csgLeaf >= 0) forest.clearPath(m_frags[size_t(f)].csgLeaf, m_csgRay);
}

void SampleBuffer::markDirty(int sx0, int sy0, int sx1, int sy1) {
    const int xs = m_cfg.xSamples, ys = m_cfg.ySamples;
    for (int py = sy0 / ys; py <= sy1 / ys; ++py)
        for (int px = sx0 / xs; px <= sx1 / xs; ++px) m_pixelDirty[size_t(py) * size_t(m_rw) + size_t(px)] = 1;
}

float SampleBuffer::pixelMax(int px, int py) const {
    // Recomputed on demand, only for the pixels a query reaches: a 64x64
    // depth-pass bucket would otherwise rescan 4096 pixels per query.
    const size_t p = size_t(py) * size_t(m_rw) + size_t(px);
    if (m_pixelDirty[p]) {
        const int xs = m_cfg.xSamples, ys = m_cfg.ySamples;
        const std::vector<float>& depth = m_cfg.mode == HiderMode::Depth && m_cfg.depthLayers > 1 ? m_z2 : m_z;
        float mx = -kInfinity;
        for (int j = 0; j < ys; ++j) {
            const size_t row = size_t(py * ys + j) * size_t(m_sw) + size_t(px * xs);
            for (int i = 0; i < xs; ++i) mx = std::max(mx, depth[row + size_t(i)]);
        }
        m_pixelMax[p] = mx;
        m_pixelDirty[p] = 0;
    }
    return m_pixelMax[p];
}

bool SampleBuffer::pixelRange(float xmin, float ymin, float xmax, float ymax, int* px0, int* py0, int* px1,
                              int* py1) const {
    if (!(xmax >= m_fx0 && xmin < m_fx1 && ymax >= m_fy0 && ymin < m_fy1)) return false;
    *px0 = std::max(0, floorToInt(std::max(xmin, m_fx0)) - m_rx0);
    *px1 = std::min(m_rw - 1, floorToInt(std::min(xmax, m_fx1)) - m_rx0);
    *py0 = std::max(0, floorToInt(std::max(ymin, m_fy0)) - m_ry0);
    *py1 = std::min(m_rh - 1, floorToInt(std::min(ymax, m_fy1)) - m_ry0);
    return true;
}

float SampleBuffer::maxOpaqueDepth(float xmin, float ymin, float xmax, float ymax) const {
    int px0, py0, px1, py1;
    if (!pixelRange(xmin, ymin, xmax, ymax, &px0, &py0, &px1, &py1)) return -kInfinity;
    float mx = -kInfinity;
    for (int py = py0; py <= py1; ++py)
        for (int px = px0; px <= px1; ++px) mx = std::max(mx, pixelMax(px, py));
    return mx;
}

bool SampleBuffer::occluded(const Bound3& b) const {
    // maxOpaqueDepth(...) < b.min.z, stopping at the first pixel that is
    // not closed in front of the bound (most queries that fail fail early).
    int px0, py0, px1, py1;
    if (!pixelRange(b.min.x, b.min.y, b.max.x, b.max.y, &px0, &py0, &px1, &py1)) return true;
    for (int py = py0; py <= py1; ++py)
        for (int px = px0; px <= px1; ++px)
            if (!(pixelMax(px, py) < b.min.z)) return false;
    return true;
}

void SampleBuffer::resolve(film::Film& film) {
    // Depth mode takes minima over each pixel's own samples: no filter, so
    // no margin is needed.
    for (int layer = 0; layer < film.filterLayers(); ++layer) {
        const film::PixelFilter& filter = film.filter(layer);
        UMBRA_CHECK(m_cfg.mode == HiderMode::Depth ||
                        (filter.xMargin() <= m_cfg.margin && filter.yMargin() <= m_cfg.margin),
                    "sample buffer margin {} is smaller than the {} filter's reach ({}, {})", m_cfg.margin,
                    filter.name(), filter.xMargin(), filter.yMargin());
    }
    const int xs = m_cfg.xSamples, ys = m_cfg.ySamples;
    const int bx0 = std::max(m_cfg.x0, film.x0()), bx1 = std::min(m_cfg.x1, film.x1());
    const int by0 = std::max(m_cfg.y0, film.y0()), by1 = std::min(m_cfg.y1, film.y1());
    if (bx0 >= bx1 || by0 >= by1) return;
    const size_t n = size_t(m_sw) * size_t(m_sh);

    // Depth and z: minima over each pixel's own samples, unfiltered.
    auto minOver = [&](const std::vector<float>& v, int px, int py) {
        float m = kInfinity;
        for (int j = 0; j < ys; ++j) {
            size_t row = size_t((py - m_ry0) * ys + j) * size_t(m_sw) + size_t((px - m_rx0) * xs);
            for (int i = 0; i < xs; ++i) m = std::min(m, v[row + size_t(i)]);
        }
        return m;
    };
    // Depth mode: the CSG trees' visible surfaces join the nearest depths.
    if (m_cfg.mode == HiderMode::Depth && m_csgFragments > 0)
        for (size_t s = 0; s < n; ++s)
            if (m_fragHead[s] >= 0) resolveCsg(s);
    if (m_cfg.mode == HiderMode::Depth && xs == 1 && ys == 1) {
        // One sample a pixel (automatic maps): every reduction of a single
        // depth is that depth, so rows are copied.
        for (int py = by0; py < by1; ++py) {
            const size_t row = size_t(py - m_ry0) * size_t(m_sw) + size_t(bx0 - m_rx0);
            std::copy_n(&m_z[row], bx1 - bx0, &film.z(bx0, py));
            if (film.hasDepthPair()) {
                if (m_cfg.depthLayers > 1)
                    std::copy_n(&m_z2[row], bx1 - bx0, &film.z2(bx0, py));
                else
                    std::fill_n(&film.z2(bx0, py), bx1 - bx0, kInfinity);  // its depths may start unset
            }
        }
        film.depthWritten(bx0, by0, bx1, by1);
        return;
    }
    if (m_cfg.mode == HiderMode::Depth) {
        for (int py = by0; py < by1; ++py)
            for (int px = bx0; px < bx1; ++px) {
                film.z(px, py) = pixelDepth(px, py);
                if (film.hasDepthPair()) film.z2(px, py) = m_cfg.depthLayers > 1 ? minOver(m_z2, px, py) : kInfinity;
            }
        film.depthWritten(bx0, by0, bx1, by1);
        return;
    }
    UMBRA_CHECK(film.aovFloats() == m_cfg.aovCount, "film has {} AOV floats, the sample buffer {}", film.aovFloats(),
                m_cfg.aovCount);

    // 1. Each sample's composited value: r g b a aov...
    const int aovN = m_cfg.aovCount;
    const int stride = 4 + aovN;
    // resolveColour() for each layer whose filter is separable when there
    // are no AOVs; every sample is composited when some layer needs the
    // general path.
    bool colourOnly = aovN == 0;
    for (int layer = 0; layer < film.filterLayers(); ++layer) colourOnly = colourOnly && film.filter(layer).separable();
    m_res.resize(n * size_t(stride));
    m_scratchAov.resize(size_t(aovN));
    // resolveColour() reads samples without fragments straight from the hit.
    const size_t composited = colourOnly && m_frags.empty() ? 0 : n;
    for (size_t s = 0; s < composited; ++s) {
        float* out = &m_res[s * size_t(stride)];
        const float* opAov = aovN > 0 ? &m_aov[s * size_t(aovN)] : nullptr;
        if (m_fragHead[s] < 0) {
            if (colourOnly) continue;  // read straight from the opaque hit in step 2
            if (m_z[s] == kInfinity) {
                std::fill_n(out, stride, 0.0f);
                continue;
            }
            out[0] = m_ci[s].x;
            out[1] = m_ci[s].y;
            out[2] = m_ci[s].z;
            out[3] = m_alpha[s];
            for (int k = 0; k < aovN; ++k) out[4 + k] = opAov[k];
            continue;
        }
        // Fragments in front of the opaque hit, sorted by the total key
        // order; of CSG hits, those on their result's boundary.
        if (m_csgFragments > 0) {
            resolveCsg(s);
        } else {
            m_order.clear();
            for (int32_t f = m_fragHead[s]; f >= 0; f = m_frags[size_t(f)].next) {
                const Fragment& fr = m_frags[size_t(f)];
                if (keyLess(fr.z, fr.id, fr.sub, m_z[s], m_id[s], m_sub[s])) m_order.push_back(f);
            }
            std::sort(m_order.begin(), m_order.end(), [&](int32_t a, int32_t b) {
                const Fragment &fa = m_frags[size_t(a)], &fb = m_frags[size_t(b)];
                return keyLess(fa.z, fa.id, fa.sub, fb.z, fb.id, fb.sub);
            });
        }
        Color ci(0.0f), oi(0.0f);
        float alpha = 0.0f;
        std::fill(m_scratchAov.begin(), m_scratchAov.end(), 0.0f);
        for (int32_t f : m_order) {
            const Fragment& fr = m_frags[size_t(f)];
            Color through = Color(1.0f) - oi;  // what the layers in front let through
            if (!fr.matte) {
                ci += through * fr.ci;
                float cover = mean3(through * fr.oi);
                alpha += cover;
                if (fr.aovBase >= 0)
                    for (int k = 0; k < aovN; ++k) m_scratchAov[size_t(k)] += cover * m_fragAov[size_t(fr.aovBase + k)];
            }
            oi += through * fr.oi;
        }
        if (m_z[s] != kInfinity) {
            Color through = Color(1.0f) - oi;
            ci += through * m_ci[s];
            float cover = mean3(through);
            alpha += cover * m_alpha[s];
            for (int k = 0; k < aovN; ++k) m_scratchAov[size_t(k)] += cover * opAov[k];
        }
        out[0] = ci.x;
        out[1] = ci.y;
        out[2] = ci.z;
        out[3] = alpha;
        for (int k = 0; k < aovN; ++k) out[4 + k] = m_scratchAov[size_t(k)];
    }

    while (m_weights.size() < size_t(film.filterLayers())) m_weights.push_back(std::make_unique<PatternFilterWeights>());
    for (int layer = 0; layer < film.filterLayers(); ++layer) {
        const film::PixelFilter& filter = film.filter(layer);
        PatternFilterWeights& table = *m_weights[size_t(layer)];
        if (filter.separable()) table.prepare(*m_pattern, filter);
        if (aovN == 0 && filter.separable())
            resolveColour(film, layer, table, bx0, by0, bx1, by1);
        else
            resolveFiltered(film, layer, table, bx0, by0, bx1, by1);
    }
}

void SampleBuffer::resolveFiltered(film::Film& film, int layer, const PatternFilterWeights& table, int bx0, int by0,
                                   int bx1, int by1) {
    const film::PixelFilter& filter = film.filter(layer);
    const int xs = m_cfg.xSamples, ys = m_cfg.ySamples;
    const int aovN = m_cfg.aovCount;
    const int stride = 4 + aovN;
    const int bw = bx1 - bx0, bh = by1 - by0;

    // 2. Filter: every sample adds its weighted value to the bucket pixels
    // its filter support reaches, in a fixed order (deterministic sums).
    // Separable filters use the tabulated weights, as resolveColour(), so
    // both give the same pixels.
    const bool separable = filter.separable();
    const int accStride = separable ? stride : stride + 1;  // non-separable: the weight sum too
    m_acc.assign(size_t(bw) * size_t(bh) * size_t(accStride), 0.0f);
    if (separable) {
        splatSeparable(table, bx0, by0, bx1, by1, accStride, [&](size_t s) {
            const float* val = &m_res[s * size_t(stride)];
            return [val, stride](float* acc, float w) {
                for (int k = 0; k < stride; ++k) acc[k] += w * val[k];
            };
        });
    } else {
        // Only samples of pixels within the filter's reach of the bucket matter.
        const int mx = filter.xMargin(), my = filter.yMargin();
        const int qy0 = std::max(m_ry0, by0 - my), qy1 = std::min(m_ry0 + m_rh, by1 + my);
        const int qx0 = std::max(m_rx0, bx0 - mx), qx1 = std::min(m_rx0 + m_rw, bx1 + mx);
        for (int sy = (qy0 - m_ry0) * ys; sy < (qy1 - m_ry0) * ys; ++sy) {
            const int qy = m_ry0 + sy / ys;
            const int ty0 = std::max(by0, qy - my), ty1 = std::min(by1 - 1, qy + my);
            for (int sx = (qx0 - m_rx0) * xs; sx < (qx1 - m_rx0) * xs; ++sx) {
                const int qx = m_rx0 + sx / xs;
                const int tx0 = std::max(bx0, qx - mx), tx1 = std::min(bx1 - 1, qx + mx);
                const size_t s = size_t(sy) * size_t(m_sw) + size_t(sx);
                const float x = m_px[s], y = m_py[s];
                const float* val = &m_res[s * size_t(stride)];
                for (int ty = ty0; ty <= ty1; ++ty)
                    for (int tx = tx0; tx <= tx1; ++tx) {
                        const float w = filter.weight(x - (float(tx) + 0.5f), y - (float(ty) + 0.5f));
                        if (w == 0.0f) continue;
                        float* acc = &m_acc[(size_t(ty - by0) * size_t(bw) + size_t(tx - bx0)) * size_t(accStride)];
                        for (int k = 0; k < stride; ++k) acc[k] += w * val[k];
                        acc[stride] += w;
                    }
            }
        }
    }

    // 3. Normalise into the film.
    for (int py = by0; py < by1; ++py)
        for (int px = bx0; px < bx1; ++px) {
            const float* acc = &m_acc[(size_t(py - by0) * size_t(bw) + size_t(px - bx0)) * size_t(accStride)];
            float inv;
            if (separable) {
                inv = table.inverseWeightSum(positiveMod(px, kPatternPeriod), positiveMod(py, kPatternPeriod));
            } else {
                const float wsum = acc[stride];
                inv = wsum != 0.0f ? 1.0f / wsum : 0.0f;
            }
            float* rgba = film.rgba(layer, px, py);
            for (int k = 0; k < 4; ++k) rgba[k] = acc[k] * inv;
            float* aov = film.aov(layer, px, py);
            for (int k = 0; k < aovN; ++k) aov[k] = acc[4 + k] * inv;
            if (layer == 0 && film.hasDepth()) film.z(px, py) = pixelDepth(px, py);
        }
}

float SampleBuffer::pixelDepth(int px, int py) const {
    // RenderMan's depth filters over the pixel's own samples, unfiltered:
    // "min" the nearest, "max" the farthest (+infinity if any missed),
    // "average" the mean of the samples that hit something.
    using Reduce = SampleBufferConfig::DepthReduce;
    const int xs = m_cfg.xSamples, ys = m_cfg.ySamples;
    auto rowOf = [&](int j) { return &m_z[size_t((py - m_ry0) * ys + j) * size_t(m_sw) + size_t((px - m_rx0) * xs)]; };
    if (m_cfg.depthReduce == Reduce::Min) {
        float mn = kInfinity;
        for (int j = 0; j < ys; ++j) {
            const float* row = rowOf(j);
            for (int i = 0; i < xs; ++i) mn = std::min(mn, row[i]);
        }
        return mn;
    }
    float mx = -kInfinity, sum = 0;
    int hits = 0;
    for (int j = 0; j < ys; ++j) {
        const float* row = rowOf(j);
        for (int i = 0; i < xs; ++i) {
            mx = std::max(mx, row[i]);
            if (row[i] != kInfinity) {
                sum += row[i];
                ++hits;
            }
        }
    }
    if (m_cfg.depthReduce == Reduce::Max) return mx;
    return hits > 0 ? sum / float(hits) : kInfinity;
}

template <class Splat>
void SampleBuffer::splatSeparable(const PatternFilterWeights& table, int bx0, int by0, int bx1, int by1,
                                  int accStride, Splat splat) {
    const int xs = m_cfg.xSamples, ys = m_cfg.ySamples;
    const int mx = table.xMargin(), my = table.yMargin();
    const int columns = m_pattern->columns(), rows = m_pattern->rows();
    const size_t rowStride = size_t(bx1 - bx0) * size_t(accStride);
    float* acc = m_acc.data();
    // Only samples of pixels within the filter's reach of the bucket matter.
    const int qy0 = std::max(m_ry0, by0 - my), qy1 = std::min(m_ry0 + m_rh, by1 + my);
    const int qx0 = std::max(m_rx0, bx0 - mx), qx1 = std::min(m_rx0 + m_rw, bx1 + mx);
    for (int sy = (qy0 - m_ry0) * ys; sy < (qy1 - m_ry0) * ys; ++sy) {
        const int qy = m_ry0 + sy / ys;
        const int ty = positiveMod(m_sy0 + sy, rows);
        const PatternFilterWeights::Reach* reach = table.reachRow(ty);
        const size_t rowBase = size_t(sy) * size_t(m_sw);
        int tx = positiveMod((qx0 - m_rx0) * xs + m_sx0, columns);
        for (int qx = qx0; qx < qx1; ++qx)
            for (int i = 0; i < xs; ++i, tx = tx + 1 == columns ? 0 : tx + 1) {
                const size_t s = rowBase + size_t((qx - m_rx0) * xs + i);
                // Samples that hit nothing add zeros; their weights are in
                // the tabulated sums all the same.
                if (m_z[s] == kInfinity && m_fragHead[s] < 0) continue;
                const PatternFilterWeights::Reach r = reach[tx];
                const int py0 = std::max(by0, qy + r.y0), py1 = std::min(by1 - 1, qy + r.y1);
                const int px0 = std::max(bx0, qx + r.x0), px1 = std::min(bx1 - 1, qx + r.x1);
                if (px0 > px1 || py0 > py1) continue;
                const float* wx = table.weights(tx, ty) + mx;  // by pixel offset from the sample's pixel
                const float* wy = wx + mx + 1 + my;
                auto add = splat(s);
                for (int py = py0; py <= py1; ++py) {
                    const float wyv = wy[py - qy];
                    float* row = acc + size_t(py - by0) * rowStride;
                    for (int px = px0; px <= px1; ++px)
                        add(row + size_t(px - bx0) * size_t(accStride), wx[px - qx] * wyv);
                }
            }
    }
}

void SampleBuffer::resolveColour(film::Film& film, int layer, const PatternFilterWeights& table, int bx0, int by0,
                                 int bx1, int by1) {
    // The common case (no AOVs, a separable filter), written for speed: r g
    // b a travel in one vector. The sums are those of the general path.
    const int bw = bx1 - bx0, bh = by1 - by0;
    m_acc.assign(size_t(bw) * size_t(bh) * 4, 0.0f);
    splatSeparable(table, bx0, by0, bx1, by1, 4, [&](size_t s) {
        F4 value;
        if (m_fragHead[s] >= 0) {
            const float* r = &m_res[s * 4];  // composited (aovCount is 0: stride 4)
            value = F4{r[0], r[1], r[2], r[3]};
        } else {
            value = F4{m_ci[s].x, m_ci[s].y, m_ci[s].z, m_alpha[s]};
        }
        return [value](float* acc, float w) {
            store4(acc, load4(acc) + w * value);
        };
    });
    const float* acc = m_acc.data();
    for (int py = by0; py < by1; ++py)
        for (int px = bx0; px < bx1; ++px) {
            const float* a = &acc[(size_t(py - by0) * size_t(bw) + size_t(px - bx0)) * 4];
            const float inv = table.inverseWeightSum(positiveMod(px, kPatternPeriod), positiveMod(py, kPatternPeriod));
            float* rgba = film.rgba(layer, px, py);
            for (int k = 0; k < 4; ++k) rgba[k] = a[k] * inv;
            if (layer == 0 && film.hasDepth()) film.z(px, py) = pixelDepth(px, py);
        }
}

}  // namespace umbra::hider
