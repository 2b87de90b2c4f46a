// Point-light cube maps: six faces in one multi-part EXR.

#include "shadow_test_util.h"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <future>
#include <thread>

namespace umbra {
namespace {

// A light at L inside a room whose walls are 20 away on every axis, with
// two small occluders: the square x = 5, |y|,|z| < 2 and the square y = -6,
// |x|,|z| < 2 (coordinates relative to L).
const Vec3 kLight(1, 2, 3);

float sceneDepth(const Vec3& D) {  // D = direction with camera z = 1 on its face
    float t = 20.0f / std::max({std::abs(D.x), std::abs(D.y), std::abs(D.z)});
    if (D.x > 0) {
        float s = 5.0f / D.x;
        if (std::abs(s * D.y) < 2 && std::abs(s * D.z) < 2) t = std::min(t, s);
    }
    if (D.y < 0) {
        float s = -6.0f / D.y;
        if (std::abs(s * D.x) < 2 && std::abs(s * D.z) < 2) t = std::min(t, s);
    }
    return t;
}

std::array<DepthImage, 6> cubeFaces(int res) {
    // View direction and up vector of each face, in kCubeFaceNames order.
    const Vec3 dirs[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    const Vec3 ups[6] = {{0, 1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}, {0, 1, 0}, {0, 1, 0}};
    std::array<DepthImage, 6> faces;
    for (int f = 0; f < 6; ++f) {
        const Vec3 d = dirs[f], u = ups[f], r = cross(u, d);
        DepthImage img(res, res);
        Mat4 rot;
        for (int c = 0; c < 3; ++c) {
            rot.m[0][c] = r[c];
            rot.m[1][c] = u[c];
            rot.m[2][c] = d[c];
        }
        img.lightFromWorld = rot * Mat4::translate(-kLight);
        img.ndcFromWorld = test::ndcFromCamera90() * img.lightFromWorld;
        for (int y = 0; y < res; ++y)
            for (int x = 0; x < res; ++x) {
                float sx = (float(x) + 0.5f) / float(res) * 2 - 1, sy = 1 - (float(y) + 0.5f) / float(res) * 2;
                img.at(x, y) = sceneDepth(r * sx + u * sy + d);
            }
        faces[size_t(f)] = std::move(img);
    }
    return faces;
}

TEST(CubeMap, WritesSixPartsAndPicksTheFaceByDirection) {
    Diagnostics diag;
    const std::string path = test::scratchFile("cube.exr");
    auto faces = cubeFaces(64);
    ASSERT_TRUE(writeCubeDepthMap(path, faces, diag));
    auto map = ShadowMap::open(path, diag);
    ASSERT_TRUE(map);
    ASSERT_TRUE(map->isCube());
    for (int f = 0; f < 6; ++f) {
        const ShadowMap& face = map->face(f);
        EXPECT_TRUE(face.lightFromWorld() == faces[size_t(f)].lightFromWorld);
        for (int y = 0; y < 64; y += 7)
            for (int x = 0; x < 64; x += 5) ASSERT_EQ(face.texel(x, y), faces[size_t(f)].at(x, y));
    }
    MapInfo info = map->info();
    EXPECT_EQ(info.faces, 6);
    EXPECT_EQ(info.rawBytes, 6u * 64u * 64u * 4u);
    EXPECT_EQ(info.tileCount, 6 * 4);

    struct Case {
        Vec3 offset;  // from the light
        float shadowed;
    };
    const Case cases[] = {
        {{20, 0.5f, -0.5f}, 1},  // +x wall behind the first occluder
        {{20, 15, 0}, 0},        // +x wall, clear
        {{-20, 0, 0}, 0},        // -x wall
        {{0.5f, -20, 0}, 1},     // -y wall behind the second occluder
        {{12, -20, 0}, 0},       // -y wall, clear
        {{3, 20, -4}, 0},        // +y wall
        {{-5, 6, 20}, 0},        // +z wall
        {{4, -3, -20}, 0},       // -z wall
        {{3, 0.5f, 1}, 0},       // in front of the first occluder
    };
    std::vector<Vec3> P, du, dv;
    for (const Case& c : cases) {
        P.push_back(kLight + c.offset);
        du.push_back(Vec3(0.05f, 0, 0));
        dv.push_back(Vec3(0, 0, 0.05f));
    }
    ShadowBatch b;
    b.count = int(P.size());
    b.P = P.data();
    b.dPdu_du = du.data();
    b.dPdv_dv = dv.data();
    ShadowParams params;
    params.bias = 0.05f;
    std::vector<float> out(P.size()), point(P.size());
    ShadowStats st;
    map->lookup(b, params, out.data(), st);
    map->lookupPoint(b, params, point.data(), st);
    for (size_t i = 0; i < P.size(); ++i) {
        EXPECT_EQ(out[i], cases[i].shadowed) << i;
        EXPECT_EQ(point[i], cases[i].shadowed) << i;
    }
    EXPECT_EQ(st.points, 2 * P.size());

    // Other tools see six subimages.
    auto in = OIIO::ImageInput::open(path);
    ASSERT_TRUE(in) << OIIO::geterror();
    int subimages = 0;
    while (in->seek_subimage(subimages, 0)) ++subimages;
    EXPECT_EQ(subimages, 6);
}

TEST(CubeMap, FromMemoryEqualsTheFileAndWaitsForItForUncachedTiles) {
    auto faces = cubeFaces(64);
    // Points all around the light, a little nearer and farther than the
    // walls and occluders they lie on or behind.
    std::vector<Vec3> P, du, dv;
    for (int i = 0; i < 2000; ++i) {
        const float a = float(i) * 2.39996f, h = 1.0f - 2.0f * (float(i) + 0.5f) / 2000.0f;
        const float r = std::sqrt(1.0f - h * h);
        const Vec3 D(r * std::cos(a), h, r * std::sin(a));
        const float t = sceneDepth(D / std::max({std::abs(D.x), std::abs(D.y), std::abs(D.z)})) /
                        std::max({std::abs(D.x), std::abs(D.y), std::abs(D.z)});
        P.push_back(kLight + D * (t * (i % 2 ? 1.02f : 0.98f)));
        du.push_back(Vec3(0.05f, 0, 0));
        dv.push_back(Vec3(0, 0, 0.05f));
    }
    ShadowParams params;
    params.bias = 0.05f;

    for (bool cacheAll : {true, false}) {
        SCOPED_TRACE(cacheAll ? "every tile cached" : "some tiles cached");
        Diagnostics diag;
        const std::string path = test::scratchFile(cacheAll ? "cube-memory.exr" : "cube-late.exr");
        // Too small for all 24 tiles: some are read from the file.
        auto cache = cacheAll ? std::make_shared<TileCache>() : std::make_shared<TileCache>(64 << 10);
        std::promise<bool> written;
        bool everyTileCached = !cacheAll;
        auto memory =
            ShadowMap::fromCubeImages(faces, path, written.get_future().share(), diag, {}, cache, &everyTileCached);
        ASSERT_TRUE(memory);
        ASSERT_TRUE(memory->isCube());
        EXPECT_EQ(everyTileCached, cacheAll);
        std::thread writer([&] {
            std::this_thread::sleep_for(std::chrono::milliseconds(cacheAll ? 0 : 50));
            written.set_value(writeCubeDepthMap(path, faces, diag));
        });
        test::Lookups a = test::lookUp(*memory, P, du, dv, params);
        writer.join();
        auto file = ShadowMap::open(path, diag, {}, std::make_shared<TileCache>());
        ASSERT_TRUE(file);
        test::expectSameLookups(a, test::lookUp(*file, P, du, dv, params));
        EXPECT_GT(std::count(a.filtered.begin(), a.filtered.end(), 1.0f), 50);
        EXPECT_GT(std::count(a.filtered.begin(), a.filtered.end(), 0.0f), 50);
        for (int f = 0; f < 6; ++f) test::expectSameMap(memory->face(f), file->face(f));
        test::expectSameInfo(memory->info(), file->info());
        EXPECT_EQ(cache->stats().tilesRead == 0, cacheAll);
        EXPECT_EQ(diag.errorCount(), 0);
    }
}

}  // namespace
}  // namespace umbra
