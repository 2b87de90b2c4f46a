// Depth layers of light-view depth frames: the stored value of each depth
// filter (min, second, midpoint, dual) against the exact depths of planes
// parallel to an orthographic view, and depth-pass culling of Sides 1
// solids only.

#include "support/render_harness.h"
#include "umbra/shadow/shadow_map.h"
#include "umbra/shadow/tile_cache.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <limits>

using namespace umbra;
using umbra::test::ScratchDir;

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

/// An orthographic 32x32 depth frame of [-2,2]^2 looking down +z from
/// z = -5, so world z = 0 is at depth 5 and z = 1 at depth 6. Raster
/// column c has its centre at world x = -2 + (c + 0.5) / 8.
std::string depthFrame(const std::string& out, const std::string& filter, const std::string& cull, float offset,
                       const std::string& world) {
    return fmt::format(R"(
Display "{}" "shadow" "z"
Format 32 32 1
ScreenWindow -2 2 -2 2
Projection "orthographic"
Option "umbra" "depthfilter" ["{}"]
Option "umbra" "depthcull" ["{}"]
Option "umbra" "dualoffset" [{}]
Translate 0 0 5
WorldBegin
{}
WorldEnd
)",
                       out, filter, cull, offset, world);
}

/// Renders `world` as a depth frame and reads texels (x, 16) for the
/// given columns.
std::vector<float> depthRow(const std::string& name, const std::string& filter, const std::string& cull, float offset,
                            const std::string& world, const std::vector<int>& columns) {
    ScratchDir dir(name);
    Diagnostics diag;
    test::renderRib(depthFrame(dir.file("d.shd"), filter, cull, offset, world), diag);
    EXPECT_EQ(diag.errorCount(), 0);
    auto map = ShadowMap::open(dir.file("d.shd"), diag, {}, std::make_shared<TileCache>());
    std::vector<float> out;
    if (!map) {
        ADD_FAILURE() << "no map written";
        return std::vector<float>(columns.size(), -1.0f);
    }
    EXPECT_EQ(map->width(), 32);
    for (int c : columns) out.push_back(map->texel(c, 16));
    return out;
}

// Two stacked planes: the near one (depth 5) covers x in [-2, 0], the far
// one (depth 6) x in [-2, 1]; nothing covers x > 1. Columns 4, 20 and 28
// sit at x = -1.44 (two layers), 0.56 (far plane alone) and 1.56 (empty).
const char* kStackedPlanes = R"(
    Polygon "P" [-2 -2 0  0 -2 0  0 2 0  -2 2 0]
    Polygon "P" [-2 -2 1  1 -2 1  1 2 1  -2 2 1]
)";
const std::vector<int> kColumns = {4, 20, 28};

// A closed unit-half-size box, z in [0, 1], wound so that its outward
// normals are (v1-v0) x (v2-v0) in a right-handed frame: the winding the
// study's solids use (scenes/quality/make_scenes.py).
std::string box(int sides) {
    return fmt::format(R"(
    Sides {}
    Polygon "P" [-1 -1 0  -1 1 0  1 1 0  1 -1 0]
    Polygon "P" [-1 -1 1  1 -1 1  1 1 1  -1 1 1]
    Polygon "P" [-1 -1 0  1 -1 0  1 -1 1  -1 -1 1]
    Polygon "P" [-1 1 0  -1 1 1  1 1 1  1 1 0]
    Polygon "P" [-1 -1 0  -1 -1 1  -1 1 1  -1 1 0]
    Polygon "P" [1 -1 0  1 1 0  1 1 1  1 -1 1]
)",
                       sides);
}

}  // namespace

TEST(DepthLayers, MinKeepsNearestLayer) {
    auto z = depthRow("layers-min", "min", "none", 0.05f, kStackedPlanes, kColumns);
    EXPECT_FLOAT_EQ(z[0], 5.0f);
    EXPECT_FLOAT_EQ(z[1], 6.0f);
    EXPECT_EQ(z[2], kInf);
}

TEST(DepthLayers, SecondKeepsSecondLayerAndInfinityForOne) {
    // One-sided surfaces (culling off): each is one layer.
    auto z = depthRow("layers-second", "second", "none", 0.05f, std::string("Sides 1\n") + kStackedPlanes, kColumns);
    EXPECT_FLOAT_EQ(z[0], 6.0f);
    EXPECT_EQ(z[1], kInf);  // nothing behind the far plane
    EXPECT_EQ(z[2], kInf);
}

