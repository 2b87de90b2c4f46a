#include "umbra/hider/bucket_scheduler.h"
#include "umbra/hider/bucket_work.h"

#include "umbra/util/cpu_time.h"
#include "umbra/util/interrupt.h"
#include "umbra/util/parallel.h"
#include "umbra/util/rng.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>
#include <optional>

namespace umbra::hider {

MicroGrid ShadedGrid::view() const {
    MicroGrid g;
    g.nu = nu;
    g.nv = nv;
    g.P = P.data();
    g.Ci = Ci.data();
    g.Oi = Oi.empty() ? nullptr : Oi.data();  // none: opaque
    g.aov = aov.empty() ? nullptr : aov.data();
    g.aovCount = aovFloats;
    g.matte = matte;
    g.culled = culled.empty() ? nullptr : culled.data();
    g.trim = trim && !uv.empty() ? trim.get() : nullptr;
    g.uv = g.trim ? uv.data() : nullptr;
    g.id = id;
    g.ownSecondLayer = ownSecondLayer;
    g.discs = discs;
    g.csgLeaf = csgLeaf;
    g.dissolveFrom = dissolveFrom;
    g.dissolveBelow = dissolveBelow;
    g.leaving = leaving.empty() ? nullptr : leaving.data();
    if (keyTimes.size() > 1) {
        g.keyCount = int(keyTimes.size());
        g.keyTimes = keyTimes.data();
    }
    return g;
}

void SchedulerStats::add(const SchedulerStats& o) {
    primitives += o.primitives;
    culled += o.culled;
    occlusionCulled += o.occlusionCulled;
    splits += o.splits;
    grids += o.grids;
    micropolygons += o.micropolygons;
    buckets += o.buckets;
    peakGridsAlive = std::max(peakGridsAlive, o.peakGridsAlive);
    blur.micropolygons += o.blur.micropolygons;
    blur.sampleTests += o.blur.sampleTests;
    blur.sampleHits += o.blur.sampleHits;
    workerCpuSeconds += o.workerCpuSeconds;
}

namespace {

/// A primitive or a piece of one, shared by every bucket it covers.
struct Node {
    const geometry::Primitive* prim = nullptr;
    geometry::PrimitivePtr owned;  // pieces made by splitting own their primitive
    uint64_t id = 0;
    int eyeSplits = 0;
    double splitBudget = -1;       // pixels (Frame::shareBudget); -1: its own, measured when resolved
    double need = -1;              // pixels (Frame::need); -1 until measured
    Bound3 bound;                  // raster x, y; camera z
    int bx0 = 0, by0 = 0, bx1 = -1, by1 = -1;  // buckets covered, inclusive

    enum class State { Culled, Split, Grid };
    /// Whether the node was planned (split, diced and shaded, or culled):
    /// one bucket's thread does it; others wait, or first visit the rest
    /// of their bucket (see Frame::walk).
    enum Resolution : int { kUnresolved, kResolving, kResolved };
    std::atomic<int> resolution{kUnresolved};
    State state = State::Culled;
    /// A split node's pieces, each beside the buckets it covers: every
    /// bucket visiting the node looks through them all for its own, and
    /// reading the ranges side by side instead of from each piece was a
    /// quarter of the scheduler's own time on the production frame.
    struct Piece {
        int bx0, by0, bx1, by1;
        std::unique_ptr<Node> node;
        bool covers(int bx, int by) const { return bx >= bx0 && bx <= bx1 && by >= by0 && by <= by1; }
    };
    std::vector<Piece> children;
    std::unique_ptr<ShadedGrid> grid;
    std::atomic<int> visitsLeft{0};

