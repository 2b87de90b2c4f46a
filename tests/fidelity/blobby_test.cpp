// Blobby implicit surfaces rendered end to end, against answers computed
// here: the closed-form threshold surface of a lone ellipsoid (its unit
// sphere scaled by 1/2: the field (1 - r^2)^3 equals 0.75^3 at r = 0.5), the
// silhouettes of combined fields evaluated in the test, a sphere's shadow on
// a floor under a distant light, displacement along the outward normal, the
// flopped picture under a flopping camera, and a blob pushed off a ground by
// a repelling plane whose depth map umbra rendered (PRMan Application Note
// #31's field of the height above the map, written here).

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>

using namespace umbra;
using umbra::test::Image;
using umbra::test::ScratchDir;

namespace {

constexpr double kT = 0.421875;  // 0.75^3

Image renderBlobby(const ScratchDir& dir, const std::string& body, const std::string& camera, int width, int height,
             const std::string& options = "", int threads = 0, Diagnostics* recorded = nullptr) {
    const std::string image = dir.file("blobby.tif");
    const std::string rib = fmt::format(R"(
Option "searchpath" "shader" ["{}:&"]
{}
Format {} {} 1
PixelSamples 4 4
Display "{}" "file" "rgba"
{}
WorldBegin
{}
WorldEnd
)",
                                        dir.file(""), options, width, height, image, camera, body);
    Diagnostics own;
    Diagnostics& diag = recorded ? *recorded : own;
    diag.setQuiet(true);
    Image img = test::renderImage(rib, image, diag, threads);
    EXPECT_EQ(diag.errorCount(), 0) << rib;
    return img;
}

std::string sphereLeaf(double s, double x, double y, double z) {
    return fmt::format("{0} 0 0 0  0 {0} 0 0  0 0 {0} 0  {1} {2} {3} 1", s, x, y, z);
}

double alphaSum(const Image& img) { return img.channelSum(3); }

/// A render's alpha against a silhouette known at 4x4 points per pixel:
/// `inside(x, y)` at raster positions (pixel px spans [px, px + 1)).
/// Pixels wholly in or out must agree to within half; the others are
/// edges; expectedTotal is the silhouette's area in pixels.
struct SilhouetteScore {
    double expectedTotal = 0;
    int wrong = 0, edges = 0;
};
SilhouetteScore scoreSilhouette(const Image& img, int width, int height,
                                const std::function<bool(double, double)>& inside) {
    SilhouetteScore score;
    for (int py = 0; py < height; ++py)
        for (int px = 0; px < width; ++px) {
            int in = 0;
            for (int sy = 0; sy < 4; ++sy)
                for (int sx = 0; sx < 4; ++sx) in += inside(px + (sx + 0.5) / 4, py + (sy + 0.5) / 4);
            score.expectedTotal += in / 16.0;
            if (in == 0 || in == 16) {
                if (std::fabs(img.at(px, py, 3) - in / 16.0) > 0.5) ++score.wrong;
            } else {
                ++score.edges;
            }
        }
    return score;
}

// The leaf field, written again: (1 - r^2)^3 inside the unit ball.
double bump(double r2) { return r2 < 1 ? std::pow(1 - r2, 3) : 0; }
double sphere(double s, double cx, double x, double y, double z) {
    const double dx = (x - cx) / s, dy = y / s, dz = z / s;
    return bump(dx * dx + dy * dy + dz * dz);
}

// A repelling plane's field at height z above its map's surface, written
// again from Application Note #31.
double repulsion(double z, double A, double B, double C, double D) {
    auto bump2 = [](double r) { return r <= 0 || r >= 2 ? 0 : (((6 - r) * r - 12) * r + 8) * r * r * r; };
    auto ease = [](double r) { return r <= 0 ? 0 : r >= 1 ? 1 : r * r * (3 - 2 * r); };
    if (z >= A) return 0;
    if (z <= 1e-6) z = 1e-6;
    return (D * bump2(z / C) - B / z) * (1 - ease(z / A));
}

// Side view for the ground scenes: orthographic along world +y, 80 pixels
// per unit, world x in [-1, 1] across and z in [-0.5, 1.5] up.
const char* const kSideCamera =
    "Projection \"orthographic\" ScreenWindow -1 1 -0.5 1.5 Transform [1 0 0 0  0 0 1 0  0 1 0 0  0 0 5 1]";

