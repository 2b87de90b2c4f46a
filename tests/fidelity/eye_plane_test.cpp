// Geometry crossing the eye plane: a ground running under and behind the
// camera, a sky sphere around the eye (as Advanced RenderMan writes it), a
// cylinder around the camera and a polygon through the eye plane. Each is
// checked pixel by pixel against the closed-form coverage of the part in
// front of the camera (once all culled at the root: black, exit 0).

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <functional>

using namespace umbra;
using umbra::test::Image;
using umbra::test::maxAbsDiff;
using umbra::test::meanAbsDiff;
using umbra::test::ScratchDir;

namespace {

constexpr int kWidth = 160, kHeight = 120;
constexpr float kFov = 60;  // degrees, across the narrower (vertical) side

/// Whether the camera ray through (sx, sy, 1) (a direction in camera space)
/// meets the surface in front of the eye.
using Coverage = std::function<bool(double sx, double sy)>;

struct EyeCase {
    const char* name;
    const char* world;
    Coverage covers;
};

const EyeCase kCases[] = {
    // The ground y = -1, x and z in [-10, 10]: the ray meets y = -1 at
    // t = -1/sy, in the patch while |x| = t|sx| <= 10 and z = t <= 10.
    {"ground under and behind the camera",
     "Patch \"bilinear\" \"P\" [-10 -1 -10  10 -1 -10  -10 -1 10  10 -1 10]",
     [](double sx, double sy) { return sy < 0 && -1 / sy <= 10 && std::fabs(sx / sy) <= 10; }},
    // Radius 50 around the eye: every ray meets it.
    {"sky sphere around the eye", "Sphere 50 -50 50 360", [](double, double) { return true; }},
    // The same sphere with its poles on the eye plane (a sky sphere under a
    // camera that looks along the horizon, as the RenderMan Repository's
    // starfield scenes have it): every full turn of u and every meridian
    // ends at the eye plane, so splitting by the z of a row's ends never
    // separated the front from the back (once black, exit 0).
    {"sky sphere with its poles on the eye plane", "Rotate 90 1 0 0 Sphere 50 -50 50 360",
     [](double, double) { return true; }},
    // Radius 2 about the y axis, y in [-1, 1] (Rotate 90 about x takes the
    // cylinder's z to -y): the ray meets it at t = 2 / sqrt(sx^2 + 1).
    {"cylinder around the camera", "Rotate 90 1 0 0 Cylinder 2 -1 1 360",
     [](double sx, double sy) { return std::fabs(sy) * 2 / std::sqrt(sx * sx + 1) <= 1; }},
    // The plane z = y + 2, x and y in [-3, 3], from z = -1 behind the eye to
    // z = 5: the ray meets it at t = 2 / (1 - sy), in front when sy < 1.
    {"polygon through the eye plane", "Polygon \"P\" [-3 -3 -1  3 -3 -1  3 3 5  -3 3 5]",
     [](double sx, double sy) {
         if (sy >= 1) return false;
         double t = 2 / (1 - sy);
         return std::fabs(t * sx) <= 3 && std::fabs(t * sy) <= 3;
     }},
};

/// The camera-space direction (sx, sy, 1) through a pixel's centre.
void pixelRay(double px, double py, double* sx, double* sy) {
    const double tanHalf = std::tan(kFov / 2 * 3.14159265358979 / 180);
    const double aspect = double(kWidth) / kHeight;
    *sx = ((px + 0.5) / kWidth * 2 - 1) * aspect * tanHalf;
    *sy = (1 - (py + 0.5) / kHeight * 2) * tanHalf;
}

Image renderCase(const ScratchDir& dir, const std::string& world, const std::string& options, Diagnostics& diag) {
    std::string image = dir.file("eye.tif");
    std::string rib = fmt::format(R"(
{}
Format {} {} 1
PixelSamples 4 4
Display "{}" "file" "rgb"
Projection "perspective" "fov" {}
WorldBegin
Surface "constant"
{}
WorldEnd
)",
                                  options, kWidth, kHeight, image, kFov, world);
    return test::renderImage(rib, image, diag);
}

}  // namespace

TEST(EyePlane, GeometryAroundAndThroughTheEyeCoversWhatLiesInFront) {
    ScratchDir dir("eye-plane");
    for (const EyeCase& c : kCases) {
        SCOPED_TRACE(c.name);
        Diagnostics diag;
        diag.setQuiet(true);
        Image img = renderCase(dir, c.world, "", diag);
        EXPECT_EQ(diag.errorCount(), 0);
        ASSERT_EQ(img.width, kWidth);
        // Pixels whose centre and all four corners agree on the closed form
        // are wholly in or out: they must be white or black. Edge pixels are
        // partly covered and are not checked; single missing samples at
        // grid cracks (Pixie and Aqsis have them too) are allowed for 1%.
        int inside = 0, outside = 0, wrong = 0;
        for (int y = 0; y < kHeight; ++y)
            for (int x = 0; x < kWidth; ++x) {
                double sx, sy;
                int votes = 0;
                for (auto [dx, dy] : {std::pair{0.0, 0.0}, {-0.5, -0.5}, {0.5, -0.5}, {-0.5, 0.5}, {0.5, 0.5}}) {
                    pixelRay(x + dx, y + dy, &sx, &sy);
                    votes += c.covers(sx, sy) ? 1 : 0;
                }
                if (votes != 0 && votes != 5) continue;
                const float v = img.at(x, y, 0);
                if (votes == 5) {
                    ++inside;
                    wrong += v < 0.9f;
                } else {
                    ++outside;
                    wrong += v > 0.0f;
                }
            }
        EXPECT_GT(inside, kWidth * kHeight / 8);
        EXPECT_LE(wrong, (inside + outside) / 100) << "inside " << inside << ", outside " << outside;
    }
}

TEST(EyePlane, TheEyeSplitLimitIsHonouredWithAWarning) {
    // With no eye splits allowed, geometry across the eye plane is culled,
    // and the user is told which primitive and which option to raise.
    ScratchDir dir("eye-limit");
    Diagnostics diag;
    diag.setQuiet(true);
    diag.setRecord(true);
    Image img = renderCase(dir, kCases[1].world, "Option \"limits\" \"eyesplits\" [0]", diag);
    EXPECT_EQ(img.channelSum(0), 0.0);
    bool warned = false;
    for (const Diagnostic& d : diag.recorded())
        warned |= d.message.find("eyesplits") != std::string::npos && d.message.find("Sphere") == 0 && d.loc.line == 9;
    EXPECT_TRUE(warned);
    // The default limit renders the same sphere.
    Diagnostics plain;
    plain.setQuiet(true);
    Image full = renderCase(dir, kCases[1].world, "", plain);
    EXPECT_GT(full.channelSum(0), 0.99 * kWidth * kHeight);
}
