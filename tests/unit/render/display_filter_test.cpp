// Per-display pixel filters: `Display ... "string filter" "gaussian"
// "float[2] filterwidth" [2 2]` (PRMan's and Pixie's parameters) resolves
// that display with its own filter. Each such display must be exactly the
// image a render with that filter as the frame's `PixelFilter` gives, the
// other displays unchanged; depth is never filtered; an unknown name warns
// at the parameter and falls back to the frame's filter.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <fstream>

using namespace umbra;
using umbra::test::Image;
using umbra::test::ScratchDir;

namespace {

/// A lit plastic sphere in front of a constant square and a backdrop square
/// farther away: hard edges and smooth shading, with transparent
/// background around them (alpha edges too).
const char* kWorld = R"(WorldBegin
LightSource "distantlight" 1 "from" [-1 1 -1] "to" [0 0 0] "intensity" 1.2
LightSource "ambientlight" 2 "intensity" 0.1
AttributeBegin
Translate 0.3 0.1 0
Surface "plastic" "roughness" 0.15
Color [0.9 0.4 0.2]
Sphere 0.9 -0.9 0.9 360
AttributeEnd
AttributeBegin
Translate 0 0 3
Surface "constant"
Color [0.2 0.6 1]
Polygon "P" [-1.7 -1.1 0  0.2 -1.1 0  0.2 0.7 0  -1.7 0.7 0]
AttributeEnd
WorldEnd
)";

/// The frame: options, then the displays' lines, then kWorld.
std::string frame(const std::string& pixelFilter, const std::string& displays) {
    return fmt::format(R"(Format 48 36 1
PixelSamples 3 3
{}
{}
Projection "perspective" "fov" 40
Translate 0 0 5
{})", pixelFilter, displays, kWorld);
}

std::string exr(const std::string& path, const std::string& mode = "rgba", const std::string& more = "",
                bool first = false) {
    return fmt::format(R"(Display "{}{}" "openexr" "{}" "string type" "float"{})", first ? "" : "+", path, mode, more);
}

Image renderAt(const std::string& rib, const std::string& path, Diagnostics& diag) {
    // Two threads and a bucket size that does not divide the frame: the
    // layers' resolves meet at bucket edges.
    return test::renderImage(rib, path, diag, 2, 13);
}

double maxDiff(const Image& a, const Image& b) {
    if (a.width != b.width || a.height != b.height || a.channels != b.channels || a.pixels.empty()) return 1e9;
    double d = 0;
    for (size_t i = 0; i < a.pixels.size(); ++i) d = std::max(d, std::fabs(double(a.pixels[i]) - double(b.pixels[i])));
    return d;
}

std::vector<std::string> messages(const Diagnostics& d, Severity s) {
    std::vector<std::string> out;
    for (const Diagnostic& m : d.recorded())
        if (m.severity == s) out.push_back(m.str());
    return out;
}

}  // namespace

TEST(DisplayFilter, EachDisplayIsTheRenderWithItsFilterAsThePixelFilter) {
    ScratchDir dir("display-filter");
    // One render, four displays: the frame's mitchell 4 4, a box 1 1, a
    // gaussian 2 2 (one width given for both) and a catmull-rom 3 3 (not
    // separable: the general resolve path).
    const std::string displays =
        exr(dir.file("frame.exr"), "rgba", "", true) + "\n" +
        exr(dir.file("box.exr"), "rgba", R"( "string filter" "box" "float[2] filterwidth" [1 1])") + "\n" +
        exr(dir.file("gauss.exr"), "rgba", R"( "string filter" "gaussian" "float filterwidth" 2)") + "\n" +
        exr(dir.file("cr.exr"), "rgba", R"( "filter" "catmull-rom" "filterwidth" [3 3])");
    Diagnostics diag;
    diag.setQuiet(true);
    diag.setRecord(true);
    const Image frameImg = renderAt(frame("PixelFilter \"mitchell\" 4 4", displays), dir.file("frame.exr"), diag);
    EXPECT_EQ(diag.errorCount(), 0);
    EXPECT_TRUE(messages(diag, Severity::Warning).empty()) << messages(diag, Severity::Warning)[0];
    Image box, gauss, cr;
    ASSERT_TRUE(test::readImage(dir.file("box.exr"), &box));
    ASSERT_TRUE(test::readImage(dir.file("gauss.exr"), &gauss));
    ASSERT_TRUE(test::readImage(dir.file("cr.exr"), &cr));

    // The references: one render per filter, as the frame's PixelFilter.
    struct Ref {
        const char* filter;
        const Image* got;
    } refs[] = {{"\"mitchell\" 4 4", &frameImg}, {"\"box\" 1 1", &box}, {"\"gaussian\" 2 2", &gauss},
                {"\"catmull-rom\" 3 3", &cr}};
    std::vector<Image> refImages;
    for (const Ref& r : refs) {
        Diagnostics d;
        d.setQuiet(true);
        const std::string path = dir.file("ref.exr");
        const Image want = renderAt(frame(fmt::format("PixelFilter {}", r.filter), exr(path, "rgba", "", true)), path, d);
        EXPECT_EQ(d.errorCount(), 0);
        EXPECT_LE(maxDiff(*r.got, want), 1e-6) << r.filter;
        refImages.push_back(want);
    }
    // The filters differ visibly, so the comparisons above say something.
    EXPECT_GT(maxDiff(refImages[1], refImages[2]), 0.05);
    EXPECT_GT(maxDiff(refImages[2], refImages[3]), 0.02);
    EXPECT_GT(maxDiff(refImages[0], refImages[1]), 0.05);
}