// A blob of surface radius 0.6 centred 0.45 above the ground z = 0, added
// to RI spec 3.2's example plane (A B C D = 0.4 0.01 0.3 0.08) of `map`.
std::string blobOverGround(const std::string& map) {
    return fmt::format("Surface \"constant\" Translate 0 0 0.45 Blobby 2 [1001 0 1003 0 16 0 2 0 1] [{}  0.4 0.01 "
                       "0.3 0.08] [\"{}\"]",
                       sphereLeaf(1.2, 0, 0, 0), map);
}

}  // namespace

TEST(BlobbyRender, EllipsoidSilhouetteHasTheClosedFormArea) {
    // Semi-axes 1.6/2 and 1.2/2 in x and y, turned 30 degrees about z, seen
    // down z: an ellipse of area pi * 0.8 * 0.6 whatever the turn.
    ScratchDir dir("blobby-ellipse");
    const double c = std::cos(kPi / 6), s = std::sin(kPi / 6);
    const std::string m = fmt::format("{} {} 0 0  {} {} 0 0  0 0 1 0  0.1 -0.05 0 1", 1.6 * c, 1.6 * s, -1.2 * s,
                                      1.2 * c);
    const std::string body = fmt::format("Surface \"constant\" Blobby 1 [1001 0] [{}] [\"\"]", m);
    // 100 pixels per unit.
    Image img = renderBlobby(dir, body, "Projection \"orthographic\" ScreenWindow -1 1 -1 1 Translate 0 0 5", 200, 200);
    const double expected = kPi * 0.8 * 0.6 * 100 * 100;
    EXPECT_NEAR(alphaSum(img), expected, 0.01 * expected);
}

TEST(BlobbyRender, CombinedFieldsHaveTheSilhouettesOfTheFieldEvaluatedHere) {
    // Orthographic down z, 50 pixels per unit. Each case's silhouette is
    // where max over z of the field reaches the threshold, computed here at
    // 4x4 points per pixel; the rendered coverage must match it pixel by
    // pixel but for antialiased edges, and in total within 1%.
    ScratchDir dir("blobby-ops");
    struct Case {
        const char* name;
        std::string code, floats;
        std::function<double(double, double, double)> field;
    };
    const std::string two = sphereLeaf(1.2, -0.7, 0, 0) + "  " + sphereLeaf(1.2, 0.7, 0, 0);
    const Case cases[] = {
        {"add (bridge)", "1001 0 1001 16 0 2 0 1", two,
         [](double x, double y, double z) { return sphere(1.2, -0.7, x, y, z) + sphere(1.2, 0.7, x, y, z); }},
        {"max (no bridge)", "1001 0 1001 16 2 2 0 1", two,
         [](double x, double y, double z) {
             return std::max(sphere(1.2, -0.7, x, y, z), sphere(1.2, 0.7, x, y, z));
         }},
        {"subtract (carves)", "1001 0 1001 16 4 0 1", sphereLeaf(1.8, 0, 0, 0) + "  " + sphereLeaf(1.2, 0.7, 0, 0),
         [](double x, double y, double z) { return sphere(1.8, 0, x, y, z) - sphere(1.2, 0.7, x, y, z); }},
        {"min (lens)", "1001 0 1001 16 3 2 0 1", sphereLeaf(1.8, -0.35, 0, 0) + "  " + sphereLeaf(1.8, 0.35, 0, 0),
         [](double x, double y, double z) {
             return std::min(sphere(1.8, -0.35, x, y, z), sphere(1.8, 0.35, x, y, z));
         }},
    };
    constexpr int W = 150, H = 75;
    for (const Case& c : cases) {
        Image img = renderBlobby(dir,
                           fmt::format("Surface \"constant\" Blobby 2 [{}] [{}] [\"\"]", c.code, c.floats),
                           "Projection \"orthographic\" ScreenWindow -1.5 1.5 -0.75 0.75 Translate 0 0 5", W, H);
        const SilhouetteScore sc = scoreSilhouette(img, W, H, [&](double rx, double ry) {
            const double x = -1.5 + rx / 50, y = 0.75 - ry / 50;
            double best = -1e9;
            for (int k = -50; k <= 50; ++k) best = std::max(best, c.field(x, y, k * 0.02));
            return best >= kT;
        });
        EXPECT_EQ(sc.wrong, 0) << c.name;
        EXPECT_NEAR(alphaSum(img), sc.expectedTotal, 0.01 * sc.expectedTotal) << c.name;
        // The centre pixel: bridged by add, a gap under max, carved out by
        // subtract only off centre (checked by the pixels above).
        const float centre = img.at(W / 2, H / 2, 3);
        if (c.name[0] == 'a') {
            EXPECT_GT(centre, 0.99f);
        }
        if (c.name[1] == 'a') {
            EXPECT_LT(centre, 0.01f);
        }
        EXPECT_GT(sc.edges, 0) << c.name;
    }
}

