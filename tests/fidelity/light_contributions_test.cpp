// Light contributions from a RIB, as exporters write them: a light given
// `"__nonspecular" [1]` (or `"__nondiffuse" [1]`) on its LightSource line.
// Checked against the same frame written plainly: the standard plastic
// under a light that adds no highlight is plastic with Ks 0 under the same
// light without the parameter; no diffuse light is Kd 0.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <fstream>
#include <string>

using namespace umbra;
using umbra::test::Image;
using umbra::test::ScratchDir;

namespace {

// A distant light with the two category parameters (as Maya exporters'
// lights declare them), and a flat square facing the camera lit from the
// viewer's shoulder: a wide highlight and a diffuse gradient.
constexpr const char* kLight = R"(light catdistant(float intensity = 1; color lightcolor = 1;
    point from = point "shader" (0, 0, 0); point to = point "shader" (0, 0, 1);
    output float __nondiffuse = 0; output float __nonspecular = 0;)
{
    solar(to - from, 0) { Cl = intensity * lightcolor; }
}
)";

constexpr const char* kScene = R"(
Option "searchpath" "shader" ["{dir}:&"]
Format 48 48 1
PixelSamples 2 2
Quantize "rgba" 0 0 0 0
Display "{image}" "file" "rgb"
Projection "perspective" "fov" 40
Translate 0 0 4
WorldBegin
LightSource "catdistant" 1 "from" [0.3 -0.4 -1] "to" [0 0 0] {light}
Surface "plastic" "roughness" [0.3] {surface}
Polygon "P" [-1.5 1.5 0  1.5 1.5 0  1.5 -1.5 0  -1.5 -1.5 0]
WorldEnd
)";

Image renderFrame(const ScratchDir& dir, const std::string& light, const std::string& surface) {
    const std::string image = dir.file("lc.tif");
    Diagnostics diag;
    diag.setQuiet(true);
    Image img = test::renderImage(fmt::format(kScene, fmt::arg("dir", dir.file("")), fmt::arg("image", image),
                                              fmt::arg("light", light), fmt::arg("surface", surface)),
                                  image, diag);
    EXPECT_EQ(diag.errorCount(), 0);
    EXPECT_EQ(diag.warningCount(), 0);
    return img;
}

}  // namespace

TEST(LightContributions, FromTheRibNonSpecularIsPlasticWithoutHighlights) {
    ScratchDir dir("light-contrib");
    std::ofstream(dir.file("catdistant.sl")) << kLight;
    const Image all = renderFrame(dir, "", "");
    const Image nonSpecular = renderFrame(dir, "\"__nonspecular\" [1]", "");
    const Image noKs = renderFrame(dir, "", "\"Ks\" [0]");
    // The highlight is a visible part of the plain frame.
    ASSERT_GT(test::meanAbsDiff(all, noKs), 0.01);
    EXPECT_LT(test::maxAbsDiff(nonSpecular, noKs, 3), 1e-5);
}

TEST(LightContributions, FromTheRibNonDiffuseIsPlasticWithoutDiffuse) {
    ScratchDir dir("light-contrib-diffuse");
    std::ofstream(dir.file("catdistant.sl")) << kLight;
    const Image all = renderFrame(dir, "", "");
    const Image nonDiffuse = renderFrame(dir, "\"__nondiffuse\" [1]", "");
    const Image noKd = renderFrame(dir, "", "\"Kd\" [0]");
    ASSERT_GT(test::meanAbsDiff(all, noKd), 0.01);
    EXPECT_LT(test::maxAbsDiff(nonDiffuse, noKd, 3), 1e-5);
}
