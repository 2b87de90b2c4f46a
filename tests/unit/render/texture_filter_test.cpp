// texture()'s filter parameters mean what the RI Spec (3.2, table 15.1)
// says: "blur" adds its length, in texture coordinates, to the region the
// lookup filters, with a box filter. Seen through a step edge (black left,
// white right) that fills the frame texel for pixel, a blur b turns the step
// into a ramp b long: 0.8 b from 10% to 90%. Pixie gives 0.8-0.9 b and Aqsis
// 1.1-1.16 b on the same scene; umbra gave 2.6 b while OpenImageIO's own blur
// did it, now 1.0 b (taps across the box, src/plugins/oiio/oiio_texture_backend.cpp).

#include "support/render_harness.h"

#include <OpenImageIO/imageio.h>

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <fstream>
#include <vector>

namespace umbra {
namespace {

constexpr int kSize = 256;  // texels across the map and pixels across the frame

void writeStepEdge(const std::string& path) {
    auto out = OIIO::ImageOutput::create(path);
    ASSERT_TRUE(out);
    OIIO::ImageSpec spec(kSize, kSize, 1, OIIO::TypeDesc::FLOAT);
    ASSERT_TRUE(out->open(path, spec));
    std::vector<float> px(size_t(kSize) * kSize);
    for (int y = 0; y < kSize; ++y)
        for (int x = 0; x < kSize; ++x) px[size_t(y) * kSize + x] = x < kSize / 2 ? 0.0f : 1.0f;
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, px.data()));
    ASSERT_TRUE(out->close());
}

class TextureFilter : public ::testing::Test {
protected:
    void SetUp() override {
        writeStepEdge(dir.file("edge.tif"));
        std::ofstream(dir.file("blurred.sl")) << R"(surface blurred(string map = ""; float sblur = 0, tblur = 0;)
{
    Ci = float texture(map, s, t, "sblur", sblur, "tblur", tblur);
    Oi = 1;
}
)";
    }

    /// The middle row of the step edge seen with the given blurs: pixel x
    /// looks at texel x (an orthographic camera on the unit square).
    std::vector<float> row(float sblur, float tblur, const char* mipFilter = "\"gaussian\" 2 2") {
        const std::string image = dir.file(fmt::format("edge_{}_{}.tif", sblur, tblur));
        const std::string rib = fmt::format(R"(Option "searchpath" "shader" ["{0}:&"]
MakeTexture "{0}/edge.tif" "{0}/edge.tx" "clamp" "clamp" {5}
Format {1} 16 1
PixelSamples 4 4
PixelFilter "box" 1 1
Quantize "rgba" 0 0 0 0
Display "{2}" "file" "rgba"
Projection "orthographic"
ScreenWindow -1 1 -0.0625 0.0625
Translate 0 0 5
WorldBegin
Surface "blurred" "string map" "{0}/edge.tx" "float sblur" {3} "float tblur" {4}
Patch "bilinear" "P" [-1 -1 0  1 -1 0  -1 1 0  1 1 0]
WorldEnd
)",
                                            scratch(), kSize, image, sblur, tblur, mipFilter);
        Diagnostics diag;
        diag.setQuiet(true);
        const test::Image img = test::renderImage(rib, image, diag, 2);
        EXPECT_EQ(diag.errorCount(), 0);
        std::vector<float> r;
        if (img.width != kSize) return r;
        for (int x = 0; x < kSize; ++x) r.push_back(img.at(x, 8, 0));
        return r;
    }

    /// The 10%-90% rise of the edge, in texture coordinates.
    static float rise(const std::vector<float>& r) {
        int i10 = -1, i90 = -1;
        for (int x = 0; x < int(r.size()); ++x) {
            if (i10 < 0 && r[size_t(x)] > 0.1f) i10 = x;
            if (i90 < 0 && r[size_t(x)] > 0.9f) i90 = x;
        }
        return i10 < 0 || i90 < 0 ? -1.0f : float(i90 - i10) / float(kSize);
    }

    /// The scratch directory, without a trailing slash.
    std::string scratch() const {
        std::string d = dir.file("");
        return d.substr(0, d.size() - 1);
    }

    test::ScratchDir dir{"texture-filter"};
};