    int bucketCount() const { return std::max(0, bx1 - bx0 + 1) * std::max(0, by1 - by0 + 1); }
};

/// The identity of the k-th piece of a split node: stable whatever the
/// order of evaluation, so random numbers seeded from it are too.
uint64_t childId(uint64_t parent, size_t k) {
    uint32_t lo = hashKeys(uint32_t(parent), uint32_t(parent >> 32), uint32_t(k));
    uint32_t hi = hashKeys(uint32_t(k), uint32_t(parent), 0x5bd1e995u);
    return (uint64_t(hi) << 32) | lo;
}

bool nearerFirst(const Node* a, const Node* b) {
    if (a->bound.min.z != b->bound.min.z) return a->bound.min.z < b->bound.min.z;
    return a->id < b->id;
}

}  // namespace

struct Frame {
    const SchedulerSettings& settings;
    GeometryPipeline& pipeline;
    film::Film& film;
    int bucketsX = 0, bucketsY = 0;
    std::atomic<int64_t> gridsAlive{0};
    std::atomic<uint64_t> peakGrids{0};

    // Fills the node's bound and bucket range; false when it covers no bucket.
    bool place(Node& node, const Node* parent) {
        node.bound = pipeline.rasterBound(*node.prim);
        if (node.bound.empty()) return false;
        const int m = settings.filterMargin;
        const int bw = settings.bucketSize[0], bh = settings.bucketSize[1];
        // Bounds across the eye plane are infinite: clamp before converting.
        auto bucketOf = [](float v, int origin, int margin, int size, int count) {
            return floorToIntClamped((double(v) - margin - origin) / size, -1, count);
        };
        node.bx0 = std::max(0, bucketOf(node.bound.min.x, film.x0(), m, bw, bucketsX));
        node.by0 = std::max(0, bucketOf(node.bound.min.y, film.y0(), m, bh, bucketsY));
        node.bx1 = std::min(bucketsX - 1, bucketOf(node.bound.max.x, film.x0(), -m, bw, bucketsX));
        node.by1 = std::min(bucketsY - 1, bucketOf(node.bound.max.y, film.y0(), -m, bh, bucketsY));
        if (parent) {  // only buckets that visit the parent can visit a piece
            node.bx0 = std::max(node.bx0, parent->bx0);
            node.by0 = std::max(node.by0, parent->by0);
            node.bx1 = std::min(node.bx1, parent->bx1);
            node.by1 = std::min(node.by1, parent->by1);
        }
        node.visitsLeft = node.bucketCount();
        return node.bucketCount() > 0;
    }

    /// What a node needs diced in the frame, in pixels
    /// (GeometryPipeline::rasterNeed), and a little more, so that a piece
    /// that only touches the frame has a share.
    static constexpr double kLeastNeed = 16;
    double need(const Node& node) { return pipeline.rasterNeed(*node.prim, node.bound) + kLeastNeed; }

    /// The split budget (dice::DiceParams::splitBudget): a primitive's
    /// pieces may need kSplitBudget times its own need between them. The
    /// pieces of a split share their parent's budget in proportion to
    /// their needs. Needs are measured on the surface, not on bounds, so
    /// the pieces of a surface that tile the image (a ground plane's
    /// wedges, whose bounds all reach the horizon; slivers along the
    /// horizon) keep the budget whole, and only pieces that pile up in
    /// view (a surface folded on itself, corrupt control points) use it up;
    /// pieces that leave the frame give their share to the others. A
    /// container's pieces (the faces of a mesh, a procedural's output, a
    /// blob's cells) are whole surfaces of their own and start their own
    /// budget when first resolved, as top-level primitives do. Handed down
    /// the tree, not counted as pieces are made, so it is the same whatever
    /// the threads or the bucket order.
    static constexpr double kSplitBudget = 64;
    static constexpr double kOwnBudget = -1;  // Node::splitBudget: to be measured when resolved

    void shareBudget(Node& parent) {
        if (!parent.prim->diceable()) {
            for (auto& child : parent.children) child.node->splitBudget = kOwnBudget;
            return;
        }
        double total = 0;
        for (auto& child : parent.children) total += child.node->need = need(*child.node);
        for (auto& child : parent.children)
            child.node->splitBudget = parent.splitBudget * (child.node->need / total);
    }

