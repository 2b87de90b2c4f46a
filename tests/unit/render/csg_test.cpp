// CSG (SolidBegin, RI spec 3.2 §5.8) end to end: coverage of differences
// and intersections against closed forms, the colour and depth of a crater
// cut by a difference, a nested tree against a ray-interval evaluation
// written here, a mirrored camera and determinism.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <optional>

using namespace umbra;
using umbra::test::Image;
using umbra::test::ScratchDir;

namespace {

/// An orthographic view of [-2,2]^2 looking down +z from z = -5 (the
/// world is moved 5 along z), box filter 1x1; `hider` adds requests before
/// WorldBegin.
std::string orthoFrame(const std::string& out, const std::string& world, int samples, int res,
                       const std::string& extra = "") {
    return fmt::format(R"(
Display "{}" "openexr" "rgbaz" "string type" "float"
Format {} {} 1
ScreenWindow -2 2 -2 2
Projection "orthographic"
PixelSamples {} {}
PixelFilter "box" 1 1
ShadingRate 1
{}
Translate 0 0 5
WorldBegin
Surface "constant"
{}
WorldEnd
)", out, res, res, samples, samples, extra, world);
}

Image renderCsg(const std::string& world, const std::string& name, int samples = 4, int res = 256,
             const std::string& extra = "", int threads = 0, int bucket = 0) {
    ScratchDir dir(name);
    Diagnostics diag;
    test::renderRib(orthoFrame(dir.file("out.exr"), world, samples, res, extra), diag, threads, bucket);
    EXPECT_EQ(diag.errorCount(), 0);
    Image img;
    EXPECT_TRUE(test::readImage(dir.file("out.exr"), &img));
    return img;
}

double coveredArea(const Image& img) { return img.channelSum(3) * (4.0 / img.width) * (4.0 / img.height); }

std::string sphere(const char* colour, float x, float y, float z, float r) {
    return fmt::format("SolidBegin \"primitive\" AttributeBegin Color [{}] Translate {} {} {} Sphere {} {} {} 360 "
                       "AttributeEnd SolidEnd\n",
                       colour, x, y, z, r, -r, r);
}

/// A capped cylinder along z, radius r, from z0 to z1: one closed solid
/// made of three surfaces.
std::string cappedCylinder(float r, float z0, float z1) {
    return fmt::format(R"(SolidBegin "primitive" AttributeBegin Color [0 0 1]
        Cylinder {0} {1} {2} 360
        AttributeBegin Translate 0 0 {2} Disk 0 {0} 360 AttributeEnd
        AttributeBegin Rotate 180 1 0 0 Disk {3} {0} 360 AttributeEnd
        AttributeEnd SolidEnd
)", r, z0, z1, -z0);
}

}  // namespace

TEST(Csg, DifferenceByALongerCylinderLeavesARing) {
    // A sphere of radius 1 less a capped cylinder of radius 0.5 that runs
    // through it along the view: an annulus, area pi (1 - 0.25).
    const Image img =
        renderCsg("SolidBegin \"difference\"\n" + sphere("1 0 0", 0, 0, 0, 1) + cappedCylinder(0.5f, -2, 2) + "SolidEnd",
               "csg-ring");
    const double expected = M_PI * (1.0 - 0.25);
    EXPECT_NEAR(coveredArea(img), expected, 0.005 * expected);
}

TEST(Csg, DifferenceByAnEnclosingSphereIsEmpty) {
    const Image img = renderCsg("SolidBegin \"difference\"\n" + sphere("1 0 0", 0, 0, 0, 1) +
                                 sphere("0 1 0", 0, 0, 0.2f, 1.5f) + "SolidEnd",
                             "csg-empty");
    // A few samples fall through cracks between the enclosing sphere's
    // grids (they do with the sphere drawn alone, without CSG, too): less
    // than two pixels' worth.
    EXPECT_LT(coveredArea(img), 2 * (4.0 / 256) * (4.0 / 256));
}

