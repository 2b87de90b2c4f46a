// Curves and Points end to end: covered areas against closed forms, a
// mirrored camera, and shadows into an automatic depth map.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <fstream>

using namespace umbra;
using umbra::test::Image;
using umbra::test::ScratchDir;

namespace {

constexpr int kRes = 256;  // pixels across the [-2, 2]^2 view: 64 pixels per unit

/// An orthographic view of [-2,2]^2 looking down +z, box filter 1x1 so
/// each pixel's alpha is the fraction of its samples covered.
std::string orthoFrame(const std::string& out, const std::string& world, const std::string& camera = "") {
    return fmt::format(R"(
Display "{}" "openexr" "rgba" "string type" "float"
Format {} {} 1
ScreenWindow -2 2 -2 2
Projection "orthographic"
PixelSamples 8 8
PixelFilter "box" 1 1
ShadingRate 1
{}
WorldBegin
{}
WorldEnd
)", out, kRes, kRes, camera.empty() ? "Translate 0 0 5" : camera, world);
}

double coveredPixels(const std::string& rib, const ScratchDir& dir) {
    Diagnostics diag;
    diag.setRecord(true);
    test::renderRib(rib, diag);
    EXPECT_EQ(diag.errorCount(), 0);
    Image img;
    EXPECT_TRUE(test::readImage(dir.file("out.exr"), &img));
    return img.channelSum(3);
}

/// Twelve straight horizontal linear curves of length 3 and widths from
/// 0.004 (a quarter pixel) to 0.1 units, slanted a little so they cross
/// sample rows and columns at every phase.
std::string lineField(double* expectedPixels) {
    std::string world;
    double area = 0;
    for (int k = 0; k < 12; ++k) {
        const float y = -1.7f + 0.3f * float(k), w = 0.004f + 0.0087f * float(k);
        world += fmt::format("Curves \"linear\" [2] \"nonperiodic\" \"P\" [-1.5 {} 0 1.5 {} 0] \"constantwidth\" [{}]\n",
                             y, y + 0.05f, w);
        area += std::sqrt(9.0 + 0.05 * 0.05) * w;
    }
    *expectedPixels = area * 64.0 * 64.0;
    return world;
}

TEST(Curves, StraightFieldCoversLengthTimesWidth) {
    ScratchDir dir("curves-field");
    double expected = 0;
    const std::string world = lineField(&expected);
    const double got = coveredPixels(orthoFrame(dir.file("out.exr"), world), dir);
    EXPECT_NEAR(got / expected, 1.0, 0.01) << got << " vs " << expected;
}

TEST(Curves, MirroredCameraGivesTheSameCoverage) {
    ScratchDir dir("curves-mirror");
    double expected = 0;
    const std::string world = "Sides 1\n" + lineField(&expected);
    const double plain = coveredPixels(orthoFrame(dir.file("out.exr"), world), dir);
    const double mirrored = coveredPixels(orthoFrame(dir.file("out.exr"), world, "Scale 1 1 -1\nTranslate 0 0 -5"), dir);
    EXPECT_NEAR(plain / expected, 1.0, 0.01);
    EXPECT_NEAR(mirrored / plain, 1.0, 1e-3);
}

TEST(Curves, PeriodicCubicCircleCoversItsAnnulus) {
    // A periodic B-spline through 8 points of a circle of radius 1.2 is
    // nearly a circle (radius about 1.2 * 0.95); width 0.05 around it: an
    // annulus of area 2 pi r w, closed (no gap at the seam).
    ScratchDir dir("curves-periodic");
    std::string pts;
    for (int k = 0; k < 8; ++k)
        pts += fmt::format("{} {} 0 ", 1.2 * std::cos(k * M_PI / 4), 1.2 * std::sin(k * M_PI / 4));
    const std::string world =
        "Basis \"bspline\" 1 \"bspline\" 1\nCurves \"cubic\" [8] \"periodic\" \"P\" [" + pts + "] \"constantwidth\" [0.05]";
    const double got = coveredPixels(orthoFrame(dir.file("out.exr"), world), dir);
    // A uniform cubic B-spline of a regular octagon of radius R passes at
    // R (4 + 2 cos 45deg) / 6 = 0.902 R at the knots and 0.901 R mid-span.
    const double r = 1.2 * (4 + 2 * std::cos(M_PI / 4)) / 6;
    const double expected = 2 * M_PI * r * 0.05 * 64 * 64;
    EXPECT_NEAR(got / expected, 1.0, 0.03) << got << " vs " << expected;
}

TEST(Points, DiscsCoverPiRSquared) {
    ScratchDir dir("points-discs");
    std::string pts;
    const int n = 36;
    for (int k = 0; k < n; ++k) pts += fmt::format("{} {} 0 ", -1.5 + 0.55 * (k % 6) + 0.013 * k, -1.5 + 0.55 * (k / 6));
    const float width = 0.3f;  // radius 9.6 pixels
    const std::string world = fmt::format("Points \"P\" [{}] \"constantwidth\" [{}]", pts, width);
    const double got = coveredPixels(orthoFrame(dir.file("out.exr"), world), dir);
    const double r = 0.5 * width * 64;
    const double expected = n * M_PI * r * r;
    EXPECT_NEAR(got / expected, 1.0, 0.005) << got << " vs " << expected;
}

TEST(Points, DiscsStayRoundUnderANonUniformScale) {
    // RI Spec 3.2: points are discs facing the camera. Under Scale 1 0.2 1
    // (a star field flattened so) umbra squashed them into dashes; both
    // peers draw circles. umbra's radius is the width's half times the
    // scale's cube root of its volume (0.2^(1/3)); the same stays true
    // turned 30 degrees about the view axis and scaled the other way.
    ScratchDir dir("points-scaled");
    const struct {
        const char* transform;
        double volume;
    } cases[] = {{"Scale 1 0.2 1", 0.2}, {"Rotate 30 0 0 1 Scale 0.2 1 1", 0.2}, {"Scale 0.5 2 0.7", 0.7}};
    for (const auto& [transform, volume] : cases) {
        SCOPED_TRACE(transform);
        const std::string world =
            fmt::format("AttributeBegin {} Points \"P\" [0 0 0] \"constantwidth\" [2] AttributeEnd", transform);
        Diagnostics diag;
        test::renderRib(orthoFrame(dir.file("out.exr"), world), diag);
        EXPECT_EQ(diag.errorCount(), 0);
        Image img;
        ASSERT_TRUE(test::readImage(dir.file("out.exr"), &img));
        // Coverage and its second moments: a disc of radius R has area
        // pi R^2 and the same spread, R^2 / 4, along x and y.
        double area = 0, sx = 0, sy = 0, sxx = 0, syy = 0;
        for (int y = 0; y < img.height; ++y)
            for (int x = 0; x < img.width; ++x) {
                const double a = img.at(x, y, 3), px = x + 0.5, py = y + 0.5;
                area += a;
                sx += a * px;
                sy += a * py;
                sxx += a * px * px;
                syy += a * py * py;
            }
        const double R = std::cbrt(volume) * 64;  // width 2: radius 1 unit, 64 pixels a unit
        EXPECT_NEAR(area / (M_PI * R * R), 1.0, 0.01);
        const double vx = sxx / area - (sx / area) * (sx / area), vy = syy / area - (sy / area) * (sy / area);
        EXPECT_NEAR(vx / vy, 1.0, 0.02);
        EXPECT_NEAR(vx / (R * R / 4), 1.0, 0.03);
    }
}

TEST(Points, PerspectiveMirroredCameraSameCoverage) {
    // Mirrored in x: the picture mirrors, one-sided discs and ribbons still face the camera.
    ScratchDir dir("points-mirror");
    const std::string frame = R"(
Display "{}" "openexr" "rgba" "string type" "float"
Format 128 128 1
Projection "perspective" "fov" [40]
PixelSamples 4 4
PixelFilter "box" 1 1
{}
Translate 0 0 5
WorldBegin
Sides 1
Points "P" [-1 -1 0 1 1 0 0.5 -1 1] "width" [0.4 0.3 0.5]
Curves "cubic" [4] "nonperiodic" "P" [-1.5 0 0  -0.5 1 1  0.5 -1 -1  1.5 0 0] "width" [0.1 0.2]
WorldEnd
)";
    const double a = coveredPixels(fmt::format(fmt::runtime(frame), dir.file("out.exr"), ""), dir);
    const double b = coveredPixels(fmt::format(fmt::runtime(frame), dir.file("out.exr"), "Scale -1 1 1"), dir);
    EXPECT_GT(a, 100);
    EXPECT_NEAR(b / a, 1.0, 0.01);
}