TEST(DepthLayers, SecondTreatsOpenSurfacesAsTheirOwnSecondLayer) {
    // Two-sided surfaces are solids of no thickness (Wang & Molnar §3.3):
    // the nearest is also the second layer, so it casts shadows.
    auto z = depthRow("layers-second-open", "second", "none", 0.05f, kStackedPlanes, kColumns);
    EXPECT_FLOAT_EQ(z[0], 5.0f);
    EXPECT_FLOAT_EQ(z[1], 6.0f);
    EXPECT_EQ(z[2], kInf);
    // A one-sided plane in front of a two-sided one: the second layer is the
    // two-sided plane.
    z = depthRow("layers-second-mixed", "second", "none", 0.05f,
                 "AttributeBegin Sides 1 Polygon \"P\" [-2 -2 0  0 -2 0  0 2 0  -2 2 0] AttributeEnd\n"
                 "Polygon \"P\" [-2 -2 1  1 -2 1  1 2 1  -2 2 1]\n",
                 kColumns);
    EXPECT_FLOAT_EQ(z[0], 6.0f);
    EXPECT_FLOAT_EQ(z[1], 6.0f);
}

TEST(DepthLayers, MidpointAveragesLayers) {
    const float offset = 0.25f;
    auto z = depthRow("layers-mid", "midpoint", "none", offset, kStackedPlanes, kColumns);
    EXPECT_FLOAT_EQ(z[0], 0.5f * (5.0f + 6.0f));
    EXPECT_FLOAT_EQ(z[1], 6.0f + offset);  // single layer: z1 + dualoffset
    EXPECT_EQ(z[2], kInf);
}

TEST(DepthLayers, DualClampsHalfGapByOffset) {
    // Offset smaller than half the gap: z1 + offset.
    auto z = depthRow("layers-dual-small", "dual", "none", 0.2f, kStackedPlanes, kColumns);
    EXPECT_FLOAT_EQ(z[0], 5.0f + std::min(0.5f * (6.0f - 5.0f), 0.2f));
    EXPECT_FLOAT_EQ(z[1], 6.0f + 0.2f);
    EXPECT_EQ(z[2], kInf);
    // Offset larger than half the gap: the midpoint.
    z = depthRow("layers-dual-large", "dual", "none", 2.0f, kStackedPlanes, kColumns);
    EXPECT_FLOAT_EQ(z[0], 5.5f);
    EXPECT_FLOAT_EQ(z[1], 6.0f + 2.0f);
}

TEST(DepthLayers, CullingDropsFacesOfOneSidedSolidsOnly) {
    // Column 16 is x = 0.06, inside the box: its near face is at depth 5,
    // its far face at depth 6; column 28 misses it.
    const std::vector<int> cols = {16, 28};
    auto none = depthRow("cull-none", "min", "none", 0.05f, box(1), cols);
    EXPECT_FLOAT_EQ(none[0], 5.0f);
    EXPECT_EQ(none[1], kInf);
    // Front (light-facing) culling leaves the far, back-facing face.
    auto front = depthRow("cull-front", "min", "front", 0.05f, box(1), cols);
    EXPECT_FLOAT_EQ(front[0], 6.0f);
    // Back culling leaves the near face.
    auto back = depthRow("cull-back", "min", "back", 0.05f, box(1), cols);
    EXPECT_FLOAT_EQ(back[0], 5.0f);
    // The same box two-sided is never culled: both layers stay.
    auto twoSided = depthRow("cull-front-2", "min", "front", 0.05f, box(2), cols);
    EXPECT_FLOAT_EQ(twoSided[0], 5.0f);
    // With front culling the pass has already removed the first layer of
    // solids, so "second" stores the nearest remaining surface: for a
    // two-sided (unculled) box that is its near face, which the lookup's
    // virtual samples keep from shadowing itself.
    auto twoSidedSecond = depthRow("cull-front-2s", "second", "front", 0.05f, box(2), cols);
    EXPECT_FLOAT_EQ(twoSidedSecond[0], 5.0f);
    auto oneSidedSecond = depthRow("cull-front-1s", "second", "front", 0.05f, box(1), cols);
    EXPECT_FLOAT_EQ(oneSidedSecond[0], 6.0f);
    // One-sided, no culling: the second layer is the far face.
    auto second = depthRow("cull-none-2s", "second", "none", 0.05f, box(1), cols);
    EXPECT_FLOAT_EQ(second[0], 6.0f);
}
