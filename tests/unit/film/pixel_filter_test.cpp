#include "umbra/film/pixel_filter.h"
#include "umbra/util/math.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

using namespace umbra;
using umbra::film::FilterKind;
using umbra::film::PixelFilter;

namespace {

float sincPi(float t) { return t == 0 ? 1.0f : std::sin(kPi * t) / (kPi * t); }

/// The filters as RI spec 3.2 writes them (triangle corrected, sinc windowed,
/// see pixel_filter.h), evaluated inside the support.
float reference(FilterKind k, float x, float y, float xw, float yw) {
    float rx = xw / 2, ry = yw / 2;
    switch (k) {
    case FilterKind::Box: return 1.0f;
    case FilterKind::Triangle: return (1 - std::fabs(x) / rx) * (1 - std::fabs(y) / ry);
    case FilterKind::Gaussian: {
        x *= 2.0f / xw;
        y *= 2.0f / yw;
        return std::exp(-2.0f * (x * x + y * y));
    }
    case FilterKind::CatmullRom: {
        x *= 4.0f / xw;
        y *= 4.0f / yw;
        float r2 = x * x + y * y, r = std::sqrt(r2);
        return r >= 2 ? 0.0f : r < 1 ? 3 * r * r2 - 5 * r2 + 2 : -r * r2 + 5 * r2 - 8 * r + 4;
    }
    case FilterKind::Sinc: return sincPi(x) * sincPi(x / rx) * sincPi(y) * sincPi(y / ry);
    }
    return 0;
}

}  // namespace

TEST(PixelFilter, CreateByName) {
    EXPECT_EQ(PixelFilter::create("box", 1, 1)->kind(), FilterKind::Box);
    EXPECT_EQ(PixelFilter::create("triangle", 2, 2)->kind(), FilterKind::Triangle);
    EXPECT_EQ(PixelFilter::create("gaussian", 2, 2)->kind(), FilterKind::Gaussian);
    EXPECT_EQ(PixelFilter::create("RiGaussianFilter", 2, 2)->kind(), FilterKind::Gaussian);
    EXPECT_EQ(PixelFilter::create("catmull-rom", 4, 4)->kind(), FilterKind::CatmullRom);
    EXPECT_EQ(PixelFilter::create("sinc", 4, 4)->kind(), FilterKind::Sinc);
    EXPECT_FALSE(PixelFilter::create("mitchell", 4, 4).has_value());
    EXPECT_FALSE(PixelFilter::create("box", 0, 1).has_value());
    EXPECT_STREQ(PixelFilter::create("catmull-rom", 4, 4)->name(), "catmull-rom");
}

TEST(PixelFilter, MatchesClosedFormsAndTablesAgree) {
    const FilterKind kinds[] = {FilterKind::Box, FilterKind::Triangle, FilterKind::Gaussian, FilterKind::CatmullRom,
                                FilterKind::Sinc};
    const float widths[][2] = {{1, 1}, {2, 2}, {3, 2}, {4, 4}, {2.5f, 5}};
    for (FilterKind k : kinds)
        for (const auto& w : widths) {
            PixelFilter f(k, w[0], w[1]);
            SCOPED_TRACE(std::string(f.name()) + " " + std::to_string(w[0]) + "x" + std::to_string(w[1]));
            for (int i = 0; i <= 40; ++i)
                for (int j = 0; j <= 40; ++j) {
                    float x = (float(i) / 20.0f - 1.0f) * w[0] / 2 * 0.999f;
                    float y = (float(j) / 20.0f - 1.0f) * w[1] / 2 * 0.999f;
                    float ref = reference(k, x, y, w[0], w[1]);
                    EXPECT_NEAR(f.evaluate(x, y), ref, 1e-5f) << x << "," << y;
                    EXPECT_NEAR(f.weight(x, y), ref, 1e-4f) << x << "," << y;
                }
            // Zero past the support.
            EXPECT_EQ(f.evaluate(w[0] / 2 * 1.001f, 0), 0.0f);
            EXPECT_EQ(f.evaluate(0, -w[1] / 2 * 1.001f), 0.0f);
            EXPECT_EQ(f.weight(w[0] / 2 * 1.001f, 0), 0.0f);
            EXPECT_EQ(f.weight(0, -w[1] / 2 * 1.001f), 0.0f);
        }
}

TEST(PixelFilter, GaussianIsRenderMansAndSeparable) {
    PixelFilter g(FilterKind::Gaussian, 2, 2);
    EXPECT_FLOAT_EQ(g.evaluate(0, 0), 1.0f);
    EXPECT_FLOAT_EQ(g.evaluate(0.5f, 0), std::exp(-0.5f));
    EXPECT_FLOAT_EQ(g.evaluate(1.0f, 0), std::exp(-2.0f));  // the closed support's edge
    EXPECT_TRUE(g.separable());
    EXPECT_FALSE(PixelFilter(FilterKind::CatmullRom, 4, 4).separable());
}

TEST(PixelFilter, MarginIsThePixelsWithinReach) {
    // Samples of pixel q lie in [q, q+1); pixel p's centre is p + 0.5.
    EXPECT_EQ(PixelFilter(FilterKind::Box, 1, 1).margin(), 1);  // a sample on the pixel edge reaches both
    EXPECT_EQ(PixelFilter(FilterKind::Gaussian, 2, 2).margin(), 1);
    EXPECT_EQ(PixelFilter(FilterKind::Box, 2.8f, 2.8f).margin(), 1);
    EXPECT_EQ(PixelFilter(FilterKind::Box, 3, 3).margin(), 2);
    EXPECT_EQ(PixelFilter(FilterKind::CatmullRom, 4, 4).margin(), 2);
    PixelFilter f(FilterKind::Sinc, 6, 2);
    EXPECT_EQ(f.xMargin(), 3);
    EXPECT_EQ(f.yMargin(), 1);
    EXPECT_EQ(f.margin(), 3);
    // Never more than ceil(radius), the margin the renderer samples.
    for (float w = 0.5f; w < 8; w += 0.37f)
        EXPECT_LE(PixelFilter(FilterKind::Box, w, w).margin(), int(std::ceil(w / 2)));
}
