#pragma once
// Helpers shared by the shadow module's tests: scratch files and simple,
// analytically understood maps.

#include "umbra/shadow/depth_image.h"
#include "umbra/shadow/shadow_map.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <vector>

namespace umbra::test {

/// A per-process scratch directory, removed at exit.
inline const std::filesystem::path& scratchDir() {
    static struct Dir {
        std::filesystem::path path;
        Dir() {
            path = std::filesystem::temp_directory_path() / ("umbra_shadow_test_" + std::to_string(::getpid()));
            std::filesystem::create_directories(path);
        }
        ~Dir() {
            std::error_code ec;
            std::filesystem::remove_all(path, ec);
        }
    } dir;
    return dir.path;
}

inline std::string scratchFile(const std::string& name) { return (scratchDir() / name).string(); }

/// An orthographic light looking down world +z whose raster is world x, y
/// (texel (i, j) covers world [i, i+1) x [j, j+1)) and whose depth is world z.
inline void setRasterIsWorld(DepthImage& img) {
    img.lightFromWorld = Mat4::identity();
    img.ndcFromWorld = Mat4::scale(Vec3(1.0f / float(img.width), 1.0f / float(img.height), 1.0f));
    img.projection = Projection::Orthographic;
}

/// NDC from light camera space for a 90-degree pinhole looking down +z:
/// NDC x = (x/z + 1)/2, y = (1 - y/z)/2.
inline Mat4 ndcFromCamera90() {
    Mat4 persp;
    persp.m[3][2] = 1;
    persp.m[3][3] = 0;
    Mat4 ndcFromScreen;
    ndcFromScreen.m[0][0] = 0.5f;
    ndcFromScreen.m[0][3] = 0.5f;
    ndcFromScreen.m[1][1] = -0.5f;
    ndcFromScreen.m[1][3] = 0.5f;
    return ndcFromScreen * persp;
}

/// Writes `img` to `name` in the scratch directory and opens it.
inline std::shared_ptr<ShadowMap> writeAndOpen(const DepthImage& img, const std::string& name,
                                               std::shared_ptr<TileCache> cache = nullptr) {
    static Diagnostics diag;  // outlives every map opened through here
    const std::string path = scratchFile(name);
    EXPECT_TRUE(writeDepthMap(path, img, diag));
    auto map = ShadowMap::open(path, diag, {}, std::move(cache));
    EXPECT_TRUE(map != nullptr);
    return map;
}

/// Expects two maps (or two faces of cube maps) to agree on everything
/// their headers give and on every texel.
inline void expectSameMap(const ShadowMap& a, const ShadowMap& b) {
    ASSERT_EQ(a.width(), b.width());
    ASSERT_EQ(a.height(), b.height());
    EXPECT_TRUE(a.lightFromWorld() == b.lightFromWorld());
    EXPECT_TRUE(a.ndcFromWorld() == b.ndcFromWorld());
    EXPECT_EQ(a.projection(), b.projection());
    EXPECT_EQ(a.depthFilter(), b.depthFilter());
    EXPECT_EQ(a.dualOffset(), b.dualOffset());
    EXPECT_EQ(a.empty(), b.empty());
    EXPECT_EQ(a.dataMinX(), b.dataMinX());
    EXPECT_EQ(a.dataMinY(), b.dataMinY());
    EXPECT_EQ(a.dataMaxX(), b.dataMaxX());
    EXPECT_EQ(a.dataMaxY(), b.dataMaxY());
    ASSERT_EQ(a.tilesX(), b.tilesX());
    ASSERT_EQ(a.tilesY(), b.tilesY());
    for (int ty = 0; ty < a.tilesY(); ++ty)
        for (int tx = 0; tx < a.tilesX(); ++tx) {
            EXPECT_EQ(a.tileMinZ(tx, ty), b.tileMinZ(tx, ty)) << tx << "," << ty;
            EXPECT_EQ(a.tileMaxZ(tx, ty), b.tileMaxZ(tx, ty)) << tx << "," << ty;
        }
    for (int y = 0; y < a.height(); ++y)
        for (int x = 0; x < a.width(); ++x) ASSERT_EQ(a.texel(x, y), b.texel(x, y)) << x << "," << y;
}

inline void expectSameInfo(const MapInfo& a, const MapInfo& b) {
    EXPECT_EQ(a.path, b.path);
    EXPECT_EQ(a.width, b.width);
    EXPECT_EQ(a.height, b.height);
    EXPECT_EQ(a.empty, b.empty);
    EXPECT_EQ(a.bboxMinX, b.bboxMinX);
    EXPECT_EQ(a.bboxMinY, b.bboxMinY);
    EXPECT_EQ(a.bboxMaxX, b.bboxMaxX);
    EXPECT_EQ(a.bboxMaxY, b.bboxMaxY);
    EXPECT_EQ(a.tileWidth, b.tileWidth);
    EXPECT_EQ(a.tileHeight, b.tileHeight);
    EXPECT_EQ(a.tilesX, b.tilesX);
    EXPECT_EQ(a.tilesY, b.tilesY);
    EXPECT_EQ(a.tileCount, b.tileCount);
    EXPECT_EQ(a.emptyTiles, b.emptyTiles);
    EXPECT_EQ(a.minZ, b.minZ);
    EXPECT_EQ(a.maxZ, b.maxZ);
    EXPECT_EQ(a.projection, b.projection);
    EXPECT_EQ(a.depthFilter, b.depthFilter);
    EXPECT_EQ(a.faces, b.faces);
    EXPECT_EQ(a.rawBytes, b.rawBytes);
    EXPECT_EQ(a.bboxBytes, b.bboxBytes);
    EXPECT_EQ(a.tileBytes, b.tileBytes);
    EXPECT_EQ(a.fileBytes, b.fileBytes);
}

/// Filtered and point-sampled lookups of the points P (footprint edges du,
/// dv, in world space), and their counters.
struct Lookups {
    std::vector<float> filtered, point;
    ShadowStats stats;
};

inline Lookups lookUp(const ShadowMap& map, const std::vector<Vec3>& P, const std::vector<Vec3>& du,
                      const std::vector<Vec3>& dv, const ShadowParams& params) {
    ShadowBatch b;
    b.count = int(P.size());
    b.P = P.data();
    b.dPdu_du = du.data();
    b.dPdv_dv = dv.data();
    b.seed = 1234;
    Lookups out;
    out.filtered.resize(P.size());
    out.point.resize(P.size());
    map.lookup(b, params, out.filtered.data(), out.stats);
    map.lookupPoint(b, params, out.point.data(), out.stats);
    return out;
}

inline void expectSameLookups(const Lookups& a, const Lookups& b) {
    EXPECT_EQ(a.filtered, b.filtered);
    EXPECT_EQ(a.point, b.point);
    EXPECT_EQ(a.stats.points, b.stats.points);
    EXPECT_EQ(a.stats.outside, b.stats.outside);
    EXPECT_EQ(a.stats.culledLit, b.stats.culledLit);
    EXPECT_EQ(a.stats.culledShadowed, b.stats.culledShadowed);
    EXPECT_EQ(a.stats.filtered, b.stats.filtered);
    EXPECT_EQ(a.stats.samples, b.stats.samples);
    EXPECT_EQ(a.stats.tileFetches, b.stats.tileFetches);
}

}  // namespace umbra::test