TEST(Points, SuppliedNormalsShadeTheDiscs) {
    // A supplied "N" is the shading normal (RI Spec 3.2), as Pixie and
    // Aqsis shade it; the discs still lie along the image plane. Three points under a
    // distant light shining along +z (L = (0, 0, -1)) with matte: N facing
    // the light gives 1, N at 45 degrees cos 45, N across the light 0 (the
    // three closed forms); a constant N shades every point alike. Before,
    // "N" was dropped and every disc shaded as facing the light.
    ScratchDir dir("points-normal");
    auto render = [&](const std::string& normals) {
        const std::string world = "LightSource \"distantlight\" 1 \"from\" [0 0 -1] \"to\" [0 0 0]\n"
                                  "Surface \"matte\"\n"
                                  "Points \"P\" [-1 0 0  0 0 0  1 0 0] \"constantwidth\" [0.5] " + normals;
        Diagnostics diag;
        diag.setRecord(true);
        test::renderRib(orthoFrame(dir.file("out.exr"), world), diag);
        EXPECT_EQ(diag.errorCount(), 0);
        Image img;
        EXPECT_TRUE(test::readImage(dir.file("out.exr"), &img));
        return img;
    };
    // Point centres: x = -1, 0, 1 at 64 pixels a unit from the view's left edge at -2.
    auto centre = [](const Image& img, int k) { return img.at(64 + 64 * k, kRes / 2, 0); };
    const Image varying = render("\"N\" [0 0 -1  1 0 -1  1 0 0]");
    EXPECT_NEAR(centre(varying, 0), 1.0, 1e-3);
    EXPECT_NEAR(centre(varying, 1), std::sqrt(0.5), 1e-3);
    EXPECT_NEAR(centre(varying, 2), 0.0, 1e-3);
    const Image constant = render("\"constant normal N\" [0 1 0]");
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(centre(constant, k), 0.0, 1e-3) << k;
    const Image none = render("");
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(centre(none, k), 1.0, 1e-3) << k;  // facing the eye and the light
}

