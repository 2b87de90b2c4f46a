// Displacement along N of surfaces split into many grids, as the
// RenderMan books displace patches, NURBS and subdivision meshes: a
// constant offset along a continuous normal is a continuous surface, so
// no background may show through inside its outline. Grids that shared an
// edge once gave its vertices different normals (each took differences
// from its own side) and the displaced edges parted along every seam.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <fstream>

using namespace umbra;
using umbra::test::Image;
using umbra::test::ScratchDir;

namespace {

constexpr const char* kOffset = R"(
displacement offset(float amount = 0.1)
{
    P += amount * normalize(N);
    N = calculatenormal(P);
}
)";

/// A 160 x 160 orthographic view of [-1, 1]^2 of `geometry`, offset by
/// 0.06 along its normals (a bound of that), at shading rate `rate`.
std::string sceneRib(const ScratchDir& dir, const std::string& image, const std::string& geometry, float rate) {
    return fmt::format(R"(Option "searchpath" "shader" ["{}:&"]
Format 160 160 1
PixelSamples 4 4
PixelFilter "box" 1 1
ShadingRate {}
Display "{}" "file" "rgba"
Projection "orthographic"
ScreenWindow -1 1 -1 1
Translate 0 0 5
WorldBegin
  Surface "constant"
  Attribute "displacementbound" "sphere" [0.06]
  Displacement "offset" "amount" [0.06]
  {}
WorldEnd
)",
                       dir.file(""), rate, image, geometry);
}

/// Pixels of [x0, x1) x [y0, y1) not wholly covered.
int holes(const Image& img, int x0, int x1, int y0, int y1) {
    int n = 0;
    for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) n += img.at(x, y, 3) < 0.999f;
    return n;
}

struct Case {
    const char* name;
    std::string geometry;
    int x0, x1, y0, y1;  // a box of pixels inside the outline
};

std::vector<Case> cases() {
    std::vector<Case> out;
    // A dome: one bicubic Bezier patch, its inner control points sunk.
    out.push_back({"dome", R"(Patch "bicubic" "P" [-.7 .7 0  -.25 .7 0  .25 .7 0  .7 .7 0
                     -.7 .25 0  -.25 .25 -.4  .25 .25 -.4  .7 .25 0
                     -.7 -.25 0  -.25 -.25 -.4  .25 -.25 -.4  .7 -.25 0
                     -.7 -.7 0  -.25 -.7 0  .25 -.7 0  .7 -.7 0])",
                   35, 125, 35, 125});
    // A tube: a periodic B-spline PatchMesh, a ring of 8 points around the
    // view axis' perpendicular, 5 rows along y, its front half facing us.
    std::string ring;
    for (int row = 0; row < 5; ++row)
        for (int k = 0; k < 8; ++k) {
            const double a = 2 * M_PI * k / 8;
            ring += fmt::format(" {} {} {}", 0.6 * std::cos(a), -0.9 + 0.45 * row, 0.6 * std::sin(a));
        }
    out.push_back({"tube", "Basis \"b-spline\" 1 \"b-spline\" 1\nPatchMesh \"bicubic\" 8 \"periodic\" 5 "
                           "\"nonperiodic\" \"P\" [" + ring + "]",
                   50, 110, 60, 100});
    // A cylinder: a rational quadratic NuPatch (the circle as nine weighted
    // points), linear along y.
    std::string circle;
    const double w = std::sqrt(0.5);
    const double cx[9] = {1, 1, 0, -1, -1, -1, 0, 1, 1}, cz[9] = {0, 1, 1, 1, 0, -1, -1, -1, 0};
    for (double y : {-0.8, 0.8})
        for (int k = 0; k < 9; ++k) {
            const double wk = k % 2 ? w : 1;
            circle += fmt::format(" {} {} {} {}", 0.6 * cx[k] * wk, y * wk, 0.6 * cz[k] * wk, wk);
        }
    out.push_back({"cylinder", "NuPatch 9 3 [0 0 0 .25 .25 .5 .5 .75 .75 1 1 1] 0 1 2 2 [0 0 1 1] 0 1 \"Pw\" [" +
                                   circle + "]",
                   50, 110, 30, 130});
    // A bumpy Catmull-Clark sheet of 10 x 10 faces: regular faces are
    // diced in blocks, the boundary's one by one.
    std::string verts, indices, counts;
    for (int j = 0; j <= 10; ++j)
        for (int i = 0; i <= 10; ++i)
            verts += fmt::format(" {} {} {}", -0.9 + 0.18 * i, -0.9 + 0.18 * j,
                                 -0.2 * std::sin(0.6 * i) * std::cos(0.5 * j));
    for (int j = 0; j < 10; ++j)
        for (int i = 0; i < 10; ++i) {
            const int v = j * 11 + i;
            counts += " 4";
            indices += fmt::format(" {} {} {} {}", v, v + 1, v + 12, v + 11);
        }
    out.push_back({"sheet", "SubdivisionMesh \"catmull-clark\" [" + counts + "] [" + indices +
                                "] [\"interpolateboundary\"] [0 0] [] [] \"P\" [" + verts + "]",
                   35, 125, 35, 125});
    return out;
}

}  // namespace

TEST(DisplacedSeams, AConstantOffsetLeavesNoHolesAtAnyShadingRate) {
    ScratchDir dir("displaced-seams");
    std::ofstream(dir.file("offset.sl")) << kOffset;
    for (const Case& c : cases())
        for (float rate : {0.5f, 2.0f, 8.0f}) {
            const std::string image = dir.file(fmt::format("{}-{}.tif", c.name, rate));
            Diagnostics diag;
            diag.setQuiet(true);
            const Image img = test::renderImage(sceneRib(dir, image, c.geometry, rate), image, diag);
            ASSERT_EQ(diag.errorCount(), 0) << c.name;
            ASSERT_EQ(img.width, 160) << c.name;
            EXPECT_GT(img.channelSum(3), double((c.x1 - c.x0) * (c.y1 - c.y0))) << c.name;
            EXPECT_EQ(holes(img, c.x0, c.x1, c.y0, c.y1), 0) << c.name << " at shading rate " << rate;
        }
}
