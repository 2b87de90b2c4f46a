// Bicubic PatchMeshes diced in blocks of patches (geometry/patch.h,
// BicubicBlock) against the same meshes diced patch by patch
// (Attribute "umbra" "patchblock" [0]): the same surface, so the same
// image within what a different dicing rate may change along silhouettes
// and shading, with far fewer grids.

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

// Control points of an n x n torus (major radius 1, minor 0.35), u fastest.
std::string torusPoints(int n) {
    std::string out;
    for (int j = 0; j < n; ++j) {
        const double phi = 2 * M_PI * j / n;
        for (int i = 0; i < n; ++i) {
            const double theta = 2 * M_PI * i / n, r = 1 + 0.35 * std::cos(phi);
            out += fmt::format("{} {} {} ", r * std::cos(theta), r * std::sin(theta), 0.35 * std::sin(phi));
        }
    }
    return out;
}

// A wavy nonperiodic sheet of nu x nv control points over [-1.5, 1.5]^2.
std::string sheetPoints(int nu, int nv) {
    std::string out;
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i < nu; ++i) {
            const double x = -1.5 + 3.0 * i / (nu - 1), y = -1.5 + 3.0 * j / (nv - 1);
            out += fmt::format("{} {} {} ", x, y, 0.25 * std::sin(2.5 * x) * std::cos(1.5 * y));
        }
    return out;
}

std::string frame(const std::string& out, int patchBlock, const std::string& world, const std::string& options = "") {
    return fmt::format(R"(
Display "{}" "openexr" "rgba" "string type" "float"
Format {} {} 1
PixelSamples 4 4
PixelFilter "box" 1 1
ShadingRate 1
Projection "perspective" "fov" [40]
{}
Translate 0 0 5
WorldBegin
LightSource "ambientlight" 1 "intensity" [0.2]
LightSource "distantlight" 2 "from" [1 2 -2] "to" [0 0 0]
Attribute "umbra" "patchblock" [{}]
Surface "plastic"
Rotate 60 1 0.3 0
{}
WorldEnd
)", out, kRes, kRes, options, patchBlock, world);
}

struct Rendered {
    Image image;
    long grids = 0;
};

Rendered renderMesh(const ScratchDir& dir, const std::string& world, int patchBlock, const std::string& options = "") {
    Diagnostics diag;
    diag.setRecord(true);
    Rendered r;
    const std::string path = dir.file(fmt::format("out{}.exr", patchBlock));
    const auto stats = test::renderRib(frame(path, patchBlock, world, options), diag);
    EXPECT_EQ(diag.errorCount(), 0);
    EXPECT_TRUE(test::readImage(path, &r.image));
    r.grids = stats["frames"][0]["passes"].back()["counts"]["grids"].get<long>();
    return r;
}

// Blocks against patch by patch: coverage (alpha) within 0.3% and every
// channel within a mean of 0.004 (8-bit: one level) per pixel.
void expectSameImage(const Rendered& blocks, const Rendered& patches) {
    const double aBlocks = blocks.image.channelSum(3), aPatches = patches.image.channelSum(3);
    ASSERT_GT(aPatches, 0.05 * kRes * kRes);  // the surface is on screen
    EXPECT_NEAR(aBlocks / aPatches, 1.0, 3e-3) << aBlocks << " vs " << aPatches;
    EXPECT_LT(test::meanAbsDiff(blocks.image, patches.image), 4e-3);
}

}  // namespace

TEST(PatchBlocks, PeriodicBSplineTorusMatchesPatchByPatch) {
    // 24 x 24 periodic B-spline patches: 3 x 3 blocks of 8 x 8.
    ScratchDir dir("patch-blocks-torus");
    const std::string world = "Basis \"b-spline\" 1 \"b-spline\" 1\nPatchMesh \"bicubic\" 24 \"periodic\" 24 "
                              "\"periodic\" \"P\" [" + torusPoints(24) + "]\n";
    const Rendered blocks = renderMesh(dir, world, 8), patches = renderMesh(dir, world, 0);
    expectSameImage(blocks, patches);
    // Most of the 576 patches are a grid of their own (the rest are culled
    // or hidden); the 9 blocks split only where one is too big for a grid.
    EXPECT_GE(patches.grids, 400);
    EXPECT_LT(blocks.grids * 3, patches.grids);
}

TEST(PatchBlocks, DisplacedBezierSheetMatchesPatchByPatch) {
    // 10 x 10 Bezier patches (31 x 31 control points, step 3), displaced by
    // a shader reading P and N only; the displacement bound pads both alike.
    ScratchDir dir("patch-blocks-displaced");
    {
        std::ofstream sl(dir.file("ripple.sl"));
        sl << "displacement ripple(float Km = 0.04; float freq = 9) {\n"
              "    point Po = transform(\"object\", P);\n"
              "    P += Km * sin(freq * xcomp(Po)) * cos(freq * ycomp(Po)) * normalize(N);\n"
              "    N = calculatenormal(P);\n"
              "}\n";
    }
    const std::string world = "Attribute \"displacementbound\" \"sphere\" [0.04]\nDisplacement \"ripple\"\n"
                              "PatchMesh \"bicubic\" 31 \"nonperiodic\" 31 \"nonperiodic\" \"P\" [" +
                              sheetPoints(31, 31) + "]\n";
    const std::string options = fmt::format("Option \"searchpath\" \"shader\" [\"{}:&\"]", dir.file(""));
    const Rendered blocks = renderMesh(dir, world, 8, options), patches = renderMesh(dir, world, 0, options);
    expectSameImage(blocks, patches);
    EXPECT_LT(blocks.grids, patches.grids);
}

TEST(PatchBlocks, VaryingAndVertexColoursMatchPatchByPatch) {
    // Cs per patch corner (varying) and a vertex-class "Os"-free colour
    // through Cs of a second mesh: both must be interpolated as the
    // patches do it one by one.
    ScratchDir dir("patch-blocks-vars");
    std::string cs;
    for (int j = 0; j <= 9; ++j)
        for (int i = 0; i <= 9; ++i) cs += fmt::format("{} {} {} ", i / 9.0, j / 9.0, (i + j) % 2);
    std::string vertexCs;
    for (int j = 0; j < 12; ++j)
        for (int i = 0; i < 12; ++i) vertexCs += fmt::format("{} {} 0.5 ", i / 11.0, 1 - j / 11.0);
    const std::string world =
        "Basis \"catmull-rom\" 1 \"catmull-rom\" 1\n"
        "AttributeBegin\nTranslate -0.8 0 0\nScale 0.5 0.5 0.5\nPatchMesh \"bicubic\" 12 \"nonperiodic\" 12 "
        "\"nonperiodic\" \"P\" [" + sheetPoints(12, 12) + "] \"varying color Cs\" [" + cs + "]\nAttributeEnd\n"
        "AttributeBegin\nTranslate 0.8 0 0\nScale 0.5 0.5 0.5\nPatchMesh \"bicubic\" 12 \"nonperiodic\" 12 "
        "\"nonperiodic\" \"P\" [" + sheetPoints(12, 12) + "] \"vertex color Cs\" [" + vertexCs + "]\nAttributeEnd\n";
    const Rendered blocks = renderMesh(dir, world, 8), patches = renderMesh(dir, world, 0);
    expectSameImage(blocks, patches);
}
