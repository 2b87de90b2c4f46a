// Percentage-closer filtering against references computed here.

#include "shadow_test_util.h"
#include "umbra/util/rng.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <thread>

namespace umbra {
namespace {

// A 256x256 map, raster = world x,y: columns x < 128 hold an occluder at
// depth 10, the rest is a floor at depth 100. Points at depth 50 are
// shadowed exactly where their texel column is < 128.
constexpr int kRes = 256;
constexpr float kEdge = 128;

DepthImage stepImage() {
    DepthImage img(kRes, kRes);
    test::setRasterIsWorld(img);
    for (int y = 0; y < kRes; ++y)
        for (int x = 0; x < kRes; ++x) img.at(x, y) = x < kEdge ? 10.0f : 100.0f;
    return img;
}

const std::shared_ptr<ShadowMap>& stepMap() {
    static std::shared_ptr<ShadowMap> map = test::writeAndOpen(stepImage(), "step.exr");
    return map;
}

// A region of full width `w` texels centred on P, as a micropolygon with
// edges (w,0,0) and (0,w,0) gives it.
struct Points {
    std::vector<Vec3> P, du, dv;
    ShadowBatch batch(uint32_t seed) const {
        ShadowBatch b;
        b.count = int(P.size());
        b.P = P.data();
        b.dPdu_du = du.data();
        b.dPdv_dv = dv.data();
        b.seed = seed;
        return b;
    }
    void add(Vec3 p, float w) {
        P.push_back(p);
        du.push_back(Vec3(w, 0, 0));
        dv.push_back(Vec3(0, w, 0));
    }
};

TEST(ShadowLookup, StraddlingRegionsReturnTheCoveredFraction) {
    const auto& map = stepMap();
    ASSERT_TRUE(map);
    ShadowParams params;  // 16 jittered samples, box filter
    const float w = 8;    // region [s-4, s+4): 4x4 strata of 2x2 texels
    Points pts;
    Rng rng(7);
    for (int i = 0; i < 2000; ++i) pts.add(Vec3(kEdge - 4 + 8 * rng.uniform(), 20 + 200 * rng.uniform(), 50), w);
    std::vector<float> out(pts.P.size());
    ShadowStats st;
    map->lookup(pts.batch(1), params, out.data(), st);
    EXPECT_EQ(st.filtered, pts.P.size());
    EXPECT_EQ(st.samples, 16 * pts.P.size());  // Reeves: 64 texels >= 16 samples -> 4x4

    // Reference: the region [s-4, s+4) is split into 4 columns of strata,
    // 2 texels wide, 4 jittered samples each. Columns wholly left of the
    // edge shadow all their samples, columns right of it none; in the
    // column holding the edge each sample is shadowed independently with
    // probability q = the part of the column left of the edge. So
    // 16 * result - 4 * fullColumns is Binomial(4, q).
    double sumX = 0, sumMean = 0, sumVar = 0, meanErr = 0;
    for (size_t i = 0; i < out.size(); ++i) {
        const double left = (double(kEdge) - (double(pts.P[i].x) - 4.0)) / 2.0;  // columns left of the edge
        const int full = std::clamp(int(std::floor(left)), 0, 4);
        const double q = full < 4 ? std::clamp(left - full, 0.0, 1.0) : 0.0;
        const double x = double(out[i]) * 16.0 - 4.0 * full;
        ASSERT_EQ(x, std::round(x)) << "s=" << pts.P[i].x;
        ASSERT_GE(x, 0.0) << "s=" << pts.P[i].x;
        ASSERT_LE(x, q > 0 ? 4.0 : 0.0) << "s=" << pts.P[i].x;
        sumX += x;
        sumMean += 4 * q;
        sumVar += 4 * q * (1 - q);
        // The covered fraction, within binomial error for 16 samples.
        const double p = std::clamp(left / 4.0, 0.0, 1.0);
        meanErr += out[i] - p;
    }
    EXPECT_NEAR(sumX, sumMean, 4 * std::sqrt(sumVar));
    // Unbiased: the mean error over all points is within 4 sigma of the
    // binomial error of 16 samples (the half-cell jitter printed in Figure 4
    // would bias it by about 1/16).
    meanErr /= double(out.size());
    EXPECT_NEAR(meanErr, 0.0, 4 * std::sqrt(0.25 / 16 / double(out.size())));
}

TEST(ShadowLookup, RegionsAwayFromTheEdgeAreExact) {
    const auto& map = stepMap();
    Points pts;
    pts.add(Vec3(60, 60, 50), 8);     // over the occluder, beyond it: shadowed
    pts.add(Vec3(200, 60, 50), 8);    // over the floor, in front of it: lit
    pts.add(Vec3(60, 60, 5), 8);      // in front of the occluder: lit
    pts.add(Vec3(200, 60, 150), 8);   // beyond the floor: shadowed
    pts.add(Vec3(60, 60, -50), 8);    // behind the light: lit
    pts.add(Vec3(-40, 60, 50), 8);    // off the map: lit
    pts.add(Vec3(60, 300, 150), 8);   // off the map: lit
    std::vector<float> out(pts.P.size());
    ShadowParams params;
    params.tileCulling = false;
    ShadowStats st;
    map->lookup(pts.batch(3), params, out.data(), st);
    EXPECT_EQ(out, (std::vector<float>{1, 0, 0, 1, 0, 0, 0}));
    EXPECT_EQ(st.outside, 3u);
}

TEST(ShadowLookup, BiasMovesTheComparison) {
    const auto& map = stepMap();
    Points pts;
    pts.add(Vec3(60, 60, 10.5f), 8);
    std::vector<float> out(1);
    ShadowStats st;
    ShadowParams params;
    params.tileCulling = false;
    map->lookup(pts.batch(1), params, out.data(), st);
    EXPECT_EQ(out[0], 1.0f);
    params.bias = 1;
    map->lookup(pts.batch(1), params, out.data(), st);
    EXPECT_EQ(out[0], 0.0f);
    // bias0/bias1 override bias: half the samples draw a bias below 0.5.
    params.bias0 = 0;
    params.bias1 = 1;
    params.samples = 64;
    pts.P[0].z = 10.5f;
    Points many;
    for (int i = 0; i < 200; ++i) many.add(Vec3(30 + float(i) * 0.3f, 60, 10.5f), 16);
    std::vector<float> o2(200);
    map->lookup(many.batch(9), params, o2.data(), st);
    double mean = 0;
    for (float v : o2) mean += v;
    mean /= 200;
    // Shadowed iff bias < 0.5: probability 1/2, 64*200 draws.
    EXPECT_NEAR(mean, 0.5, 4 * std::sqrt(0.25 / (64 * 200)));
}

TEST(ShadowLookup, OneSampleEqualsPointSampling) {
    // A map with structure at every texel, compared with a reference here.
    DepthImage img(96, 80);
    test::setRasterIsWorld(img);
    for (int y = 3; y < 77; ++y)
        for (int x = 2; x < 90; ++x) img.at(x, y) = float(hash32(uint32_t(y * 96 + x)) % 1000) * 0.1f;
    auto map = test::writeAndOpen(img, "noise.exr");
    ASSERT_TRUE(map);
    Points pts;
    Rng rng(11);
    for (int i = 0; i < 3000; ++i)
        pts.add(Vec3(-5 + 106 * rng.uniform(), -5 + 90 * rng.uniform(), 100 * rng.uniform()), 3 * rng.uniform());
    std::vector<float> point(pts.P.size()), one(pts.P.size()), ref(pts.P.size());
    ShadowParams params;
    params.bias0 = 0.5f;
    params.bias1 = 1.5f;  // a single sample compares with the mid bias, 1
    for (size_t i = 0; i < pts.P.size(); ++i) {
        float s = pts.P[i].x, t = pts.P[i].y;
        float d = kInfinity;
        if (s >= 0 && t >= 0 && s < 96 && t < 80) d = img.at(int(std::floor(s)), int(std::floor(t)));
        ref[i] = pts.P[i].z > d + 1.0f ? 1.0f : 0.0f;
    }
    ShadowStats st;
    map->lookupPoint(pts.batch(5), params, point.data(), st);
    EXPECT_EQ(point, ref);
    params.samples = 1;
    for (float width : {1.0f, 3.0f}) {
        params.setWidth(width);
        for (bool cull : {false, true}) {
            params.tileCulling = cull;
            map->lookup(pts.batch(5), params, one.data(), st);
            EXPECT_EQ(one, ref) << "width " << width << " culling " << cull;
        }
    }
}

// A scene-like map: boxes of different heights over an empty background,
// so tiles are empty, uniform, or mixed.
DepthImage blocksImage(int res) {
    DepthImage img(res, res);
    test::setRasterIsWorld(img);
    Rng rng(3);
    for (int k = 0; k < 40; ++k) {
        int x0 = int(rng.uniform() * float(res)), y0 = int(rng.uniform() * float(res));
        int w = 8 + int(rng.uniform() * float(res) / 6), h = 8 + int(rng.uniform() * float(res) / 6);
        float z = 10 + 80 * rng.uniform();
        for (int y = y0; y < std::min(res, y0 + h); ++y)
            for (int x = x0; x < std::min(res, x0 + w); ++x) img.at(x, y) = std::min(img.at(x, y), z + 0.01f * float(x));
    }
    return img;
}

Points randomPoints(int n, int res, uint32_t seed) {
    Points pts;
    Rng rng(seed);
    for (int i = 0; i < n; ++i)
        pts.add(Vec3(float(res) * (-0.05f + 1.1f * rng.uniform()), float(res) * (-0.05f + 1.1f * rng.uniform()),
                     100 * rng.uniform()),
                0.5f + 10 * rng.uniform());
    return pts;
}

TEST(ShadowLookup, TileCullingNeverChangesAResult) {
    auto map = test::writeAndOpen(blocksImage(320), "blocks.exr");
    ASSERT_TRUE(map);
    Points pts = randomPoints(20000, 320, 17);
    for (auto sampling : {ShadowParams::Sampling::Jittered, ShadowParams::Sampling::Uniform,
                          ShadowParams::Sampling::Gaussian}) {
        ShadowParams params;
        params.sampling = sampling;
        params.bias0 = 0.1f;
        params.bias1 = 0.4f;
        params.filter = sampling == ShadowParams::Sampling::Uniform ? ShadowParams::Filter::Gaussian
                                                                    : ShadowParams::Filter::Box;
        std::vector<float> on(pts.P.size()), off(pts.P.size());
        ShadowStats stOn, stOff;
        map->lookup(pts.batch(21), params, on.data(), stOn);
        params.tileCulling = false;
        map->lookup(pts.batch(21), params, off.data(), stOff);
        ASSERT_EQ(std::memcmp(on.data(), off.data(), on.size() * sizeof(float)), 0);
        EXPECT_GT(stOn.culledLit, 1000u);
        EXPECT_GT(stOn.culledShadowed, 100u);
        EXPECT_EQ(stOff.culledLit + stOff.culledShadowed, 0u);
        // Regions of a few texels the blocks' ranges leave open are decided
        // by their texels' own range (the memcmp above: without changing a
        // result).
        EXPECT_GT(stOn.texelRangeLit, 100u);
        EXPECT_GT(stOn.texelRangeShadowed, 100u);
        EXPECT_EQ(stOff.texelRangeLit + stOff.texelRangeShadowed, 0u);
        EXPECT_LT(stOn.samples, stOff.samples);
        // Same inputs, same bits.
        std::vector<float> again(pts.P.size());
        map->lookup(pts.batch(21), params, again.data(), stOff);
        EXPECT_EQ(std::memcmp(again.data(), off.data(), on.size() * sizeof(float)), 0);
    }
}

TEST(ShadowLookup, APointsSamplesDependOnItsIdentityNotItsCompany) {
    // The shading grid looks up only the points a light reached, so the
    // same point may come with different neighbours: its result must not
    // change. Every other point of a batch, looked up alone with its id,
    // gets the bits it got in the full batch; without ids it would not.
    const auto& map = stepMap();
    ASSERT_TRUE(map);
    ShadowParams params;
    Points all, odd;
    std::vector<int> allIds, oddIds;
    Rng rng(41);
    for (int i = 0; i < 400; ++i) {
        all.add(Vec3(kEdge - 4 + 8 * rng.uniform(), 20 + 200 * rng.uniform(), 50), 8);
        allIds.push_back(i);
        if (i % 2) {
            odd.add(all.P.back(), 8);
            oddIds.push_back(i);
        }
    }
    ShadowBatch full = all.batch(5), part = odd.batch(5);
    full.pointId = allIds.data();
    part.pointId = oddIds.data();
    std::vector<float> a(all.P.size()), b(odd.P.size()), c(odd.P.size());
    ShadowStats st;
    map->lookup(full, params, a.data(), st);
    map->lookup(part, params, b.data(), st);
    int fractional = 0, moved = 0;
    part.pointId = nullptr;  // seeded by place in the batch instead
    map->lookup(part, params, c.data(), st);
    for (size_t k = 0; k < b.size(); ++k) {
        ASSERT_EQ(b[k], a[size_t(oddIds[k])]) << "point " << oddIds[k];
        fractional += b[k] > 0 && b[k] < 1;
        moved += c[k] != b[k];
    }
    EXPECT_GT(fractional, 100);  // straddling the edge: the samples matter
    EXPECT_GT(moved, 50);        // and the check above could fail
}

TEST(ShadowLookup, RegionsReachingPastTheMapsBorderReadItsEdge) {
    // A point inside the map whose region reaches past the border reads
    // the border's texels there, as a texture lookup clamps (PRMan, Pixie
    // and Aqsis alike): behind an occluder that fills the map's edge it is
    // wholly shadowed, not lit in the part of its region beyond the edge.
    const auto& map = stepMap();
    ASSERT_TRUE(map);
    Points pts;
    Rng rng(17);
    for (int i = 0; i < 300; ++i) {
        const float a = 4 * rng.uniform(), b = 20 + 88 * rng.uniform();
        pts.add(Vec3(a, b, 50), 8);            // the left edge
        pts.add(Vec3(b, a, 50), 8);            // the top edge, occluded half
        pts.add(Vec3(b, kRes - a, 50), 8);     // the bottom edge
        pts.add(Vec3(a, kRes - a, 50), 8);     // the bottom-left corner
    }
    for (const ShadowParams::Filter filter : {ShadowParams::Filter::Box, ShadowParams::Filter::Gaussian}) {
        ShadowParams params;
        params.filter = filter;
        std::vector<float> out(pts.P.size());
        ShadowStats st;
        map->lookup(pts.batch(3), params, out.data(), st);
        for (size_t i = 0; i < out.size(); ++i) ASSERT_EQ(out[i], 1.0f) << "point " << i << " at " << pts.P[i].x << ", " << pts.P[i].y;
    }
    // Over the floor (the right half), the same regions stay lit; points
    // off the map stay lit.
    Points floor;
    for (int i = 0; i < 100; ++i) {
        const float a = 4 * rng.uniform(), b = 140 + 100 * rng.uniform();
        floor.add(Vec3(kRes - a, b, 50), 8);
        floor.add(Vec3(b, a, 50), 8);
        floor.add(Vec3(-4.5f - a, b, 50), 8);
    }
    std::vector<float> out(floor.P.size());
    ShadowStats st;
    map->lookup(floor.batch(4), ShadowParams(), out.data(), st);
    for (size_t i = 0; i < out.size(); ++i) ASSERT_EQ(out[i], 0.0f) << "point " << i;
}

TEST(ShadowLookup, FourCornersFilterTheirQuadrilateralInAnyOrder) {
    // shadow(name, P1, P2, P3, P4): the region is the box around the four
    // corners, whatever their order; the point is their centre. Boxes
    // straddling the occluder's edge return about the part of them left of
    // it (16 jittered samples: within 0.05 on average, no bias), the same
    // bits for the corners in patch order and around the outline.
    const auto& map = stepMap();
    ASSERT_TRUE(map);
    Rng rng(29);
    std::vector<Vec3> patch[4], around[4], centre;
    std::vector<double> fraction;
    for (int i = 0; i < 500; ++i) {
        const float x0 = kEdge - 20 + 18 * rng.uniform(), x1 = kEdge + 2 + 18 * rng.uniform();
        const float y0 = 20 + 100 * rng.uniform(), y1 = y0 + 4 + 30 * rng.uniform();
        const Vec3 c00(x0, y0, 50), c10(x1, y0, 50), c01(x0, y1, 50), c11(x1, y1, 50);
        const Vec3 inPatchOrder[4] = {c00, c10, c01, c11}, inOutline[4] = {c10, c11, c01, c00};
        for (int c = 0; c < 4; ++c) patch[c].push_back(inPatchOrder[c]), around[c].push_back(inOutline[c]);
        centre.push_back((c00 + c10 + c01 + c11) * 0.25f);
        fraction.push_back((double(kEdge) - x0) / (double(x1) - x0));
    }
    auto lookup = [&](std::vector<Vec3>* corners) {
        ShadowBatch b;
        b.count = int(centre.size());
        b.P = centre.data();
        for (int c = 0; c < 4; ++c) b.corners[c] = corners[c].data();
        b.seed = 5;
        std::vector<float> out(centre.size());
        ShadowStats st;
        map->lookup(b, ShadowParams(), out.data(), st);
        return out;
    };
    const std::vector<float> a = lookup(patch), b = lookup(around);
    double err = 0, bias = 0;
    for (size_t i = 0; i < a.size(); ++i) {
        ASSERT_EQ(std::memcmp(&a[i], &b[i], sizeof a[i]), 0) << "point " << i;
        err += std::abs(a[i] - fraction[i]);
        bias += a[i] - fraction[i];
    }
    EXPECT_LT(err / double(a.size()), 0.05);
    EXPECT_LT(std::abs(bias) / double(a.size()), 0.01);
}

TEST(ShadowLookup, PointsOffTheMapOrNotNumbersAreLitAndLeaveTheirNeighboursAlone) {
    // Points are projected four at a time: points far beyond an int texel
    // index, behind the light or not numbers share lanes with ordinary
    // points straddling the edge. They are lit, and every point gets the
    // bits it gets looked up alone.
    const auto& map = stepMap();
    ASSERT_TRUE(map);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    struct Case {
        Vec3 P;
        float width;
        bool lit;
    };
    const std::vector<Case> odd = {
        {Vec3(1e20f, 100, 50), 8, true},     {Vec3(-1e20f, 100, 50), 8, true},
        {Vec3(100, 3e38f, 50), 8, true},     {Vec3(kEdge, 100, -5), 8, true},  // behind the light
        {Vec3(nan, 100, 50), 8, true},       {Vec3(kEdge, 100, nan), 8, true},
        {Vec3(kEdge, 100, 50), 3e38f, false},  // the region is clamped, the point filtered
        {Vec3(kEdge, 100, 50), nan, false},    // a footprint that is not a number: MinSize
    };
    Points pts;
    std::vector<bool> lit;
    Rng rng(43);
    for (const Case& c : odd)
        for (int k = 0; k < 3; ++k) {  // each odd point between ordinary ones, in every lane
            for (int j = 0; j <= k; ++j) {
                pts.add(Vec3(kEdge - 4 + 8 * rng.uniform(), 20 + 200 * rng.uniform(), 50), 8);
                lit.push_back(false);
            }
            pts.add(c.P, c.width);
            lit.push_back(c.lit);
        }
    std::vector<int> ids(pts.P.size());
    for (size_t i = 0; i < ids.size(); ++i) ids[i] = int(i);
    ShadowBatch all = pts.batch(9);
    all.pointId = ids.data();
    std::vector<float> together(pts.P.size());
    ShadowStats st;
    map->lookup(all, ShadowParams(), together.data(), st);
    int fractional = 0;
    for (size_t i = 0; i < pts.P.size(); ++i) {
        ShadowBatch one = all;
        one.count = 1;
        one.P += i, one.dPdu_du += i, one.dPdv_dv += i, one.pointId += i;
        float alone = -1;
        map->lookup(one, ShadowParams(), &alone, st);
        ASSERT_EQ(std::memcmp(&alone, &together[i], sizeof alone), 0) << "point " << i;
        ASSERT_TRUE(together[i] >= 0 && together[i] <= 1) << "point " << i;
        if (lit[i]) {
            EXPECT_EQ(together[i], 0.0f) << "point " << i;
        }
        fractional += together[i] > 0 && together[i] < 1;
    }
    EXPECT_GT(fractional, 20);  // the ordinary points straddle the edge
}

TEST(ShadowLookup, BatchCullingMatchesThePointLoop) {
    // Shaded grids as batches: 8x8 points on a small patch each, at random
    // places and depths. Batches decided as a whole must get exactly what
    // the point loop gives (tile culling off runs the point loop only).
    auto map = test::writeAndOpen(blocksImage(320), "blocks-batch.exr");
    ASSERT_TRUE(map);
    Rng rng(29);
    ShadowParams params;
    params.bias0 = 0.1f;
    params.bias1 = 0.4f;
    ShadowStats on, off;
    for (int g = 0; g < 400; ++g) {
        Points pts;
        const float x0 = 400 * rng.uniform() - 40, y0 = 400 * rng.uniform() - 40, z0 = 100 * rng.uniform();
        for (int j = 0; j < 8; ++j)
            for (int i = 0; i < 8; ++i) pts.add(Vec3(x0 + float(i), y0 + float(j), z0 + 0.05f * float(i + j)), 1.0f);
        std::vector<float> a(pts.P.size()), b(pts.P.size());
        params.tileCulling = true;
        map->lookup(pts.batch(uint32_t(g)), params, a.data(), on);
        params.tileCulling = false;
        map->lookup(pts.batch(uint32_t(g)), params, b.data(), off);
        ASSERT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)), 0) << "grid " << g;
    }
    EXPECT_EQ(on.points, off.points);
    EXPECT_LT(on.samples, off.samples);

    // A grid wholly outside the bounding box, one nearer than every depth
    // and one beyond every depth inside it: all three decided at once.
    auto decided = [&](Vec3 origin, float* first) {
        Points pts;
        for (int j = 0; j < 8; ++j)
            for (int i = 0; i < 8; ++i) pts.add(origin + Vec3(float(i), float(j), 0), 1.0f);
        std::vector<float> r(pts.P.size(), -1);
        ShadowStats st;
        params.tileCulling = true;
        map->lookup(pts.batch(7), params, r.data(), st);
        *first = r[0];
        for (float v : r) EXPECT_EQ(v, r[0]);
        return st;
    };
    float v;
    ShadowStats st = decided(Vec3(-500, -500, 50), &v);
    EXPECT_EQ(st.outside, 64u);
    EXPECT_EQ(v, 0.0f);
    st = decided(Vec3(150, 150, 1), &v);
    EXPECT_EQ(st.culledLit, 64u);
    EXPECT_EQ(v, 0.0f);
    EXPECT_EQ(st.samples, 0u);
}

