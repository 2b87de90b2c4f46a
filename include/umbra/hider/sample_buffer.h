#pragma once
// The stochastic hider's samples for one bucket.
//
// Terms: a *micropolygon* is one cell of four neighbouring grid vertices
// (geometry/grid.h). A *sample* is a point in raster space where visibility
// is decided; each pixel holds xs * ys of them, one in each cell (*stratum*)
// of an xs x ys subdivision of the pixel, jittered inside its stratum.
//
// A SampleBuffer covers a bucket's pixels plus a margin of pixels around it
// (the pixel filter's reach), so the bucket can filter its own pixels
// without seams. Margin samples are recomputed by both neighbours; sample
// positions depend only on the global pixel, the sample index and the frame
// seed, so both compute the same samples.
//
//      +---------------------------+  <- sampled region (bucket + margin)
//      |  margin                   |
//      |    +-----------------+    |
//      |    | bucket pixels   |    |  <- resolve() writes only these
//      |    +-----------------+    |
//      +---------------------------+
//
// Samples are stored row-major over the region's stratum grid: sample
// (sx, sy) is stratum column sx = px * xs + i, row sy = py * ys + j, so the
// samples a micropolygon's bound overlaps form a rectangle of indices.

#include "umbra/geometry/trim.h"
#include "umbra/hider/csg.h"
#include "umbra/util/math.h"

#include <cstdint>
#include <memory>
#include <vector>

namespace umbra::film {
class Film;
}

namespace umbra::hider {

/// The period, in pixels, of the jittered sample pattern (samplePosition).
/// 32: the pattern and one filter's weights over it take 0.6 MB per worker
/// at 4x4 samples, which stays in a core's L2; at 64 (2.3 MB) the two
/// workers' tables crowded the shared cache, and two threads ran 3-12%
/// slower than they do now.
constexpr int kPatternPeriod = 32;

/// Motion blur's time interleaving: the pixels of each kTimeTile x
/// kTimeTile tile share out the finer time strata among themselves, so a
/// depth map of one sample a texel sees the whole shutter over one tile.
constexpr int kTimeTile = 4;

class SamplePattern;
class PatternFilterWeights;

/// A shaded grid as the hider sees it: (nu+1) x (nv+1) vertices in the
/// grid's layout (vertex (i, j) at j * (nu+1) + i). Pointers are borrowed
/// for the duration of SampleBuffer::sample().
///
/// Each micropolygon (i, j) is split along its (i, j)-(i+1, j+1) diagonal
/// into the triangles (v00, v10, v11) and (v00, v11, v01). Non-planar and
/// bow-tie quads are thus covered by the union of two (possibly
/// overlapping) triangles, a well defined and crack-free answer. Depth,
/// colour, opacity and AOVs are interpolated linearly in raster space across
/// each triangle (Gouraud shading; z is camera-space depth, linear in raster
/// space for planar micropolygons under an orthographic camera and, for the
/// sub-pixel micropolygons of REYES, close to it under perspective).
/// Back-facing micropolygons must be culled by the caller; the hider does not
/// look at winding.
struct MicroGrid {
    int nu = 0, nv = 0;
    const Vec3* P = nullptr;    // x, y raster (pixels, y down), z camera-space depth
    const Color* Ci = nullptr;  // per vertex, premultiplied by Oi (RenderMan); null: black
    const Color* Oi = nullptr;  // per vertex; null: opaque
    const float* aov = nullptr; // per vertex, aovCount floats each; may be null
    int aovCount = 0;           // must equal the buffer's aovCount when aov is set
    bool matte = false;         // Matte 1: hides what is behind, contributes no colour or alpha
    /// Per micropolygon (j * nu + i), a Facing code: kCulled to skip it
    /// (the renderer's back-face culling of one-sided surfaces, the depth
    /// pass's culling of solids' light-facing surfaces), or, on a moving
    /// grid, kept only at the sample times it faces the way it does
    /// (kKeepAsOpening) or does not (kKeepUnlikeOpening) at the opening key.
    /// Null: nothing culled.
    const uint8_t* culled = nullptr;
    enum Facing : uint8_t { kKept = 0, kCulled = 1, kKeepAsOpening = 2, kKeepUnlikeOpening = 3 };
    uint64_t id = 0;            // stable identity (same on every run) for deterministic ties
    /// Trimming: a sample is dropped where `trim` does not keep the (u, v)
    /// interpolated (linearly in raster space, as depth is) from `uv`, two
    /// floats per vertex. Null: nothing trimmed.
    const geometry::TrimRegion* trim = nullptr;
    const float* uv = nullptr;
    /// Depth mode: an open, two-sided surface that is its own second layer
    /// (Wang & Molnar 1994 §3.3: a solid of no thickness), so a second-depth
    /// map stores it where nothing else is nearer.
    bool ownSecondLayer = false;
    /// Points (Grid::discs): only even micropolygons along u are drawn,
    /// each as the disc inscribed in it: centred on its corners' mean,
    /// radius a quarter of the sum of the distances between the midpoints
    /// of opposite edges (exact for a square).
    bool discs = false;
    /// Motion blur: keyCount >= 2 position arrays, P holding them one
    /// after the other (vertexCount() each), key k at keyTimes[k], fractions
    /// of the shutter, ascending from 0 to 1. A sample at time t sees each
    /// vertex interpolated linearly in raster space (and in depth, as 1/z
    /// under perspective) between the keys around t. Colour, opacity and
    /// AOVs are those shaded once for the grid.
    int keyCount = 1;
    const float* keyTimes = nullptr;
    /// CSG (hider/csg.h): the leaf of SampleBufferConfig::csg whose surface
    /// this is, or -1 for ordinary geometry. Every hit of a leaf is kept
    /// until resolve() finds the visible ones, so leaves neither occlude nor
    /// are culled by facing; `leaving` marks, per micropolygon, those whose
    /// outward normal faces away from the eye (null: none).
    int csgLeaf = -1;
    const uint8_t* leaving = nullptr;
    /// Level of detail's cross-fade (a stochastic dissolve): each sample
    /// has a fixed value u in [0, 1) (SampleBuffer::dissolveValue), and the
    /// grid is drawn only at samples with dissolveFrom <= u < dissolveBelow.
    /// A representation fading out keeps [0, w), one fading in [1 - w, 1),
    /// so two whose weights sum to 1 share the samples without overlap.
    float dissolveFrom = 0, dissolveBelow = 1;

