// The screen transformation (RI Spec 3.2, Projection): transforms given
// before `Projection` apply after the projection, in screen space. DCC
// exporters write `Scale -1 1 1` there to mirror the image. Each case is
// compared with the scene the screen transform describes, written plainly:
// the unmirrored image flopped or turned pixel by pixel, a ScreenWindow
// scaled or shifted by hand (screen x' = s x + t sees the window [l, r] as
// [(l - t)/s, (r - t)/s]), or a closed-form area and centroid.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <fstream>
#include <string>
#include <utility>

using namespace umbra;
using umbra::test::Image;
using umbra::test::maxAbsDiff;
using umbra::test::meanAbsDiff;
using umbra::test::ScratchDir;

namespace {

constexpr int kWidth = 80, kHeight = 60;  // frame aspect 4:3: default window [-4/3, 4/3] x [-1, 1]

// Regular (unjittered) samples and a symmetric filter: the sample pattern
// of a pixel is its own mirror image, so a mirrored camera must give the
// flopped picture. The world is lopsided (a lit sphere off to the left, a
// constant square up and to the right, a cone) so that a flop, a scale or
// a shift cannot pass for no change.
constexpr const char* kScene = R"(
Format {w} {h} 1
PixelSamples 4 4
Hider "hidden" "jitter" [0]
Quantize "rgba" 0 0 0 0
Display "{image}" "file" "rgba"
{window}
{before}
Projection "{projection}" {fov}
Translate 0 0 6
WorldBegin
LightSource "distantlight" 1 "from" [-1 1 -1] "to" [0 0 0]
AttributeBegin
Translate -0.9 -0.2 0
Surface "plastic"
Color [0.9 0.5 0.2]
Sphere 1 -1 1 360
AttributeEnd
AttributeBegin
Surface "constant"
Color [0.2 0.4 1]
Polygon "P" [0.6 0.3 0.5  1.7 0.3 0.5  1.7 1.4 0.5  0.6 1.6 0.5]
AttributeEnd
AttributeBegin
Translate 1.1 -0.9 0
Rotate -60 1 0 0
Surface "matte"
Cone 1.2 0.5 360
AttributeEnd
WorldEnd
)";

struct Rendered {
    Image image;
    std::vector<Diagnostic> messages;
    int errors = 0;
};

Rendered renderFrame(const ScratchDir& dir, const std::string& before, const std::string& window = "",
                const std::string& projection = "perspective", int width = kWidth, int height = kHeight) {
    const std::string image = dir.file("st.tif");
    const std::string fov = projection == "perspective" ? "\"fov\" 45" : "";
    // Orthographic: the default window is 8/3 units wide, the scene 4.
    const std::string rib = fmt::format(kScene, fmt::arg("w", width), fmt::arg("h", height),
                                        fmt::arg("image", image), fmt::arg("window", window),
                                        fmt::arg("before", before), fmt::arg("projection", projection),
                                        fmt::arg("fov", fov));
    Diagnostics diag;
    diag.setQuiet(true);
    diag.setRecord(true);
    Rendered r;
    r.image = test::renderImage(rib, image, diag);
    r.messages = diag.recorded();
    r.errors = diag.errorCount();
    return r;
}

/// The image with pixel (x, y) taken from `a` at source(x, y).
template <typename Source>
Image remapped(const Image& a, Source source) {
    Image b = a;
    for (int y = 0; y < a.height; ++y)
        for (int x = 0; x < a.width; ++x) {
            const auto [sx, sy] = source(x, y);
            for (int c = 0; c < a.channels; ++c)
                b.pixels[(size_t(y) * a.width + x) * a.channels + c] = a.at(sx, sy, c);
        }
    return b;
}

/// The image flopped left to right.
Image flopped(const Image& a) {
    return remapped(a, [&](int x, int y) { return std::pair(a.width - 1 - x, y); });
}

/// The image turned a quarter turn counter-clockwise (a square one).
Image quarterTurned(const Image& a) {
    return remapped(a, [&](int x, int y) { return std::pair(a.width - 1 - y, x); });
}

Image flipped(const Image& a) {
    return remapped(a, [&](int x, int y) { return std::pair(x, a.height - 1 - y); });
}

