// PRMan's `Points ... "uniform string type" "sphere"`: every point is a true
// sphere of radius width/2 on the point, shaded as one. Checked against the
// same spheres written as `Translate` + `Sphere`, whose picture umbra's
// quadric tests pin down: silhouettes, shading and the points' own
// colours must agree.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>

using namespace umbra;
using umbra::test::Image;
using umbra::test::ScratchDir;

namespace {

std::string frame(const std::string& path, const std::string& body) {
    return fmt::format(R"(Format 64 48 1
PixelSamples 4 4
PixelFilter "gaussian" 2 2
Display "{}" "openexr" "rgba" "string type" "float"
Projection "perspective" "fov" 40
Translate 0 0 6
WorldBegin
LightSource "distantlight" 1 "from" [-1 1.5 -1] "to" [0 0 0]
LightSource "ambientlight" 2 "intensity" 0.1
Surface "plastic" "roughness" 0.2
AttributeBegin
Rotate 20 0 1 0
{}
AttributeEnd
WorldEnd
)",
                       path, body);
}

Image renderAt(const std::string& rib, const std::string& path) {
    Diagnostics diag;
    diag.setQuiet(true);
    diag.setRecord(true);
    Image img = test::renderImage(rib, path, diag, 2, 16);
    EXPECT_EQ(diag.errorCount(), 0);
    for (const Diagnostic& m : diag.recorded()) ADD_FAILURE() << m.str();
    return img;
}

double maxDiff(const Image& a, const Image& b) {
    if (a.width != b.width || a.height != b.height || a.channels != b.channels || a.pixels.empty()) return 1e9;
    double d = 0;
    for (size_t i = 0; i < a.pixels.size(); ++i) d = std::max(d, std::fabs(double(a.pixels[i]) - double(b.pixels[i])));
    return d;
}

}  // namespace

TEST(PointSpheres, ASpherePointIsTheSphereOfItsWidthAtItsPlace) {
    ScratchDir dir("point-spheres");
    // Three points of their own widths and colours (varying), one with an
    // opacity (constant Os for all), against three Spheres.
    const Image points = renderAt(frame(dir.file("p.exr"), R"(Opacity [1 1 1]
Points "P" [-1.2 0.3 0.5  0.4 -0.5 -0.2  1.3 0.6 1]
       "varying float width" [1.2 0.8 1.6]
       "varying color Cs" [1 0.2 0.2  0.2 1 0.2  0.3 0.4 1]
       "uniform string type" "sphere")"),
                                  dir.file("p.exr"));
    const Image spheres = renderAt(frame(dir.file("s.exr"), R"(Opacity [1 1 1]
AttributeBegin
Translate -1.2 0.3 0.5
Color [1 0.2 0.2]
Sphere 0.6 -0.6 0.6 360
AttributeEnd
AttributeBegin
Translate 0.4 -0.5 -0.2
Color [0.2 1 0.2]
Sphere 0.4 -0.4 0.4 360
AttributeEnd
AttributeBegin
Translate 1.3 0.6 1
Color [0.3 0.4 1]
Sphere 0.8 -0.8 0.8 360
AttributeEnd)"),
                                   dir.file("s.exr"));
    EXPECT_LE(maxDiff(points, spheres), 1e-5);
    // Something was drawn: the spheres' coverage is their projected area.
    double alpha = points.channelSum(3);
    EXPECT_GT(alpha, 300.0);

    // The default type draws discs facing the eye: the same silhouettes
    // (a sphere's outline is its disc's, nearly, in this narrow view) but
    // flat shading, so the pictures differ.
    const Image discs = renderAt(frame(dir.file("d.exr"), R"(Opacity [1 1 1]
Points "P" [-1.2 0.3 0.5  0.4 -0.5 -0.2  1.3 0.6 1]
       "varying float width" [1.2 0.8 1.6]
       "varying color Cs" [1 0.2 0.2  0.2 1 0.2  0.3 0.4 1])"),
                                 dir.file("d.exr"));
    EXPECT_GT(maxDiff(points, discs), 0.1);
}

TEST(PointSpheres, ConstantWidthAndAMovingTransform) {
    // "constantwidth", and a transform blurred over the shutter: each
    // sphere moves with the Points' transform as a Sphere would.
    ScratchDir dir("point-spheres-motion");
    const std::string shutter = "Shutter 0 1\n";
    auto withShutter = [&](std::string rib) { return shutter + rib; };
    const Image points = renderAt(withShutter(frame(dir.file("p.exr"), R"(MotionBegin [0 1]
Translate 0 0 0
Translate 0.6 0.2 0
MotionEnd
Points "P" [-0.8 0 0  0.9 0.2 0.4] "constantwidth" 1.1 "constant string type" "sphere")")),
                                  dir.file("p.exr"));
    const Image spheres = renderAt(withShutter(frame(dir.file("s.exr"), R"(MotionBegin [0 1]
Translate 0 0 0
Translate 0.6 0.2 0
MotionEnd
AttributeBegin
Translate -0.8 0 0
Sphere 0.55 -0.55 0.55 360
AttributeEnd
AttributeBegin
Translate 0.9 0.2 0.4
Sphere 0.55 -0.55 0.55 360
AttributeEnd)")),
                                   dir.file("s.exr"));
    EXPECT_LE(maxDiff(points, spheres), 1e-5);
    EXPECT_GT(points.channelSum(3), 100.0);
}

TEST(PointSpheres, DeformationBlurMovesEachSphereWithItsPoint) {
    // MotionBegin around the Points: each point's path is a straight line
    // between its shapes, so each sphere is the Sphere under a moving
    // Translate between the two places.
    ScratchDir dir("point-spheres-deform");
    const Image points = renderAt("Shutter 0 1\n" + frame(dir.file("p.exr"), R"(MotionBegin [0 1]
Points "P" [-0.8 0 0  0.9 0.2 0.4] "constantwidth" 1 "uniform string type" "sphere"
Points "P" [-0.2 0.3 0  0.9 -0.4 0.4] "constantwidth" 1 "uniform string type" "sphere"
MotionEnd)"),
                                  dir.file("p.exr"));
    const Image spheres = renderAt("Shutter 0 1\n" + frame(dir.file("s.exr"), R"(AttributeBegin
MotionBegin [0 1]
Translate -0.8 0 0
Translate -0.2 0.3 0
MotionEnd
Sphere 0.5 -0.5 0.5 360
AttributeEnd
AttributeBegin
MotionBegin [0 1]
Translate 0.9 0.2 0.4
Translate 0.9 -0.4 0.4
MotionEnd
Sphere 0.5 -0.5 0.5 360
AttributeEnd)"),
                                   dir.file("s.exr"));
    EXPECT_LE(maxDiff(points, spheres), 1e-5);
    EXPECT_GT(points.channelSum(3), 100.0);
}
