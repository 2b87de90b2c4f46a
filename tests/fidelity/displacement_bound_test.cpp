// Attribute "displacementbound" as the RenderMan books and exporters write
// it: in object space by default, or in the "coordinatesystem" named with
// it (3ds Max and Maya output gives ["world"]). A surface displaced past
// its bound loses pieces (the RenderMan Companion's figure 17.13 shows
// the torn cylinder); umbra says so at the Displacement request.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <fstream>

using namespace umbra;
using umbra::test::Image;
using umbra::test::meanAbsDiff;
using umbra::test::ScratchDir;

namespace {

// Pushes the surface out along its normal by `amplitude` camera units
// where sin(2 pi 6 s) is 1, and in where it is -1.
constexpr const char* kRipple = R"(
displacement ripple(float amplitude = 0.1)
{
    P += amplitude * sin(2 * PI * 6 * s) * normalize(N);
    N = calculatenormal(P);
}
)";

// A cylinder of radius 1 and length 3 seen side on, whatever its object
// scale, 0.25 camera units of displacement, and the bound written `bound`
// (the Attribute line, or nothing) on line 9, the Displacement on line 10.
std::string scene(const ScratchDir& dir, const std::string& image, const std::string& bound, double scale) {
    return fmt::format(R"(Option "searchpath" "shader" ["{}:&"]
Format 160 120 1
PixelSamples 2 2
Display "{}" "file" "rgba"
Projection "perspective" "fov" 40
Translate 0 0 5
WorldBegin
LightSource "distantlight" 1 "from" [0 0 0] "to" [0.3 -0.3 1]
{}
Displacement "ripple" "amplitude" [0.25]
Surface "matte"
Scale {} {} {}
Rotate 90 0 1 0
Cylinder {} {} {} 360
WorldEnd
)",
                       dir.file(""), image, bound, scale, scale, scale, 1 / scale, -1.5 / scale, 1.5 / scale);
}

struct Rendered {
    Image image;
    std::vector<Diagnostic> diagnostics;
    int errors = 0;
};

Rendered renderRipple(const ScratchDir& dir, const std::string& name, const std::string& bound, double scale) {
    const std::string image = dir.file(name);
    Diagnostics diag;
    diag.setQuiet(true);
    diag.setRecord(true);
    Rendered r;
    r.image = test::renderImage(scene(dir, image, bound, scale), image, diag);
    r.diagnostics = diag.recorded();
    r.errors = diag.errorCount();
    return r;
}

int boundWarnings(const Rendered& r, int* line) {
    int n = 0;
    for (const Diagnostic& d : r.diagnostics)
        if (d.message.find("displacementbound") != std::string::npos) {
            ++n;
            *line = d.loc.line;
        }
    return n;
}

}  // namespace

TEST(DisplacementBound, AWorldSpaceBoundCoversAScaledDownObject) {
    // The object is a tenth of world size (and of camera size: the camera
    // does not scale), so 0.3 world units are 3 object units. The two
    // scenes give the same bound and must draw the same whole cylinder.
    ScratchDir dir("displacementbound-world");
    std::ofstream(dir.file("ripple.sl")) << kRipple;
    const Rendered world = renderRipple(dir, "world.tif",
                                  R"(Attribute "displacementbound" "sphere" [0.3] "coordinatesystem" ["world"])", 0.1);
    const Rendered object = renderRipple(dir, "object.tif", R"(Attribute "displacementbound" "sphere" [3])", 0.1);
    ASSERT_EQ(world.errors, 0);
    ASSERT_EQ(object.errors, 0);
    int line = 0;
    EXPECT_EQ(boundWarnings(world, &line), 0);
    EXPECT_EQ(boundWarnings(object, &line), 0);
    EXPECT_GT(object.image.channelSum(3), 1000.0);
    EXPECT_LT(meanAbsDiff(world.image, object.image), 1e-4);
}

TEST(DisplacementBound, DisplacingPastTheBoundIsWarnedAtTheDisplacement) {
    // No bound at all, as in the Companion's figure 17.13: one warning
    // however many grids go past it, located at the Displacement request
    // (line 10 of the scene). A bound that covers the 0.25 units: none.
    ScratchDir dir("displacementbound-warn");
    std::ofstream(dir.file("ripple.sl")) << kRipple;
    const Rendered none = renderRipple(dir, "none.tif", "", 1);
    const Rendered covered = renderRipple(dir, "covered.tif", R"(Attribute "displacementbound" "sphere" [0.25])", 1);
    ASSERT_EQ(none.errors, 0);
    ASSERT_EQ(covered.errors, 0);
    int line = 0;
    EXPECT_EQ(boundWarnings(none, &line), 1);
    EXPECT_EQ(line, 10);
    EXPECT_EQ(boundWarnings(covered, &line), 0);
}