TEST(ShadowLookup, ATinyCacheGivesTheSameResultsAndEvicts) {
    DepthImage img = blocksImage(512);  // 256 tiles, about 1 MB
    auto big = test::writeAndOpen(img, "cache_big.exr", std::make_shared<TileCache>(size_t(64) << 20));
    auto small = test::writeAndOpen(img, "cache_small.exr", std::make_shared<TileCache>(size_t(64) << 10));
    ASSERT_TRUE(big && small);
    Points pts = randomPoints(8000, 512, 23);
    ShadowParams params;
    params.tileCulling = false;
    params.blur = 0.01f;
    std::vector<float> a(pts.P.size()), b(pts.P.size());
    ShadowStats sa, sb;
    // Batches of 64 points, as grids arrive.
    for (size_t i = 0; i < pts.P.size(); i += 64) {
        ShadowBatch batch = pts.batch(uint32_t(i));
        batch.P += i;
        batch.dPdu_du += i;
        batch.dPdv_dv += i;
        batch.count = int(std::min<size_t>(64, pts.P.size() - i));
        big->lookup(batch, params, a.data() + i, sa);
        small->lookup(batch, params, b.data() + i, sb);
    }
    EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)), 0);
    TileCacheStats cs = small->cache().stats();
    EXPECT_GT(cs.evictions, 0u);
    EXPECT_LE(cs.peakBytes, size_t(64) << 10);
    EXPECT_GT(cs.tilesRead, 256u);  // tiles were read again after eviction
    EXPECT_EQ(cs.lookups, cs.hits + cs.misses);
    TileCacheStats cb = big->cache().stats();
    EXPECT_EQ(cb.evictions, 0u);
    EXPECT_LE(cb.tilesRead, 256u);
}

