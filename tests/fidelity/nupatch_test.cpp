// NuPatch and TrimCurve (RI spec 3.2 §5.4) as exporters write them, checked
// against independent answers: the `Patch "bicubic"` a Bezier-knot NuPatch
// is, the quadric Sphere a revolved rational circle is, and the closed-form
// area of a circular trim hole, in the camera's picture and in the shadow an
// automatic depth map casts.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <string>

using namespace umbra;
using umbra::test::Image;
using umbra::test::maxAbsDiff;
using umbra::test::meanAbsDiff;
using umbra::test::ScratchDir;

namespace {

// The 9-point rational circle of order 3 (weights sqrt(2)/2 at the
// corners): control points (x, y, w), not multiplied by w.
struct CirclePoint {
    double x, y, w;
};
std::vector<CirclePoint> circle() {
    const double h = std::sqrt(0.5);
    return {{1, 0, 1}, {1, 1, h}, {0, 1, 1}, {-1, 1, h}, {-1, 0, 1}, {-1, -1, h}, {0, -1, 1}, {1, -1, h}, {1, 0, 1}};
}
constexpr const char* kCircleKnots = "[0 0 0 0.25 0.25 0.5 0.5 0.75 0.75 1 1 1]";

/// A sphere of `radius` at the origin: the circle revolved about z through
/// a half circle in the (r, z) plane.
std::string nurbsSphere(double radius) {
    const double h = std::sqrt(0.5);
    const double pr[5] = {0, 1, 1, 1, 0}, pz[5] = {-1, -1, 0, 1, 1}, pw[5] = {1, h, 1, h, 1};
    std::string pts;
    for (int j = 0; j < 5; ++j)
        for (const CirclePoint& c : circle()) {
            const double w = c.w * pw[j];
            pts +=
                fmt::format("{} {} {} {} ", c.x * pr[j] * radius * w, c.y * pr[j] * radius * w, pz[j] * radius * w, w);
        }
    return fmt::format("NuPatch 9 3 {} 0 1 5 3 [0 0 0 0.5 0.5 1 1 1] 0 1 \"Pw\" [{}]", kCircleKnots, pts);
}

/// TrimCurve: one loop, the circle of radius r about (cu, cv) in (u, v).
std::string circleTrim(double cu, double cv, double r) {
    std::string u, v, w;
    for (const CirclePoint& c : circle()) {
        u += fmt::format("{} ", (cu + r * c.x) * c.w);
        v += fmt::format("{} ", (cv + r * c.y) * c.w);
        w += fmt::format("{} ", c.w);
    }
    return fmt::format("TrimCurve [1] [3] {} [0] [1] [9] [{}] [{}] [{}]", kCircleKnots, u, v, w);
}

/// TrimCurve as exporters write a hole: a loop round the whole (u, v)
/// square (linear, the kept region's outline) and the circle of radius r
/// about (cu, cv) inside it.
std::string boundaryAndHoleTrim(double cu, double cv, double r) {
    std::string u = "0 1 1 0 0 ", v = "0 0 1 1 0 ", w = "1 1 1 1 1 ";
    for (const CirclePoint& c : circle()) {
        u += fmt::format("{} ", (cu + r * c.x) * c.w);
        v += fmt::format("{} ", (cv + r * c.y) * c.w);
        w += fmt::format("{} ", c.w);
    }
    const std::string circleKnots = kCircleKnots;
    return fmt::format("TrimCurve [1 1] [2 3] [0 0 1 2 3 4 4 {}] [0 0] [4 1] [5 9] [{}] [{}] [{}]",
                       circleKnots.substr(1, circleKnots.size() - 2), u, v, w);
}

/// A flat square NuPatch of side 2a at depth z, (u, v) = [0,1]^2.
std::string flatSquare(double a, double z) {
    return fmt::format(
        "NuPatch 2 2 [0 0 1 1] 0 1 2 2 [0 0 1 1] 0 1 \"P\" [{0} {0} {2} {1} {0} {2} {0} {1} {2} {1} {1} {2}]", -a, a,
        z);
}

constexpr int kSize = 200;  // pixels; the orthographic screen window is [-1, 1]^2

/// Renders `world` with an orthographic camera looking down +z; returns the image.
Image renderSquare(ScratchDir& dir, const std::string& world, const std::string& options = "") {
    const std::string image = dir.file("out.tif");
    const std::string rib = fmt::format(R"(
Format {0} {0} 1
PixelSamples 4 4
{2}
Display "{1}" "file" "rgba"
Projection "orthographic"
WorldBegin
{3}
WorldEnd
)",
                                        kSize, image, options, world);
    Diagnostics diag;
    diag.setQuiet(true);
    test::renderRib(rib, diag);
    EXPECT_EQ(diag.errorCount(), 0) << rib;
    Image img;
    EXPECT_TRUE(test::readImage(image, &img));
    return img;
}

