// End-to-end tests of the REYES core: coverage against closed-form
// projected areas, seams, determinism across threads and bucket layouts.

#include "support/render_harness.h"
#include "umbra/shadow/depth_image.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <fstream>

using namespace umbra;
using umbra::test::Image;
using umbra::test::ScratchDir;

namespace {

/// An orthographic view of [-2,2]^2 at 256x256 looking down +z, box filter
/// 1x1 so each pixel's alpha is the fraction of its samples covered.
std::string orthoFrame(const std::string& out, const std::string& world, int samples = 4, int res = 256) {
    return fmt::format(R"(
Display "{}" "openexr" "rgba" "string type" "float"
Format {} {} 1
ScreenWindow -2 2 -2 2
Projection "orthographic"
PixelSamples {} {}
PixelFilter "box" 1 1
ShadingRate 1
Translate 0 0 5
WorldBegin
{}
WorldEnd
)", out, res, res, samples, samples, world);
}

/// Covered area in world units of the rendered alpha channel.
double coveredArea(const Image& img) {
    double pixelArea = (4.0 / img.width) * (4.0 / img.height);
    return img.channelSum(3) * pixelArea;
}

double renderCoverage(const std::string& world, const std::string& name) {
    ScratchDir dir(name);
    Diagnostics diag;
    test::renderRib(orthoFrame(dir.file("out.exr"), world), diag);
    EXPECT_EQ(diag.errorCount(), 0);
    Image img;
    EXPECT_TRUE(test::readImage(dir.file("out.exr"), &img));
    return coveredArea(img);
}

/// `world` rendered in orthoFrame (2x2 samples, res x res) with the scratch
/// directory on the shader search path (its .sl files compiled on use) and
/// `options` before the frame.
Image renderWithShaders(const ScratchDir& dir, const std::string& options, const std::string& world,
                        Diagnostics& diag, int res = 64) {
    return test::renderImage(fmt::format("Option \"searchpath\" \"shader\" [\"{}:&\"]\n{}", dir.file(""), options) +
                                 orthoFrame(dir.file("out.exr"), world, 2, res),
                             dir.file("out.exr"), diag);
}

}  // namespace

TEST(Coverage, SphereMatchesProjectedDisk) {
    const double r = 1.5;
    double area = renderCoverage("Sphere 1.5 -1.5 1.5 360", "sphere");
    EXPECT_NEAR(area, M_PI * r * r, 0.005 * M_PI * r * r);
}

TEST(Coverage, ParaboloidFromBelowZeroIsDrawnFromZero) {
    // Paraboloid 1 -0.5 1 360: past z = 0 the radius sqrt(z / zmax) is not
    // real; Pixie and Aqsis draw the bowl from 0 to zmax, umbra refused the
    // whole primitive. Seen down its axis it covers the disc of rmax. The
    // side view (rotated onto the picture plane) covers the closed form
    // integral of 2 sqrt(z) over [0, 1], 4/3.
    EXPECT_NEAR(renderCoverage("Paraboloid 1 -0.5 1 360", "paraboloid-down"), M_PI, 0.005 * M_PI);
    EXPECT_NEAR(renderCoverage("Rotate -90 1 0 0 Translate 0 0 -0.5 Paraboloid 1 -0.5 1 360", "paraboloid-side"),
                4.0 / 3.0, 0.01 * 4.0 / 3.0);
}

TEST(Coverage, DiskMatchesClosedForm) {
    const double r = 1.2;
    double area = renderCoverage("Disk 0 1.2 360", "disk");
    EXPECT_NEAR(area, M_PI * r * r, 0.005 * M_PI * r * r);
}

TEST(Coverage, PartialDiskSweep) {
    // A 135 degree sector of radius 1.8.
    const double r = 1.8;
    double expected = M_PI * r * r * 135.0 / 360.0;
    double area = renderCoverage("Disk 0 1.8 135", "sector");
    EXPECT_NEAR(area, expected, 0.005 * expected);
}

TEST(Coverage, PartialCylinderSeenFromTheSide) {
    // Axis along x (rotated from z), viewed along +z: theta in [0, 90]
    // covers half the diameter, so the projection is an r x h rectangle.
    const double r = 1.0, h = 3.0;
    double area = renderCoverage("Rotate 90 0 1 0 Rotate -90 0 0 1 Cylinder 1 -1.5 1.5 90", "cylinder");
    EXPECT_NEAR(area, r * h, 0.005 * r * h);
}