TEST(Points, DiscsLieAlongTheImagePlaneAndShadeAlikeAcrossAWideView) {
    // Without "N" a disc lies parallel to the image plane, its normal the
    // camera's axis (Pixie and Aqsis shade it so): under a distant light at
    // 45 degrees every particle of a 90-degree view shades cos 45 with
    // matte, all over each disc. Before, each disc faced the eye (0.87 at
    // the left edge of this view) and its corners' normals were differences
    // with the neighbouring particle (0.64 to 0.76 across the middle one).
    ScratchDir dir("points-axis");
    const std::string rib = fmt::format(R"(
Display "{}" "openexr" "rgba" "string type" "float"
Format 300 200 1
PixelSamples 4 4
Projection "perspective" "fov" 90
WorldBegin
LightSource "distantlight" 1 "from" [1 0 -1] "to" [0 0 0]
Surface "matte"
Translate 0 0 1.5
Points "P" [-1.4 0 0  -0.7 0 0  0 0 0  0.7 0 0  1.4 0 0] "constantwidth" [0.5]
WorldEnd
)", dir.file("out.exr"));
    Diagnostics diag;
    const Image img = test::renderImage(rib, dir.file("out.exr"), diag);
    EXPECT_EQ(diag.errorCount(), 0);
    ASSERT_EQ(img.width, 300);
    // A disc at x lies around pixel (x / 1.5 + 1.5) / 3 * 300, radius 16.7 pixels.
    for (float x : {-1.4f, -0.7f, 0.0f, 0.7f, 1.4f}) {
        const int cx = int(std::lround((x / 1.5f + 1.5f) * 100.0f));
        for (int dy = -8; dy <= 8; dy += 8)
            for (int dx = -8; dx <= 8; dx += 4)
                EXPECT_NEAR(img.at(cx + dx, 100 + dy, 0), std::sqrt(0.5), 2e-3) << "disc at " << x << ", " << dx << " " << dy;
    }
}