/// Warnings containing `word`, each expected at the Projection request:
/// line 9 of the scene (the RIB text starts with a newline) when the
/// transforms before it take one line.
int warningsMentioning(const Rendered& r, const std::string& word, int projectionLine = 9) {
    int n = 0;
    for (const Diagnostic& d : r.messages)
        if (d.severity == Severity::Warning && d.message.find(word) != std::string::npos) {
            EXPECT_EQ(d.loc.line, projectionLine) << d.str();
            EXPECT_GT(d.loc.column, 0) << d.str();
            ++n;
        }
    return n;
}

int warnings(const Rendered& r) {
    int n = 0;
    for (const Diagnostic& d : r.messages) n += d.severity == Severity::Warning;
    return n;
}

/// Pixels that differ by more than `tol` in any channel.
int differingPixels(const Image& a, const Image& b, double tol) {
    if (a.width != b.width || a.height != b.height || a.channels != b.channels) return 1 << 30;
    int n = 0;
    for (int y = 0; y < a.height; ++y)
        for (int x = 0; x < a.width; ++x) {
            bool d = false;
            for (int c = 0; c < a.channels; ++c) d |= std::fabs(a.at(x, y, c) - b.at(x, y, c)) > tol;
            n += d;
        }
    return n;
}

}  // namespace

TEST(ScreenTransform, MirroredCameraGivesTheFloppedImage) {
    ScratchDir dir("screen-mirror");
    Rendered plain = renderFrame(dir, "");
    Rendered mirrored = renderFrame(dir, "Scale -1 1 1");
    ASSERT_EQ(plain.errors, 0);
    ASSERT_EQ(mirrored.errors, 0);
    EXPECT_EQ(warnings(mirrored), 0);
    // The scene is lopsided: the flop of the plain image is far from it.
    ASSERT_GT(meanAbsDiff(plain.image, flopped(plain.image)), 0.05);
    // Shading happens in camera space, untouched by the mirror; the
    // coverage is the mirror image sample for sample.
    EXPECT_LT(meanAbsDiff(mirrored.image, flopped(plain.image)), 1e-5);
    EXPECT_LT(maxAbsDiff(mirrored.image, flopped(plain.image), 4), 1e-3);
}

TEST(ScreenTransform, MirrorInYAndBothAxes) {
    ScratchDir dir("screen-mirror-y");
    Rendered plain = renderFrame(dir, "");
    Rendered upsideDown = renderFrame(dir, "Scale 1 -1 1");
    Rendered both = renderFrame(dir, "Scale -1 -1 1");
    EXPECT_LT(meanAbsDiff(upsideDown.image, flipped(plain.image)), 1e-5);
    EXPECT_LT(meanAbsDiff(both.image, flipped(flopped(plain.image))), 1e-5);
    // A half turn about z is the same screen transform as Scale -1 -1: no
    // rotation left to warn about.
    Rendered halfTurn = renderFrame(dir, "Rotate 180 0 0 1");
    EXPECT_EQ(warnings(halfTurn), 0);
    EXPECT_LT(meanAbsDiff(halfTurn.image, both.image), 1e-5);
}

TEST(ScreenTransform, OrthographicIsMirroredToo) {
    ScratchDir dir("screen-mirror-ortho");
    Rendered plain = renderFrame(dir, "", "ScreenWindow -2.4 2.4 -1.8 1.8", "orthographic");
    Rendered mirrored = renderFrame(dir, "Scale -1 1 1", "ScreenWindow -2.4 2.4 -1.8 1.8", "orthographic");
    ASSERT_GT(plain.image.channelSum(3), 0.1 * kWidth * kHeight);
    ASSERT_GT(meanAbsDiff(plain.image, flopped(plain.image)), 0.05);
    EXPECT_LT(meanAbsDiff(mirrored.image, flopped(plain.image)), 1e-5);
    EXPECT_LT(maxAbsDiff(mirrored.image, flopped(plain.image), 4), 1e-3);
}