TEST(Seams, ConstantPlaneAcrossBucketsIsUniform) {
    // A plane bigger than the view, split across many buckets and grids:
    // every pixel must get exactly the same colour (no seams, no gaps).
    ScratchDir dir("seams");
    Diagnostics diag;
    test::renderRib(orthoFrame(dir.file("out.exr"),
                                  R"(Color [0.25 0.5 0.75] Surface "constant"
                                     Polygon "P" [-3 -3 0  3 -3 0  3 3 0  -3 3 0])",
                                  2, 100),
                       diag);
    ASSERT_EQ(diag.errorCount(), 0);
    Image img;
    ASSERT_TRUE(test::readImage(dir.file("out.exr"), &img));
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            ASSERT_NEAR(img.at(x, y, 0), 0.25f, 1e-5f) << x << "," << y;
            ASSERT_NEAR(img.at(x, y, 1), 0.5f, 1e-5f) << x << "," << y;
            ASSERT_NEAR(img.at(x, y, 3), 1.0f, 1e-5f) << x << "," << y;
        }
}

TEST(Determinism, SamePixelsWhateverThreadsAndBuckets) {
    // Gaussian filter (crosses bucket borders), jittered samples, several
    // overlapping primitives: one thread with 16-pixel buckets and two
    // threads with 7-pixel buckets must give bit-identical pixels.
    const std::string world = R"(
        LightSource "distantlight" 1 "from" [1 1 -1] "to" [0 0 0]
        AttributeBegin Color [1 0.3 0.2] Surface "plastic" Sphere 1 -1 1 360 AttributeEnd
        AttributeBegin Translate 0.5 0.4 -0.5 Opacity [0.5 0.5 0.5] Surface "matte" Disk 0 0.9 360 AttributeEnd
        AttributeBegin Translate -0.7 -0.6 0.2 Rotate 30 1 1 0 Surface "matte" Torus 0.6 0.2 0 360 360 AttributeEnd
    )";
    auto frame = [&](const std::string& out) {
        std::string rib = orthoFrame(out, world, 3, 96);
        size_t pos = rib.find("PixelFilter \"box\" 1 1");
        return rib.replace(pos, 21, "PixelFilter \"gaussian\" 2 2");
    };
    ScratchDir dir("determinism");
    Diagnostics d1, d2;
    test::renderRib(frame(dir.file("a.exr")), d1, 1, 16);
    test::renderRib(frame(dir.file("b.exr")), d2, 2, 7);
    ASSERT_EQ(d1.errorCount(), 0);
    ASSERT_EQ(d2.errorCount(), 0);
    Image a, b;
    ASSERT_TRUE(test::readImage(dir.file("a.exr"), &a));
    ASSERT_TRUE(test::readImage(dir.file("b.exr"), &b));
    ASSERT_EQ(a.pixels.size(), b.pixels.size());
    double sum = 0;
    for (size_t i = 0; i < a.pixels.size(); ++i) {
        ASSERT_EQ(a.pixels[i], b.pixels[i]) << "at float " << i;
        sum += a.pixels[i];
    }
    EXPECT_GT(sum, 100.0);  // the frame is not empty
}

TEST(Output, FailedRenderLeavesNoFile) {
    ScratchDir dir("nofile");
    Diagnostics diag;
    diag.setSink([](const Diagnostic&) {});
    std::string missingDir = dir.file("missing/sub/out.tif");
    test::renderRib(orthoFrame(missingDir, "Sphere 1 -1 1 360"), diag);
    EXPECT_GT(diag.errorCount(), 0);
    EXPECT_FALSE(std::filesystem::exists(missingDir));
    EXPECT_FALSE(std::filesystem::exists(dir.file("missing")));
}

// The Imager shader runs on every filtered pixel before output: P is the
// pixel centre in raster space, Ci/alpha the filtered colour and coverage;
// option() answers as it does for surfaces.
TEST(Imager, RunsOnEachFilteredPixelBeforeOutput) {
    ScratchDir dir("imager");
    {
        std::ofstream(dir.file("tag.sl")) << "imager tag(color bg = color(0, 0, 1)) {\n"
                                             "  float res[3];\n"
                                             "  float ok = option(\"Format\", res);\n"
                                             "  Ci += (1 - alpha) * bg;\n"
                                             "  setcomp(Ci, 0, ok * (xcomp(P) / res[0] + ycomp(P) / (res[1] * 64)));\n"
                                             "  Oi = 1; alpha = 1;\n"
                                             "}\n";
    }
    const std::string world = "Surface \"constant\" Color [0 1 0] Polygon \"P\" [-2 -2 0  0 -2 0  0 2 0  -2 2 0]";
    Diagnostics diag;
    const Image img = renderWithShaders(dir, "Imager \"tag\"\n", world, diag);
    EXPECT_EQ(diag.errorCount(), 0);
    ASSERT_EQ(img.width, 64);
    for (int y : {0, 17, 63})
        for (int x : {0, 20, 40, 63}) {
            const bool covered = x < 32;  // the square covers the left half
            EXPECT_NEAR(img.at(x, y, 0), (x + 0.5f) / 64 + (y + 0.5f) / 4096, 1e-5f) << x << "," << y;
            EXPECT_NEAR(img.at(x, y, 1), covered ? 1.f : 0.f, 1e-5f) << x << "," << y;
            EXPECT_NEAR(img.at(x, y, 2), covered ? 0.f : 1.f, 1e-5f) << x << "," << y;
            EXPECT_NEAR(img.at(x, y, 3), 1.f, 1e-6f) << x << "," << y;
        }
}