TEST(BlobbyRender, SphereBlobCastsItsShadowIntoAnAutomaticDepthMap) {
    // A blob sphere of radius 0.5 at z = -2 over the floor z = 0, lit by a
    // distant light travelling along (1, 0, 1): its shadow is an ellipse
    // centred at (2, 0, 0) with semi-axes 0.5 / cos 45 and 0.5, seen from
    // straight above (orthographic, 80 pixels per unit), clear of the blob.
    ScratchDir dir("blobby-shadow");
    auto scene = [&](bool blob) {
        return renderBlobby(dir,
                      fmt::format(R"(
LightSource "shadowdistant" 1 "from" [-1 0 -1] "to" [0 0 0] "shadowname" ["auto"] "samples" [16]
Surface "matte"
Polygon "P" [-4 -4 0  -4 4 0  4 4 0  4 -4 0]
{}
)",
                                  blob ? "Blobby 1 [1001 0] [" + sphereLeaf(1, 0, 0, -2) + "] [\"\"]" : ""),
                      "Projection \"orthographic\" ScreenWindow -1 3 -2 2 Translate 0 0 10", 320, 320,
                      "Option \"umbra\" \"shadowmapsize\" [1024]");
    };
    const Image lit = scene(false), shadowed = scene(true);
    int dark = 0;
    for (int y = 0; y < 320; ++y)
        for (int x = 0; x < 320; ++x) {
            const double wx = -1 + (x + 0.5) / 80;
            if (wx < 1.0) continue;  // the blob itself is seen left of x = 0.5
            if (shadowed.at(x, y, 0) < 0.5f * lit.at(x, y, 0)) ++dark;
        }
    const double expected = kPi * 0.5 * (0.5 / std::cos(kPi / 4)) * 80 * 80;
    EXPECT_NEAR(dark, expected, 0.02 * expected);
}

TEST(BlobbyRender, DisplacementMovesAlongTheOutwardNormalUnderEveryCamera) {
    // P += 0.1 N grows the radius-0.5 sphere's silhouette to radius 0.6, under
    // the plain camera and under an exporter's mirroring one alike.
    ScratchDir dir("blobby-displace");
    std::ofstream(dir.file("grow.sl")) << "displacement grow() { P += 0.1 * normalize(N); N = calculatenormal(P); }\n";
    const std::string body = "Attribute \"displacementbound\" \"sphere\" [0.1] Displacement \"grow\" "
                             "Surface \"constant\" Blobby 1 [1001 0] [" + sphereLeaf(1, 0, 0, 0) + "] [\"\"]";
    const double expected = kPi * 0.6 * 0.6 * 100 * 100;
    for (const char* camera : {"Projection \"orthographic\" ScreenWindow -1 1 -1 1 Translate 0 0 5",
                               "Projection \"orthographic\" ScreenWindow -1 1 -1 1 Scale 1 1 -1 Translate 0 0 -5"}) {
        Image img = renderBlobby(dir, body, camera, 200, 200);
        EXPECT_NEAR(alphaSum(img), expected, 0.01 * expected) << camera;
    }
}

