#pragma once
// Reading depth maps and filtering them: the shadow() lookup.
//
// The lookup is percentage-closer filtering (Reeves, Salesin & Cook 1987,
// Figure 4): the shading region is mapped into the map's raster, a fixed
// number of jittered samples of the map under it are each compared with the
// region's light-space depth, and the fraction that are nearer to the light
// (the fraction of the region in shadow) is returned.

#include "umbra/shadow/depth_image.h"
#include "umbra/shadow/tile_cache.h"
#include "umbra/util/error.h"
#include "umbra/util/math.h"

#include <ImfForward.h>
#include <nlohmann/json_fwd.hpp>

#include <algorithm>
#include <cstdint>
#include <future>
#include <memory>
#include <mutex>
#include <string>
#include <vector>


namespace umbra {

/// Parameters of one shadow() call (RenderMan names in brackets, Reeves'
/// names in parentheses).
struct ShadowParams {
    /// How the samples of a region are placed (Reeves Figure 3 a, b, c).
    enum class Sampling { Jittered, Uniform, Gaussian };
    /// How sample results are weighted: equally, or by a Gaussian of their
    /// distance from the region's centre (["filter"]).
    enum class Filter { Box, Gaussian };

    int samples = 16;       ///< ["samples"] (NumSamples)
    float sWidth = 1;       ///< ["swidth"] (ResFactor along raster x); ["width"] sets both
    float tWidth = 1;       ///< ["twidth"] (ResFactor along raster y)
    float blur = 0;         ///< ["blur"] extra region width, as a fraction of the map's resolution
    int minSamples = 2;     ///< (MinSamples) per axis; Reeves' "2 or 3"; clamped to `samples`
    float minSize = 2;      ///< (MinSize) minimum full region width in texels; Reeves uses 2
    /// ["bias"]: constant depth offset (world units) added to the map depth
    /// before comparing; used when bias0 == bias1 == 0.
    float bias = 0;
    /// ["bias0"], ["bias1"] (Bias0, Bias1): when not both zero, every sample
    /// draws its bias uniformly from [bias0, bias1] (Reeves' footnote) and
    /// `bias` is ignored.
    float bias0 = 0, bias1 = 0;
    Filter filter = Filter::Box;
    Sampling sampling = Sampling::Jittered;
    /// Per-tile min/max culling (on in production; tests turn it off to
    /// check that it never changes a result).
    bool tileCulling = true;