TEST(ScreenTransform, ScaleEqualsAHalvedScreenWindow) {
    ScratchDir dir("screen-scale");
    // Screen x' = 2x: the default window [-4/3, 4/3] x [-1, 1] sees
    // [-2/3, 2/3] x [-1/2, 1/2] of the projection.
    Rendered scaled = renderFrame(dir, "Scale 2 2 1");
    Rendered window = renderFrame(dir, "", "ScreenWindow -0.6666667 0.6666667 -0.5 0.5");
    Rendered plain = renderFrame(dir, "");
    EXPECT_EQ(warnings(scaled), 0);
    ASSERT_GT(meanAbsDiff(window.image, plain.image), 0.02);  // the zoom is visible
    EXPECT_LT(meanAbsDiff(scaled.image, window.image), 1e-4);
    EXPECT_LE(differingPixels(scaled.image, window.image, 1e-3), kWidth * kHeight / 200);
    // Unequal and mirrored: x' = -2x, y' = 0.5y over the window [-1, 1]^2
    // is the window [-1/2, 1/2] x [-2, 2], flopped.
    Rendered mixed = renderFrame(dir, "Scale -2 0.5 1", "ScreenWindow -1 1 -1 1");
    Rendered mixedPlain = renderFrame(dir, "", "ScreenWindow -0.5 0.5 -2 2");
    EXPECT_LT(meanAbsDiff(mixed.image, flopped(mixedPlain.image)), 1e-4);
    EXPECT_LE(differingPixels(mixed.image, flopped(mixedPlain.image), 1e-3), kWidth * kHeight / 200);
}

TEST(ScreenTransform, TranslateEqualsAShiftedScreenWindow) {
    // Also shows the transform is reset after Projection: were the
    // Translate left in the camera transform, the world would move in
    // camera space and the perspective would differ from a window shift.
    ScratchDir dir("screen-shift");
    // Screen x' = x + 0.3, y' = y - 0.2: the window [l, r] x [b, t] sees
    // [l - 0.3, r - 0.3] x [b + 0.2, t + 0.2] of the projection.
    Rendered shifted = renderFrame(dir, "Translate 0.3 -0.2 0");
    Rendered window = renderFrame(dir, "", "ScreenWindow -1.6333333 1.0333333 -0.8 1.2");
    Rendered plain = renderFrame(dir, "");
    EXPECT_EQ(warnings(shifted), 0);
    ASSERT_GT(meanAbsDiff(window.image, plain.image), 0.02);
    EXPECT_LT(meanAbsDiff(shifted.image, window.image), 1e-4);
    EXPECT_LE(differingPixels(shifted.image, window.image, 1e-3), kWidth * kHeight / 200);
    // Scale then translate compose as transforms do: x' = 2 (x + 0.25).
    Rendered both = renderFrame(dir, "Scale 2 2 1\nTranslate 0.25 0 0");
    Rendered bothWindow = renderFrame(dir, "", "ScreenWindow -0.9166667 0.4166667 -0.5 0.5");
    EXPECT_LT(meanAbsDiff(both.image, bothWindow.image), 1e-4);
}

TEST(ScreenTransform, QuarterTurnTurnsTheImageCounterClockwise) {
    // Screen = M * projected, M a quarter turn: what the plain camera sees at
    // screen (x, y) is seen at (-y, x), a counter-clockwise turn of the
    // picture (screen y up). Aqsis 1.8.4 and Pixie 2.2.6 turn it the same
    // way. A square image, regular samples and a filter symmetric under the
    // turn: the turned camera's samples are the plain one's turned.
    ScratchDir dir("screen-rotate");
    constexpr int kSide = 64;
    Rendered plain = renderFrame(dir, "", "", "perspective", kSide, kSide);
    Rendered turned = renderFrame(dir, "Rotate 90 0 0 1", "", "perspective", kSide, kSide);
    ASSERT_EQ(turned.errors, 0);
    EXPECT_EQ(warnings(turned), 0);
    const Image expected = quarterTurned(plain.image);
    ASSERT_GT(meanAbsDiff(plain.image, expected), 0.05);  // the turn is visible
    ASSERT_GT(meanAbsDiff(turned.image, quarterTurned(quarterTurned(expected))), 0.05);  // and its direction
    // Shading is in camera space, untouched by the turn; coverage is the
    // turned coverage sample for sample (but for sample tests exactly on
    // an edge, which rounding may decide the other way).
    EXPECT_LT(meanAbsDiff(turned.image, expected), 1e-5);
    EXPECT_LE(differingPixels(turned.image, expected, 1e-3), 2);
    // Three quarter turns and a turn with a mirror compose as matrices do.
    Rendered back = renderFrame(dir, "Rotate -90 0 0 1", "", "perspective", kSide, kSide);
    EXPECT_LT(meanAbsDiff(back.image, quarterTurned(quarterTurned(expected))), 1e-5);
    Rendered mirroredTurn = renderFrame(dir, "Scale -1 1 1\nRotate 90 0 0 1", "", "perspective", kSide, kSide);
    EXPECT_EQ(warnings(mirroredTurn), 0);
    EXPECT_LT(meanAbsDiff(mirroredTurn.image, flopped(expected)), 1e-5);
}