    bool dissolves() const { return dissolveFrom > 0 || dissolveBelow < 1; }

    int vertexCount() const { return (nu + 1) * (nv + 1); }
};

/// What a SampleBuffer records: the camera pass or a light's depth pass.
enum class HiderMode {
    Colour,  // Ci/Oi compositing
    Depth,   // depth maps: nearest z1 and second-nearest z2 per sample, no colour
};

/// Everything that fixes a buffer's samples.
struct SampleBufferConfig {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // the bucket's pixels [x0,x1) x [y0,y1), raster
    int margin = 1;                      // extra pixels sampled on each side (>= the filter's margin)
    int xSamples = 2, ySamples = 2;      // PixelSamples
    bool jitter = true;                  // false: samples at the strata centres
    uint32_t frameSeed = 0;
    int aovCount = 0;                    // extra floats per sample (the film's AOV floats)
    HiderMode mode = HiderMode::Colour;
    float nearClip = 1e-10f, farClip = 1e30f;  // camera-space z range that is visible
    /// A perspective camera: depth is interpolated as 1/z, which (unlike z)
    /// is linear in raster space across a planar micropolygon.
    bool perspective = false;
    /// Depth mode: how a pixel's samples make its z (RenderMan's
    /// "depthfilter" min/max/average; the two-layer filters use min).
    enum class DepthReduce { Min, Max, Average };
    DepthReduce depthReduce = DepthReduce::Min;
    /// Depth mode: 2 keeps the nearest two surfaces per sample, 1 only the
    /// nearest (z2 stays +infinity) -- the single-layer baseline the
    /// two-layer pass is measured against.
    int depthLayers = 2;
    /// Motion blur: each sample gets a time in [0, 1), a fraction of the
    /// shutter (src/hider/sample_pattern.h: sampleTime), at which grids with
    /// several keys are tested. Needed whenever such grids are sampled.
    bool motion = false;
    float shutterOpening[2] = {0, 1};  // the shutter's shape (scene::Options)
    /// Motion and depth of field: test a moving or defocused micropolygon
    /// only against the samples of each time (or lens) stratum inside its
    /// bound over that stratum's times (or lens positions); false: every
    /// sample of its bound over the whole shutter and lens. The same samples
    /// are hit either way; false is the reference the test of the faster
    /// way compares with.
    bool sampleStrata = true;
    /// Depth of field (perspective only): each sample gets a position on
    /// the unit lens disc, and a vertex at depth z is seen displaced by
    /// lens * lensScale * (inverseFocalDistance - 1/z) raster pixels: the
    /// thin lens, with lensScale = lens radius * raster pixels per unit of
    /// x/z (y negated: raster y runs down).
    bool lens = false;
    float lensScaleX = 0, lensScaleY = 0;
    float inverseFocalDistance = 0;
    /// The world's CSG trees, which MicroGrid::csgLeaf indexes; borrowed,
    /// null when the world has none.
    const CsgForest* csg = nullptr;
};

/// Counters of the blurred sampling path (motion blur, depth of field).
struct BlurStats {
    uint64_t micropolygons = 0;  // micropolygons sampled per sample (moving, or under a lens)
    uint64_t sampleTests = 0;    // samples tested against them (each interpolates the micropolygon)
    uint64_t sampleHits = 0;     // ... of which the micropolygon covered
};

/// The visible-surface samples of one bucket (see the file comment). One per
/// worker thread, reset for each bucket; reset() keeps the memory.
///
/// Colour mode keeps per sample the nearest opaque hit (z, Ci, alpha, AOVs)
/// and a list of transparent fragments (Oi < 1) nearer than it; resolve()
/// composites them front to back. Depth mode keeps the nearest hit z1 and
/// z2 = the nearest hit that comes from a different grid (MicroGrid::id) than
/// the nearest one: the next surface behind, not a seam of the same grid.
///
/// CSG leaves' hits (MicroGrid::csgLeaf) are kept in the fragment list, in
/// depth mode too, whatever their opacity; resolve() walks them front to
/// back with the others and keeps only those on the boundary of their tree's
/// result (hider/csg.h), the first opaque one hiding what is behind.
///
/// Determinism: every hit is ordered by the key (z, grid id, triangle index
/// in the grid), a total order, so which hit wins and the order fragments are
/// composited in do not depend on the order grids arrive in.
class SampleBuffer {
public:
    SampleBuffer();
    ~SampleBuffer();
    SampleBuffer(SampleBuffer&&) noexcept;
    SampleBuffer& operator=(SampleBuffer&&) noexcept;