TEST(Csg, GeometryTeapotTakesPartInTheSetOperation) {
    // Geometry "teapot" is a primitive like any (RI Spec 3.2 §5.8): less an
    // enclosing sphere it is empty, and within one it is the teapot drawn
    // alone. Its patches were made without the CSG leaf, so the teapot
    // was drawn uncut, without a word.
    const std::string teapot = "SolidBegin \"primitive\" AttributeBegin Translate 0 -0.8 0 Rotate -90 1 0 0 "
                               "Scale 0.5 0.5 0.5 Geometry \"teapot\" AttributeEnd SolidEnd\n";
    const double alone = coveredArea(renderCsg(teapot, "csg-teapot-alone"));
    EXPECT_GT(alone, 2.0);  // a teapot 3.2 wide and 1.6 high
    const Image cut =
        renderCsg("SolidBegin \"difference\"\n" + teapot + sphere("0 1 0", 0, 0, 0, 2.5f) + "SolidEnd", "csg-teapot-cut");
    EXPECT_LT(coveredArea(cut), 2 * (4.0 / 256) * (4.0 / 256));
    const Image kept = renderCsg("SolidBegin \"intersection\"\n" + teapot + sphere("0 1 0", 0, 0, 0, 2.5f) + "SolidEnd",
                                 "csg-teapot-kept");
    EXPECT_NEAR(coveredArea(kept), alone, 0.01 * alone);
}

TEST(Csg, IntersectionOfTwoSpheresCoversTheirLens) {
    // Unit spheres with centres 1 apart in the image plane: the solid's
    // projection is the lens of their discs.
    const double r = 1, d = 1;
    const Image img = renderCsg("SolidBegin \"intersection\"\n" + sphere("1 0 0", -0.5f, 0, 0, 1) +
                                 sphere("0 1 0", 0.5f, 0, 0, 1) + "SolidEnd",
                             "csg-lens");
    const double lens = 2 * r * r * std::acos(d / (2 * r)) - d / 2 * std::sqrt(4 * r * r - d * d);
    EXPECT_NEAR(coveredArea(img), lens, 0.005 * lens);
}

TEST(Csg, CraterShowsTheSubtractedSolidsInside) {
    // A red unit sphere less a green sphere of radius 0.5 centred on its
    // front pole: along the axis the ray enters green, enters red (still
    // inside green: nothing), then leaves green at z = -0.5 inside red. The
    // crater's floor is the green sphere's inside, drawn with its own
    // shader (RI spec 3.2 §5.8, as PRMan and Aqsis do), at depth 5 - 0.5.
    const Image img = renderCsg("SolidBegin \"difference\"\n" + sphere("1 0 0", 0, 0, 0, 1) +
                                 sphere("0 1 0", 0, 0, -1, 0.5f) + "SolidEnd",
                             "csg-crater", 4, 64);
    ASSERT_EQ(img.channels, 5);
    const int c = 32;  // the pixel touching the axis
    EXPECT_NEAR(img.at(c, c, 0), 0.0f, 1e-6f);
    EXPECT_NEAR(img.at(c, c, 1), 1.0f, 1e-6f);
    EXPECT_NEAR(img.at(c, c, 3), 1.0f, 1e-6f);
    // The nearest of the pixel's samples, all within 0.09 of the axis:
    // depth 4 + sqrt(0.25 - r^2) is between 4.49 and 4.5.
    EXPECT_NEAR(img.at(c, c, 4), 4.5, 0.01) << "depth";
    // 0.8 off the axis, outside the crater's rim: the red sphere's front.
    const int x = c + int(0.8 / (4.0 / 64));
    EXPECT_NEAR(img.at(x, c, 0), 1.0f, 1e-6f);
    EXPECT_NEAR(img.at(x, c, 1), 0.0f, 1e-6f);
    // The pixel spans 0.75 to 0.8125 off the axis; its nearest sample is
    // near the inner edge.
    EXPECT_NEAR(img.at(x, c, 4), 5.0 - std::sqrt(1 - 0.75 * 0.75), 0.01);
}

