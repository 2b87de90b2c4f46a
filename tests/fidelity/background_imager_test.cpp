// The standard `background` imager, as scenes for other RenderMan renderers
// name it (`Imager "background" "bgcolor" [r g b]`, Aqsis and BMRT; or
// "background", the RI Spec's name for that colour): the colour goes under
// the image by what nothing covers, Ci + (1 - alpha) bgcolor, alpha 1.
// Checked against closed forms on pixels whose coverage is known exactly,
// and pixel by pixel against the same frame rendered without the imager.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <string>

using namespace umbra;
using umbra::test::Image;
using umbra::test::ScratchDir;

namespace {

constexpr int kSize = 32;

// Orthographic, the window [-1, 1]^2 over 32 pixels: pixel column i spans
// x in [-1 + i/16, -1 + (i + 1)/16]. The green square's right edge is at
// the middle of column 16, so columns 0-15 are covered, 16 is half covered
// (2 of each row's 4 unjittered samples, a 1-pixel box filter) and 17-31
// are empty.
constexpr const char* kScene = R"(
Format {size} {size} 1
PixelSamples 4 4
PixelFilter "{filter}" {width} {width}
Hider "hidden" "jitter" [{jitter}]
Quantize "rgba" 0 0 0 0
Display "{image}" "file" "rgba"
ScreenWindow -1 1 -1 1
{imager}
Projection "orthographic"
WorldBegin
Translate 0 0 5
Surface "constant"
Color [0 1 0]
Polygon "P" [-2 2 0  0.03125 2 0  0.03125 -2 0  -2 -2 0]
Opacity [{opacity} {opacity} {opacity}]
Translate 0 0 -1
Sphere 0.3 -0.3 0.3 360
WorldEnd
)";

Image renderFrame(const ScratchDir& dir, const std::string& imager, const char* filter = "box", float width = 1,
             int jitter = 0, float opacity = 1, int* errors = nullptr) {
    const std::string image = dir.file("bg.tif");
    const std::string rib = fmt::format(kScene, fmt::arg("size", kSize), fmt::arg("filter", filter),
                                        fmt::arg("width", width), fmt::arg("jitter", jitter),
                                        fmt::arg("image", image), fmt::arg("imager", imager),
                                        fmt::arg("opacity", opacity));
    Diagnostics diag;
    diag.setQuiet(true);
    Image img = test::renderImage(rib, image, diag);
    if (errors) *errors = diag.errorCount();
    EXPECT_EQ(diag.errorCount(), 0);
    EXPECT_EQ(diag.warningCount(), 0);
    return img;
}

}  // namespace

TEST(BackgroundImager, EmptyPixelsGetTheColourCoveredOnesKeepTheirs) {
    ScratchDir dir("bg-imager");
    const float bg[3] = {0.25f, 0.5f, 0.75f};
    const Image img = renderFrame(dir, "Imager \"background\" \"bgcolor\" [0.25 0.5 0.75]");
    ASSERT_EQ(img.width, kSize);
    ASSERT_EQ(img.channels, 4);
    // A row away from the sphere (which covers y in [-0.3, 0.3], rows
    // 11-20): only the square's edge decides.
    for (int y : {0, 3, 28, 31}) {
        for (int x = 0; x < 16; ++x) {
            EXPECT_EQ(img.at(x, y, 0), 0.0f) << x << "," << y;
            EXPECT_EQ(img.at(x, y, 1), 1.0f) << x << "," << y;
            EXPECT_EQ(img.at(x, y, 2), 0.0f) << x << "," << y;
            EXPECT_EQ(img.at(x, y, 3), 1.0f) << x << "," << y;
        }
        // Half covered: the alpha blend of green over the colour.
        EXPECT_NEAR(img.at(16, y, 0), 0.5f * bg[0], 1e-6f) << y;
        EXPECT_NEAR(img.at(16, y, 1), 0.5f + 0.5f * bg[1], 1e-6f) << y;
        EXPECT_NEAR(img.at(16, y, 2), 0.5f * bg[2], 1e-6f) << y;
        EXPECT_EQ(img.at(16, y, 3), 1.0f) << y;
        for (int x = 17; x < kSize; ++x) {
            for (int c = 0; c < 3; ++c) EXPECT_EQ(img.at(x, y, c), bg[c]) << x << "," << y << " channel " << c;
            EXPECT_EQ(img.at(x, y, 3), 1.0f) << x << "," << y;
        }
    }
}

TEST(BackgroundImager, AcceptsTheRenderManParameterName) {
    ScratchDir dir("bg-imager-name");
    const Image a = renderFrame(dir, "Imager \"background\" \"bgcolor\" [0.25 0.5 0.75]");
    const Image b = renderFrame(dir, "Imager \"background\" \"color background\" [0.25 0.5 0.75]");
    EXPECT_EQ(test::maxAbsDiff(a, b, 4), 0.0);
    // RenderMan for Maya's name for it (a type keyword, so no shader
    // parameter can be called so).
    const Image c = renderFrame(dir, "Imager \"background\" \"color color\" [0.25 0.5 0.75]");
    EXPECT_EQ(test::maxAbsDiff(a, c, 4), 0.0);
    // With no colour given the background is white (both peers' default).
    const Image white = renderFrame(dir, "Imager \"background\"");
    EXPECT_EQ(white.at(kSize - 1, 0, 0), 1.0f);
    EXPECT_EQ(white.at(kSize - 1, 0, 2), 1.0f);
}

TEST(BackgroundImager, CompositesUnderEveryPixelByItsAlpha) {
    // Any filter, jittered samples, a half-transparent sphere over the
    // square: each pixel is the plain frame's premultiplied colour plus
    // (1 - alpha) of the background, and opaque.
    ScratchDir dir("bg-imager-blend");
    const float bg[3] = {0.9f, 0.1f, 0.4f};
    const Image plain = renderFrame(dir, "", "gaussian", 2, 1, 0.5f);
    const Image img = renderFrame(dir, "Imager \"background\" \"bgcolor\" [0.9 0.1 0.4]", "gaussian", 2, 1, 0.5f);
    ASSERT_EQ(img.width, plain.width);
    int partial = 0;
    for (int y = 0; y < kSize; ++y)
        for (int x = 0; x < kSize; ++x) {
            const float a = plain.at(x, y, 3);
            partial += a > 0.01f && a < 0.99f;
            for (int c = 0; c < 3; ++c)
                EXPECT_NEAR(img.at(x, y, c), plain.at(x, y, c) + (1 - a) * bg[c], 1e-5f) << x << "," << y;
            EXPECT_NEAR(img.at(x, y, 3), 1.0f, 1e-6f) << x << "," << y;
        }
    EXPECT_GT(partial, kSize);  // edges and the see-through sphere were blended
}
