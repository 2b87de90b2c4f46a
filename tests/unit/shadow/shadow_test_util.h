#pragma once
// Helpers shared by the shadow module's tests: scratch files and simple,
// analytically understood maps.

#include "umbra/shadow/depth_image.h"
#include "umbra/shadow/shadow_map.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

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

}  // namespace umbra::test