TEST(ScreenTransform, TurnedAndShearedSquareCoversItsClosedFormArea) {
    // A constant unit square seen orthographically through the window
    // [-1, 1]^2 at 64 x 64 (32 pixels per unit), 8 x 8 regular samples and
    // a box filter: its alpha sums to its area in pixels, |det M| * 32^2,
    // and its alpha's centroid is M c + t for its centre c. Sampling moves
    // each edge by at most half a sample spacing (1/16 pixel), so the sum is
    // within perimeter / 16 pixels (7 to 8.5 here); the tolerance, 1% of
    // the area, is above that in each case and far below a wrong matrix (a
    // dropped scale changes the area by 20%, a dropped shear moves the
    // centroid by 2 pixels; the centroid is checked to 0.1 pixel).
    ScratchDir dir("screen-area");
    constexpr const char* scene = R"(
Format 64 64 1
PixelSamples 8 8
PixelFilter "box" 1 1
Hider "hidden" "jitter" [0]
Quantize "rgba" 0 0 0 0
Display "{image}" "file" "rgba"
ScreenWindow -1 1 -1 1
{before}
Projection "orthographic"
Translate 0 0 5
WorldBegin
Surface "constant"
Polygon "P" [-0.1 -0.4 0  0.9 -0.4 0  0.9 0.6 0  -0.1 0.6 0]
WorldEnd
)";
    struct Case {
        const char* before;
        float m[4], t[2];
    };
    const float c = std::cos(3.14159265f / 6), s = std::sin(3.14159265f / 6);
    const Case cases[] = {
        {"", {1, 0, 0, 1}, {0, 0}},
        {"Rotate 30 0 0 1", {c, -s, s, c}, {0, 0}},
        // x' = x + 0.5 y (RIB matrices are row-vector), then a shift.
        {"Translate -0.3 0.1 0\nConcatTransform [1 0 0 0  0.5 1 0 0  0 0 1 0  0 0 0 1]", {1, 0.5f, 0, 1}, {-0.3f, 0.1f}},
        // An uneven scale after a turn: a parallelogram, mirrored.
        {"Scale -1 0.8 1\nRotate 30 0 0 1", {-c, s, 0.8f * s, 0.8f * c}, {0, 0}},
    };
    for (const Case& k : cases) {
        // The whole square stays inside the window.
        for (const float x : {-0.1f, 0.9f})
            for (const float y : {-0.4f, 0.6f}) {
                ASSERT_LT(std::abs(k.m[0] * x + k.m[1] * y + k.t[0]), 1.0f) << k.before;
                ASSERT_LT(std::abs(k.m[2] * x + k.m[3] * y + k.t[1]), 1.0f) << k.before;
            }
        const std::string image = dir.file("area.tif");
        Diagnostics diag;
        diag.setQuiet(true);
        const Image img = test::renderImage(
            fmt::format(scene, fmt::arg("image", image), fmt::arg("before", k.before)), image, diag);
        ASSERT_EQ(img.width, 64) << k.before;
        EXPECT_EQ(diag.errorCount() + diag.warningCount(), 0) << k.before;
        double sum = 0, sx = 0, sy = 0;
        for (int y = 0; y < img.height; ++y)
            for (int x = 0; x < img.width; ++x) {
                const double a = img.at(x, y, 3);
                sum += a;
                sx += a * (x + 0.5);
                sy += a * (y + 0.5);
            }
        const double det = double(k.m[0]) * k.m[3] - double(k.m[1]) * k.m[2];
        const double area = std::abs(det) * 32 * 32;
        EXPECT_NEAR(sum, area, 0.01 * area) << k.before;
        // The square's centre (0.4, 0.1), transformed, in raster (y down).
        const double cx = k.m[0] * 0.4 + k.m[1] * 0.1 + k.t[0], cy = k.m[2] * 0.4 + k.m[3] * 0.1 + k.t[1];
        EXPECT_NEAR(sx / sum, (cx + 1) * 32, 0.1) << k.before;
        EXPECT_NEAR(sy / sum, (1 - cy) * 32, 0.1) << k.before;
    }
}

