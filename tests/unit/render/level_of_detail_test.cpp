// Level of detail (Detail, DetailRange, RelativeDetail) end to end: the
// representation drawn at a distance is the one the RI spec's rule picks
// for the detail computed here from the box's projection, and a transition
// shares the samples out in the ramp's proportions.

#include "support/render_harness.h"

#include "render/surface_pipeline.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>

using namespace umbra;
using umbra::test::Image;
using umbra::test::ScratchDir;

namespace {

/// A 90 degree perspective view at 256x256 of a unit Detail box [-1,1]^3
/// at `distance` on the axis, holding one square (half size 0.5, facing the
/// eye, `half` its half size) per representation, each a constant colour:
/// `ranges` gives each one's DetailRange and colour.
std::string lodFrame(const std::string& out, float distance, const std::vector<std::pair<std::string, std::string>>& ranges,
                     const std::string& extra = "", float half = 0.5f) {
    std::string reps;
    for (const auto& [range, colour] : ranges)
        reps += fmt::format(R"(AttributeBegin DetailRange {0} Color [{1}]
            Polygon "P" [{3} {3} 0  {2} {3} 0  {2} {2} 0  {3} {2} 0] AttributeEnd
)", range, colour, half, -half);
    return fmt::format(R"(
Display "{}" "openexr" "rgba" "string type" "float"
Format 256 256 1
Projection "perspective" "fov" 90
PixelSamples 4 4
PixelFilter "box" 1 1
{}
WorldBegin
Surface "constant"
AttributeBegin
Translate 0 0 {}
Detail [-1 1 -1 1 -1 1]
{}AttributeEnd
WorldEnd
)", out, extra, distance, reps);
}

/// The detail of the unit box at `distance`: its nearest face, at
/// distance - 1, spans 2 / (distance - 1) screen units of the 2-unit
/// screen's 256 pixels, squared; times RelativeDetail.
double boxDetail(double distance, double relative = 1) {
    const double width = 256.0 / (distance - 1);
    return width * width * relative;
}

const std::vector<std::pair<std::string, std::string>> kThree = {
    {"0 0 1000 1000", "1 0 0"}, {"1000 1000 5000 5000", "0 1 0"}, {"5000 5000 1e30 1e30", "0 0 1"}};

/// Mean colour over the square's middle pixels (the square spans 128 /
/// distance pixels each side of the centre).
Color centreColour(const Image& img, float distance) {
    const int half = int(0.8 * 64 / distance);
    Color sum(0.0f);
    int n = 0;
    for (int y = 128 - half; y < 128 + half; ++y)
        for (int x = 128 - half; x < 128 + half; ++x) {
            sum += Color(img.at(x, y, 0), img.at(x, y, 1), img.at(x, y, 2));
            ++n;
        }
    return sum * (1.0f / float(n));
}

Image renderLod(float distance, const std::vector<std::pair<std::string, std::string>>& ranges, const std::string& name,
                const std::string& extra = "", float half = 0.5f, int threads = 0, int bucket = 0) {
    ScratchDir dir(name);
    Diagnostics diag;
    test::renderRib(lodFrame(dir.file("out.exr"), distance, ranges, extra, half), diag, threads, bucket);
    EXPECT_EQ(diag.errorCount(), 0);
    Image img;
    EXPECT_TRUE(test::readImage(dir.file("out.exr"), &img));
    return img;
}

}  // namespace

TEST(LevelOfDetail, RasterDetailIsTheProjectedBoxArea) {
    hider::Camera camera;
    camera.perspective = true;
    camera.tanHalfFov = 1;
    camera.xResolution = camera.yResolution = 256;
    camera.finish();
    std::array<Vec3, 8> corners;
    for (int k = 0; k < 8; ++k) corners[size_t(k)] = Vec3(k & 1 ? 1 : -1, k & 2 ? 1 : -1, (k & 4 ? 1 : -1) + 6.0f);
    EXPECT_NEAR(render::rasterDetail(corners, camera, 1), boxDetail(6), 1e-2);
    EXPECT_NEAR(render::rasterDetail(corners, camera, 0.25f), boxDetail(6, 0.25), 1e-2);
    corners[0].z = -1;  // behind the eye: as near as can be
    EXPECT_EQ(render::rasterDetail(corners, camera, 1), kInfinity);
}