TEST(DisplayFilter, AnAovDisplayTakesItsOwnFilterToo) {
    // The general resolve path (AOVs): an AOV display with its own filter
    // equals the AOV of a render with that filter as the frame's.
    ScratchDir dir("display-filter-aov");
    Diagnostics diag;
    diag.setQuiet(true);
    renderAt(frame("PixelFilter \"box\" 1 1",
                 exr(dir.file("rgba.exr"), "rgba", "", true) + "\n" +
                     exr(dir.file("ci.exr"), "Ci", R"( "string filter" "gaussian" "float[2] filterwidth" [2.5 2])")),
           dir.file("rgba.exr"), diag);
    EXPECT_EQ(diag.errorCount(), 0);
    Image got;
    ASSERT_TRUE(test::readImage(dir.file("ci.exr"), &got));
    Diagnostics d;
    d.setQuiet(true);
    const Image want = renderAt(frame("PixelFilter \"gaussian\" 2.5 2",
                                    exr(dir.file("ref.exr"), "rgba", "", true) + "\n" + exr(dir.file("refci.exr"), "Ci")),
                              dir.file("ref.exr"), d);
    Image wantCi;
    ASSERT_TRUE(test::readImage(dir.file("refci.exr"), &wantCi));
    EXPECT_LE(maxDiff(got, wantCi), 1e-6);
    // ... and not the frame's box-filtered colour.
    Image box;
    ASSERT_TRUE(test::readImage(dir.file("rgba.exr"), &box));
    ASSERT_EQ(got.channels, 3);
    ASSERT_EQ(box.width, got.width);
    double apart = 0;
    for (int y = 0; y < got.height; ++y)
        for (int x = 0; x < got.width; ++x)
            for (int c = 0; c < 3; ++c) apart = std::max(apart, std::fabs(double(got.at(x, y, c)) - box.at(x, y, c)));
    EXPECT_GT(apart, 0.05);
    EXPECT_EQ(want.width, 48);

    // PRMan's other spelling: the filter on the DisplayChannel the display
    // names.
    Diagnostics c;
    c.setQuiet(true);
    c.setRecord(true);
    renderAt(frame("PixelFilter \"box\" 1 1",
                   R"(DisplayChannel "color Ci" "string filter" "gaussian" "filterwidth" [2.5 2])" "\n" +
                       exr(dir.file("rgba2.exr"), "rgba", "", true) + "\n" + exr(dir.file("ci2.exr"), "Ci")),
             dir.file("rgba2.exr"), c);
    EXPECT_EQ(c.errorCount(), 0);
    EXPECT_TRUE(messages(c, Severity::Warning).empty()) << messages(c, Severity::Warning)[0];
    Image viaChannel;
    ASSERT_TRUE(test::readImage(dir.file("ci2.exr"), &viaChannel));
    EXPECT_LE(maxDiff(viaChannel, wantCi), 1e-6);
}

TEST(DisplayFilter, DepthStaysUnfilteredBesideAWideColourFilter) {
    // Two squares facing the camera at camera depths 5 and 8: every
    // pixel's z is the nearest of its own samples, so exactly 5, 8 or
    // nothing (+infinity), however wide the colour display's filter and
    // whatever filter the z display names.
    ScratchDir dir("display-filter-z");
    const std::string rib = fmt::format(R"(Format 40 30 1
PixelSamples 3 3
PixelFilter "box" 1 1
Display "{}" "openexr" "rgba" "string type" "float" "string filter" "catmull-rom" "float[2] filterwidth" [6 6]
Display "+{}" "openexr" "z"
    "string filter" "gaussian" "float[2] filterwidth" [4 4]
Projection "perspective" "fov" 40
WorldBegin
Surface "constant"
AttributeBegin
Translate 0 0 5
Polygon "P" [-0.9 -0.6 0  0.4 -0.6 0  0.4 0.5 0  -0.9 0.5 0]
AttributeEnd
AttributeBegin
Translate 0 0 8
Polygon "P" [-0.5 -1 0  2 -1 0  2 1.2 0  -0.5 1.2 0]
AttributeEnd
WorldEnd
)",
                                        dir.file("c.exr"), dir.file("z.exr"));
    Diagnostics diag;
    diag.setQuiet(true);
    diag.setRecord(true);
    const Image colour = renderAt(rib, dir.file("c.exr"), diag);
    EXPECT_EQ(diag.errorCount(), 0);
    // The z display's filter is reported as ignored, at the parameter.
    const std::vector<std::string> warnings = messages(diag, Severity::Warning);
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_NE(warnings[0].find("test.rib:6:5: warning: display \"" + dir.file("z.exr") + "\": depth is not filtered"),
              std::string::npos)
        << warnings[0];
    Image z;
    ASSERT_TRUE(test::readImage(dir.file("z.exr"), &z));
    ASSERT_EQ(z.channels, 1);
    int near = 0, far = 0, none = 0;
    for (float v : z.pixels) {
        if (v == 5.0f)
            ++near;
        else if (v == 8.0f)
            ++far;
        else if (std::isinf(v) || v > 1e30f)
            ++none;
        else
            ADD_FAILURE() << "filtered depth " << v;
    }
    EXPECT_GT(near, 50);
    EXPECT_GT(far, 50);
    EXPECT_GT(none, 50);
    // The colour display was filtered: some pixel's alpha lies strictly
    // between 0 and 1 (a box 1 1 with 9 samples gives ninths; catmull-rom
    // 6 6 gives other values, and rings below 0 or above 1 near edges).
    bool blended = false;
    for (int y = 0; y < colour.height; ++y)
        for (int x = 0; x < colour.width; ++x) {
            const float a = colour.at(x, y, 3);
            const float ninths = a * 9.0f;
            blended = blended || std::fabs(ninths - std::round(ninths)) > 1e-3f;
        }
    EXPECT_TRUE(blended);
}

