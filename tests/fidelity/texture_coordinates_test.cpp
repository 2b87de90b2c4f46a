// TextureCoordinates: the default s and t of a parametric primitive (a
// quadric, a patch, a patch mesh, a NURBS) given no "s", "t" or "st" are its
// (u, v) mapped bilinearly onto the four (s, t) pairs of the current
// TextureCoordinates (RI Spec 3.2, section 4.1.3), as Aqsis's regression
// scene content/Test/mod_st_test.rib uses them. Once stored and never used:
// every surface showed s = u, t = v, with no message. Each primitive is
// checked against the same primitive given those corner values as an
// explicit varying "st", which RenderMan interpolates the same bilinear way.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <fstream>

using namespace umbra;
using umbra::test::Image;
using umbra::test::maxAbsDiff;
using umbra::test::ScratchDir;

namespace {

constexpr const char* kShowSt = "surface showst() { Ci = color(s, t, 0); Oi = 1; }\n";
// Four different corners, so a swapped or ignored corner shows.
constexpr const char* kCorners = "0.2 0.1  0.9 0.3  0.1 0.8  0.7 1.0";

Image renderSt(const ScratchDir& dir, const std::string& name, const std::string& world) {
    const std::string image = dir.file(name + ".tif");
    const std::string rib = fmt::format(R"(
Option "searchpath" "shader" ["{}:&"]
Format 64 64 1
PixelSamples 2 2
Display "{}" "file" "rgb"
Projection "orthographic"
ScreenWindow -1.2 1.2 -1.2 1.2
WorldBegin
Translate 0 0 5
Surface "showst"
{}
WorldEnd
)",
                                        dir.file(""), image, world);
    Diagnostics diag;
    diag.setQuiet(true);
    Image img = test::renderImage(rib, image, diag);
    EXPECT_EQ(diag.errorCount(), 0);
    return img;
}

}  // namespace

TEST(TextureCoordinates, MapTheDefaultStOfParametricPrimitives) {
    ScratchDir dir("texcoords");
    std::ofstream(dir.file("showst.sl")) << kShowSt;
    struct Case {
        const char* name;
        const char* prim;  // the primitive, without parameters
        const char* extra;  // its parameter list before "st", if any
    };
    const Case cases[] = {
        {"patch", "Patch \"bilinear\"", "\"P\" [-1 -1 0  1 -1 0  -1 1 0  1 1 0]"},
        {"disk", "Disk 0 1 360", ""},
        {"sphere", "Sphere 1 -1 1 360", ""},
        {"cylinder", "Rotate 90 1 0 0 Cylinder 1 -1 1 360", ""},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.name);
        Image mapped = renderSt(dir, std::string(c.name) + "_mapped",
                              fmt::format("TextureCoordinates {}\n{} {}", kCorners, c.prim, c.extra));
        Image plain = renderSt(dir, std::string(c.name) + "_plain",
                             fmt::format("{} {} \"varying float[2] st\" [{}]", c.prim, c.extra, kCorners));
        ASSERT_EQ(mapped.width, 64);
        ASSERT_EQ(plain.width, 64);
        // Something was drawn, and s is not u: the corners' s stay in [0.1, 0.9].
        EXPECT_GT(plain.channelSum(0), 64.0 * 64 * 0.1 * 0.5);
        EXPECT_LT(maxAbsDiff(mapped, plain, 3), 0.02f);
    }
    // The default TextureCoordinates leave s = u, t = v: a patch's corner
    // pixel (u, v near (0, 0), raster bottom-left) is black, the top-right white-ish.
    Image identity = renderSt(dir, "identity", "Patch \"bilinear\" \"P\" [-1 -1 0  1 -1 0  -1 1 0  1 1 0]");
    EXPECT_LT(identity.at(7, 56, 0), 0.1f);
    EXPECT_GT(identity.at(56, 7, 0), 0.9f);
}