TEST(BlobbyRender, OutwardSideFollowsOrientationAndAFloppingCameraFlopsThePicture) {
    ScratchDir dir("blobby-flop");
    std::ofstream(dir.file("facing.sl"))
        << "surface facing() { if (Ng . I < 0) Ci = color(1, 0, 0); else Ci = color(0, 1, 0); Oi = 1; }\n";
    const std::string blob = "Blobby 2 [1001 0 1001 16 0 2 0 1] [" + sphereLeaf(1.2, -0.5, 0.1, 0) + "  " +
                             sphereLeaf(0.9, 0.5, -0.1, 0.2) + "] [\"\"] \"Cs\" [1 0.2 0  0 0.3 1]";
    const std::string plainCamera = "Projection \"perspective\" \"fov\" 30 Translate 0 0 5";
    const std::string flopCamera = "Projection \"perspective\" \"fov\" 30 Scale -1 1 1 Translate 0 0 5";
    // Seen from outside, the outward side faces the camera (red); turned
    // inside out, it faces away (green). A flopping camera makes the world
    // right-handed, so "outside" is still outside.
    for (const std::string& camera : {plainCamera, flopCamera})
        for (bool reversed : {false, true}) {
            Image img = renderBlobby(dir, std::string(reversed ? "ReverseOrientation " : "") + "Surface \"facing\" " + blob,
                               camera, 160, 120);
            int covered = 0, wanted = 0;
            for (int y = 0; y < img.height; ++y)
                for (int x = 0; x < img.width; ++x) {
                    const float r = img.at(x, y, 0), g = img.at(x, y, 1);
                    if (img.at(x, y, 3) < 0.99f) continue;
                    ++covered;
                    wanted += reversed ? (g > 0.9f && r < 0.1f) : (r > 0.9f && g < 0.1f);
                }
            EXPECT_GT(covered, 2000);
            EXPECT_GE(wanted, covered * 98 / 100) << camera << (reversed ? " reversed" : "");
        }
    // Lit plastic with per-leaf colours: the flopping camera's picture is the
    // plain one flopped, but for sample positions.
    const std::string lit = "LightSource \"distantlight\" 1 \"from\" [-1 1 -1] \"to\" [0 0 0] Surface \"plastic\" " + blob;
    Image plain = renderBlobby(dir, lit, plainCamera, 160, 120), flopped = renderBlobby(dir, lit, flopCamera, 160, 120);
    double diff = 0;
    for (int y = 0; y < 120; ++y)
        for (int x = 0; x < 160; ++x)
            for (int c = 0; c < 3; ++c) diff += std::fabs(plain.at(x, y, c) - flopped.at(159 - x, y, c));
    EXPECT_LT(diff / (160 * 120 * 3), 0.005);
    EXPECT_GT(plain.channelSum(0), 500.0);
}

TEST(BlobbyRender, RenderIsTheSameWhateverTheThreadCount) {
    ScratchDir dir("blobby-threads");
    const std::string body = "LightSource \"distantlight\" 1 Surface \"plastic\" Blobby 2 [1001 0 1001 16 0 2 0 1] [" +
                             sphereLeaf(1.2, -0.5, 0, 0) + "  " + sphereLeaf(1.2, 0.5, 0, 0) + "] [\"\"]";
    const std::string camera = "Projection \"perspective\" \"fov\" 30 Translate 0 0 5";
    Image one = renderBlobby(dir, body, camera, 96, 64, "", 1), four = renderBlobby(dir, body, camera, 96, 64, "", 4);
    EXPECT_EQ(test::maxAbsDiff(one, four, 4), 0.0);
}

TEST(BlobbyRender, RepellingPlaneKeepsTheBlobOffTheGroundItsMapStores) {
    // The ground's depth map is rendered by umbra from 5 units above it: a
    // zfile from an orthographic view (as PRMan's "zfile" display writes
    // it) and a tiled EXR map (the "shadow" display) from a perspective
    // one, where the height is still measured along the view axis. The blob
    // over it is seen from the side. Its silhouette is where the field, the
    // sphere's plus the plane's of the height z above the ground, reaches
    // the threshold at y = 0 (the plane does not depend on y, so the field
    // is largest there), computed here at 4x4 points per pixel: the render
    // must match it pixel by pixel but for antialiased edges, and in total
    // within 1%.
    ScratchDir dir("blobby-plane");
    for (const bool perspective : {false, true}) {
        SCOPED_TRACE(perspective ? "perspective EXR map" : "orthographic zfile");
        const std::string map = dir.file(perspective ? "ground.exr" : "ground.zfile");
        Diagnostics mapDiag;
        mapDiag.setQuiet(true);
        test::renderRib(fmt::format(R"(
Format 64 64 1
PixelSamples 1 1
Display "{}" "{}" "z"
{}
Scale 1 1 -1 Translate 0 0 -5
WorldBegin
Polygon "P" [-6 -6 0  6 -6 0  6 6 0  -6 6 0]
WorldEnd
)",
                                    map, perspective ? "shadow" : "zfile",
                                    perspective ? "Projection \"perspective\" \"fov\" 60"
                                                : "Projection \"orthographic\" ScreenWindow -2 2 -2 2"),
                        mapDiag);
        ASSERT_EQ(mapDiag.errorCount(), 0);
        ASSERT_TRUE(std::filesystem::exists(map));
        Diagnostics diag;
        diag.setRecord(true);
        constexpr int W = 160, H = 160;
        const Image img = renderBlobby(dir, blobOverGround(map), kSideCamera, W, H, "", 0, &diag);
        EXPECT_EQ(diag.warningCount(), 0);
        auto field = [](double x, double z) {
            return sphere(1.2, 0, x, 0, z - 0.45) + repulsion(z, 0.4, 0.01, 0.3, 0.08);
        };
        const SilhouetteScore sc = scoreSilhouette(
            img, W, H, [&](double rx, double ry) { return field(-1 + rx / 80, 1.5 - ry / 80) >= kT; });
        EXPECT_EQ(sc.wrong, 0);
        EXPECT_GT(sc.edges, 0);
        EXPECT_NEAR(alphaSum(img), sc.expectedTotal, 0.01 * sc.expectedTotal);
        int lowestRow = -1;
        for (int py = 0; py < H; ++py)
            for (int px = 0; px < W; ++px)
                if (img.at(px, py, 3) > 0.5f) lowestRow = std::max(lowestRow, py);
        // The lowest point, on the vertical through the centre, by bisection:
        // 0.037 above the ground, where the sphere alone reaches 0.15 under it.
        double lo = 1e-6, hi = 0.45;
        for (int k = 0; k < 60; ++k) (field(0, (lo + hi) / 2) >= kT ? hi : lo) = (lo + hi) / 2;
        EXPECT_GT(hi, 0.03);
        EXPECT_NEAR(1.5 - (lowestRow + 0.5) / 80, hi, 1.5 / 80);
    }
}