TEST(ShadowLookup, TwoThreadsMatchSerial) {
    auto cache = std::make_shared<TileCache>(size_t(96) << 10);  // small: threads evict under each other
    auto map = test::writeAndOpen(blocksImage(384), "threads.exr", cache);
    ASSERT_TRUE(map);
    Points pts = randomPoints(6000, 384, 31);
    ShadowParams params;
    const size_t n = pts.P.size(), kBatch = 50;
    auto run = [&](std::vector<float>& out, size_t first, size_t step, ShadowStats& st) {
        for (size_t i = first * kBatch; i < n; i += step * kBatch) {
            ShadowBatch b = pts.batch(uint32_t(i / kBatch));
            b.P += i;
            b.dPdu_du += i;
            b.dPdv_dv += i;
            b.count = int(std::min(kBatch, n - i));
            map->lookup(b, params, out.data() + i, st);
        }
    };
    std::vector<float> serial(n), parallel(n);
    ShadowStats s0, s1, s2;
    run(serial, 0, 1, s0);
    std::thread t1([&] { run(parallel, 0, 2, s1); });
    std::thread t2([&] { run(parallel, 1, 2, s2); });
    t1.join();
    t2.join();
    EXPECT_EQ(std::memcmp(serial.data(), parallel.data(), n * sizeof(float)), 0);
    s1 += s2;
    EXPECT_EQ(s1.points, s0.points);
    EXPECT_EQ(s1.samples, s0.samples);
}