TEST(Depth, IsZeroAtTheNearClippingPlaneAndOneAtTheFar) {
    // RI Spec 3.2: depth() is normalised to 0 at the near and 1 at the far
    // clipping plane. The shading grid never learnt the camera's Clipping,
    // so a depth cue (K-3D's depthcue shader) gave 0 everywhere. A plane
    // tilted in depth, x from -2 to 2 at z = 5 + x: depth (z - 1) / 19 under
    // Clipping 1 20.
    ScratchDir dir("depth-clipping");
    std::ofstream(dir.file("showdepth.sl")) << "surface showdepth() { Ci = depth(P); Oi = 1; }\n";
    const std::string world =
        "Surface \"showdepth\" Polygon \"P\" [-2 -2 -2  2 -2 2  2 2 2  -2 2 -2]";
    Diagnostics diag;
    const Image img = renderWithShaders(dir, "Clipping 1 20\n", world, diag);
    EXPECT_EQ(diag.errorCount(), 0);
    ASSERT_EQ(img.width, 64);
    for (int x : {2, 20, 32, 45, 61}) {
        const float wx = -2 + 4 * (x + 0.5f) / 64, z = 5 + wx;
        EXPECT_NEAR(img.at(x, 32, 0), (z - 1) / 19, 2e-3f) << x;
    }
}

TEST(Imager, ItsOpacityIsThePixelsAlpha) {
    // RI Spec 3.2: an imager's outputs are Ci and Oi. K-3D's bluescreen
    // imager fills the background and sets Oi = 1; umbra kept the pixels'
    // coverage as alpha (0 where nothing was drawn), where Aqsis writes 1.
    ScratchDir dir("imager-oi");
    std::ofstream(dir.file("fill.sl")) << "imager fill() { Ci += (1 - alpha) * color(0, 0, 1); Oi = 1; }\n";
    std::ofstream(dir.file("half.sl")) << "imager half() { Oi = color(0.25, 0.5, 0.75); alpha = 0.125; }\n";
    const std::string world = "Surface \"constant\" Color [0 1 0] Polygon \"P\" [-2 -2 0  0 -2 0  0 2 0  -2 2 0]";
    for (const char* imager : {"fill", "half"}) {
        Diagnostics diag;
        const Image img = renderWithShaders(dir, fmt::format("Imager \"{}\"\n", imager), world, diag);
        EXPECT_EQ(diag.errorCount(), 0);
        ASSERT_EQ(img.width, 64);
        for (int x : {5, 50}) {
            if (std::string(imager) == "fill") {
                EXPECT_NEAR(img.at(x, 30, 3), 1.f, 1e-6f) << x;  // the Oi it set, covered or not
                EXPECT_NEAR(img.at(x, 30, 2), x < 32 ? 0.f : 1.f, 1e-6f) << x;
            } else {
                EXPECT_NEAR(img.at(x, 30, 3), 0.125f, 1e-6f) << x;  // alpha, set too, wins
            }
        }
    }
}

TEST(FrameAspectRatio, FitsThePictureIntoTheFormat) {
    // RI Spec 3.2: the picture takes the frame aspect ratio and is fitted
    // into the display area (Pixie writes it at that size). umbra kept the
    // Format's size and stretched the picture: a sphere came out a 2:1
    // ellipse. Orthographic, default screen window [-1, 1] on the short
    // side: a sphere of radius 0.5 covers pi / 16 of a square picture.
    ScratchDir dir("frame-aspect");
    for (float aspect : {1.0f, 4.0f}) {
        const std::string rib = fmt::format(R"(Display "{}" "openexr" "rgba" "string type" "float"
Format 200 100 1
FrameAspectRatio {}
PixelSamples 4 4
PixelFilter "box" 1 1
Projection "orthographic"
Translate 0 0 5
WorldBegin
Surface "constant"
Sphere 0.5 -0.5 0.5 360
WorldEnd
)",
                                            dir.file("out.exr"), aspect);
        Diagnostics diag;
        test::renderRib(rib, diag);
        EXPECT_EQ(diag.errorCount(), 0);
        Image img;
        ASSERT_TRUE(test::readImage(dir.file("out.exr"), &img));
        EXPECT_EQ(img.width, aspect == 1.0f ? 100 : 200);
        EXPECT_EQ(img.height, aspect == 1.0f ? 100 : 50);
        // The screen is [-a, a] x [-1, 1] (a >= 1): pixels per unit are
        // height / 2 both ways, so the disc is round.
        const double pixelsPerUnit = img.height / 2.0;
        EXPECT_NEAR(img.channelSum(3), M_PI * 0.25 * pixelsPerUnit * pixelsPerUnit, 0.01 * M_PI * 0.25 * pixelsPerUnit * pixelsPerUnit)
            << aspect;
    }
}