double pixelsPerUnit() {
    return kSize / 2.0;
}

}  // namespace

TEST(NuPatch, BezierKnotsRenderAsTheBicubicPatch) {
    ScratchDir dir("nupatch-bicubic");
    const std::string P =
        "\"P\" [-0.8 -0.8 0  -0.3 -0.9 0.5  0.3 -0.7 -0.4  0.8 -0.8 0  -0.9 -0.3 0.3  -0.2 -0.2 1 "
        "0.3 -0.3 -1  0.9 -0.2 0  -0.7 0.3 0  -0.3 0.2 -1  0.2 0.3 1  0.8 0.3 0.2  -0.8 0.8 0  -0.3 "
        "0.9 0.4  0.2 0.7 -0.3  0.8 0.8 0]";
    const std::string scene =
        "Surface \"matte\" LightSource \"distantlight\" 1 \"from\" [1 2 -3] \"to\" [0 0 0] Translate 0 0 5 ";
    const Image a = renderSquare(dir, scene + "Patch \"bicubic\" " + P);
    const Image b = renderSquare(dir, scene + "NuPatch 4 4 [0 0 0 0 1 1 1 1] 0 1 4 4 [0 0 0 0 1 1 1 1] 0 1 " + P);
    ASSERT_EQ(a.pixels.size(), b.pixels.size());
    double maxDiff = 0, sumDiff = 0;
    for (size_t k = 0; k < a.pixels.size(); ++k) {
        maxDiff = std::max(maxDiff, double(std::abs(a.pixels[k] - b.pixels[k])));
        sumDiff += std::abs(a.pixels[k] - b.pixels[k]);
    }
    EXPECT_GT(a.channelSum(3), 1000);
    EXPECT_LE(maxDiff, 1.5 / 255);  // the 8-bit file: one level at most
    EXPECT_LT(sumDiff / double(a.pixels.size()), 1e-5);
}

TEST(NuPatch, RationalSphereCoversTheQuadricSpheresArea) {
    ScratchDir dir("nupatch-sphere");
    const double r = 0.7;
    const double nurbs = renderSquare(dir, "Translate 0.1 -0.05 5 " + nurbsSphere(r)).channelSum(3);
    const double quadric =
        renderSquare(dir, fmt::format("Translate 0.1 -0.05 5 Sphere {0} -{0} {0} 360", r)).channelSum(3);
    const double disk = double(kPi) * r * r * pixelsPerUnit() * pixelsPerUnit();
    EXPECT_NEAR(nurbs / quadric, 1.0, 0.005) << nurbs << " vs " << quadric;
    EXPECT_NEAR(nurbs / disk, 1.0, 0.005) << nurbs << " vs " << disk;
}

TEST(NuPatch, PartialRangeDrawsTheSubPatch) {
    // umin umax = 0.25 0.75 of a flat square: the middle half of its width.
    ScratchDir dir("nupatch-range");
    const double covered =
        renderSquare(
            dir,
            "NuPatch 2 2 [0 0 1 1] 0.25 0.75 2 2 [0 0 1 1] 0 1 \"P\" [-0.8 -0.8 5 0.8 -0.8 5 -0.8 0.8 5 0.8 0.8 5]")
            .channelSum(3);
    const double expected = 0.8 * 1.6 * pixelsPerUnit() * pixelsPerUnit();
    EXPECT_NEAR(covered / expected, 1.0, 0.005);
}