TEST(ShadowLookup, PerspectiveMapComparesCameraDepth) {
    // A light at the origin looking down +z with a 90 degree field of view:
    // NDC x = (x/z + 1)/2, y = (1 - y/z)/2. The map holds an occluder at
    // depth 10 over the left half (x/z < 0).
    DepthImage img(128, 128);
    img.lightFromWorld = Mat4::identity();
    img.ndcFromWorld = test::ndcFromCamera90();
    for (int y = 0; y < 128; ++y)
        for (int x = 0; x < 64; ++x) img.at(x, y) = 10;
    auto map = test::writeAndOpen(img, "persp.exr");
    ASSERT_TRUE(map);
    EXPECT_EQ(map->projection(), Projection::Perspective);
    Points pts;
    const float fp = 0.05f;  // footprint, world units
    pts.add(Vec3(-8, 3, 20), fp);   // behind the occluder: shadowed
    pts.add(Vec3(8, 3, 20), fp);    // right half: lit
    pts.add(Vec3(-4, 1, 9), fp);    // in front of the occluder: lit
    pts.add(Vec3(-4, 1, -9), fp);   // behind the light: lit
    pts.add(Vec3(-40, 1, 20), fp);  // outside the field of view: lit
    // In a rotated "current" space: the same first point.
    std::vector<float> out(pts.P.size());
    ShadowStats st;
    ShadowParams params;
    map->lookup(pts.batch(2), params, out.data(), st);
    EXPECT_EQ(out, (std::vector<float>{1, 0, 0, 0, 0}));

    Mat4 currentFromWorld = Mat4::rotate(40, Vec3(0, 1, 1)) * Mat4::translate(Vec3(3, -2, 7));
    Points cur;
    for (size_t i = 0; i < pts.P.size(); ++i) {
        cur.P.push_back(currentFromWorld.point(pts.P[i]));
        cur.du.push_back(currentFromWorld.vector(pts.du[i]));
        cur.dv.push_back(currentFromWorld.vector(pts.dv[i]));
    }
    ShadowBatch b = cur.batch(2);
    b.worldFromCurrent = currentFromWorld.inverse();
    std::vector<float> out2(pts.P.size());
    map->lookup(b, params, out2.data(), st);
    EXPECT_EQ(out2, out);
}