TEST(Shading, ArrayResultsOfOptionAreStoredPerPointUnderAVaryingCondition) {
    // option(), attribute() and textureinfo() store an array into a
    // variable; under a varying condition the variable is varying, its
    // elements each holding every point's value. umbra copied each point's
    // values side by side instead: option("Format", res) gave scrambled
    // numbers at every point (Aqsis gives the Format).
    ScratchDir dir("option-array");
    std::ofstream(dir.file("fmt.sl")) << "surface fmt() { float res[3] = {0, 0, 0};\n"
                                         "  if (s < 0.5) option(\"Format\", res);\n"
                                         "  Ci = color(res[0] / 1000, res[1] / 1000, res[2]); Oi = 1; }\n";
    const std::string world = "Surface \"fmt\" Patch \"bilinear\" \"P\" [-2 -2 0  2 -2 0  -2 2 0  2 2 0]";
    Diagnostics diag;
    const Image img = renderWithShaders(dir, "", world, diag);
    EXPECT_EQ(diag.errorCount(), 0);
    ASSERT_EQ(img.width, 64);
    for (int y : {5, 40})
        for (int x : {3, 20, 45, 60}) {
            const bool left = x < 30;  // s < 0.5, away from the boundary
            EXPECT_NEAR(img.at(x, y, 0), left ? 0.064f : 0.f, 1e-6f) << x << "," << y;
            EXPECT_NEAR(img.at(x, y, 1), left ? 0.064f : 0.f, 1e-6f) << x << "," << y;
            EXPECT_NEAR(img.at(x, y, 2), left ? 1.f : 0.f, 1e-6f) << x << "," << y;
        }
}

TEST(Shading, OptionAnswersEveryNameOfTheSpecsTable) {
    // RI Spec 3.2's option() names include CropWindow, DepthOfField and
    // Shutter; umbra answered none of them (0, the variable untouched),
    // where Aqsis gives the values set.
    ScratchDir dir("option-names");
    std::ofstream(dir.file("opts.sl")) << "surface opts(float mode = 0) {\n"
                                          "  uniform float crop[4] = {0, 0, 0, 0}, dof[3] = {0, 0, 0}, sh[2] = {0, 0};\n"
                                          "  float a = option(\"CropWindow\", crop), b = option(\"DepthOfField\", dof);\n"
                                          "  float c = option(\"Shutter\", sh);\n"
                                          "  if (mode == 0) Ci = color(a + b + c, crop[0] + crop[1], crop[2] + crop[3]);\n"
                                          "  else if (mode == 1) Ci = color(dof[0], dof[1], dof[2]);\n"
                                          "  else Ci = color(sh[0], sh[1], 0);\n"
                                          "  Oi = 1; }\n";
    for (int mode : {0, 1, 2}) {
        Diagnostics diag;
        const Image img = renderWithShaders(
            dir, "CropWindow 0 1 0 1\nDepthOfField 22 0.05 7\nShutter 0.25 0.75\n",
            fmt::format("Surface \"opts\" \"mode\" {} Patch \"bilinear\" \"P\" [-2 -2 0  2 -2 0  -2 2 0  2 2 0]", mode), diag);
        EXPECT_EQ(diag.errorCount(), 0);
        const Vec3 expected = mode == 0 ? Vec3(3, 1, 1) : mode == 1 ? Vec3(22, 0.05f, 7) : Vec3(0.25f, 0.75f, 0);
        EXPECT_NEAR(img.at(32, 32, 0), expected.x, 1e-5f) << mode;
        EXPECT_NEAR(img.at(32, 32, 1), expected.y, 1e-5f) << mode;
        EXPECT_NEAR(img.at(32, 32, 2), expected.z, 1e-5f) << mode;
    }
}

