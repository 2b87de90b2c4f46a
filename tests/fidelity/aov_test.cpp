// Output variables (AOVs) as RenderMan scenes ask for them: a shader's
// `output varying` parameters named by `Display "+file" "driver" "name"`,
// typed inline or by an earlier `Declare`, each display with its own
// "quantize" and "exposure". Checked against the same values rendered as
// Ci by a shader that computes them plainly.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <fstream>

using namespace umbra;
using umbra::test::Image;
using umbra::test::maxAbsDiff;
using umbra::test::meanAbsDiff;
using umbra::test::ScratchDir;

namespace {

const char* kAovShader = R"(
surface aovs(output varying color diffusecol = 0; output varying float mask = 0;) {
    normal Nf = faceforward(normalize(N), I);
    diffusecol = Cs * diffuse(Nf);
    mask = s;
    Ci = Cs * 0.25;
    Oi = 1;
}
)";
const char* kDiffuseAsCi = "surface diffuseci() { Ci = Cs * diffuse(faceforward(normalize(N), I)); Oi = 1; }\n";
const char* kMaskAsCi = "surface maskci() { Ci = s; Oi = 1; }\n";

std::string aovScene(const ScratchDir& dir, const std::string& displays, const std::string& surface) {
    return fmt::format(R"(
Option "searchpath" "shader" ["{}:&"]
Format 96 72 1
PixelSamples 3 3
Declare "mask" "varying float"
{}
Projection "perspective" "fov" 40
Translate 0 0 5
WorldBegin
LightSource "distantlight" 1 "from" [-1 1 -1] "to" [0 0 0]
Color [1 0.5 0.2]
Surface "{}"
Sphere 1 -1 1 360
WorldEnd
)",
                       dir.file(""), displays, surface);
}

Image renderAndRead(const std::string& rib, const std::string& image) {
    Diagnostics diag;
    diag.setQuiet(true);
    int failed = 0;
    Image img = test::renderImage(rib, image, diag, 0, 0, &failed);
    EXPECT_EQ(diag.errorCount(), 0);
    EXPECT_EQ(failed, 0);
    return img;
}

}  // namespace

TEST(Aov, OutputVariablesNamedBareOrTypedWriteWhatTheShaderComputed) {
    ScratchDir dir("aov");
    std::ofstream(dir.file("aovs.sl")) << kAovShader;
    std::ofstream(dir.file("diffuseci.sl")) << kDiffuseAsCi;
    std::ofstream(dir.file("maskci.sl")) << kMaskAsCi;
    const std::string displays = fmt::format(R"(
Display "{0}" "file" "rgb"
Display "+{1}" "file" "varying color diffusecol"
Display "+{2}" "file" "mask"
Display "+{3}" "file" "mask" "quantize" [0 255 0 255]
Display "+{4}" "file" "rgb" "exposure" [2 1]
)",
                                             dir.file("beauty.exr"), dir.file("diffuse.exr"), dir.file("mask.exr"),
                                             dir.file("mask8.tif"), dir.file("bright.exr"));
    Image diffuse = renderAndRead(aovScene(dir, displays, "aovs"), dir.file("diffuse.exr"));
    Image mask, mask8, beauty, bright;
    ASSERT_TRUE(test::readImage(dir.file("mask.exr"), &mask));
    ASSERT_TRUE(test::readImage(dir.file("mask8.tif"), &mask8));
    ASSERT_TRUE(test::readImage(dir.file("beauty.exr"), &beauty));
    ASSERT_TRUE(test::readImage(dir.file("bright.exr"), &bright));

    // The same values as Ci of shaders that compute them.
    Image diffuseRef = renderAndRead(aovScene(dir, fmt::format("Display \"{}\" \"file\" \"rgb\"", dir.file("d.exr")),
                                           "diffuseci"),
                                     dir.file("d.exr"));
    Image maskRef = renderAndRead(aovScene(dir, fmt::format("Display \"{}\" \"file\" \"rgb\"", dir.file("m.exr")),
                                        "maskci"),
                                  dir.file("m.exr"));
    ASSERT_GT(diffuseRef.channelSum(0), 100.0);
    EXPECT_LT(maxAbsDiff(diffuse, diffuseRef, 3), 1e-5);
    ASSERT_EQ(mask.channels, 1);
    EXPECT_LT(maxAbsDiff(mask, maskRef, 1), 1e-5);
    // Its own quantize: 8 bits, round(255 v).
    ASSERT_EQ(mask8.channels, 1);
    double worst = 0;
    for (int y = 0; y < mask.height; ++y)
        for (int x = 0; x < mask.width; ++x)
            worst = std::max(worst, std::fabs(double(mask8.at(x, y, 0)) * 255.0 - std::round(255.0 * mask.at(x, y, 0))));
    EXPECT_LE(worst, 1.001);  // one level: the dither of the frame's default quantize
    // Its own exposure: twice the beauty's colour.
    EXPECT_LT(maxAbsDiff(bright, beauty, 1), 10.0);
    double ratioErr = 0;
    for (int y = 0; y < beauty.height; ++y)
        for (int x = 0; x < beauty.width; ++x)
            ratioErr = std::max(ratioErr, std::fabs(double(bright.at(x, y, 0)) - 2.0 * beauty.at(x, y, 0)));
    EXPECT_LT(ratioErr, 1e-5);
    EXPECT_GT(bright.channelSum(0), 1.9 * beauty.channelSum(0));
}