TEST(ShadowTile, BlockRangesAreTheMinAndMaxOfEachBlock) {
    ShadowTile t;
    t.width = t.height = 32;
    t.z.resize(1024);
    Rng rng(5);
    for (float& z : t.z) z = rng.uniform() < 0.1f ? kInfinity : 100 * rng.uniform();
    t.computeBlocks();
    for (int b = 0; b < 16; ++b) {
        float lo = kInfinity, hi = -kInfinity;
        for (int y = (b / 4) * 8; y < (b / 4) * 8 + 8; ++y)
            for (int x = (b % 4) * 8; x < (b % 4) * 8 + 8; ++x) {
                lo = std::min(lo, t.z[size_t(y * 32 + x)]);
                hi = std::max(hi, t.z[size_t(y * 32 + x)]);
            }
        EXPECT_EQ(t.blockMin[b], lo) << b;
        EXPECT_EQ(t.blockMax[b], hi) << b;
    }
    // A tile whose sides do not split into blocks gets ranges that never cull.
    ShadowTile odd;
    odd.width = odd.height = 6;
    odd.z.assign(36, 1.0f);
    odd.computeBlocks();
    EXPECT_EQ(odd.blockMin[0], -kInfinity);
    EXPECT_EQ(odd.blockMax[15], kInfinity);
}

