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
    case FilterKind::CatmullRom: {  // in pixels whatever the width: 1 at 0, 0 at 1 and from 2
        float r2 = x * x + y * y, r = std::sqrt(r2);
        return r >= 2 ? 0.0f : r < 1 ? 3 * r * r2 - 5 * r2 + 2 : -r * r2 + 5 * r2 - 8 * r + 4;
    }
    case FilterKind::Sinc: return sincPi(x) * sincPi(x / rx) * sincPi(y) * sincPi(y / ry);
    case FilterKind::Mitchell:
    case FilterKind::SeparableCatmullRom: {
        // Mitchell & Netravali (1988), k(t) for |t| < 2 with t = 4x/width.
        const float B = k == FilterKind::Mitchell ? 1.0f / 3 : 0, C = k == FilterKind::Mitchell ? 1.0f / 3 : 0.5f;
        auto cubic = [&](float t) {
            t = std::fabs(t);
            if (t < 1) return ((12 - 9 * B - 6 * C) * t * t * t + (-18 + 12 * B + 6 * C) * t * t + (6 - 2 * B)) / 6;
            return ((-B - 6 * C) * t * t * t + (6 * B + 30 * C) * t * t + (-12 * B - 48 * C) * t + (8 * B + 24 * C)) /
                   6;
        };
        return cubic(4 * x / xw) * cubic(4 * y / yw);
    }
    case FilterKind::BlackmanHarris: {
        // The window over [-width/2, width/2], phase 2 pi (x + width/2) / width.
        auto bh = [](float x, float w) {
            const float a = 2 * kPi * (x + w / 2) / w;
            return 0.35875f - 0.48829f * std::cos(a) + 0.14128f * std::cos(2 * a) - 0.01168f * std::cos(3 * a);
        };
        return bh(x, xw) * bh(y, yw);
    }
    case FilterKind::Disk: return (x / rx) * (x / rx) + (y / ry) * (y / ry) <= 1 ? 1.0f : 0.0f;
    case FilterKind::Bessel: {
        if ((x / rx) * (x / rx) + (y / ry) * (y / ry) > 1) return 0.0f;
        const double r = std::hypot(x, y);
        return r == 0 ? 1.0f : float(2 * ::j1(kPi * r) / (kPi * r));
    }
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
    EXPECT_EQ(PixelFilter::create("mitchell", 4, 4)->kind(), FilterKind::Mitchell);
    EXPECT_EQ(PixelFilter::create("separable-catmull-rom", 4, 4)->kind(), FilterKind::SeparableCatmullRom);
    EXPECT_EQ(PixelFilter::create("blackman-harris", 4, 4)->kind(), FilterKind::BlackmanHarris);
    EXPECT_EQ(PixelFilter::create("disk", 3, 3)->kind(), FilterKind::Disk);
    EXPECT_EQ(PixelFilter::create("bessel", 6.49f, 6.49f)->kind(), FilterKind::Bessel);
    EXPECT_FALSE(PixelFilter::create("lanczos-typo", 4, 4).has_value());
    EXPECT_FALSE(PixelFilter::create("box", 0, 1).has_value());
    EXPECT_STREQ(PixelFilter::create("catmull-rom", 4, 4)->name(), "catmull-rom");
}

TEST(PixelFilter, MatchesClosedFormsAndTablesAgree) {
    const FilterKind kinds[] = {FilterKind::Box,         FilterKind::Triangle, FilterKind::Gaussian,
                                FilterKind::CatmullRom,  FilterKind::Sinc,     FilterKind::Mitchell,
                                FilterKind::SeparableCatmullRom, FilterKind::BlackmanHarris, FilterKind::Disk,
                                FilterKind::Bessel};
    const float widths[][2] = {{1, 1}, {2, 2}, {3, 2}, {4, 4}, {2.5f, 5}};
    for (FilterKind k : kinds)
        for (const auto& w : widths) {
            PixelFilter f(k, w[0], w[1]);
            SCOPED_TRACE(std::string(f.name()) + " " + std::to_string(w[0]) + "x" + std::to_string(w[1]));
            // The tables interpolate linearly, 256 entries a pixel: the
            // cubics and the window squeezed into one pixel curve enough
            // to miss by up to 2.3e-4 (0.03% of their peak).
            const bool steep = w[0] < 2 && (k == FilterKind::Mitchell || k == FilterKind::SeparableCatmullRom ||
                                            k == FilterKind::BlackmanHarris);
            const float tableTolerance = steep ? 3e-4f : 1e-4f;
            for (int i = 0; i <= 40; ++i)
                for (int j = 0; j <= 40; ++j) {
                    float x = (float(i) / 20.0f - 1.0f) * w[0] / 2 * 0.999f;
                    float y = (float(j) / 20.0f - 1.0f) * w[1] / 2 * 0.999f;
                    float ref = reference(k, x, y, w[0], w[1]);
                    EXPECT_NEAR(f.evaluate(x, y), ref, 1e-5f) << x << "," << y;
                    EXPECT_NEAR(f.weight(x, y), ref, tableTolerance) << x << "," << y;
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

TEST(PixelFilter, CubicsAndWindowsHaveTheirKnownValues) {
    // Mitchell's k(0) = (6 - 2B)/6 = 8/9; its first lobe crosses zero
    // between 1 and 2 (in units of a quarter of the width).
    PixelFilter m(FilterKind::Mitchell, 4, 4);
    EXPECT_NEAR(m.evaluate(0, 0), (8.0f / 9) * (8.0f / 9), 1e-6f);
    EXPECT_NEAR(m.evaluate(1, 0), (8.0f / 9) * (1.0f / 18), 1e-6f);  // k(1) = B/6 = 1/18
    EXPECT_LT(m.evaluate(1.5f, 0), 0.0f);
    EXPECT_TRUE(m.separable());
    // Catmull-Rom interpolates: 1 at the centre, 0 one pixel away.
    PixelFilter c(FilterKind::SeparableCatmullRom, 4, 4);
    EXPECT_FLOAT_EQ(c.evaluate(0, 0), 1.0f);
    EXPECT_NEAR(c.evaluate(1, 0), 0.0f, 1e-6f);
    EXPECT_NEAR(c.evaluate(1, 1), 0.0f, 1e-6f);
    // Blackman-Harris: 1 at the centre, about 6e-5 at the edge.
    PixelFilter bh(FilterKind::BlackmanHarris, 3, 3);
    EXPECT_NEAR(bh.evaluate(0, 0), 1.0f, 1e-6f);
    EXPECT_NEAR(bh.evaluate(1.5f, 0), 6e-5f, 1e-5f);
    // Disk: round, so not the box's corners.
    PixelFilter d(FilterKind::Disk, 2, 2);
    EXPECT_EQ(d.evaluate(0.7f, 0), 1.0f);
    EXPECT_EQ(d.evaluate(0.75f, 0.75f), 0.0f);
    EXPECT_FALSE(d.separable());
    // Bessel (Airy): first zero at r = 1.2197 pixels, a negative lobe past it.
    PixelFilter j(FilterKind::Bessel, 6.49f, 6.49f);
    EXPECT_FLOAT_EQ(j.evaluate(0, 0), 1.0f);
    EXPECT_NEAR(j.evaluate(1.2197f, 0), 0.0f, 1e-4f);
    EXPECT_LT(j.evaluate(0, 1.6f), 0.0f);
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
