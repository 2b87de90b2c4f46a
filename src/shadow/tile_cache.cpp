#include "umbra/shadow/tile_cache.h"

#include "umbra/util/math.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace umbra {

namespace {

/// The plane q = q0 + gx i + gy j through the depths of one block (bw x bh
/// texels from `first`, rows `stride` apart) in the coordinate q (1/z or z),
/// fitted through three corners and accepted when every texel lies within
/// a relative ShadowTile::kPlaneFit of it; false otherwise.
bool fitBlockPlane(const float* first, int stride, int bw, int bh, ShadowTile::DepthCoordinate planes, float* q0,
                   float* gx, float* gy) {
    const bool inverse = planes == ShadowTile::DepthCoordinate::InverseDepth;
    auto q = [&](int i, int j) -> double {
        const double d = first[size_t(j) * size_t(stride) + size_t(i)];
        return inverse ? 1.0 / d : d;
    };
    const double c00 = q(0, 0);
    *q0 = float(c00);
    *gx = float((q(bw - 1, 0) - c00) / (bw - 1));
    *gy = float((q(0, bh - 1) - c00) / (bh - 1));
    // Checked against the plane as stored (floats), without a divide per
    // texel: under 1/z, |1/d - p| <= k/d is |1 - p d| <= k for d > 0.
    for (int j = 0; j < bh; ++j)
        for (int i = 0; i < bw; ++i) {
            const double d = first[size_t(j) * size_t(stride) + size_t(i)];
            if (!std::isfinite(d) || (inverse && !(d > 0))) return false;
            const double p = double(*q0) + double(*gx) * i + double(*gy) * j;
            const double off = inverse ? std::abs(1.0 - p * d) : std::abs(d - p);
            if (!(off <= ShadowTile::kPlaneFit * (inverse ? 1.0 : std::abs(d)))) return false;
        }
    return true;
}

}  // namespace

void ShadowTile::computeBlocks(DepthCoordinate planes) {
    const int bw = width / kBlocks, bh = height / kBlocks;
    for (int b = 0; b < kBlocks * kBlocks; ++b) {
        blockMin[b] = -kInfinity;
        blockMax[b] = kInfinity;
        planeQ0[b] = planeGx[b] = planeGy[b] = std::numeric_limits<float>::quiet_NaN();
    }
    if (bw * kBlocks != width || bh * kBlocks != height || z.size() != size_t(width) * size_t(height)) return;
    for (int by = 0; by < kBlocks; ++by)
        for (int bx = 0; bx < kBlocks; ++bx) {
            const int b = by * kBlocks + bx;
            const float* first = z.data() + size_t(by * bh) * size_t(width) + size_t(bx * bw);
            float lo = kInfinity, hi = -kInfinity;
            for (int y = 0; y < bh; ++y) {
                const float* row = first + size_t(y) * size_t(width);
                for (int x = 0; x < bw; ++x) {
                    lo = std::min(lo, row[x]);
                    hi = std::max(hi, row[x]);
                }
            }
            blockMin[b] = lo;
            blockMax[b] = hi;
            float q0, gx, gy;
            if (planes != DepthCoordinate::None && bw > 1 && bh > 1 && std::isfinite(hi) &&
                fitBlockPlane(first, width, bw, bh, planes, &q0, &gx, &gy)) {
                planeQ0[b] = q0;
                planeGx[b] = gx;
                planeGy[b] = gy;
            }
        }
}

TileCache::TileCache(size_t capacityBytes) : m_capacity(capacityBytes), m_shardCapacity(capacityBytes / kShards) {}

std::shared_ptr<TileCache> TileCache::shared() {
    static std::shared_ptr<TileCache> cache = std::make_shared<TileCache>();
    return cache;
}

uint32_t TileCache::newMapId() {
    static std::atomic<uint32_t> next{1};
    return next.fetch_add(1, std::memory_order_relaxed);
}

void TileCache::addBytes(int64_t delta) {
    uint64_t now = m_bytes.fetch_add(uint64_t(delta), std::memory_order_relaxed) + uint64_t(delta);
    uint64_t peak = m_peakBytes.load(std::memory_order_relaxed);
    while (now > peak && !m_peakBytes.compare_exchange_weak(peak, now, std::memory_order_relaxed)) {
    }
}