    void setWidth(float w) { sWidth = tWidth = w; }
    /// The bias range samples draw from, honouring the rule above.
    float biasLow() const { return (bias0 == 0 && bias1 == 0) ? bias : std::min(bias0, bias1); }
    float biasHigh() const { return (bias0 == 0 && bias1 == 0) ? bias : std::max(bias0, bias1); }
};

/// A batch of shading points for one shadow() call on one grid.
struct ShadowBatch {
    int count = 0;
    const Vec3* P = nullptr;        ///< points, in "current" space
    /// Footprint vectors (the micropolygon's edges along u and v, i.e.
    /// dPdu*du and dPdv*dv), current space; null means a point footprint
    /// (the region is then MinSize texels).
    const Vec3* dPdu_du = nullptr;
    const Vec3* dPdv_dv = nullptr;
    const Vec3* N = nullptr;        ///< normals (second-depth maps); may be null
    /// The four-point form shadow(name, P1, P2, P3, P4): each point's
    /// region is the box around its four corners' projections into the map
    /// (in any order), in place of the footprint's. Null: the footprint's.
    const Vec3* corners[4] = {nullptr, nullptr, nullptr, nullptr};
    Mat4 worldFromCurrent;
    uint32_t seed = 0;              ///< identity of the call (frame, grid, light): seeds the samples
    /// Moving points' paths over the shutter: `pathKeys` times, fractions of
    /// the shutter from 0 to 1 (`pathTimes`), and each point's offset from
    /// P at each, in current space with the camera held at the opening:
    /// pathOffsets[key * count + point]. On a map of moving casters whose
    /// texel times are known, each time's texels are compared with the
    /// point where it is at that time (docs/motion.md). 0 keys: still.
    int pathKeys = 0;
    const float* pathTimes = nullptr;
    const Vec3* pathOffsets = nullptr;
    /// Each point's identity within the call (its vertex in the grid), which
    /// seeds its samples with `seed`: a point's samples do not depend on
    /// which other points were looked up with it. Null: its place in the batch.
    const int* pointId = nullptr;
};

/// Counters of lookups; add them up per thread and merge.
struct ShadowStats {
    uint64_t points = 0;          ///< points looked up
    uint64_t outside = 0;         ///< behind the light, outside the map or its bounding box: lit at once
    uint64_t culledLit = 0;       ///< nearer than every covered tile's min z: lit without texel reads
    uint64_t culledShadowed = 0;  ///< beyond every covered tile's max z: shadowed without texel reads
    /// Not culled by those ranges, but decided by the min and max of the few
    /// texels the region covers, without drawing samples:
    uint64_t texelRangeLit = 0;
    uint64_t texelRangeShadowed = 0;
    uint64_t filtered = 0;        ///< points that compared texels
    uint64_t samples = 0;         ///< texel comparisons made
    uint64_t tileFetches = 0;     ///< tiles asked of the cache
    /// Second-depth maps (Wang & Molnar Fig. 10), among `filtered` points:
    uint64_t secondLit = 0;       ///< every comparison lit: lit without virtual samples
    uint64_t secondShadowed = 0;  ///< no comparison lit: shadowed without virtual samples
    uint64_t virtualPoints = 0;   ///< mixed: resolved with virtual samples on the tangent plane
    /// Second-depth maps, not among `filtered`: light-facing points whose
    /// tangent plane is the plane every covered 8x8 block stores (an open
    /// surface stored as its own second layer), lit without samples.
    uint64_t storedPlaneLit = 0;
    /// Of storedPlaneLit, points lit a whole grid (batch) at a time.
    uint64_t storedPlaneGridPoints = 0;
    ShadowStats& operator+=(const ShadowStats& o);
};

/// What `umbra info MAP` prints, including Reeves' Table 2 storage figures.
struct MapInfo {
    std::string path;
    int width = 0, height = 0;
    bool empty = true;                  ///< no finite depth at all
    int bboxMinX = 0, bboxMinY = 0;     ///< bounding box of finite depths (inclusive, raster)
    int bboxMaxX = -1, bboxMaxY = -1;
    int tileWidth = 0, tileHeight = 0;
    int tilesX = 0, tilesY = 0;         ///< tiles covering the bounding box (face 0 of a cube)
    int tileCount = 0;                  ///< all tiles (of all faces)
    int emptyTiles = 0;                 ///< tiles with no finite depth
    float minZ = kInfinity, maxZ = -kInfinity;  ///< finite depth range (light camera space)
    std::string projection, depthFilter;
    int faces = 1;                      ///< 6 for a cube map: sizes and counts then sum over faces
    uint64_t rawBytes = 0;              ///< width*height*4
    uint64_t bboxBytes = 0;             ///< bounding box area * 4
    uint64_t tileBytes = 0;             ///< tiles with a finite depth * tile bytes (4 KiB at 32x32)
    uint64_t fileBytes = 0;             ///< size on disk
};
std::string mapInfoText(const MapInfo& info);
nlohmann::json mapInfoJson(const MapInfo& info);

/// An open depth map: header, matrices and per-tile depth range in memory,
/// texels read tile by tile through a TileCache. Lookups are const and
/// thread-safe.
class ShadowMap {
public:
    /// Opens a map written by writeDepthMap (or any tiled, single-level EXR
    /// with a FLOAT "Z" channel and worldToCamera/worldToNDC), or a cube map
    /// written by writeCubeDepthMap. A missing,
    /// corrupt or truncated file gives an error naming `loc` and the file,
    /// and null. `cache` defaults to TileCache::shared(). `diag` must
    /// outlive the map: tile read failures during lookups are reported to
    /// it (once per map) and those tiles read as empty.
    static std::shared_ptr<ShadowMap> open(const std::string& path, Diagnostics& diag, const FileLoc& loc = {},
                                           std::shared_ptr<TileCache> cache = nullptr);
    /// The map writeDepthMap(path, image) stores, built from the image in
    /// memory, so it can be used before the file exists: its header values
    /// are the file's, and every tile that fits under the cache's bound goes
    /// to the cache (preload()). `*everyTileCached` (if given) tells whether
    /// all did (an empty map's lookups read no tile: always true).
    ///
    /// A tile that is not in the cache (it did not fit, or was evicted) is
    /// read from the file, opened on first need after waiting for
    /// `written`, the writer's result (an invalid future: the file is
    /// already there). When the write failed, or the file is not whole, the
    /// map's uncached tiles read as empty, with one error naming the file.
    /// A malformed image gives an error naming `loc` and null.
    static std::shared_ptr<ShadowMap> fromImage(const DepthImage& image, const std::string& path,
                                                std::shared_future<bool> written, Diagnostics& diag,
                                                const FileLoc& loc = {}, std::shared_ptr<TileCache> cache = nullptr,
                                                bool* everyTileCached = nullptr);
    /// The same for the cube map writeCubeDepthMap(path, faces) stores.
    static std::shared_ptr<ShadowMap> fromCubeImages(const std::array<DepthImage, 6>& faces, const std::string& path,
                                                     std::shared_future<bool> written, Diagnostics& diag,
                                                     const FileLoc& loc = {},
                                                     std::shared_ptr<TileCache> cache = nullptr,
                                                     bool* everyTileCached = nullptr);
    ~ShadowMap();
    ShadowMap(const ShadowMap&) = delete;
    ShadowMap& operator=(const ShadowMap&) = delete;