namespace {

struct Ball {
    double x, y, z, r;
    /// The ray (px, py, t) along +z: its entry and exit, if it meets the ball.
    std::optional<std::pair<double, double>> span(double px, double py) const {
        const double q = r * r - (px - x) * (px - x) - (py - y) * (py - y);
        if (q <= 0) return std::nullopt;
        return std::make_pair(z - std::sqrt(q), z + std::sqrt(q));
    }
};

}  // namespace

TEST(Csg, NestedDifferenceOfAUnionMatchesARayEvaluation) {
    // (A u B) - C, with A red, B green, C blue, each constant-shaded; one
    // centred sample a pixel. The reference walks the spheres' entry and
    // exit points along each pixel's ray and returns the colour of the
    // first surface where the ray enters (A u B) - C.
    const Ball a{-0.45, 0, 0, 1}, b{0.45, 0.1, 0.2, 0.9}, c{0.1, -0.1, -0.7, 0.6};
    const std::string world = "SolidBegin \"difference\"\n SolidBegin \"union\"\n" + sphere("1 0 0", -0.45f, 0, 0, 1) +
                              sphere("0 1 0", 0.45f, 0.1f, 0.2f, 0.9f) + "SolidEnd\n" +
                              sphere("0 0 1", 0.1f, -0.1f, -0.7f, 0.6f) + "SolidEnd";
    const int res = 96;
    const Image img = renderCsg(world, "csg-nested", 1, res, "Hider \"hidden\" \"jitter\" 0");
    int checked = 0, wrong = 0;
    for (int py = 0; py < res; ++py)
        for (int px = 0; px < res; ++px) {
            const double x = -2 + (px + 0.5) * 4.0 / res, y = 2 - (py + 0.5) * 4.0 / res;
            struct Event {
                double t;
                int ball;
                bool enter;
            };
            std::vector<Event> events;
            const Ball* balls[3] = {&a, &b, &c};
            bool nearEdge = false;
            for (int k = 0; k < 3; ++k)
                if (auto s = balls[k]->span(x, y)) {
                    events.push_back({s->first, k, true});
                    events.push_back({s->second, k, false});
                    nearEdge |= s->second - s->first < 0.1;  // grazing: micropolygon chords decide
                } else {
                    const double d = std::hypot(x - balls[k]->x, y - balls[k]->y);
                    nearEdge |= d < balls[k]->r + 0.05;
                }
            std::sort(events.begin(), events.end(), [](const Event& p, const Event& q) { return p.t < q.t; });
            for (size_t k = 1; k < events.size(); ++k) nearEdge |= events[k].t - events[k - 1].t < 0.02;
            if (nearEdge) continue;
            bool in[3] = {false, false, false};
            int expected = -1;  // colour channel of the visible surface; -1: none
            for (const Event& e : events) {
                const bool before = (in[0] || in[1]) && !in[2];
                in[e.ball] = e.enter;
                if (!before && ((in[0] || in[1]) && !in[2])) {
                    expected = e.ball;
                    break;
                }
            }
            ++checked;
            const float alpha = img.at(px, py, 3);
            bool ok = expected < 0 ? alpha == 0.0f : alpha == 1.0f && img.at(px, py, expected) == 1.0f;
            if (!ok) ++wrong;
        }
    EXPECT_GT(checked, res * res / 4);
    EXPECT_EQ(wrong, 0) << "of " << checked;
}

TEST(Csg, MirroredCameraGivesTheFloppedImage) {
    // The orientation rule: a mirroring camera transform reverses every
    // surface's winding, and entering/leaving must follow.
    const std::string world = "SolidBegin \"difference\"\n" + sphere("1 0 0", 0, 0, 0, 1) +
                              sphere("0 1 0", 0.4f, 0.2f, -0.8f, 0.6f) + "SolidEnd";
    const int res = 64;
    const Image plain = renderCsg(world, "csg-plain", 1, res, "Hider \"hidden\" \"jitter\" 0");
    const Image mirrored = renderCsg(world, "csg-mirror", 1, res, "Hider \"hidden\" \"jitter\" 0\nScale -1 1 1");
    int differ = 0;
    double green = 0;
    for (int y = 0; y < res; ++y)
        for (int x = 0; x < res; ++x) {
            for (int ch = 0; ch < 4; ++ch)
                if (std::fabs(plain.at(x, y, ch) - mirrored.at(res - 1 - x, y, ch)) > 1e-3f) {
                    ++differ;
                    break;
                }
            green += plain.at(x, y, 1);
        }
    EXPECT_GT(green, 20.0);        // the crater is in the picture
    EXPECT_LE(differ, res / 8);    // at most a few silhouette pixels round differently
}