TEST_F(TextureFilter, BlurRampsAStepOverItsLengthLikeABox) {
    // However the MIP levels were filtered (txmake's default, and a box).
    for (const char* mipFilter : {"\"gaussian\" 2 2", "\"box\" 1 1"})
        for (float blur : {0.1f, 0.25f}) {
            const std::vector<float> r = row(blur, blur, mipFilter);
            ASSERT_EQ(r.size(), size_t(kSize));
            // A box of length b ramps 0.8 b from 10% to 90%; the taps' cells
            // and the lookup's own footprint add a little: between the box and
            // Aqsis's 1.1-1.16 b. Before the fix: 2.6 b (gaussian levels) and
            // 1.33 b (box levels).
            const float rise10to90 = rise(r);
            EXPECT_GE(rise10to90, 0.75f * blur) << mipFilter << " blur " << blur;
            EXPECT_LE(rise10to90, 1.15f * blur) << mipFilter << " blur " << blur;
            // Symmetric about the edge: half way up at the middle.
            EXPECT_NEAR(r[kSize / 2 - 1] + r[kSize / 2], 1.0f, 0.1f) << mipFilter << " blur " << blur;
            for (int x = 1; x < kSize; ++x)
                ASSERT_GE(r[size_t(x)], r[size_t(x) - 1] - 1e-4f) << mipFilter << " blur " << blur << " x " << x;
        }
}

TEST_F(TextureFilter, UnblurredEdgeStaysSharpAndTblurLeavesAnEdgeAcrossSAlone) {
    // No blur: the step within two texels.
    EXPECT_LE(rise(row(0, 0)), 2.0f / kSize);
    // "tblur" widens the region along t only; the edge runs along t.
    EXPECT_LE(rise(row(0, 0.25f)), 2.0f / kSize);
    const float sOnly = rise(row(0.25f, 0));
    EXPECT_GE(sOnly, 0.75f * 0.25f);
    EXPECT_LE(sOnly, 1.15f * 0.25f);
}

/// A shader's image over the unit square (pixel x looks at s = (x + 0.5) / width).
test::Image renderUnitSquare(const test::ScratchDir& dir, const std::string& shaderName, const std::string& make,
                             int width, int height) {
    std::string scratch = dir.file("");
    scratch.pop_back();
    const std::string image = dir.file(shaderName + ".tif");
    const std::string rib = fmt::format(R"(Option "searchpath" "shader" ["{0}:&"]
{1}
Format {2} {3} 1
PixelSamples 4 4
PixelFilter "box" 1 1
Quantize "rgba" 0 0 0 0
Display "{4}" "file" "rgba"
Projection "orthographic"
ScreenWindow 0 1 0 1
Translate 0 0 5
WorldBegin
Surface "{5}"
Patch "bilinear" "P" [0 1 0  1 1 0  0 0 0  1 0 0]
WorldEnd
)",
                                        scratch, make, width, height, image, shaderName);
    Diagnostics diag;
    diag.setQuiet(true);
    const test::Image img = test::renderImage(rib, image, diag, 2);
    EXPECT_EQ(diag.errorCount(), 0);
    return img;
}