    /// Percentage-closer filtered lookup of every point of `batch`:
    /// `outShadowed[i]` = fraction of point i's region in shadow (0 lit,
    /// 1 shadowed). Deterministic: depends only on the inputs and the map.
    ///
    /// For maps whose depth filter is "second" and batches with normals,
    /// this is Wang & Molnar's Figure 10: the PCF comparisons (lit when
    /// z <= map + bias) decide alone when they agree; when mixed, each sample
    /// is compared again using the depth of the point's tangent plane at the
    /// sample's texel centre ("virtual sample"), found by transforming the
    /// plane into the light's projective screen space (raster x, raster y,
    /// 1/z for perspective, z for orthographic lights) where it is linear.
    /// All-shadowed comparisons of a point whose normal faces the light get
    /// virtual samples too: such a point is never the far side of a solid
    /// (Figure 10's case), but may be an open surface stored as its own
    /// second layer (§3.3), compared with its own sloped depth.
    void lookup(const ShadowBatch& batch, const ShadowParams& params, float* outShadowed, ShadowStats& stats) const;
    /// Williams' point-sampled test: the nearest texel under each point,
    /// compared with bias (biasLow+biasHigh)/2. Equal to lookup() with
    /// samples = 1 (any width).
    void lookupPoint(const ShadowBatch& batch, const ShadowParams& params, float* outShadowed, ShadowStats& stats) const;