TEST(Shading, TimeIsTheShutterOpeningAndLightsGiveTheirOpacity) {
    // RI Spec 3.2, tables 12.1-12.5: time is the shutter's opening (umbra
    // shades there; it gave 0 under Shutter 0.25 0.75, Pixie and Aqsis
    // 0.25), dtime its length, dPdtime P's motion (0 for a still grid; the
    // compiler refused both names; moving grids below); Ol inside illuminance is the light's
    // opacity (refused; Pixie gives the light's).
    ScratchDir dir("time-globals");
    std::ofstream(dir.file("tm.sl")) << "surface tm(float mode = 0) {\n"
                                        "  color o = 0; illuminance(P) o += Ol;\n"
                                        "  if (mode == 0) Ci = color(time, dtime, length(dPdtime)); else Ci = o;\n"
                                        "  Oi = 1; }\n";
    std::ofstream(dir.file("ol.sl")) << "light ol() { solar(vector(0, 0, 1), 0) { Cl = 1; Ol = color(0.25, 0.5, 0.75); } }\n";
    for (int mode : {0, 1}) {
        Diagnostics diag;
        const Image img = renderWithShaders(
            dir, "Shutter 0.25 0.75\n",
            fmt::format("LightSource \"ol\" 1 Surface \"tm\" \"mode\" {} Patch \"bilinear\" \"P\" [-2 -2 0  2 -2 0  -2 2 0  2 2 0]", mode),
            diag);
        EXPECT_EQ(diag.errorCount(), 0);
        const Vec3 expected = mode == 0 ? Vec3(0.25f, 0.5f, 0) : Vec3(0.25f, 0.5f, 0.75f);
        EXPECT_NEAR(img.at(32, 32, 0), expected.x, 1e-6f) << mode;
        EXPECT_NEAR(img.at(32, 32, 1), expected.y, 1e-6f) << mode;
        EXPECT_NEAR(img.at(32, 32, 2), expected.z, 1e-6f) << mode;
    }
}

TEST(Shading, DPdtimeIsEachPointsVelocityOverTheShutter) {
    // RI Spec 3.2 tables 12.1-12.5: dPdtime is P's derivative in time. It
    // was 0 on every grid; Pixie gives (P at the close - P at the opening)
    // / the shutter's length in current space, umbra now too. A patch moved
    // by a transform 2 along x over a shutter of 0.5, and one deformed 1
    // along y between two shapes; the camera only translates, so current
    // space velocities are the world's: (4, 0, 0) and (0, 2, 0).
    ScratchDir dir("dpdtime");
    std::ofstream(dir.file("vel.sl")) << "surface vel() { Ci = color(xcomp(dPdtime), ycomp(dPdtime), zcomp(dPdtime)); Oi = 1; }\n";
    const std::string patch = "Patch \"bilinear\" \"P\" [-2 -2 0  2 -2 0  -2 2 0  2 2 0]";
    const std::string moved = "Patch \"bilinear\" \"P\" [-2 -1 0  2 -1 0  -2 3 0  2 3 0]";
    const struct {
        std::string world;
        Vec3 expected;
    } cases[] = {
        {"MotionBegin [0.25 0.75] Translate 0 0 0 Translate 2 0 0 MotionEnd " + patch, Vec3(4, 0, 0)},
        {"MotionBegin [0.25 0.75] " + patch + " " + moved + " MotionEnd", Vec3(0, 2, 0)},
        {patch, Vec3(0, 0, 0)},
    };
    for (const auto& c : cases) {
        Diagnostics diag;
        const Image img = renderWithShaders(dir, "Shutter 0.25 0.75\n", "Surface \"vel\" " + c.world, diag);
        EXPECT_EQ(diag.errorCount(), 0);
        EXPECT_NEAR(img.at(32, 32, 0), c.expected.x, 1e-4f) << c.world;
        EXPECT_NEAR(img.at(32, 32, 1), c.expected.y, 1e-4f) << c.world;
        EXPECT_NEAR(img.at(32, 32, 2), c.expected.z, 1e-4f) << c.world;
    }
}