    void resolve(Node& node, SchedulerStats& stats) {
        if (node.need < 0) node.need = need(node);
        if (node.splitBudget == kOwnBudget) node.splitBudget = kSplitBudget * node.need;
        GeometryPipeline::Plan plan = pipeline.plan(*node.prim, node.eyeSplits, node.splitBudget, node.need);
        if (plan.action == GeometryPipeline::Action::Cull) {
            ++stats.culled;
            node.state = Node::State::Culled;
            return;
        }
        if (plan.action == GeometryPipeline::Action::Split) {
            ++stats.splits;
            std::vector<geometry::PrimitivePtr> pieces;
            node.prim->split(plan.splitU, pieces);
            for (size_t k = 0; k < pieces.size(); ++k) {
                auto child = std::make_unique<Node>();
                child->owned = std::move(pieces[k]);
                child->prim = child->owned.get();
                child->id = childId(node.id, k);
                child->eyeSplits = node.eyeSplits + (plan.eyeSplit ? 1 : 0);
                if (place(*child, &node))
                    node.children.push_back({child->bx0, child->by0, child->bx1, child->by1, std::move(child)});
                else
                    ++stats.culled;
            }
            shareBudget(node);
            node.state = Node::State::Split;
            return;
        }
        auto grid = std::make_unique<ShadedGrid>();
        if (!pipeline.shade(*node.prim, plan.nu, plan.nv, node.id, *grid)) {
            ++stats.culled;
            node.state = Node::State::Culled;
            return;
        }
        ++stats.grids;
        stats.micropolygons += uint64_t(grid->nu) * uint64_t(grid->nv);
        int64_t alive = ++gridsAlive;
        uint64_t peak = peakGrids.load();
        while (uint64_t(alive) > peak && !peakGrids.compare_exchange_weak(peak, uint64_t(alive))) {
        }
        node.grid = std::move(grid);
        node.state = Node::State::Grid;
    }

    /// Frees a node's grid and pieces (pieces a bucket skipped behind
    /// opaque samples still hold theirs until their parent goes).
    void release(Node& node) {
        if (node.grid) --gridsAlive;
        node.grid.reset();
        for (auto& child : node.children) release(*child.node);
        node.children.clear();
        node.children.shrink_to_fit();
    }

    /// True once the node is resolved, resolving it here if no thread has
    /// started; false while another thread is resolving it.
    bool resolved(Node& node, SchedulerStats& stats) {
        int r = node.resolution.load(std::memory_order_acquire);
        if (r == Node::kUnresolved &&
            node.resolution.compare_exchange_strong(r, Node::kResolving, std::memory_order_acq_rel)) {
            // Published however resolve() ends: a thread waiting for this
            // node would otherwise wait for ever when it throws (an error
            // escaping a bucket hung a two-thread render instead of
            // reporting it).
            struct Publish {
                Node& node;
                ~Publish() {
                    node.resolution.store(Node::kResolved, std::memory_order_release);
                    node.resolution.notify_all();
                }
            } publish{node};
            try {
                resolve(node, stats);
            } catch (...) {
                node.state = Node::State::Culled;
                throw;
            }
            return true;
        }
        return node.resolution.load(std::memory_order_acquire) == Node::kResolved;
    }

    /// One bucket's walk: a queue of the nodes to visit, nearest first
    /// across the whole tree of pieces (a split node's pieces join the
    /// queue beside every other node instead of being walked depth first),
    /// so a piece behind the pieces of a sibling meets them already
    /// sampled and is culled by occlusion before it is diced and shaded.
    struct Walk {
        std::vector<Node*> queue;    // a heap, the nearest node on top
        std::vector<Node*> waiting;  // nodes another thread was resolving
        std::vector<Node*> visited;  // in visit order: parents before their pieces
    };