TEST_F(TextureFilter, BlurAlongALineOrAtAPointRenders) {
    // A lookup whose footprint has no area (s and t the same, texture(m,
    // s, s); or one point for the whole grid) with "blur" aborted the
    // render: an assertion in OpenImageIO's blur. Pixie and Aqsis render
    // it. Along the diagonal the step edge is blurred as across it.
    const std::string make = fmt::format("MakeTexture \"{0}\" \"{1}\" \"clamp\" \"clamp\" \"box\" 1 1",
                                         dir.file("edge.tif"), dir.file("edge.tx"));
    const std::string shader = "diagonal";
    std::ofstream(dir.file(shader + ".sl"))
        << "surface " << shader << "() { Ci = float texture(\"" << dir.file("edge.tx")
        << "\", s, s, \"blur\", 0.1);\n  if (s > 0.5) Ci += 0 * float texture(\"" << dir.file("edge.tx")
        << "\", 0.3, 0.3, \"blur\", 0.2); Oi = 1; }\n";
    const test::Image img = renderUnitSquare(dir, shader, make, kSize, 8);
    ASSERT_EQ(img.width, kSize);
    // A box of 0.1 across the step at s = 0.5: 0 before 0.45, 1 after 0.55.
    EXPECT_NEAR(img.at(int(0.3f * kSize), 4, 0), 0.0f, 0.02f);
    EXPECT_NEAR(img.at(int(0.7f * kSize), 4, 0), 1.0f, 0.02f);
    EXPECT_NEAR(img.at(kSize / 2 - 1, 4, 0) + img.at(kSize / 2, 4, 0), 1.0f, 0.1f);
}

TEST(TextureMagnification, ATexelsCentreReadsTheTexel) {
    // A 4x4 checker seen over 256 pixels: each texel's centre reads the
    // texel's value (bilinear between texel centres, as RenderMan's
    // texture() and Pixie; Aqsis 0.74). OpenImageIO's default bicubic
    // B-spline read 0.56 at a white texel's centre with four black
    // neighbours, and smeared every edge over 1.5 texels.
    test::ScratchDir dir("texture-magnify");
    {
        auto out = OIIO::ImageOutput::create(dir.file("checker.tif"));
        ASSERT_TRUE(out);
        OIIO::ImageSpec spec(4, 4, 1, OIIO::TypeDesc::FLOAT);
        ASSERT_TRUE(out->open(dir.file("checker.tif"), spec));
        std::vector<float> px(16);
        for (int y = 0; y < 4; ++y)
            for (int x = 0; x < 4; ++x) px[size_t(y * 4 + x)] = (x + y) % 2 == 0 ? 1.0f : 0.0f;
        ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, px.data()));
        ASSERT_TRUE(out->close());
    }
    std::ofstream(dir.file("lookup.sl")) << "surface lookup() { Ci = float texture(\"" << dir.file("checker.tx")
                                         << "\", s, t, \"width\", 0); Oi = 1; }\n";
    const std::string make = fmt::format("MakeTexture \"{0}\" \"{1}\" \"clamp\" \"clamp\" \"box\" 1 1",
                                         dir.file("checker.tif"), dir.file("checker.tx"));
    const test::Image img = renderUnitSquare(dir, "lookup", make, 256, 256);
    ASSERT_EQ(img.width, 256);
    for (int ty = 0; ty < 4; ++ty)
        for (int tx = 0; tx < 4; ++tx) {
            // Texel (tx, ty)'s centre: s = (tx + 0.5) / 4, t = (ty + 0.5) / 4;
            // t runs down the image, as the texture's rows do.
            const int x = tx * 64 + 32, y = ty * 64 + 32;
            const float expected = (tx + ty) % 2 == 0 ? 1.0f : 0.0f;
            EXPECT_NEAR(0.5f * (img.at(x - 1, y - 1, 0) + img.at(x, y, 0)), expected, 0.03f) << tx << "," << ty;
        }
}

// environment()'s "blur" follows the same rule, as an angle: a blur b is
// 2 pi b radians (the lat-long map's s at the equator; Aqsis's reading),
// along the longitude for "sblur" and the latitude for "tblur". A lat-long
// map white on one side of a meridian (y < 0) seen along directions that
// sweep across it: the box of angle 2 pi b ramps the edge over that angle,
// 0.8 of it from 10% to 90%: umbra 0.81, Pixie 0.55-0.61, Aqsis 1.10-1.13
// (a gaussian) of 2 pi b on such a probe; OpenImageIO's own environment
// blur gave 0.38-0.39, and four taps without each one's cell blur a
// four-step staircase.
class EnvironmentFilter : public ::testing::Test {
protected:
    static constexpr int kMapWidth = 1024;  // 2 pi / 1024 = 0.0061 radians a texel
    static constexpr int kPixels = 512;

