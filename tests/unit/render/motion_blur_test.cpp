// Motion blur and depth of field against closed forms (issue 18): a
// translating square's averaged coverage, a rotating bar's, a point
// defocused to the thin lens's circle of confusion, an in-focus plane that
// stays sharp, deformation blur against the average of still renders, and
// the blurred shadow of a moving caster.

#include "support/render_harness.h"

#include "umbra/shadow/depth_image.h"
#include "umbra/util/motion.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <fmt/format.h>

namespace umbra {
namespace {

using test::Image;
using test::ScratchDir;

/// Renders RIB whose Display is "out.tif", written into `dir`.
Image render(std::string rib, const ScratchDir& dir, int threads = 0, int bucket = 0) {
    Diagnostics diag;
    diag.setRecord(true);
    const std::string out = dir.file("out.tif");
    rib.replace(rib.find("\"out.tif\""), 9, "\"" + out + "\"");
    Image img = test::renderImage(rib, out, diag, threads, bucket);
    EXPECT_EQ(diag.errorCount(), 0) << (diag.recorded().empty() ? "" : diag.recorded()[0].message);
    return img;
}

/// An orthographic frame whose raster pixel (x, y) is the unit square at
/// camera x in [x - w/2, x - w/2 + 1], y downwards from h/2.
std::string orthoFrame(int w, int h, int samples, const std::string& extra = "") {
    return fmt::format(
        "Format {} {} 1\nPixelSamples {} {}\nPixelFilter \"box\" 1 1\nProjection \"orthographic\"\n"
        "ScreenWindow {} {} {} {}\nQuantize \"rgba\" 0 0 0 0\nDisplay \"out.tif\" \"file\" \"rgba\"\n{}",
        w, h, samples, samples, -w / 2.0, w / 2.0, -h / 2.0, h / 2.0, extra);
}

// The average over the shutter of a square [c-4, c+4] moving from c = -10
// to c = 10 covering the pixel column [x0, x0 + 1]: closed form.
double slidingCoverage(double x0) {
    auto overlapIntegral = [](double a) {  // integral over c of max(0, min(a+1, c+4) - max(a, c-4)) dc, c in [-10, 10]
        double s = 0;
        const int n = 20000;
        for (int i = 0; i < n; ++i) {
            const double c = -10 + 20 * (i + 0.5) / n;
            s += std::max(0.0, std::min(a + 1, c + 4) - std::max(a, c - 4));
        }
        return s / n;
    };
    return overlapIntegral(x0);
}

/// A 48 x 16 frame of something sliding along x: each column's coverage
/// averaged over the rows within 0.01 of `expected(x0)` (the column
/// [x0, x0 + 1] in camera units), and the columns' sum, the covered area
/// per row, within 1% of `area`.
void expectColumnProfile(const Image& img, const char* what, const std::function<double(double)>& expected,
                         double area) {
    ASSERT_EQ(img.width, 48) << what;
    double worst = 0, total = 0;
    for (int x = 0; x < 48; ++x) {
        double column = 0;
        for (int y = 0; y < 16; ++y) column += img.at(x, y, 3);
        column /= 16;
        total += column;
        worst = std::max(worst, std::abs(column - expected(x - 24.0)));
    }
    EXPECT_NEAR(total, area, 0.01 * area) << what;
    EXPECT_LT(worst, 0.01) << what << ": largest error of a column's averaged coverage";
}

/// The square sliding from c = -10 to 10: 8 pixels a row.
void expectSlidingSquare(const Image& img, const char* what) { expectColumnProfile(img, what, slidingCoverage, 8.0); }

TEST(MotionBlur, TranslatingSquareLeavesTheAveragedCoverageProfile) {
    ScratchDir dir("mb-square");
    const std::string rib = orthoFrame(48, 16, 8, "Shutter 0 1\n") +
                            "WorldBegin\nSurface \"constant\"\n"
                            "MotionBegin [0 1]\nTranslate -10 0 0\nTranslate 10 0 0\nMotionEnd\n"
                            "Polygon \"P\" [-4 -8 5  4 -8 5  4 8 5  -4 8 5]\nWorldEnd\n";
    expectSlidingSquare(render(rib, dir), "polygon");
}

// Keys that leave part of the shutter uncovered hold the piece at their
// first (or last) position there: a square keyed at times 0.5 and 1 under
// Shutter 0 1 stands at c = -10 for the first half and slides to 10 in the
// second. (Aqsis 1.8.4 draws the held half at about a third of its
// coverage, and Pixie 2.2.6 nothing of this orthographic frame.)
TEST(MotionBlur, KeysCoveringPartOfTheShutterHoldTheirEnds) {
    ScratchDir dir("mb-held");
    const std::string rib = orthoFrame(48, 16, 8, "Shutter 0 1\n") +
                            "WorldBegin\nSurface \"constant\"\n"
                            "MotionBegin [0.5 1]\nTranslate -10 0 0\nTranslate 10 0 0\nMotionEnd\n"
                            "Polygon \"P\" [-4 -8 5  4 -8 5  4 8 5  -4 8 5]\nWorldEnd\n";
    auto heldThenSliding = [](double x0) {
        const double held = std::max(0.0, std::min(x0 + 1, -6.0) - std::max(x0, -14.0));
        return 0.5 * held + 0.5 * slidingCoverage(x0);
    };
    expectColumnProfile(render(rib, dir), "held, then sliding", heldThenSliding, 8.0);
}

// A motion block inside an object definition moves every instance (as
// Pixie and Aqsis draw it); it was dropped, and the square drawn sharp at
// its first key. An instance placed by a moving transform of its own adds
// that motion to the piece's.
TEST(MotionBlur, AMotionBlockInsideAnObjectMovesItsInstances) {
    ScratchDir dir("mb-object");
    const std::string square = "Polygon \"P\" [-4 -8 5  4 -8 5  4 8 5  -4 8 5]\n";
    for (const char* block : {"TransformBegin\n", "AttributeBegin\n"}) {
        const std::string end = std::string(block) == "TransformBegin\n" ? "TransformEnd\n" : "AttributeEnd\n";
        const std::string rib = orthoFrame(48, 16, 8, "Shutter 0 1\n") +
                                "WorldBegin\nSurface \"constant\"\nObjectBegin 1\n" + block +
                                "MotionBegin [0 1]\nTranslate -10 0 0\nTranslate 10 0 0\nMotionEnd\n" + square + end +
                                "ObjectEnd\nObjectInstance 1\nWorldEnd\n";
        expectSlidingSquare(render(rib, dir), block);
    }
    // Half the sweep in the definition, half around the instance: the same
    // profile as the whole sweep in one block.
    const std::string both = orthoFrame(48, 16, 8, "Shutter 0 1\n") +
                             "WorldBegin\nSurface \"constant\"\nObjectBegin 1\n"
                             "MotionBegin [0 1]\nTranslate -5 0 0\nTranslate 5 0 0\nMotionEnd\n" + square +
                             "ObjectEnd\nMotionBegin [0 1]\nTranslate -5 0 0\nTranslate 5 0 0\nMotionEnd\n"
                             "ObjectInstance 1\nWorldEnd\n";
    expectSlidingSquare(render(both, dir), "moving instance of a moving piece");
}

TEST(MotionBlur, MovingCurvesLeaveTheAveragedCoverageProfile) {
    // A camera-facing ribbon 8 wide from y = -8 to 8 is the square above:
    // moved by a transform and deformed between two shapes, it must leave
    // the same averaged coverage (curves take the one motion path of every
    // family).
    ScratchDir dir("mb-curves");
    const std::string transformed = orthoFrame(48, 16, 8, "Shutter 0 1\n") +
                                    "WorldBegin\nSurface \"constant\"\n"
                                    "MotionBegin [0 1]\nTranslate -10 0 0\nTranslate 10 0 0\nMotionEnd\n"
                                    "Curves \"linear\" [2] \"nonperiodic\" \"P\" [0 -8 5  0 8 5] "
                                    "\"constantwidth\" [8]\nWorldEnd\n";
    const std::string deformed = orthoFrame(48, 16, 8, "Shutter 0 1\n") +
                                 "WorldBegin\nSurface \"constant\"\nMotionBegin [0 1]\n"
                                 "Curves \"linear\" [2] \"nonperiodic\" \"P\" [-10 -8 5  -10 8 5] \"constantwidth\" [8]\n"
                                 "Curves \"linear\" [2] \"nonperiodic\" \"P\" [10 -8 5  10 8 5] \"constantwidth\" [8]\n"
                                 "MotionEnd\nWorldEnd\n";
    // A ribbon (curves given normals) facing the eye, its normals tilting
    // along the curve between the keys: its width direction, across N and
    // the tangent, stays x at every time, so it too is the square.
    const std::string ribbon = orthoFrame(48, 16, 8, "Shutter 0 1\n") +
                               "WorldBegin\nSurface \"constant\"\nMotionBegin [0 1]\n"
                               "Curves \"linear\" [2] \"nonperiodic\" \"P\" [-10 -8 5  -10 8 5] "
                               "\"N\" [0 0 -1  0 0 -1] \"constantwidth\" [8]\n"
                               "Curves \"linear\" [2] \"nonperiodic\" \"P\" [10 -8 5  10 8 5] "
                               "\"N\" [0 -0.6 -0.8  0 -0.6 -0.8] \"constantwidth\" [8]\n"
                               "MotionEnd\nWorldEnd\n";
    expectSlidingSquare(render(transformed, dir), "transformed");
    expectSlidingSquare(render(deformed, dir), "deformed");
    expectSlidingSquare(render(ribbon, dir), "ribbon");
}

TEST(MotionBlur, MovingBlobbyLeavesTheSlidingDiscsAveragedCoverage) {
    // A sphere blob of surface radius 4 (a leaf of scale 8: the threshold
    // lies at half the leaf's radius) sliding from x = -10 to 10, moved by
    // a transform and deformed between two Blobby shapes: each column's
    // coverage averaged over the shutter and the rows is the disc's, in
    // closed form (the chord 2 sqrt(16 - (x - c)^2) integrated over the
    // column and over c). Before deformation blur was built, the deformed
    // Blobby rendered its first shape only.
    ScratchDir dir("mb-blobby");
    auto leaf = [](double c) { return fmt::format("8 0 0 0  0 8 0 0  0 0 8 0  {} 0 5 1", c); };
    const std::string transformed = orthoFrame(48, 16, 8, "Shutter 0 1\n") +
                                    "WorldBegin\nSurface \"constant\"\n"
                                    "MotionBegin [0 1]\nTranslate -10 0 0\nTranslate 10 0 0\nMotionEnd\n"
                                    "Blobby 1 [1001 0] [" + leaf(0) + "] [\"\"]\nWorldEnd\n";
    const std::string deformed = orthoFrame(48, 16, 8, "Shutter 0 1\n") +
                                 "WorldBegin\nSurface \"constant\"\nMotionBegin [0 1]\n"
                                 "Blobby 1 [1001 0] [" + leaf(-10) + "] [\"\"]\n"
                                 "Blobby 1 [1001 0] [" + leaf(10) + "] [\"\"]\n"
                                 "MotionEnd\nWorldEnd\n";
    auto chordIntegral = [](double a, double b) {  // integral of 2 sqrt(16 - u^2) du over [a, b] within [-4, 4]
        auto F = [](double u) {
            u = std::clamp(u, -4.0, 4.0);
            return u * std::sqrt(16 - u * u) + 16 * std::asin(u / 4);
        };
        return F(b) - F(a);
    };
    auto expected = [&](double x0) {
        double s = 0;
        const int n = 4000;
        for (int i = 0; i < n; ++i) {
            const double c = -10 + 20 * (i + 0.5) / n;
            s += chordIntegral(x0 - c, x0 + 1 - c);
        }
        return s / n / 16;  // averaged over the shutter and the 16 rows
    };
    for (const std::string* rib : {&transformed, &deformed})
        expectColumnProfile(render(*rib, dir), rib == &deformed ? "deformed" : "transformed", expected,
                            16 * M_PI / 16);  // the disc's area over the 16 rows
}

TEST(MotionBlur, RotatingBarMatchesItsClosedForm) {
    // A bar of half-width 0.5 (256 samples a pixel) from the centre out to radius 30 turns through
    // 90 degrees (Rotate keys: the path is the arc, not the chord). A point
    // at radius r inside the swept quarter is covered while the bar's
    // angular width 2 asin(0.5 / r) passes over it: a fraction
    // 2 asin(0.5 / r) / (pi / 2) of the shutter.
    ScratchDir dir("mb-bar");
    const std::string rib = orthoFrame(80, 80, 16, "Shutter 0 1\n") +
                            "WorldBegin\nSurface \"constant\"\n"
                            "MotionBegin [0 1]\nRotate 0 0 0 1\nRotate 90 0 0 1\nMotionEnd\n"
                            "Polygon \"P\" [0 -0.5 5  30 -0.5 5  30 0.5 5  0 0.5 5]\nWorldEnd\n";
    Image img = render(rib, dir);
    ASSERT_EQ(img.width, 80);
    // Rings of radius 10..25, angles 20..70 degrees (away from the ends).
    for (double r0 : {10.0, 15.0, 20.0}) {
        double sum = 0;
        int count = 0;
        for (int y = 0; y < 80; ++y)
            for (int x = 0; x < 80; ++x) {
                const double cx = x + 0.5 - 40, cy = 40 - (y + 0.5);
                const double r = std::hypot(cx, cy), a = std::atan2(cy, cx);
                if (r < r0 || r >= r0 + 5 || a < 0.35 || a > 1.22) continue;
                sum += img.at(x, y, 3) / (2 * std::asin(0.5 / r) / (kPi / 2));
                ++count;
            }
        ASSERT_GT(count, 20);
        EXPECT_NEAR(sum / count, 1.0, 0.03) << "ring at radius " << r0 << ": measured / closed-form coverage";
    }
}

TEST(MotionBlur, RotationKeysFollowTheArc) {
    // Decomposed interpolation: halfway between Rotate 0 and Rotate 90 is Rotate 45.
    MotionTransform m;
    m.postMultiplyMoving({0, 1}, {Mat4::rotate(0, {0, 0, 1}), Mat4::rotate(90, {0, 0, 1})});
    const Mat4 half = m.at(0.5f), expected = Mat4::rotate(45, {0, 0, 1});
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) EXPECT_NEAR(half.m[i][j], expected.m[i][j], 1e-5) << i << "," << j;
    // Translation and scale interpolate linearly, and a fixed transform after a
    // moving one stays outside it: an orbit at radius 2.
    MotionTransform orbit;
    orbit.postMultiplyMoving({0, 1}, {Mat4::rotate(0, {0, 0, 1}), Mat4::rotate(90, {0, 0, 1})});
    orbit.postMultiply(Mat4::translate({2, 0, 0}));
    const Vec3 p = orbit.at(0.5f).point({0, 0, 0});
    EXPECT_NEAR(length(p), 2.0f, 1e-5);
    MotionTransform grow;
    grow.postMultiplyMoving({0, 2}, {Mat4::scale({1, 1, 1}), Mat4::scale({3, 3, 3})});
    EXPECT_NEAR(grow.at(1.0f).point({1, 0, 0}).x, 2.0f, 1e-5);
    EXPECT_NEAR(grow.at(5.0f).point({1, 0, 0}).x, 3.0f, 1e-5);  // held after the last key
}

TEST(MotionBlur, ABlockOfOneRequestMovesItsParametersLinearly) {
    // RI Spec 3.2: a motion block's parameters change linearly. A Rotate
    // keyed 0 and 270 degrees is at 135 halfway (the matrices' shorter arc
    // would turn the other way); 0 and 360 is a whole turn, not a standstill.
    using Kind = TransformRequest::Kind;
    auto rotate = [](float angle) {
        return TransformRequest{Kind::Rotate, {angle, 0, 0, 2}, Mat4::rotate(angle, {0, 0, 2})};
    };
    auto expectMatrix = [](const Mat4& got, const Mat4& want, const char* what) {
        for (int i = 0; i < 4; ++i)
            for (int j = 0; j < 4; ++j) EXPECT_NEAR(got.m[i][j], want.m[i][j], 1e-5) << what << " " << i << "," << j;
    };
    MotionTransform threeQuarters, whole;
    threeQuarters.postMultiplyMoving({0, 1}, std::vector<TransformRequest>{rotate(0), rotate(270)});
    whole.postMultiplyMoving({0, 1}, std::vector<TransformRequest>{rotate(0), rotate(360)});
    expectMatrix(threeQuarters.at(0.5f), Mat4::rotate(135, {0, 0, 1}), "rotate 0..270 at 1/2");
    expectMatrix(whole.at(0.25f), Mat4::rotate(90, {0, 0, 1}), "rotate 0..360 at 1/4");
    EXPECT_NEAR(whole.turnBetween(0, 1), 2 * kPi, 1e-5);  // placements sample the whole turn
    // A Scale from 1 to -1 flattens through 0 (the matrices' decomposition
    // tumbled it as a half turn); a Skew stays a shear.
    MotionTransform flip;
    flip.postMultiplyMoving({0, 1}, std::vector<TransformRequest>{{Kind::Scale, {1, 1, 1}, Mat4::scale({1, 1, 1})},
                                                                 {Kind::Scale, {-1, 1, 1}, Mat4::scale({-1, 1, 1})}});
    expectMatrix(flip.at(0.25f), Mat4::scale({0.5f, 1, 1}), "scale 1..-1 at 1/4");
    expectMatrix(flip.at(0.5f), Mat4::scale({0, 1, 1}), "scale 1..-1 at 1/2");
    Mat4 skew0, skew60, skew30;
    ASSERT_TRUE(skewMatrix(0, {0, 1, 0}, {1, 0, 0}, &skew0));
    ASSERT_TRUE(skewMatrix(60, {0, 1, 0}, {1, 0, 0}, &skew60));
    ASSERT_TRUE(skewMatrix(30, {0, 1, 0}, {1, 0, 0}, &skew30));
    MotionTransform shear;
    shear.postMultiplyMoving({0, 1}, std::vector<TransformRequest>{{Kind::Skew, {0, 0, 1, 0, 1, 0, 0}, skew0},
                                                                  {Kind::Skew, {60, 0, 1, 0, 1, 0, 0}, skew60}});
    expectMatrix(shear.at(0.5f), skew30, "skew 0..60 at 1/2");
    EXPECT_NEAR(shear.at(0.5f).point({0, 1, 0}).y, 1.0f, 1e-6);  // y untouched at every time
    // Requests of different kinds, or Rotates about different axes, blend
    // their matrices as before.
    MotionTransform mixed, byMatrix;
    mixed.postMultiplyMoving({0, 1}, std::vector<TransformRequest>{rotate(0), {Kind::Rotate, {90, 1, 0, 0},
                                                                              Mat4::rotate(90, {1, 0, 0})}});
    byMatrix.postMultiplyMoving({0, 1}, {Mat4::rotate(0, {0, 0, 1}), Mat4::rotate(90, {1, 0, 0})});
    expectMatrix(mixed.at(0.3f), byMatrix.at(0.3f), "rotations about two axes");
}

TEST(MotionBlur, ABarKeyedThreeQuartersOfATurnSweepsThem) {
    // The bar of RotatingBarMatchesItsClosedForm keyed Rotate 0 and 270:
    // it sweeps counter-clockwise through three quadrants, covering a
    // point at radius r there a fraction 2 asin(0.5 / r) / (3 pi / 2) of
    // the shutter, and never the fourth (the matrices' shorter way round
    // turned it 90 degrees clockwise through that one alone). Its path
    // is placed in chords of at most pi/16 (8 a key interval, before: 0.965
    // of the closed form).
    ScratchDir dir("mb-bar270");
    const std::string rib = orthoFrame(80, 80, 16, "Shutter 0 1\n") +
                            "WorldBegin\nSurface \"constant\"\n"
                            "MotionBegin [0 1]\nRotate 0 0 0 1\nRotate 270 0 0 1\nMotionEnd\n"
                            "Polygon \"P\" [0 -0.5 5  30 -0.5 5  30 0.5 5  0 0.5 5]\nWorldEnd\n";
    Image img = render(rib, dir);
    ASSERT_EQ(img.width, 80);
    double swept = 0, fourth = 0;
    int count = 0, fourthCount = 0;
    for (int y = 0; y < 80; ++y)
        for (int x = 0; x < 80; ++x) {
            const double cx = x + 0.5 - 40, cy = 40 - (y + 0.5);
            const double r = std::hypot(cx, cy);
            double a = std::atan2(cy, cx);
            if (a < 0) a += 2 * kPi;
            if (r < 10 || r >= 25) continue;  // away from the bar's ends
            if (a > 0.35 && a < 3 * kPi / 2 - 0.35) {
                swept += img.at(x, y, 3) / (2 * std::asin(0.5 / r) / (3 * kPi / 2));
                ++count;
            } else if (a > 3 * kPi / 2 + 0.35 && a < 2 * kPi - 0.35) {
                fourth += img.at(x, y, 3);
                ++fourthCount;
            }
        }
    ASSERT_GT(count, 100);
    ASSERT_GT(fourthCount, 20);
    EXPECT_NEAR(swept / count, 1.0, 0.03) << "measured / closed-form coverage in the swept quadrants";
    EXPECT_EQ(fourth, 0.0) << "the quadrant the bar never reaches";
}

TEST(MotionBlur, AOneSidedCardTurningItsBackShowsWhileItFacesTheEye) {
    // A Sides 1 card 40 units wide turning about y from 0 to 180 degrees
    // (orthographic, Rotate keyed linearly in its angle): at angle a its
    // half-width is 20 |cos a|, and it faces the eye for a < 90 only. A
    // column at x is covered while 20 |cos a| > |x|: a fraction
    // acos(|x| / 20) / pi of the shutter facing the eye, and as long again
    // facing away, which Sides 2 shows too. Culled only when it faced
    // away at every key, it showed for both (the Sides 2 picture).
    ScratchDir dir("mb-card");
    const std::string card = "MotionBegin [0 1]\nRotate 0 0 1 0\nRotate 180 0 1 0\nMotionEnd\n"
                             "Polygon \"P\" [-20 -10 0  20 -10 0  20 10 0  -20 10 0]\nWorldEnd\n";
    auto frame = [&](int sides) {
        return orthoFrame(48, 16, 8, "Shutter 0 1\n") + fmt::format("WorldBegin\nSurface \"constant\"\nSides {}\n", sides) +
               "Translate 0 0 30\n" + card;
    };
    const Image one = render(frame(1), dir), two = render(frame(2), dir);
    ASSERT_EQ(one.width, 48);
    ASSERT_EQ(two.width, 48);
    double worst = 0;
    for (int x = 8; x < 40; ++x) {
        double a = 0, b = 0;
        for (int y = 0; y < 16; ++y) a += one.at(x, y, 3), b += two.at(x, y, 3);
        a /= 16, b /= 16;
        const double expected = std::acos(std::abs(x + 0.5 - 24) / 20) / kPi;
        worst = std::max({worst, std::abs(a - expected), std::abs(b - 2 * expected)});
    }
    EXPECT_LT(worst, 0.03) << "largest error of a column's coverage, Sides 1 and 2";
}

/// A perspective frame with a lens; fov 90 over 96 pixels: 48 pixels per unit of x/z.
std::string lensFrame(const std::string& dof, int samples = 8) {
    return fmt::format("Format 96 96 1\nPixelSamples {0} {0}\nPixelFilter \"box\" 1 1\n"
                       "Projection \"perspective\" \"fov\" 90\n{1}\nQuantize \"rgba\" 0 0 0 0\nDisplay \"out.tif\" \"file\" \"rgba\"\n",
                       samples, dof);
}

TEST(DepthOfField, APointBlursToTheThinLensCircle) {
    // fstop 2, focal length 1: lens radius 0.25 camera units. Focused at
    // 20, a point at depth 2 spreads over radius 0.25 |1/20 - 1/2| in x/z,
    // times 48 pixels per unit: 5.4 pixels. The "point" is a square of
    // half-side 0.04 (0.96 pixels; its area on screen is exact, where a
    // disc this small dices into a polygon).
    ScratchDir dir("dof-point");
    const double lensRadius = 0.25, focus = 20, depth = 2, half = 0.04;
    const double confusion = lensRadius * std::abs(1 / focus - 1 / depth) * 48;  // radius in pixels
    const double halfPixels = half / depth * 48;
    const std::string rib = fmt::format(
        "Format 96 96 1\nPixelSamples 16 16\nPixelFilter \"box\" 1 1\nProjection \"perspective\" \"fov\" 90\n"
        "DepthOfField 2 1 20\nQuantize \"rgba\" 0 0 0 0\nDisplay \"out.tif\" \"file\" \"rgba\"\n"
        "WorldBegin\nSurface \"constant\"\nTranslate 0 0 {0}\n"
        "Polygon \"P\" [-{1} -{1} 0  {1} -{1} 0  {1} {1} 0  -{1} {1} 0]\nWorldEnd\n", depth, half);
    Image img = render(rib, dir);
    ASSERT_EQ(img.width, 96);
    // The image is the square convolved with the circle of confusion and the
    // one-pixel box filter: mean squared radius R^2/2 + 2 a^2/3 + 1/6.
    double sum = 0, moment = 0;
    for (int y = 0; y < 96; ++y)
        for (int x = 0; x < 96; ++x) {
            const double a = img.at(x, y, 3), r2 = std::pow(x + 0.5 - 48, 2) + std::pow(y + 0.5 - 48, 2);
            sum += a;
            moment += a * r2;
        }
    ASSERT_GT(sum, 0);
    const double measured = std::sqrt(2 * (moment / sum - 2 * halfPixels * halfPixels / 3 - 1.0 / 6));
    EXPECT_NEAR(2 * measured, 2 * confusion, 1.0) << "diameter of the blurred point, pixels";
    // Alpha is conserved: the square's own area on screen.
    const double squarePixels = 4 * halfPixels * halfPixels;
    EXPECT_NEAR(sum, squarePixels, 0.03 * squarePixels);
}

TEST(DepthOfField, AnInFocusPlaneStaysSharp) {
    ScratchDir dir("dof-focus");
    const std::string world =
        "WorldBegin\nSurface \"constant\"\nColor [1 0.5 0.25]\nTranslate 0 0 4\n"
        "Polygon \"P\" [-1 -1 0  1.5 -1 0  1.5 0.7 0  -1 0.7 0]\nWorldEnd\n";
    Image sharp = render(lensFrame("") + world, dir);
    Image focused = render(lensFrame("DepthOfField 1.4 0.5 4") + world, dir);
    ASSERT_EQ(sharp.width, focused.width);
    EXPECT_EQ(test::maxAbsDiff(sharp, focused, 4), 0.0) << "bit-identical at the focal distance";
    Image defocused = render(lensFrame("DepthOfField 1.4 0.5 8") + world, dir);
    EXPECT_GT(test::maxAbsDiff(sharp, defocused, 4), 0.2);
}

TEST(MotionBlur, DeformationEqualsTheAverageOfStillRenders) {
    // A bilinear patch whose corners move between two shapes; the blurred
    // render against the average of 32 still renders at the stratum centres
    // of the shutter, each with its corners interpolated.
    ScratchDir dir("mb-deform");
    const float a[12] = {-8, -6, 5, 6, -6, 5, -6, 6, 5, 8, 6, 5};
    const float b[12] = {-4, -8, 5, 10, -3, 5, -9, 4, 5, 5, 8, 5};
    auto patch = [](const float* p) {
        std::string s = "Patch \"bilinear\" \"P\" [";
        for (int i = 0; i < 12; ++i) s += fmt::format("{} ", p[i]);
        return s + "]\n";
    };
    const std::string head = orthoFrame(40, 24, 8, "Shutter 0 1\n") + "WorldBegin\nSurface \"constant\"\n";
    Image blurred = render(head + "MotionBegin [0 1]\n" + patch(a) + patch(b) + "MotionEnd\nWorldEnd\n", dir);
    const int steps = 32;
    std::vector<double> average(blurred.pixels.size(), 0.0);
    for (int k = 0; k < steps; ++k) {
        const float f = (k + 0.5f) / steps;
        float p[12];
        for (int i = 0; i < 12; ++i) p[i] = a[i] + f * (b[i] - a[i]);
        Image still = render(orthoFrame(40, 24, 8) + "WorldBegin\nSurface \"constant\"\n" + patch(p) + "WorldEnd\n", dir);
        ASSERT_EQ(still.pixels.size(), average.size());
        for (size_t i = 0; i < average.size(); ++i) average[i] += still.pixels[i] / steps;
    }
    double sumDiff = 0, sumBlur = 0, sumAverage = 0;
    for (size_t i = 3; i < average.size(); i += 4) {
        sumDiff += std::abs(blurred.pixels[i] - average[i]);
        sumBlur += blurred.pixels[i];
        sumAverage += average[i];
    }
    EXPECT_NEAR(sumBlur, sumAverage, 0.01 * sumAverage) << "covered area";
    EXPECT_LT(sumDiff / (average.size() / 4), 0.02) << "mean per-pixel difference of alpha";
}

TEST(MotionBlur, SamePixelsForAnyThreadCountAndBucketSize) {
    ScratchDir dir("mb-determinism");
    const std::string rib =
        "Format 96 64 1\nPixelSamples 4 4\nShutter 0 1\nProjection \"perspective\" \"fov\" 40\n"
        "DepthOfField 4 0.5 6\nDisplay \"out.tif\" \"file\" \"rgba\"\n"
        "MotionBegin [0 1]\nTranslate 0 0 0\nTranslate 0.3 0 0\nMotionEnd\n"
        "WorldBegin\nLightSource \"distantlight\" 1\nSurface \"plastic\"\n"
        "AttributeBegin\nMotionBegin [0 0.5 1]\nTranslate -1 0 6\nTranslate 0 0.5 6\nTranslate 1 0 7\nMotionEnd\n"
        "Sphere 1 -1 1 360\nAttributeEnd\n"
        "AttributeBegin\nTranslate 0 0 9\nMotionBegin [0 1]\nRotate 0 0 0 1\nRotate 60 0 0 1\nMotionEnd\n"
        "Patch \"bilinear\" \"P\" [-3 -2 0 3 -2 0 -3 2 0 3 2 0]\nAttributeEnd\nWorldEnd\n";
    Image one = render(rib, dir, 1, 16);
    Image two = render(rib, dir, 2, 8);
    Image odd = render(rib, dir, 2, 13);
    EXPECT_EQ(test::maxAbsDiff(one, two, 4), 0.0);
    EXPECT_EQ(test::maxAbsDiff(one, odd, 4), 0.0);
}

TEST(MotionBlur, CameraPassesTake32PixelBucketsUnlessTold) {
    // A camera pass, blurred or still, is cut into 32-pixel buckets unless
    // --bucket-size or Option "limits" "bucketsize" says otherwise. The
    // picture is the same whatever the buckets.
    ScratchDir dir("mb-buckets");
    const std::string frame =
        "Format 96 64 1\nPixelSamples 4 4\n{}Projection \"perspective\" \"fov\" 40\n{}"
        "Display \"out.tif\" \"file\" \"rgba\"\n"
        "MotionBegin [0 1]\nTranslate 0 0 0\nTranslate 0.3 0 0\nMotionEnd\n"
        "WorldBegin\nLightSource \"distantlight\" 1\nSurface \"plastic\"\n"
        "AttributeBegin\nMotionBegin [0 1]\nTranslate -1 0 6\nTranslate 1 0.5 7\nMotionEnd\n"
        "Sphere 1 -1 1 360\nAttributeEnd\n"
        "AttributeBegin\nTranslate 0 0 9\nPatch \"bilinear\" \"P\" [-3 -2 0 3 -2 0 -3 2 0 3 2 0]\nAttributeEnd\n"
        "WorldEnd\n";
    struct Run {
        Image image;
        nlohmann::json camera;  // the camera pass's statistics
    };
    auto run = [&](const std::string& shutter, const std::string& option, int bucket) {
        Diagnostics diag;
        diag.setRecord(true);
        std::string rib = fmt::format(fmt::runtime(frame), shutter, option);
        const std::string out = dir.file("out.tif");
        rib.replace(rib.find("\"out.tif\""), 9, "\"" + out + "\"");
        Run r;
        const nlohmann::json stats = test::renderRib(rib, diag, 2, bucket);
        EXPECT_EQ(diag.errorCount(), 0) << (diag.recorded().empty() ? "" : diag.recorded()[0].message);
        EXPECT_TRUE(test::readImage(out, &r.image));
        for (const auto& p : stats["frames"][0]["passes"])
            if (p["name"] == "camera") r.camera = p;
        return r;
    };
    auto bucketSize = [](const Run& r) { return r.camera["bucket_size"].get<std::vector<int>>(); };
    auto buckets = [](const Run& r) { return r.camera["counts"]["buckets"].get<int>(); };
    const std::string blurred = "Shutter 0 1\n", still = "";
    const Run automatic = run(blurred, "", 0);
    EXPECT_EQ(bucketSize(automatic), (std::vector<int>{32, 32}));
    EXPECT_EQ(buckets(automatic), 3 * 2);  // 96 x 64 pixels
    const Run option = run(blurred, "Option \"limits\" \"bucketsize\" [16 16]\n", 0);
    EXPECT_EQ(bucketSize(option), (std::vector<int>{16, 16}));
    EXPECT_EQ(buckets(option), 6 * 4);
    const Run flag = run(blurred, "", 16);
    EXPECT_EQ(bucketSize(flag), (std::vector<int>{16, 16}));
    EXPECT_EQ(buckets(flag), 6 * 4);
    const Run oddOption = run(blurred, "Option \"limits\" \"bucketsize\" [24 8]\n", 0);
    EXPECT_EQ(bucketSize(oddOption), (std::vector<int>{24, 8}));
    const Run sharp = run(still, "", 0);
    EXPECT_EQ(bucketSize(sharp), (std::vector<int>{32, 32}));
    const Run sharpFlag = run(still, "", 16);
    EXPECT_EQ(bucketSize(sharpFlag), (std::vector<int>{16, 16}));
    EXPECT_EQ(test::maxAbsDiff(sharp.image, sharpFlag.image, 4), 0.0);
    // Bit-identical pictures, and the frame was blurred (not the still one).
    EXPECT_EQ(test::maxAbsDiff(automatic.image, option.image, 4), 0.0);
    EXPECT_EQ(test::maxAbsDiff(automatic.image, flag.image, 4), 0.0);
    EXPECT_EQ(test::maxAbsDiff(automatic.image, oddOption.image, 4), 0.0);
    EXPECT_GT(test::maxAbsDiff(automatic.image, sharp.image, 4), 0.1);
}

TEST(MotionBlur, BlurredShadingStaysSmoothUnderTheDefaultFilter) {
    // A grey ramp (0 to 1 over 120 pixels) slides 60 pixels under the
    // default 2 x 2 Gaussian at 4 x 4 samples. Its colour is linear in time,
    // so the blurred ramp is the ramp at mid-shutter; a symmetric filter of
    // a linear function is its centre value. A Gaussian weighs a pixel's
    // samples unequally, so time strata a weighted subset happens to miss
    // show as noise: with times permuted freely over each pixel the error
    // was 0.011 RMS (a box filter: 0.0004); rows and columns spread over the
    // shutter bring it near what the jitter alone leaves.
    ScratchDir dir("mb-ramp");
    const std::string rib =
        "Format 100 40 1\nPixelSamples 4 4\nShutter 0 1\nProjection \"orthographic\"\n"
        "ScreenWindow -50 50 -20 20\nQuantize \"rgba\" 0 0 0 0\nDisplay \"out.tif\" \"file\" \"rgba\"\n"
        "WorldBegin\nSurface \"constant\"\nTranslate 0 0 10\n"
        "MotionBegin [0 1]\nTranslate -30 0 0\nTranslate 30 0 0\nMotionEnd\n"
        "Patch \"bilinear\" \"P\" [-60 -40 0  60 -40 0  -60 40 0  60 40 0] \"Cs\" [0 0 0  1 1 1  0 0 0  1 1 1]\n"
        "WorldEnd\n";
    Image img = render(rib, dir);
    ASSERT_EQ(img.width, 100);
    double sum2 = 0;
    int count = 0;
    for (int y = 4; y < 36; ++y)
        for (int x = 25; x < 75; ++x) {  // camera x in [-25, 25]: inside the ramp at every time
            const double expected = (x + 0.5 - 50 + 60) / 120.0;
            sum2 += std::pow(img.at(x, y, 0) - expected, 2);
            ++count;
        }
    const double rms = std::sqrt(sum2 / count);
    RecordProperty("rms_error", fmt::format("{:.5f}", rms));
    EXPECT_LT(rms, 0.0075);
}

/// A floor at z = 10 under a spotlight at the origin that looks along +z,
/// moved by `motion` (a MotionBegin block of Translates).
std::string floorMovedBy(const std::string& motion) {
    return "Surface \"matte\" \"Kd\" [1] \"Ka\" [0]\n" + motion +
           "Polygon \"P\" [-6 -6 10  6 -6 10  6 6 10  -6 6 10]\n";
}
/// The floor moving `toward` the light over the shutter.
std::string movingFloor(double toward) {
    return floorMovedBy(fmt::format("MotionBegin [0 1]\nTranslate 0 0 0\nTranslate 0 0 {}\nMotionEnd\n", -toward));
}
/// The floor going `toward` the light by mid-shutter and back by the close.
std::string thereAndBackFloor(double toward) {
    return floorMovedBy(fmt::format(
        "MotionBegin [0 0.5 1]\nTranslate 0 0 0\nTranslate 0 0 {}\nTranslate 0 0 0\nMotionEnd\n", -toward));
}

/// The floor's map made as exporters make one: a light-view frame writing
/// a zfile, then MakeShadow.
std::string movingFloorMapFrames(double toward) {
    return "FrameBegin 1\nFormat 256 256 1\nShutter 0 1\nProjection \"perspective\" \"fov\" [80.2]\n"
           "Display \"floor.z\" \"zfile\" \"z\"\nWorldBegin\n" +
           movingFloor(toward) + "WorldEnd\nFrameEnd\nMakeShadow \"floor.z\" \"floor.shd\"\n";
}

/// The floor seen from the light (orthographic, 40 x 40), lit by the spot
/// with the shadow map `map` ("" for none).
std::string movingFloorFrame(double toward, const std::string& map, const std::string& options = "",
                             const std::string& floor = "", const std::string& lightParams = "") {
    return fmt::format(
        "FrameBegin 2\nFormat 40 40 1\nPixelSamples 4 4\nPixelFilter \"box\" 1 1\nProjection \"orthographic\"\n"
        "ScreenWindow -1 1 -1 1\nShutter 0 1\nOption \"umbra\" \"shadowmapsize\" [256]\n{}"
        "Quantize \"rgba\" 0 0 0 0\nDisplay \"out.tif\" \"file\" \"rgba\"\nWorldBegin\n"
        "LightSource \"shadowspot\" 1 \"coneangle\" [0.7] \"conedeltaangle\" [0] \"intensity\" [100]{}\n{}"
        "WorldEnd\nFrameEnd\n",
        options, map.empty() ? "" : " \"shadowname\" [\"" + map + "\"]" + lightParams,
        floor.empty() ? movingFloor(toward) : floor);
}

/// The floor's mean red over its middle, and the warnings that it may
/// shadow itself. File names in quotes are made the scratch folder's.
double movingFloorLight(const std::string& frames, const ScratchDir& dir, int* warnings) {
    Diagnostics diag;
    diag.setRecord(true);
    std::string rib = frames;
    for (const char* name : {"out.tif", "floor.z", "floor.shd"})
        for (size_t at; (at = rib.find(fmt::format("\"{}\"", name))) != std::string::npos;)
            rib.replace(at, std::string(name).size() + 2, "'" + dir.file(name) + "'");
    std::replace(rib.begin(), rib.end(), '\'', '"');
    Image img = test::renderImage(rib, dir.file("out.tif"), diag);
    EXPECT_EQ(diag.errorCount(), 0) << (diag.recorded().empty() ? "" : diag.recorded()[0].message);
    *warnings = 0;
    for (const Diagnostic& m : diag.recorded()) *warnings += m.message.find("may shadow itself") != std::string::npos;
    double sum = 0;
    for (int y = 10; y < 30; ++y)
        for (int x = 10; x < 30; ++x) sum += img.at(x, y, 0);
    return sum / 400;
}

// A map of moving casters holds each texel at one time of the shutter. A
// surface is shaded at the opening, so compared with every time's texels
// at its opening's depth, a surface moving toward the light by more than
// the bias shadowed itself (a floor moving 0.3 under the default bias
// 0.225 read 0.75 of its light, 2.0 about half). Each time's texels are
// now compared with the surface where it is at that time: it is lit
// whatever its motion, as in Pixie and Aqsis (whose maps hold one time),
// with an automatic map and with one made from a zfile (which carries the
// texels' times after its depths).
TEST(MotionBlur, ASurfaceMovingTowardItsLightIsComparedWithItselfAtEachTime) {
    ScratchDir dir("mb-receiver");
    int warnings = 0;
    for (double toward : {0.1, 0.3, 2.0}) {
        const double lit = movingFloorLight(movingFloorFrame(toward, ""), dir, &warnings);
        ASSERT_GT(lit, 0.1);
        EXPECT_NEAR(movingFloorLight(movingFloorFrame(toward, "auto"), dir, &warnings) / lit, 1.0, 0.01)
            << "automatic map, moving " << toward << " toward the light";
        EXPECT_EQ(warnings, 0);
        EXPECT_NEAR(movingFloorLight(movingFloorMapFrames(toward) + movingFloorFrame(toward, "floor.shd"), dir,
                                     &warnings) /
                        lit,
                    1.0, 0.01)
            << "map from a zfile, moving " << toward << " toward the light";
        EXPECT_EQ(warnings, 0);
    }
    // Exactly, not within a bias: the depth pass moves a micropolygon
    // linearly in its raster space and 1/z, so a texel holds the floor
    // where the lookup's straight path puts it at that time only through
    // that change of parameter (missing it, a floor moving 2 under a bias
    // of 0.01 read 0). The two-layer maps, which need no bias, likewise.
    for (const char* options : {"Option \"shadow\" \"bias\" [0.01]\n", "Option \"umbra\" \"depthfilter\" \"second\"\n",
                                "Option \"umbra\" \"depthfilter\" \"midpoint\"\n",
                                "Option \"umbra\" \"depthfilter\" \"dual\"\n"}) {
        const double lit = movingFloorLight(movingFloorFrame(2.0, "", options), dir, &warnings);
        EXPECT_NEAR(movingFloorLight(movingFloorFrame(2.0, "auto", options), dir, &warnings) / lit, 1.0, 0.01)
            << options;
    }
    // A wide filter region (16 times the footprint: 12 texels) takes
    // jittered samples, each the nearest texel of its time, instead of
    // every texel.
    for (const char* options : {"", "Option \"umbra\" \"depthfilter\" \"second\"\n"}) {
        const double lit = movingFloorLight(movingFloorFrame(2.0, "", options), dir, &warnings);
        EXPECT_NEAR(movingFloorLight(movingFloorFrame(2.0, "auto", options, "", " \"width\" [16]"), dir, &warnings) / lit,
                    1.0, 0.01)
            << "width 16, " << options;
    }
    // Along its keys, not the line from its opening to its close: a floor
    // that goes 1 toward the light and back (read 0.25 when followed on
    // that line, which stands still).
    for (const char* options : {"", "Option \"umbra\" \"depthfilter\" \"second\"\n"}) {
        const std::string floor = thereAndBackFloor(1.0);
        const double lit = movingFloorLight(movingFloorFrame(0, "", options, floor), dir, &warnings);
        EXPECT_NEAR(movingFloorLight(movingFloorFrame(0, "auto", options, floor), dir, &warnings) / lit, 1.0, 0.01)
            << "there and back, " << options;
        EXPECT_EQ(warnings, 0);
    }
}

// A map of moving casters that does not say when its texels hold them (one
// written before maps did) cannot be looked up time by time: a surface
// moving further than the bias is still compared at its opening, and the
// renderer says so, once per map, with the workarounds (docs/motion.md).
TEST(MotionBlur, AMapOfUnknownTexelTimesWarnsOfAMovingReceiver) {
    ScratchDir dir("mb-receiver-unknown");
    int warnings = 0;
    const double lit = movingFloorLight(movingFloorFrame(0.3, ""), dir, &warnings);
    ASSERT_GT(lit, 0.1);
    auto withoutTimes = [&](double toward) {
        movingFloorLight(movingFloorMapFrames(toward) + movingFloorFrame(toward, ""), dir, &warnings);
        Diagnostics diag;
        DepthImage image;
        ASSERT_TRUE(readDepthImage(dir.file("floor.shd"), image, diag));
        ASSERT_EQ(image.timeTile, 4);
        ASSERT_EQ(image.texelTimes.size(), 32u * 32u);
        image.texelTimes.clear();
        ASSERT_TRUE(writeDepthMap(dir.file("floor.shd"), image, diag));
    };
    withoutTimes(0.1);
    const double near = movingFloorLight(movingFloorFrame(0.1, "floor.shd"), dir, &warnings);
    EXPECT_NEAR(near / movingFloorLight(movingFloorFrame(0.1, ""), dir, &warnings), 1.0, 0.01);
    EXPECT_EQ(warnings, 0) << "within the bias: silent";
    withoutTimes(0.3);
    const double far = movingFloorLight(movingFloorFrame(0.3, "floor.shd"), dir, &warnings);
    EXPECT_EQ(warnings, 1);
    EXPECT_LT(far / lit, 0.9);  // what the warning is about
}

/// A slab 2 above a floor (both moved by `motion`, a MotionBegin block of
/// two Translates), under a distant light straight down, seen from above
/// through an orthographic 128 x 32 window of x in [-8, 8]; the slab is
/// hidden from the camera. Each column's mean red over the middle rows.
std::vector<double> slabOverFloorColumns(const std::string& motion, const ScratchDir& dir,
                                         const std::string& cameraMotion = "") {
    const std::string rib =
        "Format 128 32 1\nPixelSamples 4 4\nPixelFilter \"box\" 1 1\nShutter 0 1\nProjection \"orthographic\"\n"
        "ScreenWindow -8 8 -2 2\nQuantize \"rgba\" 0 0 0 0\nDisplay \"out.tif\" \"file\" \"rgba\"\n"
        "Rotate -90 1 0 0\nTranslate 0 -10 0\n" + cameraMotion +
        "WorldBegin\n"
        "LightSource \"shadowdistant\" 1 \"from\" [0 10 0] \"to\" [0 0 0] \"shadowname\" \"auto\" "
        "\"float intensity\" 1\n"
        "Surface \"matte\"\n" + motion +
        "AttributeBegin\nAttribute \"visibility\" \"camera\" 0\n"
        "Polygon \"P\" [-1 2 -5  1 2 -5  1 2 5  -1 2 5]\nAttributeEnd\n"
        "Polygon \"P\" [-20 0 -20  -20 0 20  20 0 20  20 0 -20]\nWorldEnd\n";
    Image img = render(rib, dir);
    std::vector<double> columns(128, 0.0);
    for (int x = 0; x < 128 && img.width == 128; ++x) {
        for (int y = 8; y < 24; ++y) columns[size_t(x)] += img.at(x, y, 0);
        columns[size_t(x)] /= 16;
    }
    return columns;
}

/// Each column's mean and largest error against `expected` (of the
/// column's centre x), excluding columns within `margin` of `edges`.
void expectColumns(const std::vector<double>& columns, const std::function<double(double)>& expected,
                   std::vector<double> edges, double margin, double meanLimit, const char* what) {
    double error = 0, worst = 0;
    int counted = 0;
    std::string profile;
    for (int x = 0; x < 128; ++x) {
        const double cx = (x + 0.5) / 8.0 - 8.0;
        profile += fmt::format("{:.2f}/{:.2f} ", columns[size_t(x)], expected(cx));
        if (std::any_of(edges.begin(), edges.end(), [&](double e) { return std::abs(cx - e) < margin; })) continue;
        const double e = std::abs(columns[size_t(x)] - expected(cx));
        error += e, worst = std::max(worst, e), ++counted;
    }
    EXPECT_LT(error / counted, meanLimit) << what << ": mean error; measured/expected: " << profile;
    EXPECT_LT(worst, 0.12) << what << ": largest error; measured/expected: " << profile;
}

// A receiver that moves with its caster keeps, in its own frame, the
// shadow it has standing still. Moving together 1.5 toward the light (the
// camera looks along the motion, so sees no blur), the floor shows the
// slab's sharp shadow (but for the edges, which a map of moving casters
// filters over at least a time tile, 4 texels: 1.25 units of this
// 128-texel map); compared at the opening with the texels of every
// time, it shadowed itself in patches. Sliding together 8 along x, the
// camera sees that sharp shadow slide: the trapezoid a caster moving over
// a still floor leaves (MovingCasterBlursItsShadow); compared at the
// opening, the floor took the trapezoid as its shading and the slide
// blurred it a second time. Under a camera sliding with them, the floor
// shows the still shadow.
TEST(MotionBlur, AReceiverMovingWithItsCasterKeepsItsStillShadow) {
    ScratchDir dir("mb-together");
    const auto sharp = [](double x) { return std::abs(x) < 1 ? 0.0 : 1.0; };
    expectColumns(slabOverFloorColumns("MotionBegin [0 1]\nTranslate 0 0 0\nTranslate 0 1.5 0\nMotionEnd\n", dir),
                  sharp, {-1, 1}, 0.75, 0.02, "moving together toward the light");
    const auto slid = [](double x) {
        return 1.0 - std::max(0.0, std::min(x + 1, 4.0) - std::max(x - 1, -4.0)) / 8.0;
    };
    expectColumns(slabOverFloorColumns("MotionBegin [0 1]\nTranslate -4 0 0\nTranslate 4 0 0\nMotionEnd\n", dir),
                  slid, {}, 0, 0.03, "sliding together");
    // A camera sliding with them sees the still shadow, though nothing
    // moves in its own space: the motion shadow() follows is the world's.
    expectColumns(slabOverFloorColumns("MotionBegin [0 1]\nTranslate -4 0 0\nTranslate 4 0 0\nMotionEnd\n", dir,
                                       "MotionBegin [0 1]\nTranslate 4 0 0\nTranslate -4 0 0\nMotionEnd\n"),
                  sharp, {-1, 1}, 0.75, 0.02, "sliding together under a camera sliding with them");
}

TEST(MotionBlur, MovingCasterBlursItsShadow) {
    // A distant light straight down; a 2 x 10 slab 2 units above a floor
    // moves 8 units along x over the shutter. The floor's time-averaged
    // shadow is a trapezoid: fully shadowed nowhere (the slab covers a floor
    // point for 2 of the 8 units: 25% of the time) between x = -2 and 2,
    // ramping to lit at x = -5 and 5. Depth-map texels are sampled at
    // interleaved times and percentage-closer filtering averages them.
    ScratchDir dir("mb-shadow");
    const std::string rib =
        "Format 128 32 1\nPixelSamples 4 4\nPixelFilter \"box\" 1 1\nShutter 0 1\nProjection \"orthographic\"\n"
        "ScreenWindow -8 8 -2 2\nQuantize \"rgba\" 0 0 0 0\nDisplay \"out.tif\" \"file\" \"rgba\"\n"
        "Rotate -90 1 0 0\nTranslate 0 -10 0\n"  // looking straight down at the floor y = 0
        "WorldBegin\n"
        "LightSource \"shadowdistant\" 1 \"from\" [0 10 0] \"to\" [0 0 0] \"shadowname\" \"auto\" "
        "\"float intensity\" 1\n"
        "Surface \"matte\"\n"
        "AttributeBegin\nAttribute \"visibility\" \"camera\" 0\n"
        "MotionBegin [0 1]\nTranslate -4 0 0\nTranslate 4 0 0\nMotionEnd\n"
        "Polygon \"P\" [-1 2 -5  1 2 -5  1 2 5  -1 2 5]\nAttributeEnd\n"
        "Polygon \"P\" [-20 0 -20  -20 0 20  20 0 20  20 0 -20]\nWorldEnd\n";
    Image img = render(rib, dir);
    ASSERT_EQ(img.width, 128);
    auto lit = [](double x) {  // fraction of the shutter a floor point at x is lit
        const double covered = std::max(0.0, std::min(x + 1, 4.0) - std::max(x - 1, -4.0)) / 8.0;
        return 1.0 - covered;
    };
    double error = 0, worst = 0;
    std::string profile;
    for (int x = 0; x < 128; ++x) {
        double v = 0;
        for (int y = 8; y < 24; ++y) v += img.at(x, y, 0);
        v /= 16;
        const double cx = (x + 0.5) / 8.0 - 8.0;
        const double e = std::abs(v - lit(cx));
        profile += fmt::format("{:.2f}/{:.2f} ", v, lit(cx));
        error += e / 128;
        worst = std::max(worst, e);
    }
    // The unblurred shadow (the slab at the opening) would be off by up to 0.75.
    EXPECT_LT(error, 0.03) << "mean error of the floor's lit fraction; measured/expected: " << profile;
    EXPECT_LT(worst, 0.12) << "largest error (the filter's penumbra at the ramps' ends)";
    RecordProperty("mean_error", fmt::format("{:.4f}", error));
    RecordProperty("worst_error", fmt::format("{:.4f}", worst));
}

}  // namespace
}  // namespace umbra