ShadowTilePtr TileCache::find(uint32_t mapId, uint32_t tileIndex) {
    const uint64_t k = key(mapId, tileIndex);
    Shard& s = shardFor(k);
    m_lookups.fetch_add(1, std::memory_order_relaxed);
    {
        std::lock_guard<std::mutex> lock(s.mutex);
        auto it = s.index.find(k);
        if (it != s.index.end()) {
            s.lru.splice(s.lru.begin(), s.lru, it->second);
            ShadowTilePtr tile = it->second->tile;
            m_hits.fetch_add(1, std::memory_order_relaxed);
            return tile;
        }
    }
    m_misses.fetch_add(1, std::memory_order_relaxed);
    return nullptr;
}

ShadowTilePtr TileCache::insert(uint32_t mapId, uint32_t tileIndex, ShadowTilePtr tile) {
    const uint64_t k = key(mapId, tileIndex);
    Shard& s = shardFor(k);
    m_tilesRead.fetch_add(1, std::memory_order_relaxed);
    // Evicted tiles are released after the lock is dropped: freeing memory
    // under a shard lock would only lengthen other threads' waits.
    std::vector<ShadowTilePtr> dropped;
    {
        std::lock_guard<std::mutex> lock(s.mutex);
        auto it = s.index.find(k);
        if (it != s.index.end()) {
            s.lru.splice(s.lru.begin(), s.lru, it->second);
            return it->second->tile;
        }
        size_t bytes = tile->bytes();
        s.lru.push_front(Entry{k, tile, bytes});
        s.index.emplace(k, s.lru.begin());
        s.bytes += bytes;
        addBytes(int64_t(bytes));
        // Evict least recently used tiles over the shard's share; the tile
        // just inserted goes too if it alone exceeds it (the caller keeps it).
        while (s.bytes > m_shardCapacity && !s.lru.empty()) {
            Entry& victim = s.lru.back();
            s.bytes -= victim.bytes;
            addBytes(-int64_t(victim.bytes));
            s.index.erase(victim.key);
            dropped.push_back(std::move(victim.tile));
            s.lru.pop_back();
            m_evictions.fetch_add(1, std::memory_order_relaxed);
        }
    }
    return tile;
}

bool TileCache::preload(uint32_t mapId, uint32_t tileIndex, ShadowTilePtr tile) {
    const uint64_t k = key(mapId, tileIndex);
    Shard& s = shardFor(k);
    const size_t bytes = tile->bytes();
    std::lock_guard<std::mutex> lock(s.mutex);
    if (s.bytes + bytes > m_shardCapacity || s.index.count(k)) return false;
    // At the back of the LRU: a preloaded tile nobody reads goes first.
    s.lru.push_back(Entry{k, std::move(tile), bytes});
    s.index.emplace(k, std::prev(s.lru.end()));
    s.bytes += bytes;
    addBytes(int64_t(bytes));
    m_preloaded.fetch_add(1, std::memory_order_relaxed);
    return true;
}

void TileCache::erase(uint32_t mapId) {
    for (Shard& s : m_shards) {
        std::vector<ShadowTilePtr> dropped;
        std::lock_guard<std::mutex> lock(s.mutex);
        for (auto it = s.lru.begin(); it != s.lru.end();) {
            if (uint32_t(it->key >> 32) == mapId) {
                s.bytes -= it->bytes;
                addBytes(-int64_t(it->bytes));
                s.index.erase(it->key);
                dropped.push_back(std::move(it->tile));
                it = s.lru.erase(it);
            } else {
                ++it;
            }
        }
    }
}

TileCacheStats TileCache::stats() const {
    TileCacheStats st;
    st.lookups = m_lookups.load(std::memory_order_relaxed);
    st.hits = m_hits.load(std::memory_order_relaxed);
    st.misses = m_misses.load(std::memory_order_relaxed);
    st.tilesRead = m_tilesRead.load(std::memory_order_relaxed);
    st.preloaded = m_preloaded.load(std::memory_order_relaxed);
    st.evictions = m_evictions.load(std::memory_order_relaxed);
    st.bytes = m_bytes.load(std::memory_order_relaxed);
    st.peakBytes = m_peakBytes.load(std::memory_order_relaxed);
    return st;
}

}  // namespace umbra