    void reset(const SampleBufferConfig& config);
    const SampleBufferConfig& config() const { return m_cfg; }

    /// Hides one grid's micropolygons against this buffer's samples. Cheap
    /// when the grid misses the sampled region.
    void sample(const MicroGrid& grid);

    /// True when every sample of this buffer inside the raster rectangle
    /// [b.min.x, b.max.x] x [b.min.y, b.max.y] already has an opaque hit
    /// nearer than b.min.z (in depth mode: a second depth nearer than it), so
    /// nothing at depth >= b.min.z there can change the image. Conservative:
    /// may answer false when it could answer true. Rectangles that miss the
    /// buffer entirely are occluded (nothing to change here).
    bool occluded(const Bound3& rasterBound) const;
    /// The largest opaque depth (depth mode: second depth) of the samples in
    /// the pixels overlapping the raster rectangle [xmin,xmax] x [ymin,ymax];
    /// +infinity where some sample has none; -infinity if the rectangle
    /// misses the buffer.
    float maxOpaqueDepth(float xmin, float ymin, float xmax, float ymax) const;

    /// Filters the samples into the film's pixels of the bucket (not the
    /// margin) with the film's pixel filter: r g b a, z (nearest opaque
    /// depth, minimum over the pixel's own samples, unfiltered) and AOVs;
    /// in depth mode z (z1) and z2 (minima over the pixel's own samples).
    /// Each further filter layer of the film (displays with filters of
    /// their own) gets r g b a and AOVs filtered with its filter.
    void resolve(film::Film& film);