    /// The tangent plane of a receiver in the light's raster space (Wang &
    /// Molnar Fig. 10): raster depth Z(x, y) = a x + b y + d, linear there
    /// although camera-space depth is not. Invalid (second-depth lookups
    /// keep plain comparisons) when the map cannot take virtual samples or
    /// the plane is seen edge-on.
    struct TangentPlane {
        float a = 0, b = 0, d = 0;
        /// The flags are whole words: bytes packed after the floats made
        /// GCC copy the struct through a misaligned reload that stalled on
        /// the store buffer (by perf, a tenth of the lookup loop's time).
        int32_t valid = false;
        /// The normal points towards the light: a surface the light reaches
        /// from its front (its lit side), never the far side of a solid.
        int32_t facesLight = false;
    };
    /// The plane through P with normal N (both in the space `lightFromSpace`
    /// maps to the light's camera space; `spaceFromLight` is its inverse,
    /// which normals need).
    TangentPlane tangentPlane(const Vec3& P, const Vec3& N, const Mat4& lightFromSpace,
                              const Mat4& spaceFromLight) const {
        return tangentPlane(planeFrame(spaceFromLight), P, N);
    }
    TangentPlane tangentPlane(const Vec3& P, const Vec3& N, const Mat4& lightFromSpace) const {
        return tangentPlane(P, N, lightFromSpace, lightFromSpace.inverse());
    }
    /// The light camera-space depth of the plane at the centre of texel
    /// (x, y): the virtual sample compared with the map's depth there.
    float virtualDepth(const TangentPlane& plane, int x, int y) const {
        const float Z = plane.a * (float(x) + 0.5f) + plane.b * (float(y) + 0.5f) + plane.d;
        if (m_virtualMode == 1) return Z > 0 ? 1.0f / (m_wScale * Z) : kInfinity;  // no crossing in front: far away
        return m_wScale * Z;
    }
    /// virtualDepth(plane, x, y) > limit, without its divide: under a
    /// perspective light the plane gives 1/z, and for 1/z > 0 the test
    /// 1/(1/z) <= limit is 1/z * limit >= 1.
    bool virtualDeeper(const TangentPlane& plane, int x, int y, float limit) const {
        const float Z = plane.a * (float(x) + 0.5f) + plane.b * (float(y) + 0.5f) + plane.d;
        if (m_virtualMode == 1) {
            const float inverseDepth = m_wScale * Z;
            return inverseDepth > 0 ? !(inverseDepth * limit >= 1.0f) : !(limit == kInfinity);
        }
        return !(m_wScale * Z <= limit);
    }

    /// Hands the depths of `image` -- the image this map was written from
    /// (writeDepthMap), or face f's image for face(f) of a cube -- to the
    /// tile cache, so lookups in the frame that rendered the map do not
    /// read back and decompress what is still in memory (fromImage() does
    /// this for the maps it builds). Only tiles that fit
    /// under the cache's bound are added; the rest are read from the file as
    /// usual. Returns the tiles added; 0 when the image does not match.
    int preload(const DepthImage& image) const;

    /// The stored depth of texel (x, y) in raster coordinates (+infinity
    /// outside the bounding box); reads through the cache. For tools/tests.
    float texel(int x, int y) const;