TEST(Film, DepthFiltersOfAColourFrame) {
    // PRMan's Hider "depthfilter" "max" and "average" were refused (warned,
    // "min" used); Pixie writes the farthest and the mean sample depth. A
    // pixel half covered by a plane at z = 2 before one at z = 5 (regular
    // 4x4 samples): min 2, max 5, average 3.5. "midpoint" needs the second
    // surface, which a colour frame does not keep: warned, and its zfile
    // and its "file" z agree on the nearest depth (the zfile held the
    // nearest plus the dual offset, the TIFF the nearest, silently).
    ScratchDir dir("colour-depthfilter");
    const std::string frame = R"(Format 4 2 1
ScreenWindow 0 4 0 2
PixelFilter "box" 1 1
PixelSamples 4 4
Display "{0}" "file" "rgbaz"
{1}
Hider "hidden" "jitter" [0] "depthfilter" "{2}"
Projection "orthographic"
WorldBegin
Surface "constant"
Polygon "P" [0 0 5  4 0 5  4 2 5  0 2 5]
Polygon "P" [1 0 2  2.5 0 2  2.5 2 2  1 2 2]
WorldEnd
)";
    for (const auto& [filter, expected] : {std::pair{"min", 2.0f}, {"max", 5.0f}, {"average", 3.5f}}) {
        Diagnostics diag;
        diag.setRecord(true);
        test::renderRib(fmt::format(fmt::runtime(frame), dir.file("z.tif"), "", filter), diag);
        EXPECT_EQ(diag.warningCount(), 1) << filter;  // rgbaz mixes quantised and float channels
        Image img;
        ASSERT_TRUE(test::readImage(dir.file("z.tif"), &img));
        ASSERT_EQ(img.channels, 5);
        EXPECT_FLOAT_EQ(img.at(2, 0, 4), expected) << filter;
        EXPECT_FLOAT_EQ(img.at(1, 0, 4), 2.0f) << filter;  // wholly the near plane
    }
    Diagnostics diag;
    diag.setRecord(true);
    test::renderRib(fmt::format(fmt::runtime(frame), dir.file("z.tif"),
                                fmt::format("Display \"+{}\" \"zfile\" \"z\"", dir.file("mid.z")), "midpoint"),
                    diag);
    EXPECT_EQ(diag.errorCount(), 0);
    bool warned = false;
    for (const Diagnostic& m : diag.recorded()) warned = warned || m.str().find("needs a frame whose displays") != std::string::npos;
    EXPECT_TRUE(warned);
    Image img;
    ASSERT_TRUE(test::readImage(dir.file("z.tif"), &img));
    EXPECT_FLOAT_EQ(img.at(2, 0, 4), 2.0f);
    DepthImage zfile;
    ASSERT_TRUE(readZFile(dir.file("mid.z"), zfile, diag));
    ASSERT_EQ(zfile.width, 4);
    EXPECT_FLOAT_EQ(zfile.z[2], 2.0f);
    EXPECT_FLOAT_EQ(zfile.z[0], 5.0f);
}

TEST(Shading, AVaryingPrimitiveVariableLeavesAUniformParameterAlone) {
    // "varying float Kvu" given per vertex for a parameter the shader
    // declares uniform: Pixie and Aqsis keep the parameter's default, with
    // a message; umbra gave the whole patch the first vertex's value,
    // silently. A varying parameter still reads it per point.
    ScratchDir dir("uniform-param-primvar");
    std::ofstream(dir.file("kvu.sl")) << "surface kvu(float Kvu = 0.25; varying float Kvv = 0.25) { Ci = color(Kvu, Kvv, 0); }\n";
    Diagnostics diag;
    diag.setRecord(true);
    const Image img = renderWithShaders(dir, "",
                                        "Surface \"kvu\" Patch \"bilinear\" \"P\" [-2 -2 0  2 -2 0  -2 2 0  2 2 0] "
                                        "\"varying float Kvu\" [0.9 0.1 0.5 0.3] \"varying float Kvv\" [0.9 0.1 0.5 0.3]",
                                        diag);
    EXPECT_EQ(diag.errorCount(), 0);
    EXPECT_EQ(diag.warningCount(), 1);
    EXPECT_FLOAT_EQ(img.at(2, 2, 0), 0.25f);
    EXPECT_FLOAT_EQ(img.at(61, 61, 0), 0.25f);
    // Kvv bilinear over the patch: 0.9, 0.1, 0.5, 0.3 at its corners.
    for (const auto& [x, y] : {std::pair{2, 2}, {61, 61}, {10, 50}}) {
        const float u = (4.0f * (float(x) + 0.5f) / 64.0f) / 4.0f, v = (4.0f - 4.0f * (float(y) + 0.5f) / 64.0f) / 4.0f;
        const float expected = (1 - v) * ((1 - u) * 0.9f + u * 0.1f) + v * ((1 - u) * 0.5f + u * 0.3f);
        EXPECT_NEAR(img.at(x, y, 1), expected, 0.01f) << x << "," << y;
    }
}

TEST(Shading, PrimitiveVariablesBindToTheSurfacesShadersNotToItsLights) {
    // A floor carrying "constant float intensity" dimmed every light that
    // lit it to that intensity (and a "width" changed shadowspot's blur):
    // umbra bound primitive variables to light shaders too. PRMan binds
    // them to the primitive's own shaders, and Pixie and Aqsis light such
    // a floor as if it had none. matte under a distant light of intensity
    // 1 along the view: Ci = Kd, the patch's own Kd of 0.5.
    ScratchDir dir("primvars-not-lights");
    const std::string light = "LightSource \"distantlight\" 1 \"from\" [0 0 0] \"to\" [0 0 1] \"intensity\" [1]\n";
    const std::string patch = "Surface \"matte\" Patch \"bilinear\" \"P\" [-2 -2 0  2 -2 0  -2 2 0  2 2 0] "
                              "\"constant float Kd\" [0.5]";
    for (const char* extra : {"", " \"constant float intensity\" [0.25]", " \"varying float intensity\" [0 0 0 0]"}) {
        Diagnostics diag;
        diag.setRecord(true);
        const Image img = renderWithShaders(dir, "", light + patch + extra, diag);
        EXPECT_EQ(diag.errorCount(), 0) << extra;
        EXPECT_EQ(diag.warningCount(), 0) << extra;
        for (const auto& [x, y] : {std::pair{2, 2}, {32, 32}, {61, 40}})
            EXPECT_FLOAT_EQ(img.at(x, y, 0), 0.5f) << extra << " at " << x << "," << y;
    }
}