TEST(TileCache, EvictsLeastRecentlyUsedAndHandsOutLiveTiles) {
    auto tile = [](float v) {
        auto t = std::make_shared<ShadowTile>();
        t->width = t->height = 32;
        t->z.assign(1024, v);
        return ShadowTilePtr(t);
    };
    const size_t tileBytes = tile(0)->bytes();
    const uint32_t map = TileCache::newMapId();
    // Keys sharing key 0's shard, found through the public API: with room
    // for one tile per shard, inserting such a key evicts key 0.
    std::vector<uint32_t> sameShard;
    for (uint32_t k = 1; k < 1000 && sameShard.size() < 2; ++k) {
        TileCache probe(8 * tileBytes);
        probe.insert(map, 0, tile(0));
        probe.insert(map, k, tile(0));
        if (!probe.find(map, 0)) sameShard.push_back(k);
    }
    ASSERT_EQ(sameShard.size(), 2u);
    {
        TileCache lru(8 * 2 * tileBytes);  // two tiles per shard
        lru.insert(map, 0, tile(0));
        lru.insert(map, sameShard[0], tile(1));
        EXPECT_TRUE(lru.find(map, 0));  // 0 is now the most recently used
        lru.insert(map, sameShard[1], tile(2));
        EXPECT_TRUE(lru.find(map, 0));
        EXPECT_FALSE(lru.find(map, sameShard[0]));
        EXPECT_TRUE(lru.find(map, sameShard[1]));
        EXPECT_EQ(lru.stats().evictions, 1u);
    }

    TileCache cache(8 * 2 * tileBytes);
    std::vector<ShadowTilePtr> kept;
    for (uint32_t i = 0; i < 200; ++i) kept.push_back(cache.insert(map, i, tile(float(i))));
    TileCacheStats st = cache.stats();
    EXPECT_LE(st.bytes, 16 * tileBytes);
    EXPECT_EQ(st.bytes + st.evictions * tileBytes, 200 * tileBytes);
    EXPECT_EQ(st.tilesRead, 200u);
    // The most recent insert is still cached; the first is gone, but the
    // pointer handed out earlier still reads its values.
    ShadowTilePtr last = cache.find(map, 199);
    ASSERT_TRUE(last);
    EXPECT_EQ(last->z[5], 199.0f);
    EXPECT_FALSE(cache.find(map, 0));
    EXPECT_EQ(kept[0]->z[5], 0.0f);
    // Re-inserting an existing key returns the cached tile.
    ShadowTilePtr again = cache.insert(map, 199, tile(-1));
    EXPECT_EQ(again.get(), last.get());
    cache.erase(map);
    EXPECT_EQ(cache.stats().bytes, 0u);
    EXPECT_FALSE(cache.find(map, 199));
}

}  // namespace
}  // namespace umbra