TEST(Csg, SamePixelsWhateverThreadsAndBuckets) {
    const std::string world = "SolidBegin \"difference\"\n SolidBegin \"intersection\"\n" +
                              sphere("1 0 0", -0.3f, 0, 0, 1) + sphere("0 1 0", 0.3f, 0, 0, 1) + "SolidEnd\n" +
                              sphere("0 0 1", 0, 0.3f, -0.6f, 0.5f) + "SolidEnd\n" +
                              "AttributeBegin Opacity [0.5 0.5 0.5] Translate 0 0 -1.5 Disk 0 0.6 360 AttributeEnd";
    const Image one = renderCsg(world, "csg-det1", 3, 80, "PixelFilter \"gaussian\" 2 2", 1, 16);
    const Image two = renderCsg(world, "csg-det2", 3, 80, "PixelFilter \"gaussian\" 2 2", 2, 7);
    ASSERT_EQ(one.pixels.size(), two.pixels.size());
    for (size_t i = 0; i < one.pixels.size(); ++i) ASSERT_EQ(one.pixels[i], two.pixels[i]) << "at float " << i;
}

TEST(Csg, DepthMapsSeeTheResolvedSolid) {
    // A distant light straight down the view; the ring (a unit sphere less
    // a longer capped cylinder of radius 0.5), invisible to the camera,
    // shadows a floor at z = 1.5: the shadow is the annulus, and the hole's
    // middle is lit (drawn as a union, the cylinder's cap would shade it),
    // with the nearest-depth map and a two-layer one.
    const std::string world = R"(
LightSource "shadowdistant" 1 "from" [0 0 -10] "to" [0 0 0] "shadowname" ["auto"] "intensity" [1]
AttributeBegin
  Attribute "visibility" "camera" [0]
  SolidBegin "difference"
)" + sphere("1 0 0", 0, 0, 0, 1) + cappedCylinder(0.5f, -2, 2) + R"(
  SolidEnd
AttributeEnd
AttributeBegin
  Surface "matte" "Kd" [1] "Ka" [0]
  Polygon "P" [-2 -2 1.5  2 -2 1.5  2 2 1.5  -2 2 1.5]
AttributeEnd
)";
    for (const char* filter : {"min", "midpoint"}) {
        SCOPED_TRACE(filter);
        const Image img = renderCsg(world, "csg-shadow", 4, 128,
                                    fmt::format("Option \"umbra\" \"shadowmapsize\" [512]\nHider \"hidden\" \"depthfilter\" \"{}\"", filter));
        double lit = 0, maxLit = 0;
        for (int y = 0; y < img.height; ++y)
            for (int x = 0; x < img.width; ++x) {
                lit += img.at(x, y, 0);
                maxLit = std::max(maxLit, double(img.at(x, y, 0)));
            }
        ASSERT_GT(maxLit, 0.1);
        EXPECT_NEAR(img.at(64, 64, 0), maxLit, 0.02 * maxLit) << "the hole's middle";
        EXPECT_LT(img.at(64 + 24, 64, 0), 0.02 * maxLit) << "under the ring, 0.75 off the axis";
        const double darkArea = (double(img.width) * img.height - lit / maxLit) * (4.0 / 128) * (4.0 / 128);
        const double annulus = M_PI * (1.0 - 0.25);
        EXPECT_NEAR(darkArea / annulus, 1.0, 0.05) << darkArea << " vs " << annulus;
    }
}
