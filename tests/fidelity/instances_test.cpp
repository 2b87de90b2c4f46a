// Object instancing as PRMan and Aqsis render it: attributes given inside
// ObjectBegin/ObjectEnd belong to the object, everything else comes from
// where it is instanced. Checked against the same scene written without
// instancing. And a shader that cannot be found: the peers draw the
// object with the default surface, and so does umbra.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>

using namespace umbra;
using umbra::test::Image;
using umbra::test::maxAbsDiff;
using umbra::test::meanAbsDiff;
using umbra::test::ScratchDir;

namespace {

Image renderScene(const ScratchDir& dir, const std::string& world, Diagnostics& diag) {
    const std::string image = dir.file("inst.tif");
    std::string rib = fmt::format(R"(
Format 240 120 1
Display "{}" "file" "rgb"
Projection "perspective" "fov" 40
Translate 0 0 6
WorldBegin
LightSource "ambientlight" 1 "intensity" [0.3]
LightSource "distantlight" 2 "from" [-1 1 -1] "to" [0 0 0]
{}
WorldEnd
)",
                                  image, world);
    return test::renderImage(rib, image, diag);
}

}  // namespace

TEST(Instances, AttributesInsideTheDefinitionBelongToTheObject) {
    ScratchDir dir("instances");
    // A red object with its own opacity, and one that sets nothing; each
    // instanced under a green plastic and a blue matte state.
    const char* instanced = R"(
ObjectBegin "red"
  Color [1 0 0]
  AttributeBegin
    Opacity [0.5 0.5 0.5]
    Translate 0 0.5 0
    Sphere 0.5 -0.5 0.5 360
  AttributeEnd
  Translate 0 -0.5 0
  Sphere 0.5 -0.5 0.5 360
ObjectEnd
ObjectBegin "plain"
  Sphere 0.8 -0.8 0.8 360
ObjectEnd
AttributeBegin Translate -2.7 0 0 Color [0 1 0] Surface "plastic" ObjectInstance "red" AttributeEnd
AttributeBegin Translate -0.9 0 0 Color [0 0 1] Surface "matte" ObjectInstance "red" AttributeEnd
AttributeBegin Translate 0.9 0 0 Color [0 1 0] Surface "plastic" ObjectInstance "plain" AttributeEnd
AttributeBegin Translate 2.7 0 0 Color [0 0 1] Surface "matte" ObjectInstance "plain" AttributeEnd
)";
    const char* plain = R"(
AttributeBegin Translate -2.7 0 0 Surface "plastic" Color [1 0 0]
  AttributeBegin Opacity [0.5 0.5 0.5] Translate 0 0.5 0 Sphere 0.5 -0.5 0.5 360 AttributeEnd
  Translate 0 -0.5 0 Sphere 0.5 -0.5 0.5 360
AttributeEnd
AttributeBegin Translate -0.9 0 0 Surface "matte" Color [1 0 0]
  AttributeBegin Opacity [0.5 0.5 0.5] Translate 0 0.5 0 Sphere 0.5 -0.5 0.5 360 AttributeEnd
  Translate 0 -0.5 0 Sphere 0.5 -0.5 0.5 360
AttributeEnd
AttributeBegin Translate 0.9 0 0 Color [0 1 0] Surface "plastic" Sphere 0.8 -0.8 0.8 360 AttributeEnd
AttributeBegin Translate 2.7 0 0 Color [0 0 1] Surface "matte" Sphere 0.8 -0.8 0.8 360 AttributeEnd
)";
    Diagnostics d1, d2;
    d1.setQuiet(true);
    d2.setQuiet(true);
    Image a = renderScene(dir, instanced, d1);
    Image b = renderScene(dir, plain, d2);
    EXPECT_EQ(d1.errorCount(), 0);
    ASSERT_GT(b.channelSum(0), 100.0);
    EXPECT_LT(meanAbsDiff(a, b), 1e-6);
}

TEST(Instances, AMissingShaderDrawsTheDefaultSurfaceAndIsReportedOnce) {
    ScratchDir dir("missing-shader");
    const char* missing = R"(
ObjectBegin 1 Surface "nosuchshader" Sphere 0.8 -0.8 0.8 360 ObjectEnd
AttributeBegin Translate -1.8 0 0 ObjectInstance 1 AttributeEnd
AttributeBegin ObjectInstance 1 AttributeEnd
AttributeBegin Translate 1.8 0 0 Surface "nosuchshader" Sphere 0.8 -0.8 0.8 360 AttributeEnd
)";
    const char* fallback = R"(
AttributeBegin Translate -1.8 0 0 Surface "defaultsurface" Sphere 0.8 -0.8 0.8 360 AttributeEnd
AttributeBegin Surface "defaultsurface" Sphere 0.8 -0.8 0.8 360 AttributeEnd
AttributeBegin Translate 1.8 0 0 Surface "defaultsurface" Sphere 0.8 -0.8 0.8 360 AttributeEnd
)";
    Diagnostics d1, d2;
    d1.setQuiet(true);
    d1.setRecord(true);
    d2.setQuiet(true);
    Image a = renderScene(dir, missing, d1);
    Image b = renderScene(dir, fallback, d2);
    ASSERT_GT(b.channelSum(0), 100.0);
    EXPECT_LT(meanAbsDiff(a, b), 1e-6);
    // One message for the name, at its first use, however many pieces use it.
    int reports = 0;
    for (const Diagnostic& d : d1.recorded()) reports += d.message.find("nosuchshader") != std::string::npos;
    EXPECT_EQ(reports, 1);
}