    int width() const { return m_width; }
    int height() const { return m_height; }
    const Mat4& lightFromWorld() const { return m_lightFromWorld; }
    const Mat4& ndcFromWorld() const { return m_ndcFromWorld; }
    Projection projection() const { return m_projection; }
    DepthFilter depthFilter() const { return m_filter; }
    float dualOffset() const { return m_dualOffset; }
    int timeTile() const { return m_timeTile; }
    /// A map of moving casters that knows when each texel holds them
    /// (DepthImage::texelTimes): moving receivers are looked up time by time.
    bool knowsTexelTimes() const { return !m_slotTexel.empty(); }
    bool empty() const { return m_finiteCount == 0; }
    /// Data window (bounding box of finite depths), inclusive raster bounds.
    int dataMinX() const { return m_dx0; }
    int dataMinY() const { return m_dy0; }
    int dataMaxX() const { return m_dx1; }
    int dataMaxY() const { return m_dy1; }
    int tilesX() const { return m_tilesX; }
    int tilesY() const { return m_tilesY; }
    float tileMinZ(int tx, int ty) const { return m_tileMin[size_t(ty) * m_tilesX + tx]; }
    float tileMaxZ(int tx, int ty) const { return m_tileMax[size_t(ty) * m_tilesX + tx]; }
    const TileCache& cache() const { return *m_cache; }
    /// A cube map (six faces, from writeCubeDepthMap) rather than one map;
    /// the accessors above then describe face 0, texel() reads face 0.
    bool isCube() const { return !m_faces.empty(); }
    /// Face f of a cube map (kCubeFaceNames order).
    const ShadowMap& face(int f) const { return *m_faces[size_t(f)]; }
    MapInfo info() const;
    const std::string& path() const { return m_path; }

private:
    struct File;
    ShadowMap() = default;
    static std::shared_ptr<ShadowMap> fromImages(const DepthImage* images, int count, const std::string& path,
                                                 std::shared_future<bool> written, Diagnostics& diag,
                                                 const FileLoc& loc, std::shared_ptr<TileCache> cache,
                                                 bool* everyTileCached);
    /// The tile from the cache, reading it from the file on a miss.
    ShadowTilePtr fetchTile(int tx, int ty) const;
    ShadowTilePtr readTile(int tx, int ty) const;
    void setupVirtualSampling();
    /// Takes the map's layout (sizes, data window, tiles, matrices, depth
    /// ranges) from a header, the file's or the one prepared in memory.
    bool initHeader(const Imf::Header& header, int tilesX, int tilesY, std::string& why);
    /// Opens this map's part of the file (and the file, if no part did) and
    /// checks it is whole and laid out as initHeader() read; false with a
    /// reason in `why`. Called with m_file->mutex held (or before the map
    /// is handed out).
    bool openPart(std::string& why) const;
    /// Part p of a map of `parts` parts on one file: `whole` itself for a
    /// single map, a new face of it for a cube.
    static std::shared_ptr<ShadowMap> part(const std::shared_ptr<ShadowMap>& whole, int parts, int p,
                                           const std::string& path, Diagnostics& diag,
                                           const std::shared_ptr<TileCache>& cache, const std::shared_ptr<File>& file);
    /// Makes this map the cube of `faces`: it dispatches lookups to them,
    /// and its own fields (file, path, sizes, matrices) are face 0's.
    void setFaces(std::vector<std::shared_ptr<ShadowMap>> faces);
    /// Cube maps: splits a batch by face and looks each part up there.
    void lookupCube(const ShadowBatch& batch, const ShadowParams& params, float* out, ShadowStats& stats,
                    bool pointSample) const;
    template <bool kPointSample>
    void lookupImpl(const ShadowBatch& batch, const ShadowParams& params, float* out, ShadowStats& stats) const;
    /// What the tangent planes of one batch need, in its space: the map
    /// applied to a plane covector (n, -n.P) of that space gives the plane
    /// in the light's raster space; and where the light is.
    struct PlaneFrame {
        Mat4 rasterPlaneFromSpace;  // (screenFromLight^-1)^T (spaceFromLight)^T
        Vec3 light;                 // perspective: the light's position; orthographic: its view axis
    };
    PlaneFrame planeFrame(const Mat4& spaceFromLight) const;
    /// Defined here so the lookup loop inlines it.
    TangentPlane tangentPlane(const PlaneFrame& frame, const Vec3& P, const Vec3& N) const {
        TangentPlane plane;
        if (m_virtualMode == 0) return plane;
        // The plane n.x - n.P = 0 through P, carried to the light's raster
        // space (x, y, 1/z or z), where it is linear.
        const float c[4] = {N.x, N.y, N.z, -dot(N, P)};
        const auto& M = frame.rasterPlaneFromSpace.m;
        float pl[4];
        for (int r = 0; r < 4; ++r) pl[r] = M[r][0] * c[0] + M[r][1] * c[1] + M[r][2] * c[2] + M[r][3] * c[3];
        // An edge-on plane (c = 0) says nothing about depth.
        if (!(std::abs(pl[2]) > 1e-30f) || !std::isfinite(pl[0] + pl[1] + pl[2] + pl[3])) return plane;
        const float inv = -1.0f / pl[2];
        plane.a = pl[0] * inv;
        plane.b = pl[1] * inv;
        plane.d = pl[3] * inv;
        plane.valid = true;
        plane.facesLight = facesLight(frame, P, N);
        return plane;
    }
    bool facesLight(const PlaneFrame& frame, const Vec3& P, const Vec3& N) const {
        return m_projection == Projection::Perspective ? dot(N, frame.light - P) > 0 : dot(N, frame.light) < 0;
    }
    /// The coordinate tiles fit their blocks' planes in: second-depth maps
    /// that take virtual samples only.
    ShadowTile::DepthCoordinate blockPlanes() const;
    /// Receivers' tangent planes in the map's depth coordinate q (m_wScale
    /// times the raster plane): q = A x + B y + D for one of them, every
    /// other within `spread` of it over the texels tested; the largest |a|,
    /// |b|, |d| of the raster planes bound the rounding of the sample loop.
    struct PlaneEnvelope {
        double A = 0, B = 0, D = 0, spread = 0;
        double absA = 0, absB = 0, absD = 0;
    };
    // Both inline in the lookup's loop (shadow_lookup.cpp, their only
    // user): called per point, the calls cost as much as their bodies.
    [[gnu::always_inline]] inline PlaneEnvelope envelope(const TangentPlane& plane) const;
    /// The most the sample loop's float evaluation of a plane of `env` can
    /// be off, in q, at raster |x| <= xAbs, |y| <= yAbs: four roundings of
    /// |a x| + |b y| + |d|.
    double evaluationError(const PlaneEnvelope& env, double xAbs, double yAbs) const {
        return 4.0 * 0x1p-24 * std::abs(double(m_wScale)) * (env.absA * xAbs + env.absB * yAbs + env.absD);
    }
    /// True when every plane of `env` matches the planes stored in blocks
    /// [bx0, bx1] x [by0, by1] of `tile` (whose first texel is raster
    /// (tileX, tileY)) closely enough that every virtual sample there
    /// compares lit, rounding included.
    bool onStoredPlanes(const PlaneEnvelope& env, const ShadowTile& tile, int tileX, int tileY, int bx0, int bx1,
                        int by0, int by1) const;
    /// One block's stored plane in the form onStoredPlanes() tests it: the
    /// centre (xc, yc) of its texel centres, its half extents, the plane's
    /// q there and its slopes, the least |q| over the block (NaN when the
    /// block stores no plane), and the extents the rounding bound reads.
    /// Points of a grid mostly cover the same blocks, so the lookup keeps
    /// the blocks it has met in this form.
    struct PlaneBlock {
        double xc, yc, hx, hy, stored, gx, gy, least, xAbs, yAbs;
    };
    /// Block (bx, by) of `tile`, whose first texel is raster (tileX, tileY).
    static PlaneBlock planeBlock(const ShadowTile& tile, int tileX, int tileY, int bx, int by);
    /// onStoredPlanes() for one block.
    [[gnu::always_inline]] inline bool onPlaneBlock(const PlaneEnvelope& env, const PlaneBlock& k) const;