TEST(ScreenTransform, DepthPartWarnsAndIsDropped) {
    ScratchDir dir("screen-depth");
    Rendered plain = renderFrame(dir, "");
    // A z flip or shift before Projection cannot move the picture; umbra
    // keeps camera depth and says so.
    Rendered flippedZ = renderFrame(dir, "Scale 1 1 -1");
    EXPECT_EQ(warningsMentioning(flippedZ, "depth"), 1);
    EXPECT_LT(meanAbsDiff(flippedZ.image, plain.image), 1e-5);
    Rendered shiftedZ = renderFrame(dir, "Translate 0 0 3");
    EXPECT_EQ(warningsMentioning(shiftedZ, "depth"), 1);
    EXPECT_LT(meanAbsDiff(shiftedZ.image, plain.image), 1e-5);
}

TEST(ScreenTransform, ShadersSeeNdcAfterIt) {
    // NDC space follows the screen transformation (RI Spec 3.2: NDC is the
    // screen window of screen space, which the screen transform is part
    // of): under any camera, a surface point's NDC x and y are where its
    // pixel is in the image. Checked at pixel centres a large plane covers.
    ScratchDir dir("screen-ndc");
    std::ofstream(dir.file("ndc.sl")) << "surface ndc() { point q = transform(\"NDC\", P);\n"
                                         "  Ci = color(xcomp(q), ycomp(q), 0); Oi = 1; }\n";
    constexpr const char* scene = R"(
Option "searchpath" "shader" ["{dir}:&"]
Format 40 30 1
PixelSamples 1 1
PixelFilter "box" 1 1
Hider "hidden" "jitter" [0]
Quantize "rgba" 0 0 0 0
Display "{image}" "file" "rgb"
{before}
Projection "{projection}"
Translate 0 0 4
WorldBegin
Surface "ndc"
Polygon "P" [-20 20 0  20 20 0  20 -20 0  -20 -20 0]
WorldEnd
)";
    for (const char* projection : {"perspective", "orthographic"})
        for (const char* before : {"", "Scale -1 1 1", "Scale 1.5 -2 1\nTranslate 0.1 0.2 0", "Rotate 30 0 0 1",
                                   "Rotate 90 0 0 1\nScale 1 -1 1"}) {
            const std::string image = dir.file("ndc.tif");
            Diagnostics diag;
            diag.setQuiet(true);
            const Image img = test::renderImage(fmt::format(scene, fmt::arg("dir", dir.file("")),
                                                            fmt::arg("image", image), fmt::arg("before", before),
                                                            fmt::arg("projection", projection)),
                                                image, diag);
            ASSERT_EQ(img.width, 40) << projection << " / " << before;
            EXPECT_EQ(diag.errorCount(), 0);
            for (int y = 0; y < img.height; y += 7)
                for (int x = 0; x < img.width; x += 9) {
                    EXPECT_NEAR(img.at(x, y, 0), (x + 0.5f) / 40, 2e-3f) << projection << " / " << before << " at " << x << "," << y;
                    EXPECT_NEAR(img.at(x, y, 1), (y + 0.5f) / 30, 2e-3f) << projection << " / " << before << " at " << x << "," << y;
                }
        }
}