    /// The raster position of sample s (0 .. xs*ys-1, row-major in the
    /// pixel's strata) of pixel (px, py) for the given settings; what the
    /// buffer uses, exposed for tests and for the shadow lookups' users.
    /// It is the pixel plus the offset of sample s in pixel (px mod P,
    /// py mod P), P = kPatternPeriod: the jitter repeats every P pixels (see
    /// src/hider/sample_pattern.h), and each sample lies strictly inside its
    /// stratum, floor(x * xs) == px * xs + s % xs (likewise in y).
    static Vec2 samplePosition(int px, int py, int s, int xSamples, int ySamples, bool jitter, uint32_t frameSeed);
    /// The time of that sample (motion blur) and its position on the unit
    /// lens disc (depth of field), for the buffer's settings `config`.
    static float sampleTime(int px, int py, int s, const SampleBufferConfig& config);
    static Vec2 sampleLens(int px, int py, int s, const SampleBufferConfig& config);
    /// The time of each pixel's one sample over one period of the pattern:
    /// pixel (x, y)'s at [(y mod P) * P + x mod P]. What a depth map of
    /// moving casters records of its texels (DepthImage::texelTimes);
    /// `config` takes one sample a pixel.
    static std::vector<float> periodTimes(const SampleBufferConfig& config);
    /// The dissolve value of the sample in global stratum column sx, row sy
    /// (sample s of pixel (px, py) is column px * xs + s % xs, row
    /// py * ys + s / xs): a hash of the stratum and the frame seed, so
    /// uncorrelated with the sample's position and the same in every bucket.
    static float dissolveValue(int sx, int sy, uint32_t frameSeed);

    const BlurStats& blurStats() const { return m_blur; }

    /// Inspection (tests, statistics). Pixel and sample as samplePosition;
    /// the pixel must lie in the sampled region.
    Vec2 position(int px, int py, int s) const;
    float depth(int px, int py, int s) const;        // opaque z / z1; +inf when none
    float secondDepth(int px, int py, int s) const;  // depth mode z2; +inf when none
    int fragmentCount(int px, int py, int s) const;  // transparent fragments recorded (colour mode)
    size_t fragmentsInUse() const { return m_frags.size(); }

private:
    struct Fragment {
        float z;
        uint32_t sub;
        uint64_t id;
        Color ci, oi;
        int32_t next;
        int32_t aovBase;  // into m_fragAov, or -1
        bool matte;
        bool opaque;      // a CSG hit that hides what is behind it when visible
        bool leaving;     // a CSG hit leaving its leaf's volume
        int32_t csgLeaf;  // -1: an ordinary transparent fragment
    };
    struct Tri;
    struct HitContext;