    /// The tangent planes of a batch's points, made on first use (all at
    /// once, for tests of the whole batch). `frame` is null when the lookup
    /// takes no virtual samples.
    struct BatchPlanes {
        const PlaneFrame* frame = nullptr;
        std::vector<TangentPlane>* planes = nullptr;
        bool ready = false;
    };
    const TangentPlane* planesOf(const ShadowBatch& batch, BatchPlanes& bp) const {
        return bp.ready ? bp.planes->data() : makePlanes(batch, bp);
    }
    /// Four points at a time, each plane exactly the one tangentPlane()
    /// gives (the same operations lane by lane).
    const TangentPlane* makePlanes(const ShadowBatch& batch, BatchPlanes& bp) const;
    /// True when at every texel centre of [i0, i1] x [j0, j1] every plane
    /// of `env` lies deeper than `limit` as the sample loop's virtual
    /// comparison finds it (rounding included): a light-facing point whose
    /// plain comparisons are all shadowed is then shadowed by its virtual
    /// samples too, and may be culled as shadowed.
    bool planesDeeper(const PlaneEnvelope& env, int i0, int i1, int j0, int j1, double limit) const;
    /// The envelope of the valid, light-facing planes among `planes` over
    /// raster [x0, x1] x [y0, y1]; `all` tells whether every plane was one,
    /// `any` whether at least one was.
    PlaneEnvelope envelopeOfFacing(const TangentPlane* planes, int count, double x0, double x1, double y0, double y1,
                                   bool* all, bool* any) const;