TEST(DisplayFilter, AnUnknownFilterWarnsWithItsLocationAndFallsBackToTheFrameFilter) {
    ScratchDir dir("display-filter-unknown");
    const std::string displays = exr(dir.file("main.exr"), "rgba", "", true) + "\n" +
                                 exr(dir.file("odd.exr"), "rgba") + "\n    \"string filter\" \"fuzzy\"";
    Diagnostics diag;
    diag.setQuiet(true);
    diag.setRecord(true);
    const Image main = renderAt(frame("PixelFilter \"gaussian\" 2 2", displays), dir.file("main.exr"), diag);
    EXPECT_EQ(diag.errorCount(), 0);
    const std::vector<std::string> warnings = messages(diag, Severity::Warning);
    ASSERT_EQ(warnings.size(), 1u);
    // Line 6 (Format, PixelSamples, PixelFilter, two Displays, then the
    // second's parameter line), column 5.
    EXPECT_NE(warnings[0].find("test.rib:6:5: warning: display \"" + dir.file("odd.exr") +
                               "\": unknown pixel filter \"fuzzy\""),
              std::string::npos)
        << warnings[0];
    EXPECT_NE(warnings[0].find("using the frame's PixelFilter \"gaussian\" 2 2"), std::string::npos) << warnings[0];
    Image odd;
    ASSERT_TRUE(test::readImage(dir.file("odd.exr"), &odd));
    EXPECT_EQ(maxDiff(odd, main), 0.0);
}

TEST(DisplayFilter, TheImagerRunsOnEveryDisplaysPixels) {
    // An Imager shader sees each display's own filtered pixels: with one,
    // the gaussian display still equals the gaussian frame's image.
    ScratchDir dir("display-filter-imager");
    std::ofstream(dir.file("under.sl")) << "imager under(color bg = color(0, 0, 1)) {\n"
                                           "  Ci += (1 - alpha) * bg;\n"
                                           "  alpha = 1;\n"
                                           "}\n";
    const std::string imager =
        fmt::format("Option \"searchpath\" \"shader\" [\"{}:&\"]\nImager \"under\"\n", dir.file(""));
    Diagnostics diag;
    diag.setQuiet(true);
    const Image box = renderAt(imager + frame("PixelFilter \"box\" 1 1",
                                              exr(dir.file("box.exr"), "rgba", "", true) + "\n" +
                                                  exr(dir.file("g.exr"), "rgba", R"( "filter" "gaussian" "filterwidth" 2)")),
                               dir.file("box.exr"), diag);
    EXPECT_EQ(diag.errorCount(), 0);
    Image gauss;
    ASSERT_TRUE(test::readImage(dir.file("g.exr"), &gauss));
    Diagnostics d;
    d.setQuiet(true);
    const Image want = renderAt(imager + frame("PixelFilter \"gaussian\" 2 2", exr(dir.file("ref.exr"), "rgba", "", true)),
                                dir.file("ref.exr"), d);
    EXPECT_EQ(d.errorCount(), 0);
    EXPECT_LE(maxDiff(gauss, want), 1e-6);
    // The imager ran on both: alpha 1 everywhere, the blue backdrop in the
    // corner nothing covers.
    for (const Image* img : {&box, static_cast<const Image*>(&gauss)}) {
        ASSERT_EQ(img->channels, 4);
        for (int y = 0; y < img->height; ++y)
            for (int x = 0; x < img->width; ++x) ASSERT_NEAR(img->at(x, y, 3), 1.0f, 1e-6f) << x << "," << y;
        EXPECT_NEAR(img->at(img->width - 1, 0, 2), 1.0f, 1e-6f);
    }
}
