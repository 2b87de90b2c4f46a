// GeometricApproximation "flatness" (RI Spec 3.2: the greatest distance, in
// raster pixels, between the true surface and its polygonal approximation)
// at a coarse ShadingRate: a sphere's disc must cover the closed-form area
// within what a polygon inscribed to half a pixel can lose, for every
// family that dices (a quadric, a bicubic patch mesh, a NURBS surface); a
// flat surface is diced exactly as without it.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>

using namespace umbra;
using umbra::test::Image;
using umbra::test::ScratchDir;

namespace {

constexpr int kSize = 128;
constexpr double kPiD = 3.14159265358979;

struct Rendered {
    double area = 0;              // covered pixels: the sum of alpha
    uint64_t micropolygons = 0;   // camera pass
};

Rendered renderScene(const ScratchDir& dir, const std::string& camera, const std::string& attributes,
                const std::string& world) {
    const std::string image = dir.file("flat.tif");
    const std::string rib = fmt::format(R"(
Format {0} {0} 1
PixelSamples 4 4
PixelFilter "box" 1 1
Quantize "rgba" 0 0 0 0
Display "{1}" "file" "rgba"
{2}
ShadingRate 1000
{3}
WorldBegin
Surface "constant"
{4}
WorldEnd
)",
                                        kSize, image, camera, attributes, world);
    Diagnostics diag;
    diag.setQuiet(true);
    const nlohmann::json stats = test::renderRib(rib, diag);
    EXPECT_EQ(diag.errorCount(), 0);
    Image img;
    EXPECT_TRUE(test::readImage(image, &img));
    Rendered r;
    if (img.channels == 4) r.area = img.channelSum(3);
    r.micropolygons = stats["frames"][0]["passes"][0]["counts"]["micropolygons"].get<uint64_t>();
    return r;
}

// A sphere of radius 0.75 at z = 5 seen head on: orthographic (64 pixels a unit) or
// perspective (fov 40). Its outline is a circle of `radius` pixels.
struct View {
    const char* name;
    const char* camera;
    double radius;
};

const View kViews[] = {
    {"orthographic", "Projection \"orthographic\" ScreenWindow -1 1 -1 1", 0.75 * 64},
    // The outline's half angle is asin(R / d), so its radius is
    // tan(asin(0.75 / 5)) / tan(20 degrees) x 64 pixels.
    {"perspective", "Projection \"perspective\" \"fov\" 40",
     std::tan(std::asin(0.75 / 5)) / std::tan(20 * kPiD / 180) * 64},
};

// Sphere-like surfaces of radius 0.75 about the origin, each family's own.
struct Family {
    const char* name;
    const char* world;
    bool exact;  // the surface is the sphere itself; else its reference is its own render at ShadingRate 0.25
};

const Family kFamilies[] = {
    // Pole towards the camera (the outline is the u circle) and sideways
    // (half of it runs along v).
    {"sphere, pole on", "Translate 0 0 5 Sphere 0.75 -0.75 0.75 360", true},
    {"sphere, pole sideways", "Translate 0 0 5 Rotate 90 1 0 0 Sphere 0.75 -0.75 0.75 360", true},
    // A rational quadratic NURBS sphere (9 x 5 control points).
    {"NURBS sphere", R"(Translate 0 0 5 Scale 0.75 0.75 0.75
NuPatch 9 3 [0 0 0 0.25 0.25 0.5 0.5 0.75 0.75 1 1 1] 0 1
        5 3 [0 0 0 0.5 0.5 1 1 1] 0 1
 "Pw" [ 0 0 -1 1   0 0 -0.7071068 0.7071068   0 0 -1 1   0 0 -0.7071068 0.7071068   0 0 -1 1   0 0 -0.7071068 0.7071068   0 0 -1 1   0 0 -0.7071068 0.7071068   0 0 -1 1
        0.7071068 0 -0.7071068 0.7071068  0.5 0.5 -0.5 0.5  0 0.7071068 -0.7071068 0.7071068  -0.5 0.5 -0.5 0.5  -0.7071068 0 -0.7071068 0.7071068  -0.5 -0.5 -0.5 0.5  0 -0.7071068 -0.7071068 0.7071068  0.5 -0.5 -0.5 0.5  0.7071068 0 -0.7071068 0.7071068
        1 0 0 1  0.7071068 0.7071068 0 0.7071068  0 1 0 1  -0.7071068 0.7071068 0 0.7071068  -1 0 0 1  -0.7071068 -0.7071068 0 0.7071068  0 -1 0 1  0.7071068 -0.7071068 0 0.7071068  1 0 0 1
        0.7071068 0 0.7071068 0.7071068  0.5 0.5 0.5 0.5  0 0.7071068 0.7071068 0.7071068  -0.5 0.5 0.5 0.5  -0.7071068 0 0.7071068 0.7071068  -0.5 -0.5 0.5 0.5  0 -0.7071068 0.7071068 0.7071068  0.5 -0.5 0.5 0.5  0.7071068 0 0.7071068 0.7071068
        0 0 1 1   0 0 0.7071068 0.7071068   0 0 1 1   0 0 0.7071068 0.7071068   0 0 1 1   0 0 0.7071068 0.7071068   0 0 1 1   0 0 0.7071068 0.7071068   0 0 1 1 ])",
     true},
    // A Catmull-Clark cube (its limit is a rounded box, not a sphere).
    {"subdivision cube", R"(Translate 0 0 5 Rotate 30 1 1 0 Scale 0.6 0.6 0.6
SubdivisionMesh "catmull-clark" [4 4 4 4 4 4]
  [0 1 3 2  2 3 5 4  4 5 7 6  6 7 1 0  1 7 5 3  6 0 2 4] [] [] [] []
  "P" [-1 -1 1  1 -1 1  -1 1 1  1 1 1  -1 1 -1  1 1 -1  -1 -1 -1  1 -1 -1])",
     false},
};

}  // namespace