    int sampleIndex(int px, int py, int s) const;
    /// Samples micropolygon (i, j), whose raster bound is given (z: its
    /// vertices' nearest and farthest depths).
    void rasterizeQuad(const MicroGrid& g, const HitContext& ctx, int i, int j, float minx, float miny, float maxx,
                       float maxy, float minz, float maxz);
    /// sample() for a moving grid, or any grid under a lens: each sample
    /// places the micropolygon's corners at its time and lens position.
    void sampleBlurred(const MicroGrid& g);
    /// A two-key micropolygon's motion bound in this buffer (boundMotion).
    struct MotionBound {
        float lo[2], hi[2];        // its corners' bound at the first key (x, y) ...
        float dlo[2], dhi[2];      // ... and the least and greatest motion of a corner to the second
        float swept0[2], swept1[2];  // the corners' bound over both keys
        float minz, maxz;          // their depths over both keys
        float margin[2];           // what its bounds are widened by (the ulps of interpolation)
        /// The second key's weights between which it can meet this
        /// buffer's region at a time some sample of the region has;
        /// first > last: never.
        float first, last;
    };
    /// Motion blur, two keys, no lens: each micropolygon's bound over the
    /// part of the shutter this buffer's samples cover, and the weights at
    /// which it can reach the region, into m_motion (j * nu + i). False when
    /// no micropolygon of the grid can reach the region at such a time.
    bool boundMotion(const MicroGrid& g);
    void rasterizeBlurred(const MicroGrid& g, const HitContext& ctx, int i, int j, const MotionBound* bound);
    /// The cells the strata tables are laid out by: `cell` x `cell` pixels
    /// (1: pixels; a power of two), and the region's cells, x0 .. x0 + w - 1
    /// by y0 .. y0 + h - 1 in cells of the whole frame.
    struct StrataGrid {
        int cellShift = 0;  // cell = 1 << cellShift
        int x0 = 0, y0 = 0, w = 0, h = 0;
        int cellX(int pixelX) const { return (pixelX >> cellShift) - x0; }  // an arithmetic shift: floor
        int cellY(int pixelY) const { return (pixelY >> cellShift) - y0; }
        size_t plane() const { return size_t(w) * size_t(h); }
    };
    StrataGrid strataGrid(int cell) const;
    /// The sample of each region cell in each stratum, [stratum][row][column]
    /// of `grid`, and that sample's raster position alike (NaN where a cell
    /// has none; three floats of padding, read in groups of four).
    void tabulateStrata(const uint16_t* (SamplePattern::*row)(int) const, int strata, const StrataGrid& grid,
                        std::vector<int32_t>& table, std::vector<float>& tableX, std::vector<float>& tableY,
                        std::vector<float>* tableTime = nullptr) const;
    /// Records a hit of triangle t at sample s: depth z (within the clipping
    /// planes), barycentric weights b1, b2 of t's second and third vertices.
    /// True if it changed a depth the occlusion bound is made of.
    bool record(const MicroGrid& g, const HitContext& ctx, const Tri& t, size_t s, float z, float b1, float b2);
    /// The lanes (bits of `lanes`) whose sample, at barycentric weights
    /// b1[k], b2[k] of t, the grid's trim region keeps.
    static int trimKept(const MicroGrid& g, const Tri& t, const float b1[4], const float b2[4], int lanes);
    /// A depth pass's nearest hit: keeps depth z of grid gid, triangle sub
    /// at sample s when nearer by the full key; true if kept.
    bool takeNearest(size_t s, float z, uint64_t gid, uint32_t sub);
    /// A depth pass's hit (record()'s depth mode): z1, and z2 from another
    /// layer: another grid, a micropolygon of the same grid wound the other
    /// way (`reversed`: the far side of a rim inside one grid), or a grid
    /// that is its own second layer; true if kept.
    bool recordDepth(size_t s, float z, uint64_t gid, uint32_t sub, bool reversed, bool ownSecondLayer);
    /// A depth pass's hit of a CSG leaf: kept as a fragment for resolveCsg.
    void recordCsgDepth(const MicroGrid& g, const Tri& t, size_t s, float z);
    /// Walks sample s's fragments front to back, leaving in m_order the
    /// ordinary ones and the CSG hits on their tree's boundary up to the
    /// first opaque one, which becomes the sample's opaque hit (colour
    /// mode); depth mode merges the boundary hits into z1 and z2 instead.
    void resolveCsg(size_t s);
    void markDirty(int sx0, int sy0, int sx1, int sy1);
    /// Pixel (px, py) of the region: the max opaque (depth mode: second)
    /// depth of its samples, recomputed if marked dirty.
    float pixelMax(int px, int py) const;
    /// The region's pixels overlapping a raster rectangle; false if none.
    bool pixelRange(float xmin, float ymin, float xmax, float ymax, int* px0, int* py0, int* px1, int* py1) const;
    /// resolve()'s filtering into the film's filter layer `layer` (general
    /// path: AOVs, or a filter that is not separable); `table` holds a
    /// separable filter's weights.
    void resolveFiltered(film::Film& film, int layer, const PatternFilterWeights& table, int bx0, int by0, int bx1,
                         int by1);
    /// The depth of pixel (px, py) from its own samples' nearest opaque
    /// depths, by the frame's depth filter (SampleBufferConfig::depthReduce).
    float pixelDepth(int px, int py) const;
    /// resolve() for frames without AOVs and a separable filter, into the
    /// film's filter layer `layer` with `table` (its filter's weights).
    void resolveColour(film::Film& film, int layer, const PatternFilterWeights& table, int bx0, int by0, int bx1,
                       int by1);
    /// Adds each sample's weighted value to the accumulators (accStride
    /// floats a pixel in m_acc) of the bucket pixels it reaches, with the
    /// tabulated weights of a separable filter, in the fixed order of the
    /// samples' strata: splat(s) gives the sample's adder, called as
    /// add(pixel's accumulator, weight).
    template <class Splat>
    void splatSeparable(const PatternFilterWeights& table, int bx0, int by0, int bx1, int by1, int accStride,
                        Splat splat);

    SampleBufferConfig m_cfg;
    int m_rx0 = 0, m_ry0 = 0;        // sampled region's first pixel (raster)
    int m_rw = 0, m_rh = 0;          // sampled region's size in pixels
    int m_sw = 0, m_sh = 0;          // strata grid size: m_rw * xs, m_rh * ys
    int m_sx0 = 0, m_sy0 = 0;        // global stratum index of the region's first stratum
    float m_fx0 = 0, m_fy0 = 0, m_fx1 = 0, m_fy1 = 0;  // region in raster space