TEST(TrimCurve, CircleRemovesExactlyItsArea) {
    ScratchDir dir("trim-circle");
    const double a = 0.8, r = 0.3;  // r in (u, v), which spans 2a units
    const double square = 4 * a * a * pixelsPerUnit() * pixelsPerUnit();
    const double hole = double(kPi) * r * r * square;
    // As exporters write a hole: the outline of the kept region and the
    // hole's loop. What lies inside an odd number of loops is kept (the
    // default "sense" "inside", as Aqsis and PRMan); before, umbra removed
    // it, and such a surface drew only its holes.
    const double kept = renderSquare(dir, boundaryAndHoleTrim(0.5, 0.5, r) + " " + flatSquare(a, 5)).channelSum(3);
    EXPECT_NEAR(kept / (square - hole), 1.0, 0.005) << kept << " vs " << square - hole;
    // One loop alone keeps only its disk (Aqsis draws the same)...
    const std::string trim = circleTrim(0.5, 0.5, r);
    const double disk = renderSquare(dir, trim + " " + flatSquare(a, 5)).channelSum(3);
    EXPECT_NEAR(disk / hole, 1.0, 0.005) << disk << " vs " << hole;
    // ...and "sense" "outside" keeps the rest.
    const double outside =
        renderSquare(dir, "Attribute \"trimcurve\" \"sense\" \"outside\" " + trim + " " + flatSquare(a, 5))
            .channelSum(3);
    EXPECT_NEAR(outside / (square - hole), 1.0, 0.005) << outside << " vs " << square - hole;
    // Off-centre, crossing the knot lines of a finer patch (4 x 4 spans) and
    // seen at a slant (rotated about y): the area scales by cos(angle).
    const std::string fine = "NuPatch 5 2 [0 0 0.25 0.5 0.75 1 1] 0 1 5 2 [0 0 0.25 0.5 0.75 1 1] 0 1 \"P\" [";
    std::string pts;
    for (int j = 0; j < 5; ++j)
        for (int i = 0; i < 5; ++i) pts += fmt::format("{} {} 0 ", -a + 2 * a * i / 4.0, -a + 2 * a * j / 4.0);
    const double cosAngle = std::cos(30 * double(kPi) / 180);
    const double slanted =
        renderSquare(dir, "Translate 0 0 5 Rotate 30 0 1 0 " + boundaryAndHoleTrim(0.4, 0.55, 0.25) + " " + fine + pts + "]")
            .channelSum(3);
    const double expected = (square - double(kPi) * 0.25 * 0.25 * square) * cosAngle;
    EXPECT_NEAR(slanted / expected, 1.0, 0.005) << slanted << " vs " << expected;
    // AttributeEnd ends the trim: the next NuPatch is whole.
    const double whole =
        renderSquare(dir, "AttributeBegin " + trim + " AttributeEnd " + flatSquare(a, 5)).channelSum(3);
    EXPECT_NEAR(whole / square, 1.0, 0.002);
}

TEST(TrimCurve, AutomaticShadowMapsSeeTheHole) {
    // A ground plane lit straight on by a shadowed distant light; between
    // them, invisible to the camera, a trimmed square: its shadow has a lit
    // disk where the hole is.
    ScratchDir dir("trim-shadow");
    const double a = 0.6, r = 0.3;
    const std::string world = fmt::format(R"(
LightSource "shadowdistant" 1 "from" [0 0 0] "to" [0 0 1] "shadowname" ["auto"] "samples" [16] "width" [1] "bias" [0.05]
AttributeBegin
  Attribute "visibility" "camera" [0]
  {}
  {}
AttributeEnd
Surface "matte" "Ka" [0]
Polygon "P" [-1 -1 8  1 -1 8  1 1 8  -1 1 8]
)",
                                          boundaryAndHoleTrim(0.5, 0.5, r), flatSquare(a, 4));
    const Image img = renderSquare(dir, world, "Option \"umbra\" \"shadowmapsize\" [400]");
    double lit = 0;
    int centreLit = 0, ringDark = 0;
    const double ppu = pixelsPerUnit();
    for (int y = 0; y < kSize; ++y)
        for (int x = 0; x < kSize; ++x) {
            const double wx = (x + 0.5) / ppu - 1, wy = 1 - (y + 0.5) / ppu;
            const double red = img.at(x, y, 0);
            if (std::abs(wx) < a && std::abs(wy) < a) lit += red;
            const double d = std::hypot(wx, wy) / (2 * a);  // in (u, v) units from the hole's centre
            if (d < r - 0.05 && red > 0.9) ++centreLit;
            if (d > r + 0.05 && std::abs(wx) < a - 0.05 && std::abs(wy) < a - 0.05 && red < 0.1) ++ringDark;
        }
    const double hole = double(kPi) * r * r * 4 * a * a * ppu * ppu;
    EXPECT_NEAR(lit / hole, 1.0, 0.03) << lit << " vs " << hole;
    EXPECT_GT(centreLit, int(double(kPi) * (r - 0.05) * (r - 0.05) * 4 * a * a * ppu * ppu * 0.98));
    EXPECT_GT(ringDark, 0);
}