    void SetUp() override {
        // RenderMan's lat-long layout (Aqsis's and Pixie's; see
        // EnvironmentOrientation below): s = atan2(y, x) / 2 pi + 1/2, so
        // y < 0 is s < 1/2 (and the other meridian, at s = 0 and 1, faces
        // away from the sweep, along -x).
        const std::string path = dir.file("half.tif");
        auto out = OIIO::ImageOutput::create(path);
        ASSERT_TRUE(out);
        OIIO::ImageSpec spec(kMapWidth, kMapWidth / 2, 1, OIIO::TypeDesc::FLOAT);
        ASSERT_TRUE(out->open(path, spec));
        std::vector<float> px(size_t(kMapWidth) * kMapWidth / 2);
        for (int y = 0; y < kMapWidth / 2; ++y)
            for (int x = 0; x < kMapWidth; ++x) px[size_t(y) * kMapWidth + x] = x < kMapWidth / 2 ? 1.0f : 0.0f;
        ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, px.data()));
        ASSERT_TRUE(out->close());
        // Pixel x looks along phi = (2 (x + 1/2) / kPixels - 1) range
        // from +x towards -y, at latitude `lat` (radians, towards +z).
        // corners > 0: the four-direction form, the region phi +- corners
        // by lat +- corners.
        std::ofstream(dir.file("sweep.sl")) << R"(surface sweep(string map = ""; float sblur = 0, tblur = 0, range = 1, lat = 0, corners = 0;)
{
    float phi = (2 * s - 1) * range;
    vector D = vector(cos(lat) * cos(phi), -cos(lat) * sin(phi), sin(lat));
    if (corners > 0) {
        float p0 = phi - corners, p1 = phi + corners, l0 = lat - corners, l1 = lat + corners;
        Ci = float environment(map, vector(cos(l0) * cos(p0), -cos(l0) * sin(p0), sin(l0)),
                                    vector(cos(l0) * cos(p1), -cos(l0) * sin(p1), sin(l0)),
                                    vector(cos(l1) * cos(p0), -cos(l1) * sin(p0), sin(l1)),
                                    vector(cos(l1) * cos(p1), -cos(l1) * sin(p1), sin(l1)));
    } else {
        Ci = float environment(map, D, "sblur", sblur, "tblur", tblur);
    }
    Oi = 1;
}
)";
    }

    /// The middle row across the meridian with the given blurs; `range`
    /// is the largest phi, at the frame's edges.
    std::vector<float> row(float sblur, float tblur, float range, float lat = 0, float corners = 0) {
        const std::string image = dir.file(fmt::format("env_{}_{}_{}_{}.tif", sblur, tblur, lat, corners));
        const std::string rib = fmt::format(R"(Option "searchpath" "shader" ["{0}:&"]
MakeLatLongEnvironment "{0}/half.tif" "{0}/half.env" "gaussian" 2 2
Format {1} 8 1
PixelSamples 2 2
PixelFilter "box" 1 1
Quantize "rgba" 0 0 0 0
Display "{2}" "file" "rgba"
Projection "orthographic"
ScreenWindow -1 1 -0.015625 0.015625
Translate 0 0 5
WorldBegin
Surface "sweep" "string map" "{0}/half.env" "float sblur" {3} "float tblur" {4} "float range" {5} "float lat" {6} "float corners" {7}
Patch "bilinear" "P" [-1 -1 0  1 -1 0  -1 1 0  1 1 0]
WorldEnd
)",
                                            scratch(), kPixels, image, sblur, tblur, range, lat, corners);
        Diagnostics diag;
        diag.setQuiet(true);
        const test::Image img = test::renderImage(rib, image, diag, 2);
        EXPECT_EQ(diag.errorCount(), 0);
        std::vector<float> r;
        if (img.width != kPixels) return r;
        for (int x = 0; x < kPixels; ++x) r.push_back(img.at(x, 4, 0));
        return r;
    }

    /// The 10%-90% rise of the edge in phi (radians), crossings
    /// interpolated between pixels; negative when there is no edge.
    static float rise(const std::vector<float>& r, float range) {
        auto crossing = [&](float level) {
            for (size_t x = 1; x < r.size(); ++x)
                if (r[x - 1] < level && r[x] >= level) return float(x - 1) + (level - r[x - 1]) / (r[x] - r[x - 1]);
            return -1e9f;
        };
        return (crossing(0.9f) - crossing(0.1f)) * 2 * range / float(r.size());
    }

    std::string scratch() const {
        std::string d = dir.file("");
        return d.substr(0, d.size() - 1);
    }

    test::ScratchDir dir{"environment-filter"};
};