TEST(Flatness, ACoarselyShadedSphereKeepsItsOutlineWithinTheFlatness) {
    // At ShadingRate 1000 (micropolygons about 32 pixels on a side) the
    // rate alone dices a sphere 48 pixels in radius into about ten facets
    // around: chords stand off it by more than a pixel and the disc loses
    // about 6% of its area. With flatness 0.5 every chord stands within
    // half a pixel of the surface, so the polygonal outline lies between
    // the circles of radius r and r - 0.5: the area is within
    // band = pi r^2 - pi (r - 0.5)^2 = pi (r - 0.25) of the closed form,
    // plus the sampling error of 16 samples a pixel along the outline
    // (allowed: 0.2% of the disc). Without flatness it must fall short
    // by more than twice the band.
    ScratchDir dir("flatness");
    for (const View& view : kViews)
        for (const Family& family : kFamilies) {
            SCOPED_TRACE(fmt::format("{}, {}", family.name, view.name));
            double r = view.radius;
            if (!family.exact) {
                // The reference outline: the surface diced to a quarter pixel,
                // whose chords stand off it by hundredths of a pixel; r is the
                // radius of a disc of its area.
                const Rendered fine = renderScene(dir, view.camera, "ShadingRate 0.25", family.world);
                r = std::sqrt(fine.area / kPiD);
            }
            const double disc = kPiD * r * r, band = kPiD * (r - 0.25), sampling = 0.002 * disc;
            const Rendered coarse = renderScene(dir, view.camera, "", family.world);
            const Rendered flat = renderScene(dir, view.camera, "GeometricApproximation \"flatness\" 0.5", family.world);
            EXPECT_LE(flat.area, disc + sampling);
            EXPECT_GE(flat.area, disc - band - sampling);
            // Without flatness the facets are plain (the test would fail).
            EXPECT_LT(coarse.area, disc - 2 * band - sampling);
            EXPECT_GT(flat.micropolygons, coarse.micropolygons);
        }
}

TEST(Flatness, FlatSurfacesAreDicedAsWithoutIt) {
    // A tilted polygon and a planar bilinear patch: nothing stands off a
    // plane, so flatness adds no micropolygon and changes no pixel.
    ScratchDir dir("flatness-plane");
    const char* worlds[] = {
        "Translate 0 0 5 Rotate 50 1 0.3 0 Polygon \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]",
        "Translate 0 0 5 Rotate 50 1 0.3 0 Patch \"bilinear\" \"P\" [-1 -1 0  1 -1 0.5  -1 1 -0.5  1 1 0]",
    };
    for (const View& view : kViews)
        for (const char* world : worlds) {
            SCOPED_TRACE(fmt::format("{}, {}", world, view.name));
            for (const char* rate : {"ShadingRate 1000", "ShadingRate 1"}) {
                const Rendered before = renderScene(dir, view.camera, rate, world);
                const Rendered after =
                    renderScene(dir, view.camera, std::string(rate) + " GeometricApproximation \"flatness\" 0.5", world);
                EXPECT_EQ(after.micropolygons, before.micropolygons) << rate;
                EXPECT_EQ(after.area, before.area) << rate;
                EXPECT_GT(before.area, 100);
            }
        }
}
