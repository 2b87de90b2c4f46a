// Catmull-Clark meshes whose regular regions dice as bicubic blocks
// (makeSubdivisionMesh, geometry/subdivision.h) against the same meshes
// diced face by face (Attribute "umbra" "patchblock" [0]); and the
// shaders that keep a mesh face by face.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <fstream>

using namespace umbra;
using umbra::test::Image;
using umbra::test::ScratchDir;

namespace {

constexpr int kRes = 160;

std::string torusMesh(int n) {
    std::string P, nverts, verts;
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const double theta = 2 * M_PI * i / n, phi = 2 * M_PI * j / n, r = 1 + 0.35 * std::cos(phi);
            P += fmt::format("{} {} {} ", r * std::cos(theta), r * std::sin(theta), 0.35 * std::sin(phi));
            auto at = [n](int a, int b) { return (b % n) * n + a % n; };
            nverts += "4 ";
            verts += fmt::format("{} {} {} {} ", at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
        }
    return fmt::format("SubdivisionMesh \"catmull-clark\" [{}] [{}] [] [] [] [] \"P\" [{}]\n", nverts, verts, P);
}

struct Rendered {
    Image image;
    long grids = 0;
};

Rendered renderTorus(const ScratchDir& dir, int patchBlock, const std::string& shading, int threads = 0) {
    const std::string path = dir.file(fmt::format("out{}.exr", patchBlock));
    const std::string rib = fmt::format(R"(
Display "{}" "openexr" "rgba" "string type" "float"
Format {} {} 1
PixelSamples 4 4
PixelFilter "box" 1 1
ShadingRate 1
Projection "perspective" "fov" [40]
Option "searchpath" "shader" ["{}:&"]
Translate 0 0 5
WorldBegin
LightSource "ambientlight" 1 "intensity" [0.2]
LightSource "distantlight" 2 "from" [1 2 -2] "to" [0 0 0]
Attribute "umbra" "patchblock" [{}]
{}
Rotate 60 1 0.3 0
{}
WorldEnd
)", path, kRes, kRes, dir.file(""), patchBlock, shading, torusMesh(24));
    Diagnostics diag;
    diag.setRecord(true);
    Rendered r;
    const auto stats = test::renderRib(rib, diag, threads);
    EXPECT_EQ(diag.errorCount(), 0);
    EXPECT_TRUE(test::readImage(path, &r.image));
    r.grids = stats["frames"][0]["passes"].back()["counts"]["grids"].get<long>();
    return r;
}

}  // namespace

TEST(SubdivisionBlocks, RegularTorusMatchesFaceByFace) {
    // 24 x 24 regular quads: 9 blocks of 8 x 8 faces. Same surface, so the
    // same image within what another dicing changes (coverage within
    // 0.3%, a mean of 0.004 a channel); far fewer grids.
    ScratchDir dir("subdiv-blocks-torus");
    const Rendered blocks = renderTorus(dir, 8, "Surface \"plastic\""),
                   faces = renderTorus(dir, 0, "Surface \"plastic\"");
    const double aBlocks = blocks.image.channelSum(3), aFaces = faces.image.channelSum(3);
    ASSERT_GT(aFaces, 0.05 * kRes * kRes);
    EXPECT_NEAR(aBlocks / aFaces, 1.0, 3e-3) << aBlocks << " vs " << aFaces;
    EXPECT_LT(test::meanAbsDiff(blocks.image, faces.image), 4e-3);
    EXPECT_GE(faces.grids, 400);
    EXPECT_LT(blocks.grids * 3, faces.grids);
}

TEST(SubdivisionBlocks, ShadersThatCouldTellKeepFaces) {
    // A surface reading s and t, or a displacement: the mesh dices face by
    // face whatever the patchblock attribute, so the pixels and the grids
    // are the same (one thread: which grids occlusion culling saves
    // depends on the order buckets finish in).
    ScratchDir dir("subdiv-blocks-readers");
    {
        std::ofstream(dir.file("stripes.sl")) << "surface stripes() { Ci = Cs * mod(floor(8 * s) + floor(8 * t), 2); }\n";
        std::ofstream(dir.file("bump.sl")) << "displacement bump() { P += 0.01 * normalize(N); N = calculatenormal(P); }\n";
    }
    for (const std::string shading : {"Surface \"stripes\"",
                                      "Surface \"plastic\"\nAttribute \"displacementbound\" \"sphere\" [0.01]\n"
                                      "Displacement \"bump\""}) {
        const Rendered blocks = renderTorus(dir, 8, shading, 1), faces = renderTorus(dir, 0, shading, 1);
        EXPECT_EQ(blocks.grids, faces.grids) << shading;
        EXPECT_EQ(test::maxAbsDiff(blocks.image, faces.image, 4), 0.0) << shading;
    }
}