    // Per sample (structure of arrays).
    std::vector<float> m_px, m_py;   // raster position
    std::vector<float> m_time;       // motion: time in [0, 1)
    // Motion: the sample of each region cell in each time stratum,
    // [stratum][cell row][cell column], and each stratum's time range.
    StrataGrid m_strataGrid, m_lensStrataGrid;  // the cells of the time and lens tables
    std::vector<int32_t> m_strataSample;
    std::vector<float> m_strataX, m_strataY, m_strataTime;  // those samples' positions and times, likewise
    std::vector<float> m_strataStart, m_strataEnd;
    // Two-key grid being sampled: the interpolation weight of its second
    // key at each stratum's first time, and at the last one's end.
    std::vector<float> m_strataWeight;
    std::vector<float> m_strataW0, m_strataW1;  // m_strataWeight[k], [k + 1], padded to groups of four
    std::vector<int> m_strataLive;              // per group of four strata: bit l set for a stratum
    float m_timeMin = 0, m_timeMax = 1;         // the least and greatest time of the region's samples
    std::vector<MotionBound> m_motion;          // boundMotion(): per micropolygon of the grid being sampled
    // Depth of field likewise: the sample of each region pixel in each lens
    // stratum, and each stratum's box of lens positions (x0, y0, x1, y1).
    std::vector<int32_t> m_lensStrataSample;
    std::vector<float> m_lensStrataX, m_lensStrataY;
    std::vector<float> m_lensStrataBox;
    std::vector<float> m_lensX, m_lensY;  // depth of field: position on the unit lens disc
    BlurStats m_blur;
    std::vector<float> m_columnPixel;  // per region stratum column: its pixel's x (reset scratch)
    std::vector<float> m_z;          // opaque z (colour) or z1 (depth)
    std::vector<uint64_t> m_id;      // key of that hit: grid id ...
    std::vector<uint32_t> m_sub;     // ... and triangle index
    std::vector<Color> m_ci;         // colour mode: opaque hit's Ci (0 for matte)
    std::vector<float> m_alpha;      // colour mode: 1, or 0 for matte / no hit
    std::vector<float> m_aov;        // colour mode: aovCount per sample
    std::vector<int32_t> m_fragHead; // colour mode: transparent fragment list, -1 none
    std::vector<float> m_z2;         // depth mode: second depth ...
    std::vector<uint64_t> m_id2;     // ... its grid id and triangle
    std::vector<uint32_t> m_sub2;
    std::vector<uint8_t> m_wind;     // depth mode, two layers: the nearest hit's triangle is reversed

    std::unique_ptr<SamplePattern> m_pattern;          // positions of one period
    std::vector<std::unique_ptr<PatternFilterWeights>> m_weights;  // each film filter layer's weights over it

    std::vector<float> m_dissolve;   // per sample: dissolveValue(), made when a dissolving grid first arrives
    bool m_dissolveReady = false;
    /// Makes m_dissolve for this bucket if not done yet.
    void prepareDissolve();

    std::vector<float> m_inverseDepth;  // perspective: 1/z per vertex (and key) of the grid being sampled

    std::vector<Fragment> m_frags;
    std::vector<float> m_fragAov;

    // Occlusion cache: per region pixel the max opaque (depth mode: second)
    // depth of its samples, recomputed lazily for pixels marked dirty.
    mutable std::vector<float> m_pixelMax;
    mutable std::vector<uint8_t> m_pixelDirty;

    // Resolve scratch.
    std::vector<float> m_res;        // per sample: r g b a, aov...
    std::vector<float> m_acc;        // per bucket pixel: r g b a aov... (non-separable filters: and the weight)
    std::vector<int32_t> m_order;    // fragment sort scratch
    size_t m_csgFragments = 0;       // CSG hits recorded since reset()
    CsgRayState m_csgRay;            // resolveCsg: where the ray being walked is
    std::vector<uint8_t> m_csgNext;  // resolveCsg: per leaf, its next hit along the ray (0 none, 1 enters, 2 leaves)
    std::vector<uint8_t> m_csgAfter; // resolveCsg: per sorted fragment, whether the ray is inside its leaf after it
    std::vector<float> m_scratchAov;
};

}  // namespace umbra::hider