    /// A batch's points at once: the range of their light-space depths and
    /// the union of their regions in the map's raster.
    struct BatchBounds {
        bool allUsable;  ///< every point is in front of the light and projectable
        float zLo, zHi, loS, hiS, loT, hiT;
    };
    /// Decides a whole batch at once from its bounds when it misses the
    /// bounding box or clears the covered tiles' depth range, or (given
    /// the points' tangent planes and `planeLit`) when every block its
    /// regions cover stores the plane its points lie on; writes `out` and
    /// counts it in `st`; false when undecided. The shadowed case of
    /// second-depth lookups needs the planes of light-facing points.
    bool batchDecided(const ShadowBatch& batch, const ShadowParams& params, const BatchBounds& bounds,
                      BatchPlanes& planes, bool planeLit, float* out, ShadowStats& st) const;

    std::string m_path;
    Diagnostics* m_diag = nullptr;
    std::shared_ptr<TileCache> m_cache;
    uint32_t m_mapId = 0;
    std::shared_ptr<File> m_file;  // shared by a cube map's faces (parts of one file)
    int m_partNumber = 0;
    mutable std::unique_ptr<Imf::TiledInputPart> m_part;  // guarded by m_file->mutex; null until opened
    std::vector<std::shared_ptr<ShadowMap>> m_faces;  // a cube map's six faces; empty otherwise

    int m_width = 0, m_height = 0;
    int m_dx0 = 0, m_dy0 = 0, m_dx1 = -1, m_dy1 = -1;  // data window clipped to the display window
    int m_fileX0 = 0, m_fileY0 = 0;                    // the file's data window corner: tile (0,0)
    int m_tileW = 0, m_tileH = 0, m_tileShiftX = 0, m_tileShiftY = 0;
    // log2 of a tile block's size (ShadowTile::kBlocks blocks per side), or
    // -1 when tiles are too small to have blocks.
    int m_blockShiftX = -1, m_blockShiftY = -1;
    int m_tilesX = 0, m_tilesY = 0;
    std::vector<float> m_tileMin, m_tileMax;
    float m_minZ = kInfinity, m_maxZ = -kInfinity;
    int64_t m_finiteCount = 0;
    Mat4 m_lightFromWorld, m_ndcFromWorld;
    Projection m_projection = Projection::Perspective;
    DepthFilter m_filter = DepthFilter::Min;
    float m_dualOffset = 0;
    int m_timeTile = 0;  // see DepthImage::timeTile
    /// Known texel times (DepthImage::texelTimes), over a period of
    /// m_timePeriod texels a side; for each time tile of the period, its
    /// texels in order of time (dy * m_timeTile + dx), the k-th of every
    /// tile being "slot" k; and each slot's time, averaged over the tiles
    /// (the same in every tile for umbra's maps, which time a texel's one
    /// sample at its fine stratum's middle). Empty when unknown.
    int m_timePeriod = 0;
    std::vector<float> m_texelTimes;
    std::vector<uint8_t> m_slotTexel;
    std::vector<float> m_slotTime;
    std::vector<uint8_t> m_texelSlot;  // each texel's slot over the period, [y * period + x]
    void setupTimeSlots(const std::vector<float>& texelTimes);
    uint64_t m_fileBytes = 0;
    /// Virtual sampling: planes go from light camera space to the light's
    /// screen space (raster x, raster y, depth coordinate) by
    /// m_planeFromLight = (screenFromLight^-1)^T. Mode: 0 unavailable (an
    /// unusual projection), 1 perspective (depth coordinate 1/(k z)), 2
    /// orthographic (depth coordinate z).
    Mat4 m_planeFromLight;
    int m_virtualMode = 0;
    float m_wScale = 1;
};

}  // namespace umbra
