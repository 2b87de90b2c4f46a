// Percentage-closer filtering (Reeves, Salesin & Cook 1987, Figure 4).
//
// Per shading point:
//  1. z = the point's light camera-space depth; z < 0 (behind the light) is
//     lit.
//  2. The region: the micropolygon footprint (P +- dPdu_du/2 +- dPdv_dv/2)
//     projected into the map's raster (to first order, through the
//     projection's derivative at P); half-widths (hs, ht) are the largest
//     distances of its corners from the projected P, scaled by swidth/twidth
//     (ResFactor), widened by blur, and at least MinSize/2.
//  3. A region wholly outside the map's bounding box (data window) is lit.
//  4. Per-tile culling (umbra's addition, from the tile scheme of §3.3):
//     z nearer than every covered tile's min z (with the lowest bias) is
//     lit; z beyond every covered tile's max z (with the highest bias), for
//     a region wholly inside the bounding box, is shadowed. Both are exact:
//     they give the result filtering would. A region within 2x2 tiles is
//     tested with the finer depth ranges of the 8x8-texel blocks it covers
//     instead. A whole batch (a shaded grid) is tested first, with the
//     union of its regions. On second-depth maps a light-facing point
//     would take virtual samples even when every comparison is shadowed
//     (see lookup()), so it is culled as shadowed only when its tangent
//     plane is deeper than the covered depths too.
//  4b. Second-depth maps (umbra's addition): a light-facing point whose
//     tangent plane is the plane every covered block stores -- an open
//     surface stored as its own second layer (Wang & Molnar §3.3) -- gets
//     every virtual sample lit, so it is lit without samples. Exact too:
//     the match is bounded with the blocks' fit and the rounding of the
//     sample loop. Whole grids are decided so when they lie on one plane.
//  5. ns x nt samples, counted as Reeves does (fewer for regions smaller
//     than NumSamples texels, at least MinSamples per axis); each compares
//     z > map + bias. Samples outside the bounding box see +infinity (lit).
//
// Deviations from the printed Figure 4, all deliberate:
//  - The jitter spans the whole cell (the figure's `s + Rand()*js` spans
//    only its upper half, which shifts the region by a quarter cell).
//  - Texel indices use floor, not truncation toward zero.
//  - A single sample (ns = nt = 1) is taken unjittered at the region's
//    centre with the mid bias: Williams' point-sampled algorithm, as
//    Figure 6a simulates it.

#include "umbra/shadow/shadow_map.h"
#include "umbra/util/lanes.h"
#include "umbra/util/rng.h"

#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

namespace umbra {

namespace {

/// The tiles a thread's lookups used last, pinned, indexed by the low bits
/// of the map id and the tile coordinates: an 8x8 neighbourhood of one
/// map's tiles never collides, and the next grid's lookups, mostly in the
/// same tiles, find them without touching the shared cache (whose lock and
/// reference counts the two threads would contend for). Map ids are never
/// reused, so a slot never answers for a closed map. A slot holds its tile
/// until replaced: a thread holds at most 256 tiles (1 MB of 32x32 tiles)
/// beyond the cache's bound.
struct TileMemo {
    static constexpr int kSlots = 256;
    uint32_t map[kSlots];
    int tx[kSlots], ty[kSlots];
    const float* data[kSlots];
    const ShadowTile* tile[kSlots];
    ShadowTilePtr hold[kSlots];
    TileMemo() {
        for (int i = 0; i < kSlots; ++i) {
            map[i] = 0;  // no map has id 0
            tx[i] = ty[i] = -1;
            data[i] = nullptr;
            tile[i] = nullptr;
        }
    }
    static int slot(uint32_t mapId, int x, int y) { return (x & 7) | ((y & 7) << 3) | int((mapId & 3) << 6); }
};

/// floor() as an int, for |v| < 2^31 (callers bound their values first).
/// std::floor is a libm call on baseline x86-64, which has no SSE4.1 round.
inline int floorInt(float v) {
    int i = int(v);
    return i - (float(i) > v ? 1 : 0);
}

/// The largest float below the integer n (|n| < 2^24, where float(n) is
/// exact): one step of the float's bits towards minus infinity, without
/// the libm call std::nextafter is on baseline x86-64.
inline float floatBelow(int n) {
    if (n == 0) return -std::numeric_limits<float>::denorm_min();
    const uint32_t bits = std::bit_cast<uint32_t>(float(n));
    return std::bit_cast<float>(n > 0 ? bits - 1 : bits + 1);
}

/// Relative tolerance of virtual-sample comparisons (float rounding of the
/// plane's transform and evaluation, measured at a few 1e-6).
constexpr float kVirtualSlack = 1e-4f;
/// Regions of at most this many texels are tested against the min and max
/// of their texels before sampling: reading them costs less than drawing a
/// lookup's samples, and most regions the 8x8 blocks do not decide are.
constexpr int kTexelRangeLimit = 64;
/// How closely (relative) a receiver's tangent plane must match the planes
/// of the blocks its region covers to be lit without samples. With the
/// blocks' own fit and the rounding of the sample loop it stays well inside
/// kVirtualSlack, so every virtual sample there would compare lit.
constexpr double kPlaneMatch = 2.5e-5;
static_assert(kPlaneMatch + 2.0 * double(ShadowTile::kPlaneFit) < 0.5 * double(kVirtualSlack),
              "a match of the stored planes must imply lit virtual samples");

/// The random numbers of sample k of a lookup whose point hash is
/// `pointSeed`: a hash of the two, not a sequential generator, so a
/// region's samples do not wait on one another (a generator's state update
/// is a chain of dependent multiplies) and any sample can be replayed alone.
struct SampleRandoms {
    uint32_t h;
    explicit SampleRandoms(uint32_t pointSeed, int k) : h(hash32(pointSeed + uint32_t(k) * 0x9e3779b9u)) {}
    /// One hash, three uniforms in [0,1): the jitter inside the sample's
    /// cell (11 bits each, 1/2048 of a cell) and the bias (10 bits, 1/1024
    /// of the bias range).
    float ju() const { return float(h & 0x7ffu) * (1.0f / 2048.0f); }
    float jv() const { return float((h >> 11) & 0x7ffu) * (1.0f / 2048.0f); }
    float jbias() const { return float(h >> 22) * (1.0f / 1024.0f); }
    /// Further independent uniforms (24 bits), for Gaussian sampling.
    float extra(uint32_t which) const { return hashToUnit(hash32(h ^ (0x5bd1e995u * (which + 1)))); }
};

/// A region's samples, structure of arrays padded to a multiple of four:
/// texel, bias, filter weight and the depth the map holds there. Lanes
/// past the sample count hold anything but weigh 0 and read +infinity.
/// Each array is written and read four lanes at a time where it can be: a
/// vector load of values just stored one by one stalls on the store buffer.
struct RegionSamples {
    std::vector<int32_t> iu, iv;
    std::vector<float> bias, weight, depth;
    int padded = 0;
    /// The cell (a, b) = (k / nt, k % nt) of each jittered sample k, as
    /// floats, for the (ns, nt) of the last region: consecutive points of a
    /// grid mostly share their sample counts.
    std::vector<float> cellA, cellB;
    int cellsNs = 0, cellsNt = 0;
    void resize(int count) {
        padded = (count + 3) & ~3;
        if (iu.size() < size_t(padded)) {
            for (auto* v : {&iu, &iv}) v->resize(size_t(padded));
            for (auto* v : {&bias, &weight, &depth}) v->resize(size_t(padded));
        }
        for (int k = count; k < padded; ++k) weight[size_t(k)] = 0;
    }
    void cells(int ns, int nt) {
        if (ns == cellsNs && nt == cellsNt) return;
        const int n = ns * nt, p = (n + 3) & ~3;
        cellA.assign(size_t(p), 0.0f);  // padding lanes: cell (0, 0)
        cellB.assign(size_t(p), 0.0f);
        for (int k = 0; k < n; ++k) {
            cellA[size_t(k)] = float(k / nt);
            cellB[size_t(k)] = float(k % nt);
        }
        cellsNs = ns, cellsNt = nt;
    }
    template <typename T> static auto load(const std::vector<T>& v, int k) { return load4(&v[size_t(k)]); }
    template <typename T, typename V> static void store(std::vector<T>& v, int k, V x) { store4(&v[size_t(k)], x); }
};

/// Reeves' sample counts: a region smaller than NumSamples texels gets
/// about one sample per texel, else NumSamples split by the region's
/// aspect ratio; at least MinSamples per axis.
inline void reevesCounts(int samples, int minSamples, float hs, float ht, int* ns, int* nt) {
    if (samples == 1) {
        *ns = *nt = 1;
    } else if (hs * ht * 4.0f < float(samples)) {
        *ns = clamp(int(hs * 2.0f + 0.5f), minSamples, samples);
        *nt = clamp(int(ht * 2.0f + 0.5f), minSamples, samples);
    } else {
        *nt = clamp(int(std::sqrt(ht * float(samples) / hs) + 0.5f), minSamples, samples);
        *ns = clamp(int(float(samples) / float(*nt) + 0.5f), minSamples, samples);
    }
}

/// The most time slots (texels of a time tile) a map's lookups handle.
constexpr int kMaxTimeSlots = 256;
/// A moving receiver's region of at most this area (texels) is filtered
/// over every texel of every time in it; a larger one with Reeves' count of
/// jittered samples.
constexpr int kEnumeratedRegion = 64;

/// The sum of the lanes. Box-filter weights are 1, so sums of them are
/// exact in any order; Gaussian weights sum in this fixed order.
inline float sumLanes(F4 v) { return (v[0] + v[1]) + (v[2] + v[3]); }

/// Steps 1 and 2 for a batch's points, four at a time: the light-space
/// depth z, the raster position (s, t), the region's half-widths (hs, ht)
/// and the texels it reaches, [iLo, iHi] x [jLo, jHi]. `usable` is false
/// (0) for points behind the light or not projectable, which are lit. Lane
/// by lane, the arithmetic is the scalar formulas' in the same order, so
/// every value is the one a point-by-point evaluation gives.
///
/// The texel bounds are the floors of the region's sides clamped to one
/// texel beyond the data window: what a texel outside the window holds
/// (+infinity) does not depend on how far out it is, and the clamp keeps
/// the conversion in range for points far off the map. For a point inside
/// the map (its centre in the display window) they are also clamped to
/// the map's border, as a texture lookup clamps: a region reaching past the
/// edge reads the edge's texels there, so an occluder that fills the edge
/// shadows the outermost texel wholly (as in PRMan, Pixie and Aqsis)
/// instead of counting the samples beyond it as lit.
struct PointRegions {
    std::vector<float> z, s, t, hs, ht;
    std::vector<int32_t> iLo, iHi, jLo, jHi;
    std::vector<int32_t> usable;  // -1 or 0, as vector comparisons give
    // Of them all: is every point usable; the range of z; the union of the
    // regions, [loS, hiS] x [loT, hiT].
    bool allUsable = false;
    float zLo = 0, zHi = 0, loS = 0, hiS = 0, loT = 0, hiT = 0;