TEST(LevelOfDetail, DissolveWindowFollowsTheRamps) {
    const std::array<float, 4> range{100, 200, 400, 600};
    EXPECT_EQ(render::dissolveWindow(50, range), std::make_pair(0.0f, 0.0f));
    EXPECT_EQ(render::dissolveWindow(600, range), std::make_pair(0.0f, 0.0f));
    EXPECT_EQ(render::dissolveWindow(300, range), std::make_pair(0.0f, 1.0f));
    EXPECT_EQ(render::dissolveWindow(125, range), std::make_pair(0.75f, 1.0f));  // a quarter faded in
    EXPECT_EQ(render::dissolveWindow(450, range), std::make_pair(0.0f, 0.75f));  // a quarter faded out
    const std::array<float, 4> all{0, 0, kInfinity, kInfinity};
    EXPECT_EQ(render::dissolveWindow(kInfinity, all), std::make_pair(0.0f, 1.0f));
}

TEST(LevelOfDetail, EachDistanceDrawsTheRangeItsDetailFalls) {
    // Details 16384, 2621 and 655 pixels: the high, middle and low ranges.
    const struct {
        float distance;
        Color colour;
    } cases[] = {{3, Color(0, 0, 1)}, {6, Color(0, 1, 0)}, {11, Color(1, 0, 0)}};
    for (const auto& c : cases) {
        const double detail = boxDetail(c.distance);
        const Color expected = detail >= 5000 ? Color(0, 0, 1) : detail >= 1000 ? Color(0, 1, 0) : Color(1, 0, 0);
        ASSERT_EQ(expected, c.colour) << "the case's own arithmetic";
        const Image img = renderLod(c.distance, kThree, fmt::format("lod-{}", int(c.distance)));
        const Color got = centreColour(img, c.distance);
        EXPECT_EQ(got, expected) << "at distance " << c.distance;
    }
}

TEST(LevelOfDetail, RelativeDetailScalesTheMeasure) {
    // At distance 6 (detail 2621) RelativeDetail 0.25 gives 655: the low range.
    const Image img = renderLod(6, kThree, "lod-relative", "RelativeDetail 0.25");
    EXPECT_EQ(centreColour(img, 6), Color(1, 0, 0));
}

TEST(LevelOfDetail, TransitionSharesTheSamplesByTheRamp) {
    // Low fades out and high fades in over details 400..900; at distance 11
    // (detail 655.36) the high one holds (655.36 - 400) / 500 of the samples
    // and the low one the rest, every sample exactly one of them. The
    // squares (far larger than the Detail box, which alone is measured)
    // fill the frame: 2^20 samples, so the share's standard error is 0.0005.
    const float distance = 11;
    const Image img =
        renderLod(distance, {{"0 0 400 900", "1 0 0"}, {"400 900 1e30 1e30", "0 1 0"}}, "lod-fade", "", 20.0f);
    const double expected = (boxDetail(distance) - 400) / 500;
    double green = 0;
    int wrong = 0;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            wrong += std::fabs(img.at(x, y, 0) + img.at(x, y, 1) - 1.0f) > 1e-5f || img.at(x, y, 3) != 1.0f;
            green += img.at(x, y, 1);
        }
    EXPECT_EQ(wrong, 0);
    EXPECT_NEAR(green / (double(img.width) * img.height), expected, 0.003);
}

TEST(LevelOfDetail, DissolveIsTheSameWhateverThreadsAndBuckets) {
    const std::vector<std::pair<std::string, std::string>> fade = {{"0 0 400 900", "1 0 0"},
                                                                   {"400 900 1e30 1e30", "0 1 0"}};
    const Image one = renderLod(11, fade, "lod-det1", "PixelFilter \"gaussian\" 2 2", 20.0f, 1, 16);
    const Image two = renderLod(11, fade, "lod-det2", "PixelFilter \"gaussian\" 2 2", 20.0f, 2, 7);
    ASSERT_EQ(one.pixels.size(), two.pixels.size());
    for (size_t i = 0; i < one.pixels.size(); ++i) ASSERT_EQ(one.pixels[i], two.pixels[i]) << "at float " << i;
}

TEST(LevelOfDetail, DetailRangeOutOfOrderIsALocatedError) {
    ScratchDir dir("lod-error");
    Diagnostics diag;
    diag.setRecord(true);
    test::renderRib(lodFrame(dir.file("out.exr"), 6, {{"10 5 1 0", "1 0 0"}}), diag);
    ASSERT_EQ(diag.errorCount(), 1);
    for (const Diagnostic& d : diag.recorded())
        if (d.severity == Severity::Error) {
            EXPECT_EQ(d.loc.line, 13) << d.str();  // the first DetailRange of lodFrame
            EXPECT_NE(d.str().find("test.rib:13:16:"), std::string::npos) << d.str();
            EXPECT_NE(d.message.find("DetailRange: expected 0 <= minvisible"), std::string::npos) << d.str();
        }
}