TEST(Shading, AScopedCoordinateSystemEndsWithItsAttributeBlock) {
    // PRMan's ScopedCoordinateSystem: named until AttributeEnd, then the
    // name's earlier meaning is back. umbra kept it for the frame (the
    // request was even registered twice, the unscoped entry first): a
    // square placed by CoordSysTransform after the block landed at the
    // scoped place. Shaders inside the block see the scoped space.
    ScratchDir dir("scoped-coordsys");
    std::ofstream(dir.file("place.sl")) << "surface place() { point q = transform(\"place\", P); Ci = color(xcomp(q), 0, 0); }\n";
    Diagnostics diag;
    const std::string square = "Patch \"bilinear\" \"P\" [-0.25 -0.25 0  0.25 -0.25 0  -0.25 0.25 0  0.25 0.25 0]";
    const Image img = renderWithShaders(
        dir, "",
        "AttributeBegin Translate -0.5 1 0 CoordinateSystem \"place\" AttributeEnd\n"
        "AttributeBegin Translate 1 -1 0 ScopedCoordinateSystem \"place\" Surface \"place\" " + square +
            " AttributeEnd\n"
            "AttributeBegin CoordSysTransform \"place\" Surface \"constant\" Color [0 1 0] " + square + " AttributeEnd",
        diag);
    EXPECT_EQ(diag.errorCount(), 0);
    EXPECT_EQ(diag.warningCount(), 0);
    // 16 pixels a unit, x = 0 at column 32, y = 0 at row 32 (y up).
    auto at = [&](float x, float y, int c) { return img.at(int(32 + 16 * x), int(32 - 16 * y), c); };
    // The scoped square at (1, -1): its own place-space x is about 0.
    EXPECT_NEAR(at(1.0f, -1.0f, 0), 0.0f, 0.05f);
    EXPECT_EQ(at(1.0f, -1.0f, 1), 0.0f);
    // After the block, "place" is the global one again: the green square at (-0.5, 1).
    EXPECT_EQ(at(-0.5f, 1.0f, 1), 1.0f);
    EXPECT_EQ(at(1.0f, -1.0f, 1), 0.0f);
}