TEST(Curves, VRunsAlongTheCurveAndAWideRibbonIsDicedAcross) {
    // RI Spec 3.2: on a curve u runs across the width and v along the
    // length (a hair shader's mix(root, tip, v), as Pixie and Aqsis shade
    // it). umbra had them the other way round, and one micropolygon across
    // however wide: a tube profile sqrt(1 - (2u - 1)^2), 0 at both edges,
    // came out 0 all over. A horizontal ribbon 0.5 wide (32 pixels).
    ScratchDir dir("curves-uv");
    std::ofstream(dir.file("uv.sl")) << "surface uv() { Ci = color(v, sqrt(max(0, 1 - (2 * u - 1) * (2 * u - 1))), 0); Oi = 1; }\n";
    const std::string world = "Surface \"uv\" Curves \"linear\" [2] \"nonperiodic\" \"P\" [-1.5 0 0  1.5 0 0] \"constantwidth\" [0.5]";
    Diagnostics diag;
    const Image img = test::renderImage(fmt::format("Option \"searchpath\" \"shader\" [\"{}:&\"]\n", dir.file("")) +
                                            orthoFrame(dir.file("out.exr"), world),
                                        dir.file("out.exr"), diag);
    EXPECT_EQ(diag.errorCount(), 0);
    ASSERT_EQ(img.width, kRes);
    // x = -1.5 .. 1.5 is pixels 32 .. 224: v = (px + 0.5 - 32) / 192.
    for (int px : {40, 128, 200}) {
        EXPECT_NEAR(img.at(px, kRes / 2, 0), (px + 0.5f - 32) / 192.0f, 0.01f) << px;
        // The ribbon's middle row: the profile's top (a few micropolygons
        // across: within the chord error); 8 pixels from it, u = 0.25.
        EXPECT_GT(img.at(px, kRes / 2, 1), 0.9f) << px;
        EXPECT_NEAR(img.at(px, kRes / 2 + 8, 1), std::sqrt(0.75f), 0.12f) << px;
    }
}

TEST(CurvesAndPoints, CastShadowsIntoAnAutomaticMap) {
    // A distant light straight down; a floor at z = 1 behind a field of
    // curves and discs at z = 0: the floor's darkened area is the casters'.
    ScratchDir dir("curves-shadow");
    double expected = 0;
    std::string casters = lineField(&expected);
    casters += "Points \"P\" [-1 -1.85 0 1 1.85 0] \"constantwidth\" [0.2]\n";
    expected += 2 * M_PI * 0.1 * 0.1 * 64 * 64;
    const std::string world = fmt::format(R"(
LightSource "shadowdistant" 1 "from" [0 0 -10] "to" [0 0 0] "shadowname" ["auto"] "intensity" [1]
AttributeBegin
  Attribute "visibility" "camera" [0]
  Surface "constant"
  {}
AttributeEnd
AttributeBegin
  Surface "matte" "Kd" [1] "Ka" [0]
  Polygon "P" [-2 -2 1  2 -2 1  2 2 1  -2 2 1]
AttributeEnd
)", casters);
    const std::string rib = "Option \"umbra\" \"shadowmapsize\" [1024]\n" + orthoFrame(dir.file("out.exr"), world);
    Diagnostics diag;
    diag.setRecord(true);
    test::renderRib(rib, diag);
    EXPECT_EQ(diag.errorCount(), 0);
    Image img;
    ASSERT_TRUE(test::readImage(dir.file("out.exr"), &img));
    double lit = 0, maxLit = 0;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            lit += img.at(x, y, 0);
            maxLit = std::max(maxLit, double(img.at(x, y, 0)));
        }
    ASSERT_GT(maxLit, 0.1);
    const double dark = double(img.width) * img.height - lit / maxLit;
    EXPECT_NEAR(dark / expected, 1.0, 0.15) << dark << " vs " << expected;
}

