#pragma once
// The depth-map tile cache: a memory-bounded, thread-safe LRU of map tiles
// shared by every open ShadowMap (Reeves et al. 1987 §3.3: "tiles, which
// could be cached to take better advantage of the algorithm's
// two-dimensional locality").

#include "umbra/util/zeroed_allocator.h"

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <list>
#include <memory>
#include <mutex>
#include <unordered_map>
#include <vector>

namespace umbra {

/// One tile of a depth map, as read from the file: `width` x `height`
/// depths, row-major; texels the file does not cover are +infinity.
///
/// Each tile also knows the depth range of its kBlocks x kBlocks blocks
/// (8x8 texels in a 32x32 tile), a finer level of the per-tile ranges in the
/// map's header: once a lookup has the tile, a region inside a few blocks is
/// often wholly nearer or farther than them and needs no samples.
struct ShadowTile {
    static constexpr int kBlocks = 4;
    int width = 0, height = 0;
    /// A 32x32 tile's depths come from the block pool (util/zeroed_allocator.h).
    std::vector<float, PooledAllocator<float>> z;
    float blockMin[kBlocks * kBlocks], blockMax[kBlocks * kBlocks];
    /// Second-depth maps: the plane each block's depths lie on, in the
    /// map's linear depth coordinate q (1/z under a perspective light, z
    /// under an orthographic one, as DepthCoordinate says): texel (i, j) of
    /// block b (i, j from its first texel) holds q = planeQ0[b] +
    /// planeGx[b] i + planeGy[b] j within a relative kPlaneFit. planeQ0 is
    /// NaN for blocks that are not planar, hold an empty texel, or were not
    /// fitted. An open surface stored as its own second layer is planar
    /// here wherever it is flat, and a receiver on that plane is lit.
    float planeQ0[kBlocks * kBlocks], planeGx[kBlocks * kBlocks], planeGy[kBlocks * kBlocks];
    static constexpr float kPlaneFit = 1e-5f;
    enum class DepthCoordinate { None, InverseDepth, Depth };
    /// Fills blockMin/blockMax, and the block planes in `planes` (None
    /// leaves every block unfitted), from z (call once z is final). Tiles
    /// whose sides are not multiples of kBlocks get blocks that never cull.
    void computeBlocks(DepthCoordinate planes = DepthCoordinate::None);
    size_t bytes() const { return z.size() * sizeof(float) + sizeof(ShadowTile); }
};
using ShadowTilePtr = std::shared_ptr<const ShadowTile>;

/// Counters of a TileCache; a snapshot, all since construction.
struct TileCacheStats {
    uint64_t lookups = 0;    // find() calls
    uint64_t hits = 0;       // found in the cache
    uint64_t misses = 0;     // not found (the caller then reads the tile)
    uint64_t tilesRead = 0;  // tiles read from files
    uint64_t preloaded = 0;  // tiles handed over from memory by preload()
    uint64_t evictions = 0;  // tiles dropped to stay under the bound
    uint64_t bytes = 0;      // bytes held now
    uint64_t peakBytes = 0;  // most bytes ever held
};

/// A bounded LRU of depth-map tiles keyed by (map id, tile index).
///
/// Thread-safe. The key space is split into shards, each with its own lock
/// and LRU list and an equal share of the byte bound, so the two shading
/// threads rarely wait on each other. Tiles are handed out as shared
/// pointers: eviction only drops the cache's reference, so a tile being
/// filtered is never freed under its reader.
class TileCache {
public:
    /// `capacityBytes` bounds the bytes of tiles held (RenderMan-style option
    /// in MB: pass mb * 1024 * 1024). Default 64 MB.
    explicit TileCache(size_t capacityBytes = size_t(64) << 20);
    TileCache(const TileCache&) = delete;
    TileCache& operator=(const TileCache&) = delete;

    /// The process-wide default cache (64 MB) used when a map is opened
    /// without one.
    static std::shared_ptr<TileCache> shared();

    /// A fresh id for a newly opened map (never reused in the process).
    static uint32_t newMapId();

    /// The tile, or null if not cached (counts a hit or a miss).
    ShadowTilePtr find(uint32_t mapId, uint32_t tileIndex);
    /// Inserts a tile just read (counts a tile read); if another thread
    /// inserted the same key meanwhile, returns that one instead.
    ShadowTilePtr insert(uint32_t mapId, uint32_t tileIndex, ShadowTilePtr tile);
    /// Adds a tile the renderer already holds in memory (a map it has just
    /// rendered) if the shard has room for it without evicting anything;
    /// false when it had no room (the tile is then read from the file when
    /// needed) or the key is already cached.
    bool preload(uint32_t mapId, uint32_t tileIndex, ShadowTilePtr tile);
    /// Drops every tile of a map (called when the map is closed).
    void erase(uint32_t mapId);

    size_t capacityBytes() const { return m_capacity; }
    TileCacheStats stats() const;

private:
    static constexpr int kShards = 8;
    struct Entry {
        uint64_t key;
        ShadowTilePtr tile;
        size_t bytes;
    };
    struct Shard {
        std::mutex mutex;
        std::list<Entry> lru;  // front = most recently used
        std::unordered_map<uint64_t, std::list<Entry>::iterator> index;
        size_t bytes = 0;
    };
    static uint64_t key(uint32_t mapId, uint32_t tileIndex) { return (uint64_t(mapId) << 32) | tileIndex; }
    Shard& shardFor(uint64_t k) { return m_shards[(k ^ (k >> 32) ^ (k >> 7)) % kShards]; }
    void addBytes(int64_t delta);

    size_t m_capacity;
    size_t m_shardCapacity;
    std::array<Shard, kShards> m_shards;
    std::atomic<uint64_t> m_lookups{0}, m_hits{0}, m_misses{0}, m_tilesRead{0}, m_preloaded{0}, m_evictions{0};
    std::atomic<uint64_t> m_bytes{0}, m_peakBytes{0};
};

}  // namespace umbra