TEST(Shading, TextureinfoDescribesAShadowMapAsRenderManDoes) {
    // RI Spec 3.2's textureinfo table: "type" is "shadow" for a shadow map,
    // "resolution" the map's (umbra's files store only the box of finite
    // depths: it answered that box), and "viewingmatrix" and
    // "projectionmatrix" the camera the map was made from, from current
    // space (Aqsis; shaders apply them to P). Both peers answer all four;
    // umbra answered only resolution, wrongly. The map here: fov 90 from
    // the world origin looking down +z, 64x64, a patch covering its lower
    // half only; the shading camera is elsewhere, so current space is not
    // world space.
    ScratchDir dir("textureinfo-shadow");
    Diagnostics diag;
    test::renderRib(fmt::format(R"(Format 64 64 1
Projection "perspective" "fov" 90
Display "{0}" "zfile" "z"
WorldBegin
Patch "bilinear" "P" [-4 -4 2  4 -4 2  -4 -0.5 2  4 -0.5 2]
WorldEnd
MakeShadow "{0}" "{1}"
)",
                                dir.file("map.z"), dir.file("map.shd")),
                    diag);
    ASSERT_EQ(diag.errorCount(), 0);
    std::ofstream(dir.file("ti.sl")) << "surface ti(string map = \"\"; float mode = 0) {\n"
                                        "  uniform float res[2] = {0, 0}; uniform string ty = \"\"; uniform matrix vm = 0, pm = 0;\n"
                                        "  float a = textureinfo(map, \"resolution\", res), b = textureinfo(map, \"type\", ty);\n"
                                        "  float c = textureinfo(map, \"viewingmatrix\", vm), d = textureinfo(map, \"projectionmatrix\", pm);\n"
                                        "  point q = transform(pm, transform(\"world\", \"current\", point(0.5, 0.25, 2)));\n"
                                        "  point w = transform(vm, transform(\"world\", \"current\", point(1, 2, 3)));\n"
                                        "  if (mode == 0) Ci = color(a + b + c + d, res[0] + res[1], ty == \"shadow\");\n"
                                        "  else if (mode == 1) Ci = color(xcomp(q), ycomp(q), zcomp(q));\n"
                                        "  else if (mode == 2) Ci = color(xcomp(w), ycomp(w), zcomp(w));\n"
                                        "  else Ci = color(float texture(map, 0.5, 0.9), float texture(map, 0.5, 0.1) > 1e30, 0);\n"
                                        "  Oi = 1; }\n";
    // Mode 3: texture() reads the depth where the map holds one, and
    // +infinity where nothing was rendered (Aqsis; 0 was read there, the
    // box of finite depths being all the file stores), so contact-shadow
    // shaders that read depth maps see no surface there.
    for (int mode : {0, 1, 2, 3}) {
        const Image img = renderWithShaders(
            dir, "", fmt::format("Surface \"ti\" \"map\" \"{}\" \"mode\" {} Patch \"bilinear\" \"P\" [-2 -2 0  2 -2 0  -2 2 0  2 2 0]",
                                 dir.file("map.shd"), mode),
            diag);
        EXPECT_EQ(diag.errorCount(), 0);
        const Vec3 expected = mode == 0   ? Vec3(4, 128, 1)
                              : mode == 1 ? Vec3(0.25f, 0.125f, 0)
                              : mode == 2 ? Vec3(1, 2, 3)
                                          : Vec3(2, 1, 0);
        EXPECT_NEAR(img.at(32, 32, 0), expected.x, 1e-5f) << mode;
        EXPECT_NEAR(img.at(32, 32, 1), expected.y, 1e-5f) << mode;
        if (mode != 1) {
            EXPECT_NEAR(img.at(32, 32, 2), expected.z, 1e-5f) << mode;
        }
    }
}

TEST(Shading, StringPrimitiveVariablesBindToStringParameters) {
    // Exporters write per-object texture names as string primitive
    // variables ("constant string texname"). umbra dropped every string
    // primitive variable; Aqsis delivers them (RI Spec 3.2: any shader
    // parameter may be given as a primitive variable). A constant string on
    // a patch, a uniform one per face of a mesh.
    ScratchDir dir("string-primvars");
    std::ofstream(dir.file("tag.sl")) << "surface tag(string tag = \"none\") {\n"
                                         "  Ci = color(match(\"^a$\", tag), match(\"^b$\", tag), match(\"^none$\", tag)); Oi = 1; }\n";
    const std::string world = R"(Surface "tag"
Patch "bilinear" "P" [-2 0 0  0 0 0  -2 2 0  0 2 0] "constant string tag" ["b"]
PointsPolygons [4 4] [0 1 3 2  1 4 5 3] "P" [0 0 0  1 0 0  0 2 0  1 2 0  2 0 0  2 2 0] "uniform string tag" ["a" "b"]
Patch "bilinear" "P" [-2 -2 0  2 -2 0  -2 0 0  2 0 0]
)";
    Diagnostics diag;
    const Image img = renderWithShaders(dir, "", world, diag);
    EXPECT_EQ(diag.errorCount(), 0);
    ASSERT_EQ(img.width, 64);
    // Image y grows downwards: rows 0-31 are y > 0.
    auto rgb = [&](int x, int y) { return Vec3(img.at(x, y, 0), img.at(x, y, 1), img.at(x, y, 2)); };
    auto expectColour = [&](int x, int y, Vec3 want) {
        const Vec3 c = rgb(x, y);
        EXPECT_TRUE(c.x == want.x && c.y == want.y && c.z == want.z) << x << "," << y << ": " << c.x << " " << c.y << " " << c.z;
    };
    expectColour(10, 10, Vec3(0, 1, 0));  // the patch's constant "b"
    expectColour(40, 10, Vec3(1, 0, 0));  // first face: "a"
    expectColour(56, 10, Vec3(0, 1, 0));  // second face: "b"
    expectColour(30, 50, Vec3(0, 0, 1));  // no variable: the default
    // A varying string has no meaning: warned and ignored.
    Diagnostics d2;
    d2.setRecord(true);
    renderWithShaders(dir, "",
                      "Surface \"tag\" Patch \"bilinear\" \"P\" [-2 -2 0  2 -2 0  -2 2 0  2 2 0] "
                      "\"varying string tag\" [\"a\" \"a\" \"b\" \"b\"]",
                      d2, 16);
    bool warned = false;
    for (const Diagnostic& m : d2.recorded()) warned = warned || m.message.find("constant or uniform") != std::string::npos;
    EXPECT_TRUE(warned);
}