TEST_F(EnvironmentFilter, BlurRampsAMeridianOverItsAngleLikeABox) {
    const float kTwoPi = 6.2831853f;
    for (float blur : {0.02f, 0.05f}) {
        const float range = 0.3f;
        const std::vector<float> r = row(blur, blur, range);
        ASSERT_EQ(r.size(), size_t(kPixels));
        // The box alone: 0.8 x 2 pi b. The taps' cells and the lookup's own
        // footprint add a little; the bounds are the texture() test's
        // (0.75-1.15 of the box's length).
        const float box = kTwoPi * blur;
        EXPECT_GE(rise(r, range), 0.75f * box) << "blur " << blur;
        EXPECT_LE(rise(r, range), 1.15f * box) << "blur " << blur;
        EXPECT_NEAR(r[kPixels / 2 - 1] + r[kPixels / 2], 1.0f, 0.1f) << "blur " << blur;
        for (int x = 1; x < kPixels; ++x) ASSERT_GE(r[size_t(x)], r[size_t(x) - 1] - 1e-4f) << "blur " << blur << " x " << x;
        // A ramp, not a staircase of the taps: every eighth of the box
        // inside the middle of the ramp climbs (a box: by 1/8).
        const int eighth = int(box / 8 / (2 * range / kPixels));
        for (int x = 0; x + eighth < kPixels; ++x)
            if (r[size_t(x)] > 0.2f && r[size_t(x + eighth)] < 0.8f) {
                ASSERT_GE(r[size_t(x + eighth)] - r[size_t(x)], 0.06f) << "blur " << blur << " x " << x;
            }
    }
}

TEST_F(EnvironmentFilter, BlurIsTheSameAngleAtAnyLatitudeAndTblurRunsAlongTheMeridian) {
    const float kTwoPi = 6.2831853f, range = 0.3f;
    // No blur: the edge within a few texels (0.0061 radians each).
    EXPECT_LE(rise(row(0, 0, range), range), 0.02f);
    // "tblur" turns along the meridian, which the edge is: no ramp.
    EXPECT_LE(rise(row(0, 0.05f, range), range), 0.02f);
    // At latitude 45 degrees a longitude turn phi is an angle of about
    // phi cos 45 from the meridian's plane: the same box of 2 pi b radians
    // ramps over 2 pi b / cos 45 of phi (OpenImageIO's blur in s would
    // stay 2 pi b of phi, a narrower angle).
    const float lat = 0.7853982f, blur = 0.03f;
    const float r45 = rise(row(blur, 0, 0.5f, lat), 0.5f) * std::cos(lat);
    EXPECT_GE(r45, 0.75f * kTwoPi * blur);
    EXPECT_LE(r45, 1.15f * kTwoPi * blur);
}

TEST_F(EnvironmentFilter, FourDirectionsFilterTheRegionTheySpan) {
    // environment(name, D1, D2, D3, D4) (RI Spec 3.2; Aqsis takes it, as
    // its compiler's own test does): the map over the region the four
    // directions span. Corners at phi +- w ramp the meridian over about 2 w
    // (the region's width, as a box: 0.8 of it from 10% to 90%); umbra's
    // compiler refused the form.
    const float range = 0.3f;
    for (float w : {0.05f, 0.1f}) {
        const std::vector<float> r = row(0, 0, range, 0, w);
        ASSERT_EQ(r.size(), size_t(kPixels));
        EXPECT_GE(rise(r, range), 0.75f * 2 * w) << w;
        EXPECT_LE(rise(r, range), 1.15f * 2 * w) << w;
        EXPECT_NEAR(r[kPixels / 2 - 1] + r[kPixels / 2], 1.0f, 0.1f) << w;
        EXPECT_NEAR(r.front(), 0.0f, 1e-3f);
        EXPECT_NEAR(r.back(), 1.0f, 1e-3f);
    }
}