    /// Samples the nodes covering a bucket (and their pieces) into it. A
    /// node another thread is resolving waits in `walk.waiting` while the
    /// bucket goes on with its other nodes: neighbouring buckets share
    /// their large primitives, so both threads often reach one at once.
    /// The order nodes are sampled in does not change a pixel (ties are
    /// decided by the full sample key; only occlusion culling, which is
    /// exact, sees the order). Every node visited keeps its visit (and so
    /// its pieces) until the bucket ends; then the visits are let go,
    /// pieces before their parents.
    void walk(const std::vector<Node*>& nodes, int bx, int by, SampleBuffer& buffer, SchedulerStats& stats,
              Walk& w) {
        auto nearestOnTop = [](const Node* a, const Node* b) { return nearerFirst(b, a); };
        w.queue.assign(nodes.begin(), nodes.end());
        std::make_heap(w.queue.begin(), w.queue.end(), nearestOnTop);
        size_t nextWaiting = 0;
        while (!w.queue.empty() || nextWaiting < w.waiting.size()) {
            if (interrupted()) break;  // a bucket of many pieces must not hold off Ctrl-C
            Node* node;
            const bool fromQueue = !w.queue.empty();
            if (fromQueue) {
                std::pop_heap(w.queue.begin(), w.queue.end(), nearestOnTop);
                node = w.queue.back();
                w.queue.pop_back();
            } else {
                node = w.waiting[nextWaiting++];
            }
            if (buffer.occluded(node->bound)) {
                ++stats.occlusionCulled;
                w.visited.push_back(node);
                continue;
            }
            if (!resolved(*node, stats)) {
                if (fromQueue) {
                    w.waiting.push_back(node);  // visited once the queue is empty
                    continue;
                }
                int r;
                while ((r = node->resolution.load(std::memory_order_acquire)) != Node::kResolved)
                    node->resolution.wait(r, std::memory_order_acquire);
            }
            w.visited.push_back(node);
            if (node->state == Node::State::Grid) {
                buffer.sample(node->grid->view());
            } else if (node->state == Node::State::Split) {
                for (auto& child : node->children)
                    if (child.covers(bx, by)) {
                        w.queue.push_back(child.node.get());
                        std::push_heap(w.queue.begin(), w.queue.end(), nearestOnTop);
                    }
            }
        }
        w.waiting.clear();
        for (auto it = w.visited.rbegin(); it != w.visited.rend(); ++it)
            if (--(*it)->visitsLeft == 0) release(**it);
        w.visited.clear();
    }
};

std::vector<int> bucketRowOrder(int width, int threads) {
    std::vector<int> order;
    if (width <= 0) return order;
    const int stretches = std::max(1, std::min(threads, width));
    const int stretch = (width + stretches - 1) / stretches;
    for (int k = 0; k < stretch; ++k)
        for (int s = 0; s < stretches; ++s)
            if (s * stretch + k < width) order.push_back(s * stretch + k);
    return order;
}

BucketScheduler::BucketScheduler(const SchedulerSettings& settings, GeometryPipeline& pipeline)
    : m_settings(settings), m_pipeline(pipeline) {}

SchedulerStats BucketScheduler::render(const std::vector<geometry::PrimitivePtr>& prims, film::Film& film) {
    Frame frame{m_settings, m_pipeline, film};
    const int bw = m_settings.bucketSize[0], bh = m_settings.bucketSize[1];
    frame.bucketsX = (film.width() + bw - 1) / bw;
    frame.bucketsY = (film.height() + bh - 1) / bh;
    const int bucketCount = frame.bucketsX * frame.bucketsY;

    SchedulerStats total;
    total.primitives = prims.size();

    // Top-level nodes and, per bucket, the nodes that cover it.
    // One array, not a node each: a scene of 10^6 polygons has 10^6 roots.
    std::vector<Node> roots(prims.size());
    std::vector<char> placed(prims.size());
    // In the caller's arena: the renderer's, which bounds the threads and
    // may run other passes beside this one.
    int threads = m_settings.threads > 0 ? m_settings.threads : tbb::this_task_arena::max_concurrency();
    parallelFor(size_t(0), prims.size(), [&](size_t i) {
        Node& node = roots[i];
        node.prim = prims[i].get();
        node.id = uint64_t(i) + 1;
        placed[i] = frame.place(node, nullptr);
        node.splitBudget = Frame::kOwnBudget;
    });
    std::vector<std::vector<Node*>> perBucket(size_t(std::max(bucketCount, 0)));
    std::vector<size_t> perBucketCount(perBucket.size());
    for (size_t i = 0; i < roots.size(); ++i) {
        if (!placed[i]) continue;
        for (int by = roots[i].by0; by <= roots[i].by1; ++by)
            for (int bx = roots[i].bx0; bx <= roots[i].bx1; ++bx) ++perBucketCount[size_t(by * frame.bucketsX + bx)];
    }
    for (size_t b = 0; b < perBucket.size(); ++b) perBucket[b].reserve(perBucketCount[b]);
    for (size_t i = 0; i < roots.size(); ++i) {
        if (!placed[i]) {
            ++total.culled;
            continue;
        }
        Node& node = roots[i];
        for (int by = node.by0; by <= node.by1; ++by)
            for (int bx = node.bx0; bx <= node.bx1; ++bx) perBucket[size_t(by * frame.bucketsX + bx)].push_back(&node);
    }

    // Progress by work: each bucket's share from the raster area its
    // primitives cover (an empty sky is done at once, and says so).
    std::optional<WorkFraction> work;
    if (m_settings.progress) {
        std::vector<Bound3> bounds;
        bounds.reserve(roots.size());
        for (size_t i = 0; i < roots.size(); ++i)
            if (placed[i]) bounds.push_back(roots[i].bound);
        const BucketLayout layout{film.x0(), film.y0(), film.x1(), film.y1(), bw, bh};
        const double emptyPixelWork = m_settings.sampling.mode == HiderMode::Depth ? 0.0 : kEmptyPixelWorkColour;
        work.emplace(estimateBucketWork(layout, bounds, emptyPixelWork));
    }

    // Workers take buckets a row at a time, so the grids alive at any time
    // are those of a band of buckets, not of the whole frame. Within a row
    // the threads' turns are spread over as many stretches of the row as
    // there are threads (two threads: columns 0, W/2, 1, W/2 + 1, ...), so
    // that buckets sampled at the same time are far apart: side by side
    // they share their large primitives, and a bucket that finds one being
    // resolved by the other thread goes on behind it, which diced and
    // shaded 7% more grids at two threads than at one on the production
    // frame.
    const std::vector<int> rowOrder = bucketRowOrder(frame.bucketsX, threads);
    std::atomic<int> next{0}, done{0};
    std::mutex statsMutex;
    parallelFor(0, threads, [&](int) {
        const double cpu0 = threadCpuSeconds();
        SampleBuffer buffer;
        SchedulerStats stats;
        Frame::Walk walk;
        for (int b; (b = next++) < bucketCount;) {
            if (interrupted()) break;  // the pass's film is then not written
            const int bx = rowOrder[size_t(b % frame.bucketsX)], by = b / frame.bucketsX;
            const int bucket = by * frame.bucketsX + bx;
            int x0 = film.x0() + bx * bw, y0 = film.y0() + by * bh;
            int x1 = std::min(x0 + bw, film.x1()), y1 = std::min(y0 + bh, film.y1());
            SampleBufferConfig config = m_settings.sampling;
            config.x0 = x0;
            config.y0 = y0;
            config.x1 = x1;
            config.y1 = y1;
            config.margin = m_settings.filterMargin;
            auto& nodes = perBucket[size_t(bucket)];
            // A depth film starts at +infinity, which is what a bucket
            // no primitive reaches resolves to: such buckets (most of a
            // sparse shadow map) need no samples at all.
            if (!nodes.empty() || config.mode != HiderMode::Depth) {
                buffer.reset(config);
                frame.walk(nodes, bx, by, buffer, stats, walk);
                buffer.resolve(film);
            } else {
                film.clearDepth(x0, y0, x1, y1);  // a streamed film's depths start unset
            }
            // A streamed film writes the strips this bucket completes.
            film.bucketDone(x0, y0, x1, y1);
            ++stats.buckets;
            int d = ++done;
            if (work) m_settings.progress(d, bucketCount, work->finish(bucket));
        }
        stats.workerCpuSeconds = threadCpuSeconds() - cpu0;
        stats.blur = buffer.blurStats();
        std::lock_guard<std::mutex> lock(statsMutex);
        total.add(stats);
    }, tbb::simple_partitioner());
    total.peakGridsAlive = frame.peakGrids.load();
    return total;
}

}  // namespace umbra::hider
