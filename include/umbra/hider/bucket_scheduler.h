#pragma once
// The bucket scheduler: the REYES loop, bucket by bucket, on every core.
//
// The image is cut into *buckets* (16x16 pixels by default). Each bucket
// is one TBB task that samples everything that covers it into its own
// SampleBuffer and filters its pixels into the film. A primitive is
// processed (split or diced and shaded) when the first bucket it touches is
// rendered, once, and the result is shared with every other bucket it
// covers:
//
//   Node (a primitive, or a piece of one after splitting)
//     resolve() once:  cull | split -> child Nodes | dice+shade -> ShadedGrid
//     visitsLeft:      how many buckets still have to visit it; the last
//                      visitor frees its grid or children, so memory is
//                      bounded by the buckets in flight, not the frame.
//
// Buckets sample their pixels plus a margin as wide as the pixel filter's
// radius, recomputing the margin samples their neighbours also take (the
// sample positions depend only on the global pixel), so filtering needs no
// data from other buckets and the image has no seams. Together with
// identities for every node (from the primitive index and the split path)
// this makes images independent of thread count and bucket order.

#include "umbra/film/film.h"
#include "umbra/geometry/primitive.h"
#include "umbra/hider/sample_buffer.h"

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

namespace umbra::hider {

/// A diced, shaded grid in raster space, ready to be sampled.
struct ShadedGrid {
    int nu = 0, nv = 0;
    std::vector<Vec3> P;      // raster x, raster y (pixels, y down), camera-space z; keyCount arrays when moving
    std::vector<float> keyTimes;  // motion blur: see MicroGrid::keyTimes; empty: still
    std::vector<Color> Ci, Oi;   // Oi empty: opaque (every Oi >= 1)
    std::vector<float> aov;   // aovFloats per vertex
    int aovFloats = 0;
    bool matte = false;
    std::vector<uint8_t> culled;  // per micropolygon, a MicroGrid::Facing code; empty: none
    std::shared_ptr<const geometry::TrimRegion> trim;  // see MicroGrid; null: none
    std::vector<float> uv;    // per vertex (u, v) when trimmed
    uint64_t id = 0;
    bool ownSecondLayer = false;  // see MicroGrid
    bool discs = false;       // see MicroGrid
    int csgLeaf = -1;         // see MicroGrid
    std::vector<uint8_t> leaving;  // per micropolygon, see MicroGrid; empty: none
    float dissolveFrom = 0, dissolveBelow = 1;  // see MicroGrid
    Bound3 bound;             // of P

    MicroGrid view() const;
};

/// Counters of one render (summed over threads at the end).
struct SchedulerStats {
    uint64_t primitives = 0;       // top-level primitives given
    uint64_t culled = 0;           // nodes culled by view/clipping/eye split
    uint64_t occlusionCulled = 0;  // node visits skipped behind opaque samples
    uint64_t splits = 0;
    uint64_t grids = 0;
    uint64_t micropolygons = 0;
    uint64_t buckets = 0;
    uint64_t peakGridsAlive = 0;   // most shaded grids held at once
    BlurStats blur;                // the blurred sampling path (motion blur, depth of field)
    /// CPU time of the pass's bucket workers, summed over threads: the
    /// pass's own work, without other threads of the process (such as map
    /// files being written in the background).
    double workerCpuSeconds = 0;
    void add(const SchedulerStats& o);
};

/// The renderer's side of the loop: how to bound, plan and shade a piece of
/// geometry for this pass (camera or depth).
class GeometryPipeline {
public:
    enum class Action { Cull, Split, Dice };
    struct Plan {
        Action action = Action::Cull;
        bool splitU = true;    // Split: cut across u (else v)
        bool eyeSplit = false; // Split: because the piece straddles the eye plane
        int nu = 0, nv = 0;    // Dice: micropolygons along u and v
    };
    virtual ~GeometryPipeline() = default;
    /// Raster bound of the piece: x, y in pixels, z camera depth; an empty
    /// bound culls it. Must contain everything shade() can produce.
    virtual Bound3 rasterBound(const geometry::Primitive& prim) = 0;
    /// Cull, split, or dice at which rate. `eyeSplits` counts the splits so
    /// far caused by the eye plane; `splitBudget` is the raster area, in
    /// pixels, the piece's pieces may need between them, and `need` what it
    /// needs itself (see dice::DiceParams::splitBudget and pieceNeed).
    virtual Plan plan(const geometry::Primitive& prim, int eyeSplits, double splitBudget, double need) = 0;
    /// The raster area, in pixels, the piece needs diced inside the region
    /// the frame samples (dice::rasterNeed), but no more than its raster
    /// bound (rasterBound()) holds there (dice::boundNeed), and that when
    /// it cannot be measured. Never negative.
    virtual double rasterNeed(const geometry::Primitive& prim, const Bound3& rasterBound) = 0;
    /// Dices at nu x nv, displaces and shades, and fills `out` in raster
    /// space. Returns false when nothing of it can be seen (e.g. all back
    /// facing). Called concurrently from many threads.
    virtual bool shade(const geometry::Primitive& prim, int nu, int nv, uint64_t id, ShadedGrid& out) = 0;
};

/// Settings of one pass.
struct SchedulerSettings {
    int bucketSize[2] = {16, 16};
    int threads = 0;              // bucket workers; 0: the calling arena's concurrency (run in it)
    /// Pixel samples, jitter, mode, seed, AOVs, clipping; the scheduler
    /// fills in each bucket's rectangle and the margin.
    SampleBufferConfig sampling;
    int filterMargin = 1;         // pixels sampled around each bucket (ceil of filter radius)
    int maxEyeSplits = 10;
    /// Called after each bucket with (buckets done, buckets, share of the
    /// estimated work done: hider/bucket_work.h); from worker threads.
    std::function<void(int, int, double)> progress;
};

/// The order a row of `width` buckets is taken in by `threads` workers
/// (each taking the next bucket as it finishes one): the columns of as many
/// stretches of the row as there are threads, in turn (two threads: 0,
/// W/2, 1, W/2 + 1, ...), so that buckets sampled at the same time lie far
/// apart. One thread: left to right.
std::vector<int> bucketRowOrder(int width, int threads);

/// Renders a list of primitives into a film, bucket by bucket.
class BucketScheduler {
public:
    BucketScheduler(const SchedulerSettings& settings, GeometryPipeline& pipeline);
    /// Renders `prims` into `film` (its crop region); returns the counters.
    SchedulerStats render(const std::vector<geometry::PrimitivePtr>& prims, film::Film& film);

private:
    SchedulerSettings m_settings;
    GeometryPipeline& m_pipeline;
};

}  // namespace umbra::hider