// A lat-long map's orientation, as Aqsis 1.8.4 and Pixie 2.2.6 read
// MakeLatLongEnvironment's maps (both agree on this probe; the RI Spec does
// not write it out): the poles are on z, +z at the top row (t = 0), and
// s = atan2(y, x) / 2 pi + 1/2: -x at s = 0 (and 1), -y at 1/4, +x at 1/2,
// +y at 3/4. umbra used OpenImageIO's own layout (+y up, +z at s = 1/2),
// so the same RIB read a turned map.
TEST(EnvironmentOrientation, LatLongPolesAreOnZAndLongitudeRunsFromMinusXThroughMinusY) {
    test::ScratchDir dir{"environment-orientation"};
    std::string root = dir.file("");
    root.pop_back();
    // The probe: the top quarter red, the bottom quarter blue; between, the
    // quarter of longitude nearest s = 0, 1/4, 1/2, 3/4 magenta, green,
    // grey, yellow.
    const float kColours[4][3] = {{1, 0, 1}, {0, 1, 0}, {0.5f, 0.5f, 0.5f}, {1, 1, 0}};
    constexpr int kW = 128, kH = 64;
    {
        const std::string path = dir.file("probe.tif");
        auto out = OIIO::ImageOutput::create(path);
        ASSERT_TRUE(out);
        OIIO::ImageSpec spec(kW, kH, 3, OIIO::TypeDesc::FLOAT);
        ASSERT_TRUE(out->open(path, spec));
        std::vector<float> px(size_t(kW) * kH * 3);
        for (int y = 0; y < kH; ++y)
            for (int x = 0; x < kW; ++x) {
                const float s = (float(x) + 0.5f) / kW, t = (float(y) + 0.5f) / kH;
                const float red[3] = {1, 0, 0}, blue[3] = {0, 0, 1};
                const float* c = t < 0.25f ? red : t > 0.75f ? blue : kColours[int(std::floor(s * 4 + 0.5f)) % 4];
                for (int k = 0; k < 3; ++k) px[(size_t(y) * kW + x) * 3 + k] = c[k];
            }
        ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, px.data()));
        ASSERT_TRUE(out->close());
    }
    std::ofstream(dir.file("envd.sl")) << R"(surface envd(string map = ""; vector dir = vector(1, 0, 0))
{
    Ci = color environment(map, dir);
    Oi = 1;
}
)";
    // Six patches side by side, each looking one way. No camera transform:
    // "current" space is the world's.
    struct Case {
        const char* name;
        float d[3];
        float rgb[3];
    };
    const Case cases[6] = {
        {"+x", {1, 0, 0}, {0.5f, 0.5f, 0.5f}}, {"-x", {-1, 0, 0}, {1, 0, 1}}, {"+y", {0, 1, 0}, {1, 1, 0}},
        {"-y", {0, -1, 0}, {0, 1, 0}},         {"+z", {0, 0, 1}, {1, 0, 0}},  {"-z", {0, 0, -1}, {0, 0, 1}},
    };
    const std::string image = dir.file("orient.tif");
    std::string rib = fmt::format(R"(Option "searchpath" "shader" ["{0}:&"]
MakeLatLongEnvironment "{0}/probe.tif" "{0}/probe.env" "gaussian" 2 2
Format 60 10 1
PixelSamples 2 2
PixelFilter "box" 1 1
Quantize "rgba" 0 0 0 0
Display "{1}" "file" "rgba"
Projection "orthographic"
ScreenWindow -3 3 -0.5 0.5
WorldBegin
Translate 0 0 5
)",
                                  root, image);
    for (int i = 0; i < 6; ++i)
        rib += fmt::format(R"(Surface "envd" "string map" "{0}/probe.env" "vector dir" [{1} {2} {3}]
Patch "bilinear" "P" [{4} -1 0  {5} -1 0  {4} 1 0  {5} 1 0]
)",
                           root, cases[i].d[0], cases[i].d[1], cases[i].d[2], i - 3, i - 2);
    rib += "WorldEnd\n";
    Diagnostics diag;
    diag.setQuiet(true);
    const test::Image img = test::renderImage(rib, image, diag, 2);
    EXPECT_EQ(diag.errorCount(), 0);
    ASSERT_EQ(img.width, 60);
    for (int i = 0; i < 6; ++i)
        for (int c = 0; c < 3; ++c)
            EXPECT_NEAR(img.at(i * 10 + 5, 5, c), cases[i].rgb[c], 0.05f) << cases[i].name << " channel " << c;
}