TEST(Points, ACloudAroundAPointLightLosesNoShadowToTheEyeSplitLimit) {
    // 3,000 points around a point light: the planes of its cube map's faces
    // run through the cloud, and halving the points ten times (the default
    // eye-split limit) left groups of two or three on both sides of a
    // plane. Those were culled with a warning, their shadows lost (29% of
    // the pixels of such a frame changed). A group of points reaches single
    // points in finitely many splits, so it is split past the limit: the
    // frame is the one rendered with no limit in reach.
    ScratchDir dir("points-cloud-eyesplits");
    std::string points, widths;
    uint32_t seed = 12345;
    auto uniform = [&](float lo, float hi) {
        seed = seed * 1664525u + 1013904223u;
        return lo + (hi - lo) * float(seed >> 8) / float(1u << 24);
    };
    for (int k = 0; k < 3000; ++k) {
        points += fmt::format("{} {} {} ", uniform(-1.5f, 1.5f), uniform(-1.5f, 1.5f), uniform(-1.8f, 0.5f));
        widths += fmt::format("{} ", uniform(0.02f, 0.08f));
    }
    auto render = [&](const std::string& limit, Diagnostics& diag) {
        const std::string world = "LightSource \"shadowpoint\" 1 \"from\" [0 0 -0.5] \"intensity\" [2] "
                                  "\"shadowname\" [\"auto\"]\nSurface \"matte\"\nPoints \"P\" [" + points +
                                  "] \"width\" [" + widths + "]\nPolygon \"P\" [-2 -2 1  2 -2 1  2 2 1  -2 2 1]\n";
        return test::renderImage(limit + "Option \"umbra\" \"shadowmapsize\" [256]\n" +
                                     orthoFrame(dir.file("out.exr"), world),
                                 dir.file("out.exr"), diag);
    };
    Diagnostics diag;
    diag.setRecord(true);
    const Image limited = render("", diag);
    EXPECT_EQ(diag.warningCount(), 0) << (diag.recorded().empty() ? "" : diag.recorded()[0].message);
    Diagnostics quiet;
    const Image unlimited = render("Option \"limits\" \"eyesplits\" [40]\n", quiet);
    ASSERT_EQ(limited.width, unlimited.width);
    int differing = 0;
    for (int y = 0; y < limited.height; ++y)
        for (int x = 0; x < limited.width; ++x) differing += limited.at(x, y, 0) != unlimited.at(x, y, 0);
    EXPECT_EQ(differing, 0);
}

TEST(Points, ADiscCloseToItsLightCastsItsShadow) {
    // A disc of width 0.6 held 0.4 from a light, 2 from a floor: its
    // shadow is the disc scaled by 2 / 0.4, radius 1.5. Bounded as a disc
    // turned any way (a cube of half side 0.42) it crossed the light's eye
    // plane; a lone point cannot be split, so it was culled, with a warning
    // about corrupt coordinates, and cast nothing. Both a spotlight and a
    // point light's cube map; the shadowed fraction of each pixel from the
    // same frame without the disc.
    ScratchDir dir("points-near-light");
    for (const char* light : {"LightSource \"shadowspot\" 1 \"from\" [0 0 -1] \"to\" [0 0 1] \"coneangle\" [1.3] "
                              "\"intensity\" [4] \"shadowname\" [\"auto\"]",
                              "LightSource \"shadowpoint\" 1 \"from\" [0 0 -1] \"intensity\" [4] "
                              "\"shadowname\" [\"auto\"]"}) {
        auto render = [&](const std::string& caster, Diagnostics& diag) {
            const std::string world = std::string(light) + R"(
AttributeBegin
  Attribute "visibility" "camera" [0]
  )" + caster + R"(
AttributeEnd
Surface "matte" "Kd" [1] "Ka" [0]
Polygon "P" [-2 -2 1  2 -2 1  2 2 1  -2 2 1]
)";
            return test::renderImage("Option \"umbra\" \"shadowmapsize\" [1024]\n" + orthoFrame(dir.file("out.exr"), world),
                                     dir.file("out.exr"), diag);
        };
        Diagnostics diag;
        diag.setRecord(true);
        const Image shadowed = render("Points \"P\" [0 0 -0.6] \"constantwidth\" [0.6]", diag);
        EXPECT_EQ(diag.errorCount(), 0) << light;
        EXPECT_EQ(diag.warningCount(), 0) << light << ": " << (diag.recorded().empty() ? "" : diag.recorded()[0].message);
        Diagnostics quiet;
        const Image lit = render("", quiet);
        ASSERT_EQ(shadowed.width, lit.width);
        double dark = 0;
        for (int y = 0; y < lit.height; ++y)
            for (int x = 0; x < lit.width; ++x)
                if (lit.at(x, y, 0) > 1e-3f) dark += 1.0 - double(shadowed.at(x, y, 0)) / double(lit.at(x, y, 0));
        const double expected = M_PI * 1.5 * 1.5 * 64 * 64;
        EXPECT_NEAR(dark / expected, 1.0, 0.05) << light << ": " << dark << " vs " << expected;
    }
}

}  // namespace