    struct Widths {
        float sWidth, tWidth, blurS, blurT, minHalf, maxHalf;
        int dx0, dx1, dy0, dy1;  // the data window, inclusive texel bounds
        int width, height;       // the display window, [0, width) x [0, height)
    };

    void compute(const ShadowBatch& batch, const Mat4& lightFromCurrent, const Mat4& rasterFromCurrent,
                 const Widths& wd) {
        const int n = batch.count, padded = (n + 3) & ~3;
        if (usable.size() < size_t(padded)) {
            for (auto* v : {&z, &s, &t, &hs, &ht}) v->resize(size_t(padded));
            for (auto* v : {&iLo, &iHi, &jLo, &jHi, &usable}) v->resize(size_t(padded));
        }
        const auto& L = lightFromCurrent.m;
        const auto& R = rasterFromCurrent.m;
        // The bounds, lane by lane (lanes past the end change none).
        F4 zLo4 = F4{} + kInfinity, zHi4 = -zLo4, loS4 = zLo4, hiS4 = zHi4, loT4 = zLo4, hiT4 = zHi4;
        I4 allUsable4 = I4{} - 1;
        for (int i0 = 0; i0 < n; i0 += 4) {
            // Lanes past the end repeat the last point.
            const int i[4] = {i0, std::min(i0 + 1, n - 1), std::min(i0 + 2, n - 1), std::min(i0 + 3, n - 1)};
            auto lanes = [&](const Vec3* v, F4* x, F4* y, F4* zz) {
                *x = F4{v[i[0]].x, v[i[1]].x, v[i[2]].x, v[i[3]].x};
                *y = F4{v[i[0]].y, v[i[1]].y, v[i[2]].y, v[i[3]].y};
                *zz = F4{v[i[0]].z, v[i[1]].z, v[i[2]].z, v[i[3]].z};
            };
            F4 px, py, pz;
            lanes(batch.P, &px, &py, &pz);
            const F4 depth = L[2][0] * px + L[2][1] * py + L[2][2] * pz + L[2][3];
            const F4 w = R[3][0] * px + R[3][1] * py + R[3][2] * pz + R[3][3];
            const F4 inv = 1.0f / w;
            F4 ss = (R[0][0] * px + R[0][1] * py + R[0][2] * pz + R[0][3]) * inv;
            F4 tt = (R[1][0] * px + R[1][1] * py + R[1][2] * pz + R[1][3]) * inv;
            I4 ok = (depth >= 0) & (w > 0) & finite4(ss) & finite4(tt);
            // The region: the footprint's corners P +- du/2 +- dv/2 projected
            // to first order (the projection's derivative at P), so one
            // divide serves the whole footprint; |+-a +- b| <= |a| + |b|.
            F4 hS{}, hT{};
            if (batch.dPdu_du && batch.dPdv_dv) {
                auto extent = [&](const Vec3* d, F4* ex, F4* ey) {
                    F4 dx, dy, dz;
                    lanes(d, &dx, &dy, &dz);
                    dx *= 0.5f, dy *= 0.5f, dz *= 0.5f;
                    const F4 dw = R[3][0] * dx + R[3][1] * dy + R[3][2] * dz;
                    *ex = abs4((R[0][0] * dx + R[0][1] * dy + R[0][2] * dz - ss * dw) * inv);
                    *ey = abs4((R[1][0] * dx + R[1][1] * dy + R[1][2] * dz - tt * dw) * inv);
                };
                F4 ux, uy, vx, vy;
                extent(batch.dPdu_du, &ux, &uy);
                extent(batch.dPdv_dv, &vx, &vy);
                hS = ux + vx;
                hT = uy + vy;
            }
            if (batch.corners[0]) {
                // The four-point form: the box around the corners'
                // projections, whatever their order, centred on it.
                F4 sLo = F4{} + kInfinity, sHi = -sLo, tLo = sLo, tHi = sHi;
                for (const Vec3* corner : batch.corners) {
                    F4 cx, cy, cz;
                    lanes(corner, &cx, &cy, &cz);
                    const F4 cw = R[3][0] * cx + R[3][1] * cy + R[3][2] * cz + R[3][3];
                    const F4 cs = (R[0][0] * cx + R[0][1] * cy + R[0][2] * cz + R[0][3]) / cw;
                    const F4 ct = (R[1][0] * cx + R[1][1] * cy + R[1][2] * cz + R[1][3]) / cw;
                    ok &= (cw > 0) & finite4(cs) & finite4(ct);
                    sLo = cs < sLo ? cs : sLo, sHi = cs > sHi ? cs : sHi;
                    tLo = ct < tLo ? ct : tLo, tHi = ct > tHi ? ct : tHi;
                }
                ss = (sLo + sHi) * 0.5f, tt = (tLo + tHi) * 0.5f;
                hS = (sHi - sLo) * 0.5f, hT = (tHi - tLo) * 0.5f;
            }
            // clamp(max(h * width + blur, minHalf), 0, maxHalf), keeping a
            // NaN for the test after it.
            auto widen = [&](F4 h, float width, float blur) {
                const F4 v = h * width + blur;
                const F4 m = v < wd.minHalf ? F4{} + wd.minHalf : v;
                return m < 0 ? F4{} : (m > wd.maxHalf ? F4{} + wd.maxHalf : m);
            };
            hS = widen(hS, wd.sWidth, wd.blurS);
            hT = widen(hT, wd.tWidth, wd.blurT);
            const I4 nan = ~(hS >= 0) | ~(hT >= 0);  // NaN widths
            hS = nan ? F4{} + wd.minHalf : hS;
            hT = nan ? F4{} + wd.minHalf : hT;
            store4(&z[size_t(i0)], depth);
            store4(&s[size_t(i0)], ss);
            store4(&t[size_t(i0)], tt);
            store4(&hs[size_t(i0)], hS);
            store4(&ht[size_t(i0)], hT);
            store4(&usable[size_t(i0)], ok);
            // (Lanes of unusable points, perhaps not numbers, convert 0.)
            const I4 onMap = (ss >= 0) & (ss < float(wd.width)) & (tt >= 0) & (tt < float(wd.height));
            auto texel = [&](F4 v, int lo, int hi, int last) {
                const F4 l = onMap ? F4{} + float(std::max(lo, 0)) : F4{} + float(lo);
                const F4 h = onMap ? F4{} + float(std::min(hi, last)) : F4{} + float(hi);
                const F4 inside = v < l ? l : (v > h ? h : v);
                return floorX4(ok ? inside : F4{});
            };
            const int lastS = wd.width - 1, lastT = wd.height - 1;
            const I4 il = texel(ss - hS, wd.dx0 - 1, wd.dx1 + 1, lastS), ih = texel(ss + hS, wd.dx0 - 1, wd.dx1 + 1, lastS);
            const I4 jl = texel(tt - hT, wd.dy0 - 1, wd.dy1 + 1, lastT), jh = texel(tt + hT, wd.dy0 - 1, wd.dy1 + 1, lastT);
            store4(&iLo[size_t(i0)], il);
            store4(&iHi[size_t(i0)], ih);
            store4(&jLo[size_t(i0)], jl);
            store4(&jHi[size_t(i0)], jh);
            allUsable4 &= ok;
            auto lower = [](F4 a, F4 b) { return a < b ? a : b; };
            auto upper = [](F4 a, F4 b) { return a > b ? a : b; };
            zLo4 = lower(zLo4, depth), zHi4 = upper(zHi4, depth);
            loS4 = lower(loS4, ss - hS), hiS4 = upper(hiS4, ss + hS);
            loT4 = lower(loT4, tt - hT), hiT4 = upper(hiT4, tt + hT);
        }
        auto least = [](F4 v) { return std::min(std::min(v[0], v[1]), std::min(v[2], v[3])); };
        auto most = [](F4 v) { return std::max(std::max(v[0], v[1]), std::max(v[2], v[3])); };
        allUsable = (allUsable4[0] & allUsable4[1] & allUsable4[2] & allUsable4[3]) != 0;
        zLo = least(zLo4), zHi = most(zHi4);
        loS = least(loS4), hiS = most(hiS4), loT = least(loT4), hiT = most(hiT4);
    }
};

/// A standard normal deviate from two uniforms (Box-Muller).
inline void gaussianPair(float u1, float u2, float* g1, float* g2) {
    float r = std::sqrt(-2.0f * std::log(1.0f - u1));  // 1-u1 in (0,1]
    float a = 2.0f * kPi * u2;
    *g1 = r * std::cos(a);
    *g2 = r * std::sin(a);
}

}  // namespace

bool ShadowMap::batchDecided(const ShadowBatch& batch, const ShadowParams& params, const BatchBounds& bounds,
                             BatchPlanes& planes, bool planeLit, float* out, ShadowStats& st) const {
    // The tests of the point loop (bounding box, per-tile depth ranges)
    // applied once to the union of the regions of the whole batch -- a
    // shaded grid -- and its range of depths: grids that miss the map's
    // bounding box, or lie wholly nearer or farther than the tiles their
    // regions cover, are decided at once. Each point's region lies in the
    // union and its z in the range, and float addition is monotonic, so a
    // batch decided here gets exactly what the point loop would give it.
    if (batch.count < 4 || !bounds.allUsable) return false;
    const float loS = bounds.loS, hiS = bounds.hiS, loT = bounds.loT, hiT = bounds.hiT;
    const float zLo = bounds.zLo, zHi = bounds.zHi;
    auto decide = [&](float value) {
        for (int i = 0; i < batch.count; ++i) out[i] = value;
        st.points += uint64_t(batch.count);
    };
    if (hiS < float(m_dx0) || loS >= float(m_dx1) + 1.0f || hiT < float(m_dy0) || loT >= float(m_dy1) + 1.0f) {
        decide(0.0f);
        st.outside += uint64_t(batch.count);
        return true;
    }
    if (!params.tileCulling) return false;
    // Tiles the regions can reach, clipped to the data window.
    const int ci0 = int(std::floor(std::max(loS, float(m_dx0)))), ci1 = int(std::floor(std::min(hiS, float(m_dx1))));
    const int cj0 = int(std::floor(std::max(loT, float(m_dy0)))), cj1 = int(std::floor(std::min(hiT, float(m_dy1))));
    const int tx0 = (ci0 - m_fileX0) >> m_tileShiftX, tx1 = (ci1 - m_fileX0) >> m_tileShiftX;
    const int ty0 = (cj0 - m_fileY0) >> m_tileShiftY, ty1 = (cj1 - m_fileY0) >> m_tileShiftY;
    if ((tx1 - tx0 + 1) * (ty1 - ty0 + 1) > 256) return false;
    float tileMin = kInfinity, tileMax = -kInfinity;
    for (int ty = ty0; ty <= ty1; ++ty)
        for (int tx = tx0; tx <= tx1; ++tx) {
            tileMin = std::min(tileMin, m_tileMin[size_t(ty) * m_tilesX + tx]);
            tileMax = std::max(tileMax, m_tileMax[size_t(ty) * m_tilesX + tx]);
        }
    if (zHi <= tileMin + params.biasLow()) {
        decide(0.0f);
        st.culledLit += uint64_t(batch.count);
        return true;
    }
    const bool inside = loS >= float(m_dx0) && hiS < float(m_dx1) + 1.0f && loT >= float(m_dy0) &&
                        hiT < float(m_dy1) + 1.0f;
    bool allFacing = false, anyFacing = false;
    if (inside && zLo > tileMax + params.biasHigh()) {
        // Light-facing points of a second-depth map would take virtual
        // samples (see the point loop): shadowed only if their planes are
        // deeper too.
        PlaneEnvelope env;
        if (planes.frame)
            env = envelopeOfFacing(planesOf(batch, planes), batch.count, loS, hiS, loT, hiT, &allFacing, &anyFacing);
        const double limit = double(tileMax) + params.biasHigh() + double(kVirtualSlack) * std::abs(double(tileMax));
        if (!anyFacing || planesDeeper(env, ci0, ci1, cj0, cj1, limit)) {
            decide(1.0f);
            st.culledShadowed += uint64_t(batch.count);
            return true;
        }
    }
    // A flat grid of an open surface stored as its own second layer: the
    // point loop's plane test for all points at once, with their planes'
    // differences from one of them added to the gap. Every covered block
    // must store a plane (most batches stop there) before the points'
    // planes are made.
    constexpr int kMaxTiles = 16;
    if (!planeLit || m_blockShiftX < 0 || (tx1 - tx0 + 1) * (ty1 - ty0 + 1) > kMaxTiles) return false;
    struct Covered {
        ShadowTilePtr tile;
        int x, y, bx0, bx1, by0, by1;
    };
    Covered covered[kMaxTiles];
    int n = 0;
    for (int ty = ty0; ty <= ty1; ++ty)
        for (int tx = tx0; tx <= tx1; ++tx) {
            Covered& c = covered[n++];
            c.x = m_fileX0 + (tx << m_tileShiftX), c.y = m_fileY0 + (ty << m_tileShiftY);
            c.bx0 = (std::max(ci0, c.x) - c.x) >> m_blockShiftX;
            c.bx1 = (std::min(ci1, c.x + m_tileW - 1) - c.x) >> m_blockShiftX;
            c.by0 = (std::max(cj0, c.y) - c.y) >> m_blockShiftY;
            c.by1 = (std::min(cj1, c.y + m_tileH - 1) - c.y) >> m_blockShiftY;
            c.tile = fetchTile(tx, ty);
            ++st.tileFetches;
            for (int by = c.by0; by <= c.by1; ++by)
                for (int bx = c.bx0; bx <= c.bx1; ++bx)
                    if (std::isnan(c.tile->planeQ0[by * ShadowTile::kBlocks + bx])) return false;
        }
    const PlaneEnvelope env =
        envelopeOfFacing(planesOf(batch, planes), batch.count, loS, hiS, loT, hiT, &allFacing, &anyFacing);
    if (!allFacing) return false;
    for (int k = 0; k < n; ++k) {
        const Covered& c = covered[k];
        if (!onStoredPlanes(env, *c.tile, c.x, c.y, c.bx0, c.bx1, c.by0, c.by1)) return false;
    }
    decide(0.0f);
    st.storedPlaneLit += uint64_t(batch.count);
    st.storedPlaneGridPoints += uint64_t(batch.count);
    return true;
}

const ShadowMap::TangentPlane* ShadowMap::makePlanes(const ShadowBatch& batch, BatchPlanes& bp) const {
    const int n = batch.count;
    bp.planes->resize(size_t(n));
    TangentPlane* out = bp.planes->data();
    bp.ready = true;
    int i = 0;
    if (m_virtualMode != 0) {
        const PlaneFrame& frame = *bp.frame;
        const auto& M = frame.rasterPlaneFromSpace.m;
        const Vec3 L = frame.light;
        const bool perspective = m_projection == Projection::Perspective;
        for (; i + 4 <= n; i += 4) {
            const Vec3* P = batch.P + i;
            const Vec3* N = batch.N + i;
            const F4 px{P[0].x, P[1].x, P[2].x, P[3].x}, py{P[0].y, P[1].y, P[2].y, P[3].y},
                pz{P[0].z, P[1].z, P[2].z, P[3].z};
            const F4 nx{N[0].x, N[1].x, N[2].x, N[3].x}, ny{N[0].y, N[1].y, N[2].y, N[3].y},
                nz{N[0].z, N[1].z, N[2].z, N[3].z};
            // tangentPlane(), lane by lane.
            const F4 c3 = -(nx * px + ny * py + nz * pz);
            F4 pl[4];
            for (int r = 0; r < 4; ++r) pl[r] = M[r][0] * nx + M[r][1] * ny + M[r][2] * nz + M[r][3] * c3;
            const I4 ok = (abs4(pl[2]) > 1e-30f) & finite4(pl[0] + pl[1] + pl[2] + pl[3]);
            const F4 inv = -1.0f / (ok ? pl[2] : F4{} + 1.0f);
            // An invalid plane is all zeros, as TangentPlane() is.
            const F4 a = ok ? pl[0] * inv : F4{}, b = ok ? pl[1] * inv : F4{}, d = ok ? pl[3] * inv : F4{};
            const I4 faces = perspective ? nx * (L.x - px) + ny * (L.y - py) + nz * (L.z - pz) > 0.0f
                                         : nx * L.x + ny * L.y + nz * L.z < 0.0f;
            const I4 valid = ok & 1, facing = ok & faces & 1;
            for (int l = 0; l < 4; ++l) out[i + l] = TangentPlane{a[l], b[l], d[l], valid[l], facing[l]};
        }
    }
    for (; i < n; ++i) out[i] = tangentPlane(*bp.frame, batch.P[i], batch.N[i]);
    return out;
}

ShadowMap::PlaneFrame ShadowMap::planeFrame(const Mat4& spaceFromLight) const {
    // A plane covector c of the space becomes (spaceFromLight)^T c in the
    // light's camera space and m_planeFromLight times that in its raster
    // space (plane covectors go by the inverse transpose of point maps).
    PlaneFrame f;
    f.rasterPlaneFromSpace = m_planeFromLight * spaceFromLight.transposed();
    f.light = m_projection == Projection::Perspective ? spaceFromLight.point(Vec3(0, 0, 0))
                                                      : spaceFromLight.vector(Vec3(0, 0, 1));
    return f;
}

ShadowTile::DepthCoordinate ShadowMap::blockPlanes() const {
    if (m_filter != DepthFilter::Second) return ShadowTile::DepthCoordinate::None;
    if (m_virtualMode == 1) return ShadowTile::DepthCoordinate::InverseDepth;
    if (m_virtualMode == 2) return ShadowTile::DepthCoordinate::Depth;
    return ShadowTile::DepthCoordinate::None;
}

inline ShadowMap::PlaneEnvelope ShadowMap::envelope(const TangentPlane& plane) const {
    PlaneEnvelope e;
    const double k = m_wScale;
    e.A = k * plane.a, e.B = k * plane.b, e.D = k * plane.d;
    e.absA = std::abs(double(plane.a)), e.absB = std::abs(double(plane.b)), e.absD = std::abs(double(plane.d));
    return e;
}

ShadowMap::PlaneEnvelope ShadowMap::envelopeOfFacing(const TangentPlane* planes, int count, double x0, double x1,
                                                     double y0, double y1, bool* all, bool* any) const {
    PlaneEnvelope env;
    *all = true;
    *any = false;
    // Two planes differ by (dA, dB, dD): over [x0 - 1, x1 + 1] x [y0 - 1,
    // y1 + 1] (the texel centres the points' samples reach) by at most
    // their difference at its centre plus |dA| and |dB| times its half
    // extents. About the centre, not the origin: the planes of a flat grid
    // differ in A, B and D by float rounding whose effects cancel there, and
    // bounded about the origin they spread past what the stored-plane test
    // allows on half of a floor's grids.
    const double xm = 0.5 * (x0 + x1), ym = 0.5 * (y0 + y1);
    const double hx = 0.5 * std::abs(x1 - x0) + 1.0, hy = 0.5 * std::abs(y1 - y0) + 1.0;
    for (int i = 0; i < count; ++i) {
        if (!planes[i].valid || !planes[i].facesLight) {
            *all = false;
            continue;
        }
        const PlaneEnvelope e = envelope(planes[i]);
        if (!*any) {
            env = e;
            *any = true;
            continue;
        }
        const double dA = e.A - env.A, dB = e.B - env.B, dD = e.D - env.D;
        env.spread = std::max(env.spread, std::abs(dA) * hx + std::abs(dB) * hy + std::abs(dA * xm + dB * ym + dD));
        env.absA = std::max(env.absA, e.absA);
        env.absB = std::max(env.absB, e.absB);
        env.absD = std::max(env.absD, e.absD);
    }
    // A non-finite spread fails every test that reads it.
    if (!std::isfinite(env.spread)) env.spread = kInfinity;
    return env;
}

bool ShadowMap::planesDeeper(const PlaneEnvelope& env, int i0, int i1, int j0, int j1, double limit) const {
    // The planes are linear in (x, y): their extremes over the texel
    // centres are at the corners, widened by the spread and the sample
    // loop's rounding (as in onStoredPlanes()). The loop finds a sample
    // deeper when q * limit < 1 (q = 1/z, perspective) or q > limit
    // (orthographic), with its limit rounded in float: a relative 1e-6.
    if (!std::isfinite(limit) || !std::isfinite(env.spread)) return false;
    double qMin = kInfinity, qMax = -kInfinity;
    for (int c = 0; c < 4; ++c) {
        const double x = double(c & 1 ? i1 : i0) + 0.5, y = double(c & 2 ? j1 : j0) + 0.5;
        const double q = env.A * x + env.B * y + env.D;
        const double err = env.spread + evaluationError(env, std::abs(x), std::abs(y));
        qMin = std::min(qMin, q - err);
        qMax = std::max(qMax, q + err);
    }
    if (m_virtualMode == 1) return limit > 0 && qMax < (1.0 - 1e-6) / limit;
    return qMin > limit + 1e-6 * std::abs(limit);
}

ShadowMap::PlaneBlock ShadowMap::planeBlock(const ShadowTile& tile, int tileX, int tileY, int bx, int by) {
    const int bw = tile.width / ShadowTile::kBlocks, bh = tile.height / ShadowTile::kBlocks;
    const int b = by * ShadowTile::kBlocks + bx;
    const double q0 = tile.planeQ0[b], gx = tile.planeGx[b], gy = tile.planeGy[b];  // q0 NaN: not planar
    PlaneBlock k;
    k.hx = 0.5 * (bw - 1), k.hy = 0.5 * (bh - 1);
    k.xc = double(tileX + bx * bw) + 0.5 + k.hx, k.yc = double(tileY + by * bh) + 0.5 + k.hy;
    k.gx = gx, k.gy = gy;
    k.stored = q0 + gx * k.hx + gy * k.hy;
    k.least = std::abs(k.stored) - std::abs(gx) * k.hx - std::abs(gy) * k.hy;
    k.xAbs = std::abs(k.xc) + k.hx, k.yAbs = std::abs(k.yc) + k.hy;
    return k;
}

inline bool ShadowMap::onPlaneBlock(const PlaneEnvelope& env, const PlaneBlock& k) const {
    // With (x, y) from the centre of the block's texel centres, half
    // extents (hx, hy): a receiver's q = A x + B y + D and the stored
    // plane's differ linearly, by at most |gap at the centre| + |slope
    // gaps| (hx, hy) (plus the envelope's spread), and the stored q, linear
    // too, is at least |q at the centre| - |slopes| (hx, hy) in magnitude
    // (of one sign when that is positive). The sample loop's rounding of
    // the receiver's plane counts against the match as well. A block that
    // stores no plane has a NaN `least` and fails.
    const double gap = std::abs(env.A * k.xc + env.B * k.yc + env.D - k.stored) + std::abs(env.A - k.gx) * k.hx +
                       std::abs(env.B - k.gy) * k.hy + env.spread;
    const double evaluation = evaluationError(env, k.xAbs, k.yAbs);
    return k.least > 0 && gap + evaluation <= kPlaneMatch * k.least;
}

bool ShadowMap::onStoredPlanes(const PlaneEnvelope& env, const ShadowTile& tile, int tileX, int tileY, int bx0,
                               int bx1, int by0, int by1) const {
    for (int by = by0; by <= by1; ++by)
        for (int bx = bx0; bx <= bx1; ++bx)
            if (!onPlaneBlock(env, planeBlock(tile, tileX, tileY, bx, by))) return false;
    return true;
}

template <bool kPointSample>
void ShadowMap::lookupImpl(const ShadowBatch& batch, const ShadowParams& params, float* out,
                           ShadowStats& stats) const {
    ShadowStats st;
    const Mat4 lightFromCurrent = m_lightFromWorld * batch.worldFromCurrent;
    const Mat4 rasterFromCurrent =
        Mat4::scale(Vec3(float(m_width), float(m_height), 1.0f)) * m_ndcFromWorld * batch.worldFromCurrent;

    const float biasLo = params.biasLow(), biasHi = params.biasHigh();
    const float biasMid = 0.5f * (biasLo + biasHi);
    const bool randomBias = biasLo != biasHi;
    const int samples = std::max(1, params.samples);
    const int minSamples = clamp(params.minSamples, 1, samples);
    // Moving receivers on a map of moving casters whose texel times are
    // known are looked up time by time (movingShadow below), every point
    // of the batch, without the shortcuts that assume one depth and place.
    const bool timeByTime = !kPointSample && batch.pathKeys > 1 && knowsTexelTimes();
    // A map of moving casters holds each time in one texel of every time
    // tile: regions span at least a tile, so each sees the whole shutter.
    const float minHalf = std::max({0.0f, params.minSize * 0.5f, float(m_timeTile) * 0.5f});
    // Regions larger than this (half-width, texels) gain nothing: clamping
    // keeps the sample arithmetic finite for wild footprints.
    const float maxHalf = 4.0f * float(std::max(m_width, m_height)) + 4.0f;
    const float blurS = std::max(0.0f, params.blur) * float(m_width) * 0.5f;
    const float blurT = std::max(0.0f, params.blur) * float(m_height) * 0.5f;
    const bool hasData = !empty();
    // Data window clipped to the display window, inclusive texel bounds: a
    // sample's texel (i, j) holds a depth when dx0 <= i <= dx1 and
    // dy0 <= j <= dy1, and reads +infinity otherwise.
    const int dx0 = m_dx0, dx1 = m_dx1, dy0 = m_dy0, dy1 = m_dy1;

    const int shiftX = m_tileShiftX, shiftY = m_tileShiftY;
    thread_local TileMemo t_memo;
    TileMemo& memo = t_memo;
    // A region's samples: per-thread scratch, looked up once per batch.
    thread_local RegionSamples t_region;
    RegionSamples& region = t_region;
    auto depthAt = [&](int iu, int iv) -> float {
        const int fx = iu - m_fileX0, fy = iv - m_fileY0;
        const int tx = fx >> m_tileShiftX, ty = fy >> m_tileShiftY;
        const int slot = TileMemo::slot(m_mapId, tx, ty);
        if (memo.map[slot] != m_mapId || memo.tx[slot] != tx || memo.ty[slot] != ty) {
            memo.hold[slot] = fetchTile(tx, ty);
            memo.map[slot] = m_mapId;
            memo.tile[slot] = memo.hold[slot].get();
            memo.data[slot] = memo.hold[slot]->z.data();
            memo.tx[slot] = tx;
            memo.ty[slot] = ty;
            ++st.tileFetches;
        }
        return memo.data[slot][((fy & (m_tileH - 1)) << m_tileShiftX) + (fx & (m_tileW - 1))];
    };

    // Second-depth maps with normals get virtual samples (Wang & Molnar).
    // Midpoint and dual maps get them too, where the papers are silent: a
    // light-facing receiver whose own comparisons shadow it is compared by
    // its tangent plane instead of its one depth. An open floor stored as
    // its single layer (z1 + offset) then lights itself at any slope, where
    // comparing its depth with the stored depths of its neighbours shadows
    // it in stripes at grazing light (docs/shadows.md).
    const bool secondDepth = !kPointSample && m_filter == DepthFilter::Second && batch.N && m_virtualMode != 0;
    const bool twoLayer = m_filter == DepthFilter::Second || m_filter == DepthFilter::Midpoint ||
                          m_filter == DepthFilter::Dual;
    const bool virtualCompare = !kPointSample && twoLayer && batch.N && m_virtualMode != 0;
    // Once per batch, not per point: what tangent planes need.
    const PlaneFrame planes = virtualCompare ? planeFrame(lightFromCurrent.inverse()) : PlaneFrame();

    // Second-depth maps: the points' tangent planes, all at once when a
    // test of the whole batch needs them, else one point's when it does.
    thread_local std::vector<TangentPlane> t_planes;
    BatchPlanes batchPlanes;
    if (virtualCompare) {
        batchPlanes.frame = &planes;
        batchPlanes.planes = &t_planes;
    }
    // Points on a stored plane are lit without samples when no negative
    // bias can shadow a sample on the plane itself and the region takes
    // more than one sample (a single one is a plain comparison).
    const bool planeLit = secondDepth && params.tileCulling && biasLo >= 0 && samples > 1;

    // Each point's samples are seeded by hashKeys(batch.seed, its id).
    const uint32_t batchSeed = hash32(batch.seed);
    thread_local PointRegions t_points;
    PointRegions& pts = t_points;
    pts.compute(batch, lightFromCurrent, rasterFromCurrent,
                {params.sWidth, params.tWidth, blurS, blurT, minHalf, maxHalf, m_dx0, m_dx1, m_dy0, m_dy1, m_width,
                 m_height});

    if constexpr (!kPointSample) {
        const BatchBounds bounds{pts.allUsable, pts.zLo, pts.zHi, pts.loS, pts.hiS, pts.loT, pts.hiT};
        if (hasData && !timeByTime && batchDecided(batch, params, bounds, batchPlanes, planeLit && minSamples >= 2, out, st)) {
            stats += st;
            return;
        }
    }

    // The texels a region covers in the data window, and their tiles.
    struct Covered {
        int ci0, ci1, cj0, cj1;  // inclusive texel bounds
        int tx0, tx1, ty0, ty1;  // inclusive tile bounds
    };
    auto covered = [&](int ci0, int ci1, int cj0, int cj1) {
        return Covered{ci0, ci1, cj0, cj1, (ci0 - m_fileX0) >> shiftX, (ci1 - m_fileX0) >> shiftX,
                       (cj0 - m_fileY0) >> shiftY, (cj1 - m_fileY0) >> shiftY};
    };
    // The depth range of the covered tiles, from the header without reading
    // a texel; false for regions over more than 64 tiles (not worth it).
    auto tileRange = [&](const Covered& c, float* zMin, float* zMax) {
        if ((c.tx1 - c.tx0 + 1) * (c.ty1 - c.ty0 + 1) > 64) return false;
        float lo = kInfinity, hi = -kInfinity;
        for (int ty = c.ty0; ty <= c.ty1; ++ty)
            for (int tx = c.tx0; tx <= c.tx1; ++tx) {
                lo = std::min(lo, m_tileMin[size_t(ty) * m_tilesX + tx]);
                hi = std::max(hi, m_tileMax[size_t(ty) * m_tilesX + tx]);
            }
        *zMin = lo, *zMax = hi;
        return true;
    };
    // The 8x8-texel blocks the region covers, in the (at most 2x2) tiles it
    // covers, pinned in the memo: fn(tile, its first texel, block range)
    // for each tile, stopping at the first false.
    auto everyTileOfBlocks = [&](const Covered& c, auto&& fn) -> bool {
        for (int ty = c.ty0; ty <= c.ty1; ++ty)
            for (int tx = c.tx0; tx <= c.tx1; ++tx) {
                const int tileX = m_fileX0 + (tx << shiftX), tileY = m_fileY0 + (ty << shiftY);
                const int cx0 = std::max(c.ci0, tileX), cy0 = std::max(c.cj0, tileY);
                (void)depthAt(cx0, cy0);  // pins the tile in the memo
                const ShadowTile& tile = *memo.tile[TileMemo::slot(m_mapId, tx, ty)];
                const int cx1 = std::min(c.ci1, tileX + m_tileW - 1), cy1 = std::min(c.cj1, tileY + m_tileH - 1);
                if (!fn(tile, tileX, tileY, (cx0 - tileX) >> m_blockShiftX, (cx1 - tileX) >> m_blockShiftX,
                        (cy0 - tileY) >> m_blockShiftY, (cy1 - tileY) >> m_blockShiftY))
                    return false;
            }
        return true;
    };
    // The blocks' finer depth range, for regions within 2x2 tiles of a map
    // that has blocks; `planar`: every covered block stores a plane.
    // Consecutive points of a grid mostly cover the same blocks: the last
    // range is kept with its blocks (map-wide block indices).
    struct LastBlocks {
        int bx0 = -1, bx1 = -2, by0 = -1, by1 = -2;
        float lo = 0, hi = 0;
        bool flat = false;
    } last;
    auto blockRange = [&](const Covered& c, float* zMin, float* zMax, bool* planar) {
        if (m_blockShiftX < 0 || c.tx1 - c.tx0 > 1 || c.ty1 - c.ty0 > 1) return false;
        const int bx0 = (c.ci0 - m_fileX0) >> m_blockShiftX, bx1 = (c.ci1 - m_fileX0) >> m_blockShiftX;
        const int by0 = (c.cj0 - m_fileY0) >> m_blockShiftY, by1 = (c.cj1 - m_fileY0) >> m_blockShiftY;
        if (bx0 == last.bx0 && bx1 == last.bx1 && by0 == last.by0 && by1 == last.by1) {
            *zMin = last.lo, *zMax = last.hi, *planar = last.flat;
            return true;
        }
        float lo = kInfinity, hi = -kInfinity;
        bool flat = true;
        everyTileOfBlocks(c, [&](const ShadowTile& tile, int, int, int bx0, int bx1, int by0, int by1) {
            for (int by = by0; by <= by1; ++by)
                for (int bx = bx0; bx <= bx1; ++bx) {
                    const int b = by * ShadowTile::kBlocks + bx;
                    lo = std::min(lo, tile.blockMin[b]);
                    hi = std::max(hi, tile.blockMax[b]);
                    flat = flat && !std::isnan(tile.planeQ0[b]);
                }
            return true;
        });
        *zMin = lo, *zMax = hi, *planar = flat;
        last = {bx0, bx1, by0, by1, lo, hi, flat};
        return true;
    };

    // The stored planes of the blocks met so far (PlaneBlock), by their
    // map-wide block index: consecutive points mostly cover the same ones.
    // A region's blocks lie within 2x2 tiles (blockRange()), so 8x8 slots
    // hold them without collisions.
    struct CachedBlock {
        int bx = -1, by = -1;
        PlaneBlock k;
    };
    CachedBlock blockCache[64];
    constexpr int tileBlocksShift = 2;  // log2 of the blocks along a tile's side
    static_assert(ShadowTile::kBlocks == 1 << tileBlocksShift);
    auto onCoveredPlanes = [&](const Covered& c, const PlaneEnvelope& env) {
        const int bx0 = (c.ci0 - m_fileX0) >> m_blockShiftX, bx1 = (c.ci1 - m_fileX0) >> m_blockShiftX;
        const int by0 = (c.cj0 - m_fileY0) >> m_blockShiftY, by1 = (c.cj1 - m_fileY0) >> m_blockShiftY;
        for (int by = by0; by <= by1; ++by)
            for (int bx = bx0; bx <= bx1; ++bx) {
                CachedBlock& slot = blockCache[((by & 7) << 3) | (bx & 7)];
                if (slot.bx != bx || slot.by != by) {
                    const int tx = bx >> tileBlocksShift, ty = by >> tileBlocksShift;
                    const int tileX = m_fileX0 + (tx << shiftX), tileY = m_fileY0 + (ty << shiftY);
                    (void)depthAt(tileX, tileY);  // pins the tile in the memo
                    const ShadowTile& tile = *memo.tile[TileMemo::slot(m_mapId, tx, ty)];
                    const int mask = ShadowTile::kBlocks - 1;
                    slot = {bx, by, planeBlock(tile, tileX, tileY, bx & mask, by & mask)};
                }
                if (!onPlaneBlock(env, slot.k)) return false;
            }
        return true;
    };

    // A moving receiver (docs/motion.md): the map holds each time of the
    // shutter in one texel of every time tile ("slot" k of the tile), and
    // the point is compared with each texel where it is at that texel's
    // time: with itself at one time, and with the casters where they were
    // then. Where the point is at each slot's time is projected once. A
    // region of a few texels takes every texel that overlaps it where the
    // point is at the texel's time; a wide one jittered samples, each the
    // texel, of all slots, nearest its offset from where the point is at
    // the slot's time. For two-layer maps' virtual samples the tangent
    // plane moves with the point (its turning is not followed). Points are
    // culled by the depth ranges as still ones are, with their regions
    // swept over the shutter and their depths' range over it.
    struct MovingSample {
        int iu, iv;
        Vec3 at;           // where the point is at the texel's time
        float pointDepth;  // its depth there
        float bias, depth, weight;
    };
    thread_local std::vector<MovingSample> t_moving;
    thread_local std::vector<Vec3> t_keyPoints;
    thread_local std::vector<float> t_keyDepths;
    const int pathKeys = batch.pathKeys;
    auto movingShadow = [&](int i) -> float {
        const Vec3 P = batch.P[i];
        const auto& L = lightFromCurrent.m;
        const auto& R = rasterFromCurrent.m;
        auto depthOf = [&](const Vec3& X) { return L[2][0] * X.x + L[2][1] * X.y + L[2][2] * X.z + L[2][3]; };
        const float hs = pts.hs[size_t(i)], ht = pts.ht[size_t(i)];
        // Tile and period sides are powers of two (setupTimeSlots): shifts
        // and masks, not divisions, in the search below.
        const int T = m_timeTile, slots = T * T, tileShift = std::countr_zero(unsigned(T)), tileMask = T - 1;
        const int periodMask = m_timePeriod - 1, tilesMask = (m_timePeriod >> tileShift) - 1;
        const int tilesShift = std::countr_zero(unsigned(m_timePeriod >> tileShift));
        const float inverseT = 1.0f / float(T);
        // Where the point is at time u of the shutter, as the depth pass
        // placed it: between the path's keys it moved its micropolygons
        // linearly in its raster space and, under perspective, in 1/z, so
        // between keys at depths za and zb, at fraction v of the interval,
        // the map holds the point that has made v za / ((1 - v) zb + v za)
        // of its straight way (the point whose 1/z is the ends' blend).
        const float* keyTimes = batch.pathTimes;
        std::vector<Vec3>& keyPoint = t_keyPoints;
        std::vector<float>& keyDepth = t_keyDepths;
        keyPoint.resize(size_t(pathKeys));
        keyDepth.resize(size_t(pathKeys));
        for (int k = 0; k < pathKeys; ++k) {
            keyPoint[size_t(k)] = P + batch.pathOffsets[size_t(k) * size_t(batch.count) + size_t(i)];
            keyDepth[size_t(k)] = depthOf(keyPoint[size_t(k)]);
        }
        const bool perspective = m_projection == Projection::Perspective;
        auto pointAt = [&](float u) {
            size_t a = 0;
            while (int(a) + 2 < pathKeys && u > keyTimes[a + 1]) ++a;
            const Vec3 A = keyPoint[a], B = keyPoint[a + 1];
            const float za = keyDepth[a], zb = keyDepth[a + 1], span = keyTimes[a + 1] - keyTimes[a];
            const float v = span > 0 ? std::clamp((u - keyTimes[a]) / span, 0.0f, 1.0f) : 0.0f;
            const bool projective = perspective && za > 0 && zb > 0;
            return A + (B - A) * (projective ? v * za / ((1.0f - v) * zb + v * za) : v);
        };
        // Where the point is at each slot's time, and the box of those
        // places (a slot behind the light has none).
        float slotS[kMaxTimeSlots], slotT[kMaxTimeSlots], slotDepth[kMaxTimeSlots];
        Vec3 slotPoint[kMaxTimeSlots];
        bool slotSeen[kMaxTimeSlots];
        float sLo = kInfinity, sHi = -kInfinity, tLo = kInfinity, tHi = -kInfinity;
        for (int k = 0; k < slots; ++k) {
            const Vec3 X = pointAt(m_slotTime[size_t(k)]);
            slotPoint[k] = X;
            slotDepth[k] = depthOf(X);
            const float w = R[3][0] * X.x + R[3][1] * X.y + R[3][2] * X.z + R[3][3], inverse = 1.0f / w;
            slotS[k] = (R[0][0] * X.x + R[0][1] * X.y + R[0][2] * X.z + R[0][3]) * inverse;
            slotT[k] = (R[1][0] * X.x + R[1][1] * X.y + R[1][2] * X.z + R[1][3]) * inverse;
            slotSeen[k] = w > 0 && slotDepth[k] >= 0 && std::abs(slotS[k]) < 1e9f && std::abs(slotT[k]) < 1e9f;
            if (!slotSeen[k]) continue;
            sLo = std::min(sLo, slotS[k]), sHi = std::max(sHi, slotS[k]);
            tLo = std::min(tLo, slotT[k]), tHi = std::max(tHi, slotT[k]);
        }
        if (!(sLo <= sHi)) {  // behind the light all the shutter
            ++st.outside;
            return 0.0f;
        }
        // The texels the swept region reaches (one beyond the data window at
        // most), and the point's depths over the shutter (linear in time).
        const auto bound = [](float v, int lo, int hi) { return clamp(floorInt(clamp(v, float(lo), float(hi))), lo, hi); };
        // A wide region's samples take the nearest texel of a slot, up to a
        // time tile from the sample: its reach grows by one.
        const bool enumerated = 4.0f * hs * ht <= float(kEnumeratedRegion);
        const float reach = enumerated ? 0.0f : float(T);
        const int iLo = bound(sLo - hs - reach, dx0 - 1, dx1 + 1), iHi = bound(sHi + hs + reach, dx0 - 1, dx1 + 1);
        const int jLo = bound(tLo - ht - reach, dy0 - 1, dy1 + 1), jHi = bound(tHi + ht + reach, dy0 - 1, dy1 + 1);
        if (iHi < dx0 || iLo > dx1 || jHi < dy0 || jLo > dy1) {
            ++st.outside;
            return 0.0f;
        }
        // Between keys depth runs monotonically: its range over the shutter
        // is the keys'.
        const float zLo = *std::min_element(keyDepth.begin(), keyDepth.end());
        const float zHi = *std::max_element(keyDepth.begin(), keyDepth.end());
        // The swept region's texels in the data window, and their tiles.
        const int ci0 = std::max(iLo, dx0), ci1 = std::min(iHi, dx1), cj0 = std::max(jLo, dy0), cj1 = std::min(jHi, dy1);
        const bool inside = ci0 == iLo && ci1 == iHi && cj0 == jLo && cj1 == jHi;
        const Covered c = covered(ci0, ci1, cj0, cj1);
        if (params.tileCulling) {
            float zMin, zMax;
            bool planar = false;
            if (blockRange(c, &zMin, &zMax, &planar) || tileRange(c, &zMin, &zMax)) {
                if (zHi <= zMin + biasLo) {
                    ++st.culledLit;
                    return 0.0f;
                }
                // (A two-layer map's light-facing points would take virtual
                // samples: not culled as shadowed.)
                if (inside && zLo > zMax + biasHi && !virtualCompare) {
                    ++st.culledShadowed;
                    return 1.0f;
                }
            }
        }
        const uint32_t pointSeed = hashCombine(batchSeed, uint32_t(batch.pointId ? batch.pointId[i] : i));
        const bool gaussianFilter = params.filter == ShadowParams::Filter::Gaussian;
        std::vector<MovingSample>& taken = t_moving;
        taken.clear();
        float inShadow = 0, weightSum = 0;
        // The swept region's texels, when they lie in one tile of the map
        // and its data window (the usual), read straight from the tile.
        const float* single = nullptr;
        int singleX = 0, singleY = 0;
        if (inside && c.tx0 == c.tx1 && c.ty0 == c.ty1) {
            (void)depthAt(ci0, cj0);  // pins the tile in the memo
            single = memo.data[TileMemo::slot(m_mapId, c.tx0, c.ty0)];
            singleX = m_fileX0 + (c.tx0 << shiftX);
            singleY = m_fileY0 + (c.ty0 << shiftY);
        }
        // Only two-layer maps' virtual samples look at the samples again.
        const bool keep = virtualCompare;
        const float invHs = 1.0f / std::max(hs, 1e-30f), invHt = 1.0f / std::max(ht, 1e-30f);
        int samplesTaken = 0;
        // Texel (iu, iv) as a sample at offset (du, dv) from where the point
        // is at the texel's time, weighing `area`; `sample`: the jittered
        // sample's index, or -1 for a texel taken whole (its bias drawn by
        // its place).
        auto take = [&](int iu, int iv, int slot, float du, float dv, float area, int sample) {
            ++samplesTaken;
            MovingSample m;
            m.iu = iu, m.iv = iv;
            // (The slot's time in umbra's maps, whose tiles all time their
            // k-th texel alike.)
            const float u = m_texelTimes[size_t((iv & periodMask) * m_timePeriod + (iu & periodMask))];
            if (u == m_slotTime[size_t(slot)]) {
                m.at = slotPoint[slot], m.pointDepth = slotDepth[slot];
            } else {
                m.at = pointAt(u), m.pointDepth = depthOf(m.at);
            }
            m.bias = biasMid;
            if (randomBias) {
                const int key = sample >= 0 ? sample : int(hashKeys(uint32_t(iu), uint32_t(iv)) & 0xffffffu);
                m.bias = std::min(biasHi, biasLo + SampleRandoms(pointSeed, key).jbias() * (biasHi - biasLo));
            }
            if (single) {
                m.depth = single[((iv - singleY) << shiftX) + (iu - singleX)];
            } else {
                const bool stored = iu >= dx0 && iu <= dx1 && iv >= dy0 && iv <= dy1;
                m.depth = stored ? depthAt(iu, iv) : kInfinity;
            }
            m.weight = area;
            if (gaussianFilter) {
                const float ru = du * invHs, rv = dv * invHt;
                m.weight *= std::exp(-2.0f * (ru * ru + rv * rv));
            }
            weightSum += m.weight;
            if (m.pointDepth > m.depth + m.bias) inShadow += m.weight;
            if (keep) taken.push_back(m);
        };
        auto slotTexel = [&](int tx, int ty, int slot) {
            return int(m_slotTexel[size_t(((((ty & tilesMask) << tilesShift) | (tx & tilesMask)) << (2 * tileShift)) |
                                          slot)]);
        };
        if (enumerated) {
            // A region of a few texels (the usual: a tile, or a little more):
            // every texel that overlaps the region where the point is at the
            // texel's time is a sample, weighed by the overlap, so shadows
            // ramp smoothly without jitter's noise. Found texel by texel
            // over the swept region when it is small (a point moving a few
            // texels), else slot by slot: each time tile holds one texel of
            // each slot, so a slot's texels are found tile by tile over the
            // region around where the point is at that slot's time. The
            // same texels either way.
            auto overlapping = [&](int iu, int iv, int slot) {
                const float s0 = slotS[slot] - hs, s1 = slotS[slot] + hs, t0 = slotT[slot] - ht, t1 = slotT[slot] + ht;
                const float overlapU = std::min(float(iu + 1), s1) - std::max(float(iu), s0);
                const float overlapV = std::min(float(iv + 1), t1) - std::max(float(iv), t0);
                if (!(overlapU > 0 && overlapV > 0)) return;
                take(iu, iv, slot, float(iu) + 0.5f - slotS[slot], float(iv) + 0.5f - slotT[slot], overlapU * overlapV, -1);
            };
            const int sweptTexels = (iHi - iLo + 1) * (jHi - jLo + 1);
            if (sweptTexels <= 3 * slots) {
                for (int iv = jLo; iv <= jHi; ++iv) {
                    const uint8_t* slotRow = &m_texelSlot[size_t(iv & periodMask) * size_t(m_timePeriod)];
                    for (int iu = iLo; iu <= iHi; ++iu) {
                        const int slot = slotRow[iu & periodMask];
                        if (slotSeen[slot]) overlapping(iu, iv, slot);
                    }
                }
            } else {
                for (int slot = 0; slot < slots; ++slot) {
                    if (!slotSeen[slot]) continue;
                    const int tx0 = floorInt((slotS[slot] - hs) * inverseT), tx1 = floorInt((slotS[slot] + hs) * inverseT);
                    const int ty0 = floorInt((slotT[slot] - ht) * inverseT), ty1 = floorInt((slotT[slot] + ht) * inverseT);
                    for (int ty = ty0; ty <= ty1; ++ty)
                        for (int tx = tx0; tx <= tx1; ++tx) {
                            const int texel = slotTexel(tx, ty, slot);
                            overlapping(tx * T + (texel & tileMask), ty * T + (texel >> tileShift), slot);
                        }
                }
            }
        } else {
            // A wide region (blur, a large footprint): Reeves' count of
            // jittered samples, each taking, of all the slots, the texel
            // nearest its offset from where the point is at that slot's time.
            int ns, nt;
            reevesCounts(samples, minSamples, hs, ht, &ns, &nt);
            const float ds = 2.0f * hs / float(ns), dt = 2.0f * ht / float(nt);
            for (int k = 0; k < ns * nt; ++k) {
                const SampleRandoms r(pointSeed, k);
                const float du = (float(k / nt) + r.ju()) * ds - hs, dv = (float(k % nt) + r.jv()) * dt - ht;
                float nearest = kInfinity;
                int bestU = 0, bestV = 0, bestSlot = 0;
                for (int slot = 0; slot < slots; ++slot) {
                    if (!slotSeen[slot]) continue;
                    const float u = slotS[slot] + du, v = slotT[slot] + dv;
                    const int tx = floorInt(u * inverseT), ty = floorInt(v * inverseT), texel = slotTexel(tx, ty, slot);
                    const int iu = tx * T + (texel & tileMask), iv = ty * T + (texel >> tileShift);
                    const float ex = float(iu) + 0.5f - u, ey = float(iv) + 0.5f - v, d2 = ex * ex + ey * ey;
                    if (d2 < nearest) nearest = d2, bestU = iu, bestV = iv, bestSlot = slot;
                }
                take(bestU, bestV, bestSlot, du, dv, 1.0f, k);
            }
        }
        const int count = int(samplesTaken);
        ++st.filtered;
        st.samples += uint64_t(count);
        // Two-layer maps: Wang & Molnar's Figure 10, as for a still point.
        const bool mixed = inShadow > 0 && inShadow < weightSum;
        if (virtualCompare && (mixed || (inShadow > 0 && facesLight(planes, P, batch.N[i])))) {
            ++st.virtualPoints;
            inShadow = 0;
            for (const MovingSample& m : taken) {
                const TangentPlane plane = tangentPlane(planes, m.at, batch.N[i]);
                const bool shadowed =
                    plane.valid ? m.depth != kInfinity &&
                                      virtualDeeper(plane, m.iu, m.iv,
                                                    m.depth + m.bias + kVirtualSlack * std::abs(m.depth))
                                : m.pointDepth > m.depth + m.bias;
                if (shadowed) inShadow += m.weight;
            }
        }
        return weightSum > 0 ? inShadow / weightSum : 0.0f;
    };

    for (int i = 0; i < batch.count; ++i) {
        out[i] = 0;
        ++st.points;
        const Vec3 P = batch.P[i];
        if (timeByTime && hasData) {
            out[i] = movingShadow(i);
            continue;
        }
        // This point's tangent plane (second-depth maps), made on first use.
        TangentPlane pointPlane;
        bool pointPlaneKnown = false;
        auto planeOfPoint = [&]() -> const TangentPlane& {
            if (!pointPlaneKnown) {
                // The whole batch's, four at a time, when the first point
                // needs one: most points of a grid that needs one do.
                pointPlane = planesOf(batch, batchPlanes)[i];
                pointPlaneKnown = true;
            }
            return pointPlane;
        };
        // Behind the light, unprojectable, or nothing stored: lit.
        if (!pts.usable[size_t(i)] || !hasData) {
            ++st.outside;
            continue;
        }
        const float z = pts.z[size_t(i)], s = pts.s[size_t(i)], t = pts.t[size_t(i)];

        if constexpr (kPointSample) {
            if (!(s >= float(dx0) && s < float(dx1) + 1.0f && t >= float(dy0) && t < float(dy1) + 1.0f)) {
                ++st.outside;
                continue;
            }
            ++st.filtered;
            ++st.samples;
            out[i] = z > depthAt(floorInt(s), floorInt(t)) + biasMid ? 1.0f : 0.0f;
            continue;
        } else {
            const float hs = pts.hs[size_t(i)], ht = pts.ht[size_t(i)];
            const float loS = s - hs, hiS = s + hs, loT = t - ht, hiT = t + ht;
            // The texels the samples can reach (see PointRegions)...
            const int iLo = pts.iLo[size_t(i)], iHi = pts.iHi[size_t(i)];
            const int jLo = pts.jLo[size_t(i)], jHi = pts.jHi[size_t(i)];
            if (iHi < dx0 || iLo > dx1 || jHi < dy0 || jLo > dy1) {
                ++st.outside;
                continue;
            }
            // ... clipped to the data window.
            const int ci0 = std::max(iLo, dx0), ci1 = std::min(iHi, dx1);
            const int cj0 = std::max(jLo, dy0), cj1 = std::min(jHi, dy1);
            const bool regionInside = ci0 == iLo && ci1 == iHi && cj0 == jLo && cj1 == jHi;

            // Exact culling: float addition is monotonic, so every sample's
            // map + bias lies in [zMin + biasLo, zMax + biasHi] of the texels
            // the region covers; outside the data window texels are
            // +infinity, so "shadowed" needs the region wholly inside it.
            // A light-facing point on a second-depth map would take virtual
            // samples: shadowed only if its plane is deeper too. (Out of
            // line: inlined, it kept the common path below from being.)
            auto secondDepthShadowed = [&](float zMax) __attribute__((noinline)) {
                const TangentPlane& pl = planeOfPoint();
                return samples == 1 || !pl.valid || !pl.facesLight ||
                       planesDeeper(envelope(pl), iLo, iHi, jLo, jHi,
                                    double(zMax) + biasHi + double(kVirtualSlack) * std::abs(double(zMax)));
            };
            // Counted in `lit` or `shadowed`: which test decided it.
            auto culled = [&](float zMin, float zMax, uint64_t& lit, uint64_t& shadowed) {
                if (z <= zMin + biasLo) {
                    ++lit;
                    return true;
                }
                if (regionInside && z > zMax + biasHi && (!virtualCompare || secondDepthShadowed(zMax))) {
                    ++shadowed;
                    out[i] = 1.0f;
                    return true;
                }
                return false;
            };
            // By the depth range of the covered blocks, where the map has
            // blocks and the region lies within 2x2 tiles (the common case:
            // regions are a few texels, tiles 32), else of the covered
            // tiles. A block's range lies within its tile's, so the tiles'
            // test would cull nothing more.
            const Covered c = covered(ci0, ci1, cj0, cj1);
            const int tx0 = c.tx0, tx1 = c.tx1, ty0 = c.ty0, ty1 = c.ty1;
            float zMin, zMax;
            bool blocksPlanar = false;  // every covered block stores a plane (second-depth maps)
            const bool blockTests = params.tileCulling && blockRange(c, &zMin, &zMax, &blocksPlanar);
            if ((blockTests || (params.tileCulling && tileRange(c, &zMin, &zMax))) &&
                culled(zMin, zMax, st.culledLit, st.culledShadowed))
                continue;
            // When the region lies in one tile (the common case: regions are
            // a few texels, tiles 32) its pointer is fetched once.
            const float* single = nullptr;
            int singleX = 0, singleY = 0;
            if (tx0 == tx1 && ty0 == ty1) {
                (void)depthAt(ci0, cj0);  // pins the tile in the memo
                single = memo.data[TileMemo::slot(m_mapId, tx0, ty0)];
                singleX = m_fileX0 + (tx0 << shiftX);
                singleY = m_fileY0 + (ty0 << shiftY);
            }
            // Exact culling by the covered texels themselves: a region of a
            // few texels inside one tile (a sample's texel is one of them,
            // so the ranges' argument above holds) is decided by their
            // min and max before any sample is drawn. Where a block's range
            // holds the point's depth, it is most often a receiver lit or
            // shadowed by all its texels: a floor beside a caster, a
            // surface whose block holds an edge it does not reach.
            if (params.tileCulling && single && (ci1 - ci0 + 1) * (cj1 - cj0 + 1) <= kTexelRangeLimit) {
                float lo = kInfinity, hi = -kInfinity;
                for (int v = cj0; v <= cj1; ++v) {
                    const float* row = single + ((v - singleY) << shiftX) - singleX;
                    for (int u = ci0; u <= ci1; ++u) lo = std::min(lo, row[u]), hi = std::max(hi, row[u]);
                }
                if (culled(lo, hi, st.texelRangeLit, st.texelRangeShadowed)) continue;
            }

            int ns, nt;
            reevesCounts(samples, minSamples, hs, ht, &ns, &nt);
            // An open surface stored as its own second layer (§3.3): a
            // receiver whose tangent plane is the plane the covered blocks
            // store, facing the light, gets every virtual sample lit, and
            // Figure 10 gives it 0 whatever its plain comparisons say --
            // unless a single sample makes the plain comparison final.
            // (A negative bias could shadow a sample on the plane itself.)
            if (planeLit && blockTests && blocksPlanar && ns * nt > 1 && planeOfPoint().valid &&
                planeOfPoint().facesLight) {
                if (onCoveredPlanes(c, envelope(planeOfPoint()))) {
                    ++st.storedPlaneLit;
                    continue;
                }
            }
            ++st.filtered;
            st.samples += uint64_t(ns) * uint64_t(nt);

            auto depthOf = [&](int iu, int iv) -> float {
                return single ? single[((iv - singleY) << shiftX) + (iu - singleX)] : depthAt(iu, iv);
            };
            if (ns == 1 && nt == 1) {
                const int iu = clamp(floorInt(s), iLo, iHi), iv = clamp(floorInt(t), jLo, jHi);
                if (iu >= dx0 && iu <= dx1 && iv >= dy0 && iv <= dy1) out[i] = z > depthOf(iu, iv) + biasMid ? 1.0f : 0.0f;
                continue;
            }

            // Sample (a, b) of the region: its position (u, v) in raster
            // space and its bias, a function of the point and the sample
            // alone, so the virtual-sample pass below repeats them.
            const uint32_t pointSeed = hashCombine(batchSeed, uint32_t(batch.pointId ? batch.pointId[i] : i));
            const float ds = 2.0f * hs / float(ns), dt = 2.0f * ht / float(nt);
            auto sampleAt = [&](int a, int b, float* u, float* v, float* bias) {
                const SampleRandoms r(pointSeed, a * nt + b);
                switch (params.sampling) {
                case ShadowParams::Sampling::Jittered:
                    *u = loS + (float(a) + r.ju()) * ds;
                    *v = loT + (float(b) + r.jv()) * dt;
                    break;
                case ShadowParams::Sampling::Uniform:
                    *u = loS + r.ju() * 2.0f * hs;
                    *v = loT + r.jv() * 2.0f * ht;
                    break;
                case ShadowParams::Sampling::Gaussian:
                default: {
                    // Reeves' (b): a Gaussian over the box, sigma = half the
                    // half-width, clamped into the box below (|g| < 6, so u
                    // stays within s +- 3 hs).
                    float g1, g2;
                    gaussianPair(r.extra(1), r.extra(2), &g1, &g2);
                    *u = s + g1 * 0.5f * hs;
                    *v = t + g2 * 0.5f * ht;
                    break;
                }
                }
                *bias = randomBias ? std::min(biasHi, biasLo + r.jbias() * (biasHi - biasLo)) : biasMid;
            };
            // floor is monotonic, so clamping the texel index equals clamping
            // the position into the region first.
            auto texelOf = [&](float u, float v, int* iu, int* iv) {
                *iu = clamp(floorInt(u), iLo, iHi);
                *iv = clamp(floorInt(v), jLo, jHi);
            };
            const bool gaussianFilter = params.filter == ShadowParams::Filter::Gaussian;
            const float invHs = hs > 0 ? 1.0f / hs : 0.0f, invHt = ht > 0 ? 1.0f / ht : 0.0f;
            auto weight = [&](float u, float v) -> float {
                if (!gaussianFilter) return 1.0f;
                const float ru = (clamp(u, loS, hiS) - s) * invHs, rv = (clamp(v, loT, hiT) - t) * invHt;
                return std::exp(-2.0f * (ru * ru + rv * rv));
            };
            // The depth stored at a sample's texel: +infinity outside the
            // data window.
            auto texelDepth = [&](int iu, int iv) -> float {
                const bool stored = regionInside || (iu >= dx0 && iu <= dx1 && iv >= dy0 && iv <= dy1);
                return stored ? depthOf(iu, iv) : kInfinity;
            };
            // The region's samples: texel, bias, weight and the depth stored
            // there. The virtual-sample pass below compares the same ones
            // again. Branch-free comparisons: which samples are shadowed is a
            // coin toss in a penumbra.
            const int count = ns * nt;
            region.resize(count);
            const bool unitWeights = !gaussianFilter && params.sampling == ShadowParams::Sampling::Jittered;
            float inShadow = 0, weightSum = 0;
            if (unitWeights) {
                // The production path (Figure 3c, box filter): sampleAt() for
                // jittered samples, drawn and compared four at a time, kept
                // only for a virtual-sample pass. Sample k is in cell
                // (a, b) = (k / nt, k % nt), from the region's cell table.
                const float biasRange = biasHi - biasLo;
                region.cells(ns, nt);
                // floor() is monotonic: clamping the position into
                // [iLo, iHi + 1) before it equals clamping the texel after.
                const F4 uLo = F4{} + float(iLo), uHi = F4{} + floatBelow(iHi + 1);
                const F4 vLo = F4{} + float(jLo), vHi = F4{} + floatBelow(jHi + 1);
                // A region inside the data window and one tile (the common
                // case: regions are a few texels, tiles 32) reads the tile
                // directly.
                const bool direct = single && regionInside;
                I4 shadowed{};  // counts down: a true comparison is -1
                U4 seeds = U4{} + pointSeed + U4{0, 1, 2, 3} * 0x9e3779b9u;
                for (int q = 0; q < region.padded; q += 4, seeds += 4u * 0x9e3779b9u) {
                    const U4 h = hash32Lanes(seeds);
                    const F4 a = region.load(region.cellA, q), b = region.load(region.cellB, q);
                    const F4 ju = toF4(I4(h & 0x7ffu)) * (1.0f / 2048.0f);
                    const F4 jv = toF4(I4((h >> 11) & 0x7ffu)) * (1.0f / 2048.0f);
                    const F4 u = loS + (a + ju) * ds, v = loT + (b + jv) * dt;
                    const I4 iu = floorX4(u < uLo ? uLo : (u > uHi ? uHi : u));
                    const I4 iv = floorX4(v < vLo ? vLo : (v > vHi ? vHi : v));
                    F4 bias = F4{} + biasMid;
                    if (randomBias) {
                        const F4 drawn = biasLo + toF4(I4(h >> 22)) * (1.0f / 1024.0f) * biasRange;
                        bias = drawn < F4{} + biasHi ? drawn : F4{} + biasHi;
                    }
                    // Padding lanes (cell (0, 0), inside the region) see
                    // +infinity, never shadowed.
                    const I4 real = I4{q, q + 1, q + 2, q + 3} < count;
                    F4 d;
                    if (direct) {
                        const I4 at = ((iv - singleY) << shiftX) + (iu - singleX);
                        d = real ? F4{single[at[0]], single[at[1]], single[at[2]], single[at[3]]} : F4{} + kInfinity;
                    } else {
                        for (int l = 0; l < 4; ++l) d[l] = real[l] ? texelDepth(iu[l], iv[l]) : kInfinity;
                    }
                    shadowed -= z > d + bias;
                    if (virtualCompare) {
                        region.store(region.iu, q, iu);
                        region.store(region.iv, q, iv);
                        region.store(region.bias, q, bias);
                        region.store(region.depth, q, d);
                    }
                }
                // Sums of ones: exact, as the weighted sums below.
                inShadow = float((shadowed[0] + shadowed[1]) + (shadowed[2] + shadowed[3]));
                weightSum = float(count);
            } else {
                for (int a = 0; a < ns; ++a)
                    for (int b = 0; b < nt; ++b) {
                        float u, v;
                        const size_t k = size_t(a * nt + b);
                        sampleAt(a, b, &u, &v, &region.bias[k]);
                        texelOf(u, v, &region.iu[k], &region.iv[k]);
                        region.weight[k] = weight(u, v);
                        region.depth[k] = texelDepth(region.iu[k], region.iv[k]);
                    }
                F4 shadowedWeights{}, weights{};
                for (int q = 0; q < region.padded; q += 4) {
                    // Padding lanes weigh 0.
                    const F4 d = region.load(region.depth, q), w = region.load(region.weight, q);
                    const I4 shadowed = z > d + region.load(region.bias, q);
                    weights += w;
                    shadowedWeights += shadowed ? w : F4{};
                }
                inShadow = sumLanes(shadowedWeights);
                weightSum = sumLanes(weights);
            }
            auto weightsAt = [&](int q) -> F4 {
                if (!unitWeights) return region.load(region.weight, q);
                return I4{q, q + 1, q + 2, q + 3} < count ? F4{} + 1.0f : F4{};
            };

            // Second-depth maps: Figure 10 (and, for points facing the light,
            // all-shadowed comparisons too: see lookup()).
            const bool mixed = inShadow > 0 && inShadow < weightSum;
            const bool virtualSamples =
                virtualCompare && (mixed || (inShadow > 0 && facesLight(planes, P, batch.N[i])));
            TangentPlane plane;
            if (virtualSamples) plane = planeOfPoint();
            if (virtualSamples && plane.valid) {
                // Wang & Molnar Fig. 10, mixed comparisons (or shadowed ones
                // on a light-facing surface): the tangent plane at P, in the
                // light's screen space, gives the surface's own depth at each
                // sample's texel centre (virtualDeeper(), four at a time).
                ++st.virtualPoints;
                F4 deeperWeights{};
                for (int q = 0; q < region.padded; q += 4) {
                    const F4 d = region.load(region.depth, q);
                    // Relative slack for the rounding of the plane transform:
                    // a planar surface stored in the map (two-sided, §3.3)
                    // then lights itself unbiased.
                    const F4 limit = d + region.load(region.bias, q) + kVirtualSlack * (d < F4{} ? -d : d);
                    const F4 Z = plane.a * (toF4(region.load(region.iu, q)) + 0.5f) +
                                 plane.b * (toF4(region.load(region.iv, q)) + 0.5f) + plane.d;
                    I4 deeper;
                    if (m_virtualMode == 1) {
                        const F4 inverseDepth = m_wScale * Z;
                        deeper = inverseDepth > F4{} ? ~(inverseDepth * limit >= F4{} + 1.0f) : ~(limit == F4{} + kInfinity);
                    } else {
                        deeper = ~(m_wScale * Z <= limit);
                    }
                    // Texels outside the data window (and the padding) are
                    // not compared; an empty texel is never deeper anyway.
                    deeper &= d != F4{} + kInfinity;
                    deeperWeights += deeper ? weightsAt(q) : F4{};
                }
                inShadow = sumLanes(deeperWeights);
            } else if (secondDepth && (inShadow == 0 || inShadow == weightSum)) {
                if (inShadow == 0) ++st.secondLit;
                else ++st.secondShadowed;
            }
            out[i] = weightSum > 0 ? inShadow / weightSum : 0.0f;
        }
    }
    stats += st;
}

void ShadowMap::lookupCube(const ShadowBatch& batch, const ShadowParams& params, float* out, ShadowStats& stats,
                           bool pointSample) const {
    // The face a point belongs to is the one whose view axis is nearest its
    // direction from the light: the largest light camera-space z. Points are
    // gathered per face into per-thread scratch (no allocation once warm).
    struct Scratch {
        std::vector<Vec3> P, du, dv, N, path, corners[4];
        std::vector<float> out;
        std::vector<int> index, id;
    };
    thread_local Scratch scratch[6];
    float rows[6][4];
    for (int f = 0; f < 6; ++f) {
        const Mat4 m = m_faces[size_t(f)]->m_lightFromWorld * batch.worldFromCurrent;
        for (int c = 0; c < 4; ++c) rows[f][c] = m.m[2][c];
    }
    for (Scratch& sc : scratch) {
        sc.P.clear(); sc.du.clear(); sc.dv.clear(); sc.N.clear(); sc.path.clear(); sc.index.clear(); sc.id.clear();
        for (auto& c : sc.corners) c.clear();
    }
    const bool footprint = batch.dPdu_du && batch.dPdv_dv;
    for (int i = 0; i < batch.count; ++i) {
        const Vec3& P = batch.P[i];
        int best = 0;
        float bestZ = -kInfinity;
        for (int f = 0; f < 6; ++f) {
            const float z = rows[f][0] * P.x + rows[f][1] * P.y + rows[f][2] * P.z + rows[f][3];
            if (z > bestZ) {
                bestZ = z;
                best = f;
            }
        }
        Scratch& sc = scratch[best];
        sc.P.push_back(P);
        if (footprint) {
            sc.du.push_back(batch.dPdu_du[i]);
            sc.dv.push_back(batch.dPdv_dv[i]);
        }
        if (batch.N) sc.N.push_back(batch.N[i]);
        if (batch.corners[0])
            for (int c = 0; c < 4; ++c) sc.corners[c].push_back(batch.corners[c][i]);
        sc.index.push_back(i);
        sc.id.push_back(batch.pointId ? batch.pointId[i] : i);
    }
    for (int f = 0; f < 6; ++f) {
        Scratch& sc = scratch[f];
        if (sc.index.empty()) continue;
        ShadowBatch sub = batch;
        sub.count = int(sc.index.size());
        sub.P = sc.P.data();
        sub.dPdu_du = footprint ? sc.du.data() : nullptr;
        sub.dPdv_dv = footprint ? sc.dv.data() : nullptr;
        sub.N = batch.N ? sc.N.data() : nullptr;
        if (batch.pathKeys > 1) {
            // The face's points' paths, key by key.
            const size_t count = sc.index.size();
            sc.path.resize(size_t(batch.pathKeys) * count);
            for (int k = 0; k < batch.pathKeys; ++k)
                for (size_t j = 0; j < count; ++j)
                    sc.path[size_t(k) * count + j] =
                        batch.pathOffsets[size_t(k) * size_t(batch.count) + size_t(sc.index[j])];
            sub.pathOffsets = sc.path.data();
        }
        for (int c = 0; c < 4; ++c) sub.corners[c] = batch.corners[0] ? sc.corners[c].data() : nullptr;
        sub.seed = hashKeys(batch.seed, uint32_t(f));
        sub.pointId = sc.id.data();
        sc.out.resize(sc.index.size());
        if (pointSample)
            m_faces[size_t(f)]->lookupImpl<true>(sub, params, sc.out.data(), stats);
        else
            m_faces[size_t(f)]->lookupImpl<false>(sub, params, sc.out.data(), stats);
        for (size_t k = 0; k < sc.index.size(); ++k) out[sc.index[k]] = sc.out[k];
    }
}

void ShadowMap::lookup(const ShadowBatch& batch, const ShadowParams& params, float* outShadowed,
                       ShadowStats& stats) const {
    if (isCube()) return lookupCube(batch, params, outShadowed, stats, false);
    lookupImpl<false>(batch, params, outShadowed, stats);
}

void ShadowMap::lookupPoint(const ShadowBatch& batch, const ShadowParams& params, float* outShadowed,
                            ShadowStats& stats) const {
    if (isCube()) return lookupCube(batch, params, outShadowed, stats, true);
    lookupImpl<true>(batch, params, outShadowed, stats);
}

}  // namespace umbra