TEST(TextureChannels, ChannelsPastTheLastReadAsFill) {
    // RI Spec 3.2: "fill" is the value of channels the texture lacks.
    // texture(map[3], ...) on an RGB map, minified, aborted the render on an
    // OpenImageIO assertion (exit 134); Aqsis renders 0. Now [3] reads fill
    // and [2] as a colour reads blue, then fill, fill.
    test::ScratchDir dir{"texture-channels"};
    std::string root = dir.file("");
    root.pop_back();
    {
        const std::string path = dir.file("rgb.tif");
        auto out = OIIO::ImageOutput::create(path);
        ASSERT_TRUE(out);
        OIIO::ImageSpec spec(64, 64, 3, OIIO::TypeDesc::FLOAT);
        ASSERT_TRUE(out->open(path, spec));
        std::vector<float> px(size_t(64) * 64 * 3);
        for (size_t k = 0; k < px.size(); k += 3) px[k] = 0.25f, px[k + 1] = 0.5f, px[k + 2] = 0.75f;
        ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, px.data()));
        ASSERT_TRUE(out->close());
    }
    std::ofstream(dir.file("ch.sl")) << R"(surface ch(string map = "")
{
    float past = texture(map[3], s * 20, t);
    color tail = color texture(map[2], s * 20, t, "fill", 0.5);
    Ci = color(past, comp(tail, 0), comp(tail, 1)) + color(0, 0, comp(tail, 2) - 0.5);
    Oi = 1;
}
)";
    const std::string image = dir.file("out.tif");
    const std::string rib = fmt::format(R"(Option "searchpath" "shader" ["{0}:&"]
MakeTexture "{0}/rgb.tif" "{0}/rgb.tex" "periodic" "periodic" "box" 1 1
Format 64 16 1
PixelSamples 2 2
Quantize "rgba" 0 0 0 0
Display "{1}" "file" "rgba"
Projection "orthographic"
ScreenWindow -2 2 -0.5 0.5
WorldBegin
Translate 0 0 5
Surface "ch" "string map" "{0}/rgb.tex"
Patch "bilinear" "P" [-2 0.5 0  2 0.5 0  -2 -0.5 0  2 -0.5 0]
WorldEnd
)",
                                        root, image);
    Diagnostics diag;
    diag.setQuiet(true);
    const test::Image img = test::renderImage(rib, image, diag, 2);
    EXPECT_EQ(diag.errorCount(), 0);
    ASSERT_EQ(img.width, 64);
    for (int x : {2, 30, 61}) {
        EXPECT_NEAR(img.at(x, 8, 0), 0.0f, 1e-5f) << x;   // channel 3: fill 0
        EXPECT_NEAR(img.at(x, 8, 1), 0.75f, 1e-3f) << x;  // channel 2: blue
        EXPECT_NEAR(img.at(x, 8, 2), 0.5f, 1e-5f) << x;   // channel 3: fill 0.5 (and channel 4's 0.5 - 0.5)
    }
}

}  // namespace
}  // namespace umbra