TEST(BlobbyRender, RepellingPlaneWithoutItsMapIsWarnedAtTheRequestAndLeavesTheBlobAlone) {
    ScratchDir dir("blobby-nomap");
    const std::string map = dir.file("missing.zfile");
    Diagnostics diag;
    diag.setRecord(true);
    const std::string body = blobOverGround(map);
    const Image img = renderBlobby(dir, body, kSideCamera, 160, 160, "", 0, &diag);
    ASSERT_EQ(diag.recorded().size(), 1u);
    EXPECT_EQ(diag.recorded()[0].str(),
              fmt::format("test.rib:9:{}: warning: Blobby: cannot read the depth map of repelling plane leaf 1 (opcode "
                          "1003): cannot open \"{}\"; the leaf contributes nothing to the field",
                          body.find("Blobby") + 1, map));
    // The picture of the ellipsoid alone, pixel for pixel.
    const Image alone = renderBlobby(
        dir, "Surface \"constant\" Translate 0 0 0.45 Blobby 1 [1001 0] [" + sphereLeaf(1.2, 0, 0, 0) + "] [\"\"]",
        kSideCamera, 160, 160);
    EXPECT_EQ(test::maxAbsDiff(img, alone, 4), 0.0);
    EXPECT_GT(alphaSum(alone), 0.9 * kPi * 0.36 * 80 * 80);
}

// A field divided by a long, thin leaf (as in Aqsis's blob subtraction
// scene) jumps from a huge value to 0 where the divisor's support ends:
// coarse triangles across the jump project to both sides however small
// they are split. Splitting such a piece stops at 2^-16 of its triangle
// (well under a pixel here); at the earlier 2^-24 this frame took 396,000
// splits (56 s) and now takes 62,000.
TEST(BlobbyRender, DividingByAThinLeafSplitsABoundedNumberOfTimes) {
    ScratchDir dir("blobby-divide");
    const std::string rib =
        "Format 200 150 1\nProjection \"perspective\" \"fov\" 5\nDisplay \"" + dir.file("divide.tif") +
        "\" \"file\" \"rgba\"\nTranslate 0 0 30\nWorldBegin\nLightSource \"distantlight\" 1\nSurface \"plastic\"\n"
        "Translate .7 .55 0\nRotate 140 1 -1 1\n"
        "Blobby 2 [1001 0 1001 16 5 0 1] [1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1 "
        "5 0 0 0 0 0.4 0 0 0 0 0.4 0 0 0 0 1] [\"\"]\nWorldEnd\n";
    Diagnostics diag;
    diag.setQuiet(true);
    const nlohmann::json stats = test::renderRib(rib, diag);
    EXPECT_EQ(diag.errorCount(), 0);
    const auto& counts = stats["frames"][0]["passes"][0]["counts"];
    EXPECT_GT(counts["micropolygons"].get<uint64_t>(), 1000u);  // the quotient's surface is there
    EXPECT_LT(counts["splits"].get<uint64_t>(), 250000u);
}
