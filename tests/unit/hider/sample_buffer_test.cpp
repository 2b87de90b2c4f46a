#include "umbra/film/film.h"
#include "umbra/hider/sample_buffer.h"
#include "umbra/util/rng.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

using namespace umbra;
using umbra::hider::HiderMode;
using umbra::hider::MicroGrid;
using umbra::hider::SampleBuffer;
using umbra::hider::SampleBufferConfig;

namespace {

/// A grid's storage; MicroGrid borrows from it.
struct TestGrid {
    int nu = 1, nv = 1;
    std::vector<Vec3> P;
    std::vector<Color> Ci, Oi;
    std::vector<float> aov;
    int aovCount = 0;
    bool matte = false;
    uint64_t id = 1;

    MicroGrid view() const {
        MicroGrid g;
        g.nu = nu;
        g.nv = nv;
        g.P = P.data();
        g.Ci = Ci.empty() ? nullptr : Ci.data();
        g.Oi = Oi.empty() ? nullptr : Oi.data();
        g.aov = aov.empty() ? nullptr : aov.data();
        g.aovCount = aovCount;
        g.matte = matte;
        g.id = id;
        return g;
    }
};

/// An axis-aligned rectangle [x0,x1]x[y0,y1] at depth z(x, y), nu x nv
/// micropolygons, with uniform colour and opacity (Ci premultiplied by the caller).
template <typename ZFn>
TestGrid rectGrid(float x0, float y0, float x1, float y1, int nu, int nv, ZFn zf, Color ci = Color(1.0f),
                  Color oi = Color(1.0f), uint64_t id = 1) {
    TestGrid g;
    g.nu = nu;
    g.nv = nv;
    g.id = id;
    for (int j = 0; j <= nv; ++j)
        for (int i = 0; i <= nu; ++i) {
            float x = x0 + (x1 - x0) * float(i) / float(nu);
            float y = y0 + (y1 - y0) * float(j) / float(nv);
            g.P.push_back({x, y, zf(x, y)});
            g.Ci.push_back(ci);
            g.Oi.push_back(oi);
        }
    return g;
}
TestGrid flatGrid(float x0, float y0, float x1, float y1, int nu, int nv, float z, Color ci = Color(1.0f),
                  Color oi = Color(1.0f), uint64_t id = 1) {
    return rectGrid(x0, y0, x1, y1, nu, nv, [z](float, float) { return z; }, ci, oi, id);
}

SampleBufferConfig config(int x0, int y0, int x1, int y1, int margin, int xs, int ys, bool jitter,
                          HiderMode mode = HiderMode::Colour) {
    SampleBufferConfig c;
    c.x0 = x0;
    c.y0 = y0;
    c.x1 = x1;
    c.y1 = y1;
    c.margin = margin;
    c.xSamples = xs;
    c.ySamples = ys;
    c.jitter = jitter;
    c.frameSeed = 1234;
    c.mode = mode;
    return c;
}

film::Film makeFilm(int xres, int yres, const char* filter, float width, std::vector<film::AovChannel> aovs = {},
                    film::FilmContent content = film::FilmContent::Colour) {
    const float crop[4] = {0, 1, 0, 1};
    return film::Film(xres, yres, crop, *film::PixelFilter::create(filter, width, width), std::move(aovs), content);
}

/// Calls f(px, py, s) for every sample of the buffer's sampled region.
template <typename F>
void forEachSample(const SampleBuffer& b, F f) {
    const SampleBufferConfig& c = b.config();
    for (int py = c.y0 - c.margin; py < c.y1 + c.margin; ++py)
        for (int px = c.x0 - c.margin; px < c.x1 + c.margin; ++px)
            for (int s = 0; s < c.xSamples * c.ySamples; ++s) f(px, py, s);
}

}  // namespace

TEST(SampleBuffer, PositionsAreStratifiedAndJittered) {
    const int xs = 4, ys = 3;
    std::vector<float> offsets;
    for (int s = 0; s < xs * ys; ++s) {
        Vec2 p = SampleBuffer::samplePosition(7, -3, s, xs, ys, true, 99);
        int i = s % xs, j = s / xs;
        EXPECT_GE(p.x, 7.0f + float(i) / xs);
        EXPECT_LT(p.x, 7.0f + float(i + 1) / xs);
        EXPECT_GE(p.y, -3.0f + float(j) / ys);
        EXPECT_LT(p.y, -3.0f + float(j + 1) / ys);
        offsets.push_back(p.x - (7.0f + (float(i) + 0.5f) / xs));
        // The jitter is keyed by (frame seed, pixel mod the pattern's
        // period, sample index) only: -3 mod P is P - 3.
        uint32_t h = hashKeys(99u, 7u, uint32_t(hider::kPatternPeriod - 3), uint32_t(s));
        EXPECT_NEAR(p.x, 7.0f + (float(i) + hashToUnit(h)) / xs, 1e-5f);
        EXPECT_NEAR(p.y, -3.0f + (float(j) + hashToUnit(hash32(h ^ 0x68e31da4u))) / ys, 1e-5f);
        // Regular positions are the strata centres.
        Vec2 r = SampleBuffer::samplePosition(7, -3, s, xs, ys, false, 99);
        EXPECT_FLOAT_EQ(r.x, 7.0f + (float(i) + 0.5f) / xs);
        EXPECT_FLOAT_EQ(r.y, -3.0f + (float(j) + 0.5f) / ys);
    }
    // Jittered: not all at the centres; a different seed moves them.
    EXPECT_TRUE(std::any_of(offsets.begin(), offsets.end(), [](float o) { return std::fabs(o) > 1e-3f; }));
    EXPECT_NE(SampleBuffer::samplePosition(7, -3, 0, xs, ys, true, 99).x,
              SampleBuffer::samplePosition(7, -3, 0, xs, ys, true, 100).x);
    // One regular sample per pixel is the pixel centre (depth maps).
    Vec2 c = SampleBuffer::samplePosition(10, 20, 0, 1, 1, false, 5);
    EXPECT_EQ(c.x, 10.5f);
    EXPECT_EQ(c.y, 20.5f);
}

TEST(SampleBuffer, JitterRepeatsEveryPatternPeriod) {
    const int xs = 4, ys = 4, P = hider::kPatternPeriod;
    for (int s = 0; s < xs * ys; ++s) {
        Vec2 p = SampleBuffer::samplePosition(5, 9, s, xs, ys, true, 7);
        for (int k : {-3, -1, 1, 2, 10}) {
            Vec2 q = SampleBuffer::samplePosition(5 + P * k, 9 - P * k, s, xs, ys, true, 7);
            EXPECT_NEAR(q.x - float(P * k), p.x, 1e-4f);
            EXPECT_NEAR(q.y + float(P * k), p.y, 1e-4f);
        }
        // Half the period is not a period.
        EXPECT_NE(SampleBuffer::samplePosition(5 + P / 2, 9, s, xs, ys, true, 7).x - float(P / 2), p.x);
    }
    // Far from the origin, rounding pixel + offset may cross a stratum's
    // edge; samples stay strictly inside their strata all the same.
    for (int px : {100003, -77777, 4095, -1}) {
        for (int s = 0; s < 3 * 5; ++s) {
            Vec2 p = SampleBuffer::samplePosition(px, -px, s, 3, 5, true, 3);
            EXPECT_EQ(int(std::floor(p.x * 3.0f)), px * 3 + s % 3) << px << " " << s;
            EXPECT_EQ(int(std::floor(p.y * 5.0f)), -px * 5 + s / 3) << px << " " << s;
        }
    }
}

TEST(SampleBuffer, MarginSamplesMatchTheNeighbourBucket) {
    SampleBuffer a, b;
    a.reset(config(0, 0, 16, 16, 2, 3, 3, true));
    b.reset(config(16, 0, 32, 16, 2, 3, 3, true));
    // A tilted, sheared grid across the bucket boundary.
    TestGrid g = rectGrid(10.2f, 3.3f, 22.7f, 11.9f, 9, 7, [](float x, float y) { return 3 + 0.1f * x + 0.02f * y; });
    for (Vec3& p : g.P) p.x += 0.3f * p.y;
    a.sample(g.view());
    b.sample(g.view());
    int compared = 0, hits = 0;
    for (int py = -2; py < 18; ++py)
        for (int px = 14; px < 18; ++px)  // a's pixels 14,15 are b's margin; b's 16,17 are a's margin
            for (int s = 0; s < 9; ++s) {
                Vec2 pa = a.position(px, py, s), pb = b.position(px, py, s);
                Vec2 ref = SampleBuffer::samplePosition(px, py, s, 3, 3, true, 1234);
                EXPECT_EQ(pa.x, pb.x);
                EXPECT_EQ(pa.y, pb.y);
                EXPECT_EQ(pa.x, ref.x);
                EXPECT_EQ(pa.y, ref.y);
                EXPECT_EQ(a.depth(px, py, s), b.depth(px, py, s));
                ++compared;
                hits += a.depth(px, py, s) < kInfinity;
            }
    EXPECT_EQ(compared, 20 * 4 * 9);
    EXPECT_GT(hits, 100);
}

TEST(SampleBuffer, CoverageOfASquareIsItsArea) {
    SampleBuffer b;
    b.reset(config(0, 0, 16, 16, 1, 4, 4, true));
    const float x0 = 3.3f, y0 = 2.2f, x1 = 11.7f, y1 = 9.9f;
    b.sample(flatGrid(x0, y0, x1, y1, 5, 4, 2.0f).view());
    int hits = 0, inside = 0;
    forEachSample(b, [&](int px, int py, int s) {
        Vec2 p = b.position(px, py, s);
        bool in = p.x > x0 && p.x < x1 && p.y > y0 && p.y < y1;
        bool hit = b.depth(px, py, s) < kInfinity;
        EXPECT_EQ(in, hit) << p.x << "," << p.y;
        inside += in;
        hits += hit;
    });
    EXPECT_EQ(hits, inside);
    const float area = (x1 - x0) * (y1 - y0);
    // Stratified sampling: the error comes from the strata the boundary crosses.
    EXPECT_NEAR(float(hits) / 16.0f, area, 0.5f);

    // Filtered with a box of width 1, the alpha channel sums to the area too.
    film::Film film = makeFilm(16, 16, "box", 1.0f);
    b.resolve(film);
    double alpha = 0;
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x) alpha += film.rgba(x, y)[3];
    EXPECT_NEAR(alpha, double(hits) / 16.0, 1e-4);
    EXPECT_EQ(film.rgba(7, 5)[3], 1.0f);
    EXPECT_EQ(film.rgba(0, 0)[3], 0.0f);
    EXPECT_EQ(film.z(7, 5), 2.0f);
    EXPECT_EQ(film.z(0, 0), kInfinity);
}

/// Counts, with transparent grids (every hit is recorded as a fragment), how
/// often each sample is hit.
static void expectEachSampleHitOnce(SampleBuffer& b, float ux0, float uy0, float ux1, float uy1, int* checked) {
    forEachSample(b, [&](int px, int py, int s) {
        Vec2 p = b.position(px, py, s);
        int n = b.fragmentCount(px, py, s);
        bool strictlyInside = p.x > ux0 && p.x < ux1 && p.y > uy0 && p.y < uy1;
        bool outside = p.x < ux0 || p.x > ux1 || p.y < uy0 || p.y > uy1;
        if (strictlyInside) {
            EXPECT_EQ(n, 1) << "sample at " << p.x << "," << p.y;
            ++*checked;
        } else if (outside) {
            EXPECT_EQ(n, 0) << "sample at " << p.x << "," << p.y;
        }
    });
}

TEST(SampleBuffer, SharedEdgesThroughSamplesAreHitExactlyOnce) {
    // Regular 4x4 samples sit at k + (i + 0.5)/4; the grids' vertices are
    // placed on sample positions so edges and diagonals run through samples.
    SampleBuffer b;
    b.reset(config(0, 0, 12, 8, 1, 4, 4, false));
    const Color half(0.5f);
    TestGrid a = flatGrid(1.125f, 1.125f, 5.375f, 6.125f, 4, 5, 1.0f, half, half, 1);  // spacing 1.0625, 1.0
    TestGrid c = flatGrid(5.375f, 1.125f, 9.125f, 6.125f, 3, 4, 2.0f, half, half, 2);  // shares x = 5.375
    b.sample(a.view());
    b.sample(c.view());
    int checked = 0;
    expectEachSampleHitOnce(b, 1.125f, 1.125f, 9.125f, 6.125f, &checked);
    EXPECT_EQ(checked, 31 * 19);  // sample columns strictly between the outer edges
}

TEST(SampleBuffer, SharedSkewedEdgesAreHitExactlyOnce) {
    // Random interior vertices: the shared edges between micropolygons and
    // between the two grids are skewed; jittered samples.
    for (uint32_t seed = 0; seed < 20; ++seed) {
        Rng rng(seed);
        SampleBuffer b;
        b.reset(config(0, 0, 8, 8, 1, 5, 5, true));
        const Color half(0.5f);
        // Grid A spans x in [1, 4.5] and grid B [4.5, 7.5]; both y in [1, 7].
        // The shared column is jiggled identically for both.
        TestGrid a = flatGrid(1, 1, 4.5f, 7, 4, 4, 1.0f, half, half, 1);
        TestGrid c = flatGrid(4.5f, 1, 7.5f, 7, 3, 4, 1.5f, half, half, 2);
        std::vector<float> shared(5);
        for (int j = 1; j < 4; ++j) shared[size_t(j)] = 4.5f + 0.8f * (rng.uniform() - 0.5f);
        for (int j = 0; j <= 4; ++j)
            for (int i = 0; i <= 4; ++i) {
                Vec3& p = a.P[size_t(j * 5 + i)];
                bool border = i == 0 || j == 0 || j == 4;
                if (i == 4) {
                    if (j > 0 && j < 4) p.x = shared[size_t(j)];
                } else if (!border) {
                    p.x += 0.6f * (rng.uniform() - 0.5f);
                    p.y += 0.6f * (rng.uniform() - 0.5f);
                }
            }
        for (int j = 1; j < 4; ++j) c.P[size_t(j * 4)].x = shared[size_t(j)];
        for (int j = 1; j < 4; ++j)
            for (int i = 1; i < 3; ++i) {
                Vec3& p = c.P[size_t(j * 4 + i)];
                p.x += 0.5f * (rng.uniform() - 0.5f);
                p.y += 0.5f * (rng.uniform() - 0.5f);
            }
        b.sample(c.view());
        b.sample(a.view());
        int checked = 0;
        expectEachSampleHitOnce(b, 1, 1, 7.5f, 7, &checked);
        EXPECT_GT(checked, 900);
    }
}

TEST(SampleBuffer, DepthIsExactForPlanes) {
    SampleBuffer b;
    b.reset(config(0, 0, 16, 16, 1, 3, 3, true));
    auto plane = [](float x, float y) { return 4.0f + 0.25f * x - 0.125f * y; };
    TestGrid g = rectGrid(0.5f, 0.5f, 15.5f, 15.5f, 7, 6, plane);
    // Shear it: still a plane in raster space if z follows the new positions.
    for (Vec3& p : g.P) {
        p.x += 0.2f * p.y;
        p.z = plane(p.x, p.y);
    }
    b.sample(g.view());
    int hits = 0;
    forEachSample(b, [&](int px, int py, int s) {
        float z = b.depth(px, py, s);
        if (z == kInfinity) return;
        Vec2 p = b.position(px, py, s);
        EXPECT_NEAR(z, plane(p.x, p.y), 2e-6f * plane(p.x, p.y));
        ++hits;
    });
    EXPECT_GT(hits, 1000);
}

TEST(SampleBuffer, PerspectiveDepthIsExactForPlanes) {
    // A pinhole camera: raster (x, y) = (50 + 100 X/Z, 50 + 100 Y/Z). The
    // plane Z = 5 + 2 X then has depth 5 / (1 - 2 u), u = (x - 50) / 100, at
    // raster x: not linear in raster space, but its reciprocal is. Coarse
    // micropolygons (4 per axis over 20 pixels) make the difference plain.
    auto depthAt = [](float x) { return 5.0f / (1.0f - 2.0f * (x - 50.0f) / 100.0f); };
    TestGrid g;
    g.nu = g.nv = 4;
    for (int j = 0; j <= 4; ++j)
        for (int i = 0; i <= 4; ++i) {
            const float x = 40.0f + 5.0f * float(i), y = 40.0f + 5.0f * float(j);
            g.P.push_back(Vec3(x, y, depthAt(x)));
        }
    for (bool perspective : {true, false}) {
        SampleBuffer b;
        SampleBufferConfig c = config(40, 40, 60, 60, 0, 2, 2, true);
        c.perspective = perspective;
        b.reset(c);
        b.sample(g.view());
        float worst = 0;
        int hits = 0;
        forEachSample(b, [&](int px, int py, int s) {
            const float z = b.depth(px, py, s);
            if (z == kInfinity) return;
            const float exact = depthAt(b.position(px, py, s).x);
            worst = std::max(worst, std::abs(z - exact) / exact);
            ++hits;
        });
        EXPECT_GT(hits, 1500);
        if (perspective)
            EXPECT_LT(worst, 2e-6f);
        else
            EXPECT_GT(worst, 1e-3f);  // linear z misses the plane between vertices
    }
}

TEST(SampleBuffer, TwoHalfTransparentLayersComposite) {
    SampleBuffer b;
    b.reset(config(0, 0, 4, 4, 1, 2, 2, true));
    const Color half(0.5f);
    // Premultiplied: red at 50% in front of blue at 50%.
    b.sample(flatGrid(-2, -2, 6, 6, 2, 2, 2.0f, Color(0, 0, 0.5f), half, 2).view());
    b.sample(flatGrid(-2, -2, 6, 6, 3, 3, 1.0f, Color(0.5f, 0, 0), half, 1).view());
    film::Film film = makeFilm(4, 4, "gaussian", 2.0f);
    b.resolve(film);
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 4; ++x) {
            const float* p = film.rgba(x, y);
            EXPECT_NEAR(p[0], 0.5f, 1e-6f);
            EXPECT_NEAR(p[1], 0.0f, 1e-6f);
            EXPECT_NEAR(p[2], 0.25f, 1e-6f);
            EXPECT_NEAR(p[3], 0.75f, 1e-6f);
            EXPECT_EQ(film.z(x, y), kInfinity);  // no opaque surface
        }
    // An opaque green layer behind both: it adds 0.25 of green; alpha 1.
    b.sample(flatGrid(-2, -2, 6, 6, 1, 1, 3.0f, Color(0, 1, 0), Color(1.0f), 3).view());
    b.resolve(film);
    EXPECT_NEAR(film.rgba(1, 2)[1], 0.25f, 1e-6f);
    EXPECT_NEAR(film.rgba(1, 2)[3], 1.0f, 1e-6f);
    EXPECT_EQ(film.z(1, 2), 3.0f);
    // An opaque layer in front hides everything.
    b.sample(flatGrid(-2, -2, 6, 6, 1, 1, 0.5f, Color(0.1f, 0.2f, 0.3f), Color(1.0f), 4).view());
    b.resolve(film);
    EXPECT_NEAR(film.rgba(3, 0)[0], 0.1f, 1e-6f);
    EXPECT_NEAR(film.rgba(3, 0)[2], 0.3f, 1e-6f);
    EXPECT_NEAR(film.rgba(3, 0)[3], 1.0f, 1e-6f);
}

TEST(SampleBuffer, EqualDepthTiesDoNotDependOnOrder) {
    const Color half(0.5f);
    TestGrid a = flatGrid(-1, -1, 5, 5, 3, 3, 1.0f, Color(0.5f, 0, 0), half, 7);
    TestGrid c = flatGrid(-1, -1, 5, 5, 2, 4, 1.0f, Color(0, 0.5f, 0), half, 3);
    TestGrid o1 = flatGrid(0.3f, -1, 5, 5, 2, 2, 2.0f, Color(0, 0, 1), Color(1.0f), 11);
    TestGrid o2 = flatGrid(-1, 1.7f, 5, 5, 3, 1, 2.0f, Color(1, 1, 0), Color(1.0f), 10);
    auto render = [&](std::vector<const TestGrid*> order) {
        SampleBuffer b;
        b.reset(config(0, 0, 4, 4, 1, 3, 3, true));
        for (const TestGrid* g : order) b.sample(g->view());
        film::Film film = makeFilm(4, 4, "gaussian", 2.0f);
        b.resolve(film);
        std::vector<float> px;
        for (int y = 0; y < 4; ++y)
            for (int x = 0; x < 4; ++x) px.insert(px.end(), film.rgba(x, y), film.rgba(x, y) + 4);
        return px;
    };
    std::vector<const TestGrid*> order = {&a, &c, &o1, &o2};
    std::vector<float> first = render(order);
    std::sort(order.begin(), order.end());
    int permutations = 0;
    do {
        std::vector<float> other = render(order);
        ASSERT_EQ(std::memcmp(first.data(), other.data(), first.size() * sizeof(float)), 0);
        ++permutations;
    } while (std::next_permutation(order.begin(), order.end()));
    EXPECT_EQ(permutations, 24);
    // Grid id 3 (green) is in front of id 7 (red) at equal depth; where
    // neither opaque grid is (pixel (0,0)), green + 0.5 red, alpha 0.75.
    SampleBuffer b;
    b.reset(config(0, 0, 4, 4, 1, 1, 1, false));
    b.sample(a.view());
    b.sample(c.view());
    film::Film film = makeFilm(4, 4, "box", 1.0f);
    b.resolve(film);
    EXPECT_FLOAT_EQ(film.rgba(0, 0)[0], 0.25f);
    EXPECT_FLOAT_EQ(film.rgba(0, 0)[1], 0.5f);
    EXPECT_FLOAT_EQ(film.rgba(0, 0)[3], 0.75f);
    // Opaque ties: the lower id wins, whatever the order.
    for (int k = 0; k < 2; ++k) {
        TestGrid p = flatGrid(-1, -1, 5, 5, 1, 1, 2.0f, Color(1, 0, 0), Color(1.0f), 5);
        TestGrid q = flatGrid(-1, -1, 5, 5, 1, 1, 2.0f, Color(0, 0, 1), Color(1.0f), 4);
        b.reset(config(0, 0, 4, 4, 1, 1, 1, false));
        b.sample((k ? p : q).view());
        b.sample((k ? q : p).view());
        b.resolve(film);
        EXPECT_EQ(film.rgba(2, 2)[2], 1.0f);
        EXPECT_EQ(film.rgba(2, 2)[0], 0.0f);
    }
}

TEST(SampleBuffer, HiddenMicropolygonsSkippedChangeNoDepth) {
    // Curved, tilted grids that pierce one another, sampled together
    // nearest first (so later micropolygons are often hidden at every
    // sample, or at whole groups of samples, and skipped), must leave at
    // each sample the nearest of the depths each grid gives when sampled
    // alone -- also along the lines where two grids cross, where a
    // micropolygon's visible part lies just behind its nearest vertex.
    Rng rng(77);
    std::vector<TestGrid> grids;
    for (int k = 0; k < 12; ++k) {
        const float x0 = rng.uniform() * 8, y0 = rng.uniform() * 8, base = 10.0f + rng.uniform() * 0.05f;
        const float bend = 0.001f * rng.uniform(), tilt = 0.02f * (rng.uniform() - 0.5f);
        grids.push_back(rectGrid(x0, y0, x0 + 6 + rng.uniform() * 4, y0 + 6 + rng.uniform() * 4, 7, 5,
                                 [=](float x, float y) { return base + tilt * y + bend * (x - 8) * (y - 8); },
                                 Color(1.0f), Color(1.0f), uint64_t(k + 1)));
    }
    std::sort(grids.begin(), grids.end(), [](const TestGrid& a, const TestGrid& b) {
        auto nearest = [](const TestGrid& g) {
            float z = kInfinity;
            for (const Vec3& p : g.P) z = std::min(z, p.z);
            return z;
        };
        return nearest(a) < nearest(b);
    });
    for (HiderMode mode : {HiderMode::Colour, HiderMode::Depth})
        for (bool perspective : {false, true}) {
            SampleBufferConfig c = config(0, 0, 16, 16, 0, mode == HiderMode::Depth ? 1 : 2,
                                          mode == HiderMode::Depth ? 1 : 2, mode == HiderMode::Colour, mode);
            c.perspective = perspective;
            SampleBuffer all, alone;
            all.reset(c);
            for (const TestGrid& g : grids) all.sample(g.view());
            std::vector<float> nearest;
            for (size_t k = 0; k < grids.size(); ++k) {
                alone.reset(c);
                alone.sample(grids[k].view());
                size_t n = 0;
                forEachSample(alone, [&](int px, int py, int s) {
                    const float z = alone.depth(px, py, s);
                    if (k == 0) nearest.push_back(z);
                    else nearest[n] = std::min(nearest[n], z);
                    ++n;
                });
            }
            size_t n = 0, covered = 0;
            forEachSample(all, [&](int px, int py, int s) {
                ASSERT_EQ(all.depth(px, py, s), nearest[n]) << "sample " << px << "," << py << "," << s;
                covered += nearest[n] != kInfinity;
                ++n;
            });
            EXPECT_GT(covered, n / 2);
        }
}

TEST(SampleBuffer, MatteHoldsOut) {
    SampleBuffer b;
    b.reset(config(0, 0, 8, 4, 1, 2, 2, true));
    b.sample(flatGrid(-1, -1, 9, 5, 2, 2, 2.0f, Color(1, 0, 0)).view());
    TestGrid matte = flatGrid(-1, -1, 4, 5, 2, 2, 1.0f, Color(0, 1, 0), Color(1.0f), 2);
    matte.matte = true;
    b.sample(matte.view());
    // A matte object behind the red one changes nothing.
    TestGrid behind = flatGrid(-1, -1, 9, 5, 1, 1, 3.0f, Color(0, 0, 1), Color(1.0f), 3);
    behind.matte = true;
    b.sample(behind.view());
    film::Film film = makeFilm(8, 4, "box", 1.0f);
    b.resolve(film);
    for (int y = 0; y < 4; ++y) {
        for (int x = 0; x < 4; ++x) {
            for (int k = 0; k < 4; ++k) EXPECT_EQ(film.rgba(x, y)[k], 0.0f);
            EXPECT_EQ(film.z(x, y), 1.0f);  // the matte surface is still the nearest opaque one
        }
        for (int x = 4; x < 8; ++x) {
            EXPECT_EQ(film.rgba(x, y)[0], 1.0f);
            EXPECT_EQ(film.rgba(x, y)[1], 0.0f);
            EXPECT_EQ(film.rgba(x, y)[3], 1.0f);
        }
    }
    // A 50% transparent matte in front: half the colour and half the alpha
    // of what is behind, and nothing of its own.
    b.reset(config(0, 0, 8, 4, 1, 2, 2, true));
    b.sample(flatGrid(-1, -1, 9, 5, 2, 2, 2.0f, Color(1, 0, 0)).view());
    TestGrid veil = flatGrid(-1, -1, 9, 5, 2, 2, 1.0f, Color(0, 0.5f, 0), Color(0.5f), 2);
    veil.matte = true;
    b.sample(veil.view());
    b.resolve(film);
    EXPECT_FLOAT_EQ(film.rgba(5, 2)[0], 0.5f);
    EXPECT_FLOAT_EQ(film.rgba(5, 2)[1], 0.0f);
    EXPECT_FLOAT_EQ(film.rgba(5, 2)[3], 0.5f);
}

TEST(SampleBuffer, OcclusionQuery) {
    SampleBuffer b;
    b.reset(config(16, 16, 32, 32, 1, 2, 2, true));
    Bound3 box({18, 18, 6}, {24, 24, 7});
    EXPECT_FALSE(b.occluded(box));
    EXPECT_EQ(b.maxOpaqueDepth(18, 18, 24, 24), kInfinity);
    // An opaque plane z = 5 over part of the buffer.
    b.sample(flatGrid(14, 14, 26.2f, 26.2f, 4, 4, 5.0f).view());
    EXPECT_EQ(b.maxOpaqueDepth(18, 18, 24, 24), 5.0f);
    EXPECT_TRUE(b.occluded(box));
    EXPECT_FALSE(b.occluded(Bound3({18, 18, 4.5f}, {24, 24, 7})));  // in front of the plane
    EXPECT_FALSE(b.occluded(Bound3({18, 18, 6}, {27, 24, 7})));      // reaches uncovered samples
    // Transparent surfaces do not occlude.
    b.sample(flatGrid(14, 14, 34, 34, 2, 2, 1.0f, Color(0.1f), Color(0.1f), 9).view());
    EXPECT_FALSE(b.occluded(Bound3({26.5f, 26.5f, 6}, {28, 28, 7})));
    // A nearer opaque plane lowers the bound.
    b.sample(flatGrid(14, 14, 34, 34, 2, 2, 3.0f, Color(1.0f), Color(1.0f), 2).view());
    EXPECT_EQ(b.maxOpaqueDepth(0, 0, 100, 100), 3.0f);
    EXPECT_TRUE(b.occluded(Bound3({0, 0, 3.5f}, {100, 100, 9})));
    // Outside the buffer: nothing to change here.
    EXPECT_TRUE(b.occluded(Bound3({100, 100, 0.1f}, {110, 110, 1})));
}

TEST(SampleBuffer, DepthModeKeepsNearestAndSecondSurface) {
    TestGrid near1 = flatGrid(-1, -1, 5, 5, 2, 2, 1.0f, Color(1.0f), Color(1.0f), 1);
    TestGrid near2 = flatGrid(-1, -1, 5, 5, 2, 2, 1.5f, Color(1.0f), Color(1.0f), 1);  // same grid id: not a new surface
    TestGrid back = flatGrid(-1, -1, 5, 5, 3, 3, 3.0f, Color(1.0f), Color(1.0f), 2);
    TestGrid farther = flatGrid(-1, -1, 5, 5, 1, 1, 4.0f, Color(1.0f), Color(1.0f), 3);
    std::vector<const TestGrid*> order = {&near1, &near2, &back, &farther};
    std::sort(order.begin(), order.end());
    do {
        SampleBuffer b;
        b.reset(config(0, 0, 4, 4, 1, 1, 1, false, HiderMode::Depth));
        for (const TestGrid* g : order) b.sample(g->view());
        film::Film film = makeFilm(4, 4, "box", 1.0f, {}, film::FilmContent::DepthPair);
        b.resolve(film);
        for (int y = 0; y < 4; ++y)
            for (int x = 0; x < 4; ++x) {
                ASSERT_EQ(film.z(x, y), 1.0f);
                ASSERT_EQ(film.z2(x, y), 3.0f);
            }
        EXPECT_TRUE(b.occluded(Bound3({0, 0, 3.5f}, {4, 4, 5})));
        EXPECT_FALSE(b.occluded(Bound3({0, 0, 2.5f}, {4, 4, 5})));
    } while (std::next_permutation(order.begin(), order.end()));
    // One surface only: z2 stays infinite.
    SampleBuffer b;
    b.reset(config(0, 0, 4, 4, 0, 1, 1, false, HiderMode::Depth));
    b.sample(near1.view());
    EXPECT_EQ(b.depth(2, 2, 0), 1.0f);
    EXPECT_EQ(b.secondDepth(2, 2, 0), kInfinity);
}

TEST(SampleBuffer, ClippingPlanesDiscardHits) {
    SampleBufferConfig c = config(0, 0, 4, 4, 0, 2, 2, true);
    c.nearClip = 1.0f;
    c.farClip = 10.0f;
    SampleBuffer b;
    b.reset(c);
    // z runs from 0 at x = 0 to 20 at x = 4: visible only for 1 <= z <= 10.
    b.sample(rectGrid(0, 0, 4, 4, 4, 4, [](float x, float) { return 5.0f * x; }).view());
    forEachSample(b, [&](int px, int py, int s) {
        Vec2 p = b.position(px, py, s);
        float z = 5.0f * p.x;
        bool visible = z >= 1.0f && z <= 10.0f;
        if (std::fabs(z - 1.0f) > 1e-4f && std::fabs(z - 10.0f) > 1e-4f) {
            EXPECT_EQ(b.depth(px, py, s) < kInfinity, visible) << p.x;
        }
    });
}

TEST(SampleBuffer, BoxFilterOfAConstantImageIsTheConstant) {
    SampleBuffer b;
    b.reset(config(8, 8, 24, 20, 1, 4, 4, true));
    const Color c(0.3f, 0.6f, 0.9f);
    b.sample(flatGrid(0, 0, 40, 40, 8, 8, 1.0f, c).view());
    film::Film film = makeFilm(40, 40, "box", 1.0f);
    b.resolve(film);
    for (int y = 8; y < 20; ++y)
        for (int x = 8; x < 24; ++x) {
            EXPECT_NEAR(film.rgba(x, y)[0], 0.3f, 1e-6f);
            EXPECT_NEAR(film.rgba(x, y)[1], 0.6f, 1e-6f);
            EXPECT_NEAR(film.rgba(x, y)[2], 0.9f, 1e-6f);
            EXPECT_NEAR(film.rgba(x, y)[3], 1.0f, 1e-6f);
        }
    // resolve() leaves pixels outside the bucket alone.
    EXPECT_EQ(film.rgba(7, 8)[3], 0.0f);
    EXPECT_EQ(film.rgba(24, 8)[3], 0.0f);
}

/// Closed forms of RenderMan's filters (RI spec 3.2 appendix, see pixel_filter.h).
static float referenceFilter(const std::string& name, float x, float y, float w) {
    float r = w / 2;
    if (std::fabs(x) > r || std::fabs(y) > r) return 0.0f;
    if (name == "box") return 1.0f;
    if (name == "triangle") return (1 - std::fabs(x) / r) * (1 - std::fabs(y) / r);
    if (name == "gaussian") {
        float xx = x * 2 / w, yy = y * 2 / w;
        return std::exp(-2 * (xx * xx + yy * yy));
    }
    if (name == "catmull-rom") {
        float xx = x * 4 / w, yy = y * 4 / w;
        float rr = std::sqrt(xx * xx + yy * yy);
        if (rr >= 2) return 0.0f;
        return rr < 1 ? 3 * rr * rr * rr - 5 * rr * rr + 2 : -rr * rr * rr + 5 * rr * rr - 8 * rr + 4;
    }
    auto sinc = [](float t) { return t == 0 ? 1.0f : std::sin(kPi * t) / (kPi * t); };
    return sinc(x) * sinc(x / r) * sinc(y) * sinc(y / r);
}

TEST(SampleBuffer, ResolveWeightsFollowTheFilter) {
    // One regular sample per pixel (at the pixel centre); only pixel (6, 6)'s
    // sample is lit. Pixel (6+dx, 6+dy) then holds f(-dx,-dy) / sum f over the
    // sample offsets reaching it.
    struct Case {
        const char* name;
        float width;
    };
    for (Case fc : {Case{"box", 3}, Case{"triangle", 4}, Case{"gaussian", 2}, Case{"gaussian", 3},
                    Case{"catmull-rom", 4}, Case{"sinc", 4}}) {
        SCOPED_TRACE(fc.name);
        SampleBuffer b;
        b.reset(config(0, 0, 13, 13, 2, 1, 1, false));
        b.sample(flatGrid(6.4f, 6.4f, 6.6f, 6.6f, 1, 1, 1.0f, Color(1.0f)).view());
        film::Film film = makeFilm(13, 13, fc.name, fc.width);
        b.resolve(film);
        float sum = 0;
        for (int ey = -2; ey <= 2; ++ey)
            for (int ex = -2; ex <= 2; ++ex) sum += referenceFilter(fc.name, float(ex), float(ey), fc.width);
        for (int dy = -3; dy <= 3; ++dy)
            for (int dx = -3; dx <= 3; ++dx) {
                float expect = referenceFilter(fc.name, float(-dx), float(-dy), fc.width) / sum;
                EXPECT_NEAR(film.rgba(6 + dx, 6 + dy)[0], expect, 2e-4f) << dx << "," << dy;
            }
    }
}

TEST(SampleBuffer, AovsAreInterpolatedAndFiltered) {
    SampleBuffer b;
    SampleBufferConfig c = config(0, 0, 4, 4, 1, 2, 2, true);
    c.aovCount = 4;
    b.reset(c);
    // AOV 0: a constant 2; AOVs 1..3: the raster position and 1 (linear, so
    // Gouraud interpolation reproduces it at each sample).
    TestGrid g = flatGrid(-2, -2, 6, 6, 4, 4, 1.0f, Color(0.5f));
    g.aovCount = 4;
    for (const Vec3& p : g.P) g.aov.insert(g.aov.end(), {2.0f, p.x, p.y, 1.0f});
    b.sample(g.view());
    film::Film film = makeFilm(4, 4, "box", 1.0f, {{"k", 1}, {"Pxy1", 3}});
    b.resolve(film);
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 4; ++x) {
            float ex = 0, ey = 0;
            for (int s = 0; s < 4; ++s) {
                ex += b.position(x, y, s).x / 4;
                ey += b.position(x, y, s).y / 4;
            }
            EXPECT_NEAR(film.aov(x, y)[0], 2.0f, 1e-6f);
            EXPECT_NEAR(film.aov(x, y)[1], ex, 1e-4f);
            EXPECT_NEAR(film.aov(x, y)[2], ey, 1e-4f);
            EXPECT_NEAR(film.aov(x, y)[3], 1.0f, 1e-6f);
        }
}

TEST(SampleBuffer, ResetReusesTheBufferForAnotherBucket) {
    SampleBuffer b;
    film::Film film = makeFilm(32, 16, "gaussian", 2.0f);
    TestGrid g = flatGrid(-5, -5, 40, 40, 6, 6, 1.0f, Color(0.25f));
    for (int bx = 0; bx < 32; bx += 16) {
        b.reset(config(bx, 0, bx + 16, 16, 1, 2, 2, true));
        b.sample(g.view());
        b.resolve(film);
    }
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 32; ++x) ASSERT_NEAR(film.rgba(x, y)[0], 0.25f, 1e-6f);
}

TEST(SampleBuffer, BufferPositionsAreSamplePositions) {
    // Buckets far from the origin and at negative pixels, where rounding
    // pixel + offset may need the sample moved back inside its stratum.
    for (int x0 : {-40, 100000, -70001}) {
        SampleBuffer b;
        SampleBufferConfig c = config(x0, -x0 / 2, x0 + 9, -x0 / 2 + 7, 2, 3, 5, true);
        b.reset(c);
        forEachSample(b, [&](int px, int py, int s) {
            Vec2 p = b.position(px, py, s), ref = SampleBuffer::samplePosition(px, py, s, 3, 5, true, c.frameSeed);
            ASSERT_EQ(p.x, ref.x) << px << "," << py << " " << s;
            ASSERT_EQ(p.y, ref.y) << px << "," << py << " " << s;
        });
    }
}

namespace {

/// Renders a jittered frame of opaque, transparent and matte grids bucket
/// by bucket; the buffer carries aovCount (unused, zero) AOV floats.
std::vector<float> renderBuckets(const char* filter, float width, int bucketW, int bucketH, int aovCount) {
    const int w = 37, h = 23;
    std::vector<film::AovChannel> aovs;
    if (aovCount > 0) aovs.push_back({"k", aovCount});
    film::Film film = makeFilm(w, h, filter, width, aovs);
    const int margin = film.filter().margin();
    TestGrid back = rectGrid(-3, -2, 40, 26, 9, 7, [](float x, float y) { return 5 + 0.05f * x + 0.02f * y; },
                             Color(0.2f, 0.5f, 0.9f), Color(1.0f), 1);
    for (Vec3& p : back.P) p.x += 0.3f * std::sin(p.y);
    TestGrid veil = flatGrid(4.3f, 3.1f, 30.7f, 19.4f, 5, 4, 2.0f, Color(0.4f, 0.1f, 0), Color(0.5f), 2);
    TestGrid disc = flatGrid(11.2f, 6.6f, 19.9f, 15.3f, 3, 3, 1.0f, Color(0.9f, 0.8f, 0.1f), Color(1.0f), 3);
    TestGrid matte = flatGrid(24.1f, 1.3f, 33.5f, 9.8f, 2, 2, 1.5f, Color(1.0f), Color(1.0f), 4);
    matte.matte = true;
    SampleBuffer b;
    for (int y0 = 0; y0 < h; y0 += bucketH)
        for (int x0 = 0; x0 < w; x0 += bucketW) {
            SampleBufferConfig c =
                config(x0, y0, std::min(x0 + bucketW, w), std::min(y0 + bucketH, h), margin, 3, 2, true);
            c.aovCount = aovCount;
            b.reset(c);
            for (const TestGrid* g : {&back, &veil, &disc, &matte}) b.sample(g->view());
            b.resolve(film);
        }
    std::vector<float> pixels;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) pixels.insert(pixels.end(), film.rgba(x, y), film.rgba(x, y) + 4);
    return pixels;
}

}  // namespace

TEST(SampleBuffer, ResolveDoesNotDependOnBucketSizeOrAovs) {
    // Sums run in one fixed order whatever the buckets, and the general
    // (AOV) path filters with the same weights as the colour-only one: the
    // pixels are bit-identical.
    struct Case {
        const char* name;
        float width;
    };
    for (Case fc : {Case{"gaussian", 2}, Case{"sinc", 4}, Case{"box", 1}, Case{"catmull-rom", 4}}) {
        SCOPED_TRACE(fc.name);
        std::vector<float> reference = renderBuckets(fc.name, fc.width, 16, 16, 0);
        for (int bw : {5, 37})
            for (int bh : {3, 16}) {
                std::vector<float> other = renderBuckets(fc.name, fc.width, bw, bh, 0);
                EXPECT_EQ(std::memcmp(reference.data(), other.data(), reference.size() * sizeof(float)), 0)
                    << bw << "x" << bh;
            }
        std::vector<float> withAovs = renderBuckets(fc.name, fc.width, 7, 9, 2);
        EXPECT_EQ(std::memcmp(reference.data(), withAovs.data(), reference.size() * sizeof(float)), 0);
        // Something was drawn.
        EXPECT_GT(*std::max_element(reference.begin(), reference.end()), 0.5f);
    }
}

/// Moving grids hit the same samples at the same depths whether each time
/// stratum is bounded on its own or the whole swept bound is tested: two
/// keys (translating and deforming, keys inside and beyond the shutter),
/// three keys along a bent path, opaque and transparent, both modes.
/// Strata against testing every sample: the same depth (and fragments)
/// at every sample, at least `minHits` of them hit, the same hits in less
/// than half the tests.
void expectSameHitsInFewerTests(SampleBuffer& strata, SampleBuffer& every, HiderMode mode, int minHits) {
    int hit = 0;
    forEachSample(every, [&](int px, int py, int s) {
        EXPECT_EQ(strata.depth(px, py, s), every.depth(px, py, s)) << px << "," << py << " sample " << s;
        if (mode == HiderMode::Colour) {
            EXPECT_EQ(strata.fragmentCount(px, py, s), every.fragmentCount(px, py, s));
        }
        hit += every.depth(px, py, s) < kInfinity;
    });
    EXPECT_GT(hit, minHits);
    EXPECT_EQ(strata.blurStats().sampleHits, every.blurStats().sampleHits);
    EXPECT_LT(strata.blurStats().sampleTests, every.blurStats().sampleTests / 2);
}

/// Two buffers for `c` under motion: one that bounds each time stratum
/// and one that tests every sample a micropolygon sweeps over.
void resetStrataAndEvery(SampleBuffer& strata, SampleBuffer& every, SampleBufferConfig c) {
    c.motion = true;
    strata.reset(c);
    c.sampleStrata = false;
    every.reset(c);
}

/// `base` moved by offsets[k] (and 0.1 k deeper) at its k-th key.
TestGrid keyedGrid(const TestGrid& base, const std::vector<Vec2>& offsets) {
    TestGrid g = base;
    g.P.clear();
    for (size_t k = 0; k < offsets.size(); ++k)
        for (const Vec3& p : base.P) g.P.push_back({p.x + offsets[k].x, p.y + offsets[k].y, p.z + 0.1f * float(k)});
    return g;
}

/// Samples `grid`, keyed at `times` (one per key), into both buffers.
void sampleBoth(SampleBuffer& strata, SampleBuffer& every, const TestGrid& grid, const float* times, int keys) {
    MicroGrid g = grid.view();
    g.keyCount = keys;
    g.keyTimes = times;
    strata.sample(g);
    every.sample(g);
}

TEST(SampleBuffer, TimeStrataHitWhatEverySampleWould) {
    struct Moving {
        TestGrid grid;
        std::vector<float> times;
    };
    auto moving = [](const std::vector<float>& times, const std::vector<Vec2>& offsets, float spread, Color oi,
                     uint64_t id) {
        Moving m;
        m.times = times;
        TestGrid base = flatGrid(2.3f, 3.1f, 7.9f, 8.6f, 4, 3, 2.0f, Color(0.5f), oi, id);
        m.grid = base;
        m.grid.P.clear();
        for (size_t k = 0; k < times.size(); ++k)
            for (size_t v = 0; v < base.P.size(); ++v) {
                const Vec3 p = base.P[v];
                // Each key moves the grid and stretches it by k * spread.
                m.grid.P.push_back({p.x + offsets[k].x + float(k) * spread * (p.x - 5.0f), p.y + offsets[k].y,
                                    p.z + 0.25f * float(k)});
            }
        return m;
    };
    const std::vector<Moving> grids = {
        moving({0.0f, 1.0f}, {{0, 0}, {13.5f, 4.25f}}, 0.0f, Color(1.0f), 1),
        moving({0.0f, 1.0f}, {{9, 1}, {-6, 7}}, 0.3f, Color(0.5f), 2),
        moving({-0.5f, 1.5f}, {{-4, 10}, {20, -6}}, 0.1f, Color(1.0f), 3),
        moving({0.0f, 0.3f, 1.0f}, {{1, 1}, {12, 2}, {6, 11}}, 0.2f, Color(0.5f), 4),
    };
    for (HiderMode mode : {HiderMode::Colour, HiderMode::Depth}) {
        SampleBuffer strata, every;
        resetStrataAndEvery(strata, every, config(0, 0, 16, 16, 1, 4, 4, true, mode));
        for (const Moving& m : grids) sampleBoth(strata, every, m.grid, m.times.data(), int(m.times.size()));
        expectSameHitsInFewerTests(strata, every, mode, 500);  // the grids cover a good part of the bucket
    }
}

/// One sample a pixel, as a depth map has: a pixel holds one time, so the
/// strata are a kTimeTile x kTimeTile tile's fine ones, one sample of the
/// tile in each. Bounding each of them on its own hits the same samples at
/// the same depths as testing every sample the micropolygons sweep over,
/// in a bucket that does not start on a tile: grids crossing most of it
/// during the shutter (a caster close to its light), one moving a little,
/// two keys and three, keys beyond the shutter.
TEST(SampleBuffer, DepthMapTimeStrataHitWhatEverySampleWould) {
    const float twoKeys[2] = {0.0f, 1.0f}, beyond[2] = {-0.5f, 1.5f}, threeKeys[3] = {0.0f, 0.4f, 1.0f};
    for (HiderMode mode : {HiderMode::Depth, HiderMode::Colour}) {
        SampleBuffer strata, every;
        resetStrataAndEvery(strata, every, config(3, 5, 40, 34, 1, 1, 1, true, mode));
        sampleBoth(strata, every,
                   keyedGrid(flatGrid(-30.0f, 6.0f, -10.0f, 14.0f, 12, 6, 2.0f, Color(0.5f), Color(1.0f), 1),
                             {{0, 0}, {70, 9}}),
                   twoKeys, 2);
        sampleBoth(strata, every,
                   keyedGrid(flatGrid(10.0f, 20.0f, 22.0f, 30.0f, 8, 8, 3.0f, Color(0.5f), Color(1.0f), 2),
                             {{-3, 0}, {5, -4}}),
                   beyond, 2);
        sampleBoth(strata, every,
                   keyedGrid(flatGrid(30.0f, -20.0f, 36.0f, -5.0f, 4, 10, 1.5f, Color(0.5f), Color(1.0f), 3),
                             {{0, 0}, {-20, 30}, {-5, 55}}),
                   threeKeys, 3);
        expectSameHitsInFewerTests(strata, every, mode, 150);
        // The fast grids sweep over tens of pixels in a row; a stratum's
        // share of that is a few.
        EXPECT_LT(strata.blurStats().sampleTests, every.blurStats().sampleTests / 4);
    }
}

/// Four motion keys (a turn exported as several samples): a stratum that
/// lies inside one key segment is bounded, and each of its samples
/// checked, by that segment's linear motion, as two keys' are; the same
/// hits as testing every sample, in a fraction of the exact tests.
TEST(SampleBuffer, KeySegmentsBoundTheirStrataAsTwoKeysDo) {
    const float times[4] = {0.0f, 0.3f, 0.55f, 1.0f};
    const TestGrid g = keyedGrid(flatGrid(1.3f, 0.6f, 5.9f, 4.2f, 5, 4, 2.0f, Color(0.5f), Color(1.0f), 1),
                                 {{0, 0}, {9, 3}, {14, 11}, {4, 17}});
    for (HiderMode mode : {HiderMode::Colour, HiderMode::Depth}) {
        SampleBuffer strata, every;
        resetStrataAndEvery(strata, every, config(0, 0, 24, 24, 1, 4, 4, true, mode));
        sampleBoth(strata, every, g, times, 4);
        expectSameHitsInFewerTests(strata, every, mode, 200);  // the grid covers about 16.5 pixels
        // Checked against its segment's bound at its own time, about 1.6
        // samples are tested a hit (5.7 by the strata's boxes alone).
        EXPECT_LT(strata.blurStats().sampleTests, strata.blurStats().sampleHits * 5 / 2);
    }
}

/// Per-grid motion bounds (SampleBuffer::boundMotion): a micropolygon is
/// rasterized in a bucket only when its bound at some sample's time reaches
/// the bucket's region. A grid sweeping diagonally across nine buckets (its
/// swept box covers them all, its path only the diagonal), another moving
/// only in the middle of the shutter (keys beyond it) and a deforming one
/// hit the same samples at the same depths as testing every sample of the
/// swept bound, bucket by bucket, while fewer micropolygons are visited.
TEST(SampleBuffer, MotionBoundsSkipOnlyWhatCannotHit) {
    struct Moving {
        TestGrid grid;
        std::vector<float> times;
    };
    auto moving = [](TestGrid base, const std::vector<float>& times, Vec2 motion, float stretch) {
        Moving m;
        m.times = times;
        m.grid = base;
        m.grid.P.clear();
        for (size_t k = 0; k < 2; ++k)
            for (const Vec3& p : base.P)
                m.grid.P.push_back({p.x + float(k) * (motion.x + stretch * (p.x - 6.0f)),
                                    p.y + float(k) * motion.y, p.z + 0.5f * float(k)});
        return m;
    };
    const std::vector<Moving> grids = {
        // 1 x 1 pixel micropolygons from the bottom-left corner to the top-right one.
        moving(flatGrid(-2.0f, 38.0f, 10.0f, 50.0f, 12, 12, 3.0f, Color(0.5f), Color(1.0f), 1), {0.0f, 1.0f},
               {40.0f, -40.0f}, 0.0f),
        moving(flatGrid(1.5f, 2.5f, 9.5f, 8.5f, 8, 6, 2.0f, Color(0.5f), Color(0.5f), 2), {-1.0f, 2.0f},
               {90.0f, 60.0f}, 0.0f),
        moving(flatGrid(20.0f, 4.0f, 28.0f, 12.0f, 8, 8, 4.0f, Color(0.5f), Color(1.0f), 3), {0.0f, 1.0f},
               {-14.0f, 30.0f}, 0.5f),
    };
    hider::BlurStats strataStats, everyStats;
    int hit = 0;
    for (HiderMode mode : {HiderMode::Colour, HiderMode::Depth})
        for (int by = 0; by < 48; by += 16)
            for (int bx = 0; bx < 48; bx += 16) {
                SampleBuffer strata, every;
                SampleBufferConfig c = config(bx, by, bx + 16, by + 16, 1, 4, 4, true, mode);
                c.motion = true;
                strata.reset(c);
                c.sampleStrata = false;
                every.reset(c);
                for (const Moving& m : grids) {
                    MicroGrid g = m.grid.view();
                    g.keyCount = 2;
                    g.keyTimes = m.times.data();
                    strata.sample(g);
                    every.sample(g);
                }
                forEachSample(every, [&](int px, int py, int s) {
                    ASSERT_EQ(strata.depth(px, py, s), every.depth(px, py, s))
                        << "bucket " << bx << "," << by << " pixel " << px << "," << py << " sample " << s;
                    if (mode == HiderMode::Depth) {
                        ASSERT_EQ(strata.secondDepth(px, py, s), every.secondDepth(px, py, s));
                    } else {
                        ASSERT_EQ(strata.fragmentCount(px, py, s), every.fragmentCount(px, py, s));
                    }
                    hit += every.depth(px, py, s) < kInfinity;
                });
                EXPECT_EQ(strata.blurStats().sampleHits, every.blurStats().sampleHits) << bx << "," << by;
                strataStats.micropolygons += strata.blurStats().micropolygons;
                everyStats.micropolygons += every.blurStats().micropolygons;
                strataStats.sampleTests += strata.blurStats().sampleTests;
                everyStats.sampleTests += every.blurStats().sampleTests;
            }
    EXPECT_GT(hit, 3000);  // the grids cover a good part of the buckets
    // The diagonal grid's swept box reaches every bucket, its path three
    // of them and their neighbours' margins: most visits are skipped.
    EXPECT_LT(strataStats.micropolygons, everyStats.micropolygons * 2 / 3);
    EXPECT_LT(strataStats.sampleTests, everyStats.sampleTests / 4);
}

/// Motion blur's times: each pixel's n samples take one each of n strata
/// of the shutter (each row and column of them spread over it), the pixels of each kTimeTile x kTimeTile tile take one
/// each of the n * kTimeTile^2 finer strata between them, and a sample's
/// time is uncorrelated with its place in the pixel.
TEST(SampleBuffer, TimesAreStratifiedPerPixelAndPerTile) {
    SampleBufferConfig c = config(0, 0, 16, 16, 0, 4, 4, true);
    c.motion = true;
    const int n = 16, tile = hider::kTimeTile, fine = n * tile * tile;
    double sumXT = 0, sumX = 0, sumT = 0, sumXX = 0, sumTT = 0;
    int count = 0;
    for (int ty = 0; ty < 4; ++ty)
        for (int tx = 0; tx < 4; ++tx) {
            std::vector<int> fineHits(size_t(fine), 0);
            for (int py = ty * tile; py < (ty + 1) * tile; ++py)
                for (int px = tx * tile; px < (tx + 1) * tile; ++px) {
                    std::vector<int> coarse(size_t(n), 0);
                    double pixelMean = 0;
                    // Each row and each column of the pixel's 4 x 4 samples
                    // takes one time from each quarter of the shutter.
                    int rowQuarters[4] = {0, 0, 0, 0}, columnQuarters[4] = {0, 0, 0, 0};
                    for (int s = 0; s < n; ++s) {
                        const float t = SampleBuffer::sampleTime(px, py, s, c);
                        pixelMean += double(t) / n;
                        rowQuarters[s / 4] |= 1 << int(t * 4);
                        columnQuarters[s % 4] |= 1 << int(t * 4);
                        ASSERT_GE(t, 0.0f);
                        ASSERT_LT(t, 1.0f);
                        ++coarse[size_t(std::floor(t * float(n)))];
                        ++fineHits[size_t(std::floor(t * float(fine)))];
                        const double x = double(s % 4) + 0.5;
                        sumX += x;
                        sumT += t;
                        sumXT += x * t;
                        sumXX += x * x;
                        sumTT += double(t) * t;
                        ++count;
                    }
                    for (int k = 0; k < n; ++k) EXPECT_EQ(coarse[size_t(k)], 1) << px << "," << py << " stratum " << k;
                    // The pixel's samples spread over the fine strata too: their
                    // mean is the middle of the shutter to within half a fine
                    // stratum (the jitter's mean is all that is left).
                    EXPECT_LT(std::abs(pixelMean - 0.5), 0.5 / fine + 1e-6) << px << "," << py;
                    for (int r = 0; r < 4; ++r) {
                        EXPECT_EQ(rowQuarters[r], 15) << px << "," << py << " row " << r;
                        EXPECT_EQ(columnQuarters[r], 15) << px << "," << py << " column " << r;
                    }
                }
            for (int k = 0; k < fine; ++k) EXPECT_EQ(fineHits[size_t(k)], 1) << "tile " << tx << "," << ty << " " << k;
        }
    const double cov = sumXT / count - (sumX / count) * (sumT / count);
    const double sx = std::sqrt(sumXX / count - std::pow(sumX / count, 2));
    const double st = std::sqrt(sumTT / count - std::pow(sumT / count, 2));
    EXPECT_LT(std::abs(cov / (sx * st)), 0.1);  // 4096 samples: |r| ~ 0.016 if independent
}

/// Defocused grids likewise: bounding each lens stratum on its own hits the
/// same samples at the same depths as testing the whole circle of
/// confusion, for grids in front of, at and behind the focal plane.
TEST(SampleBuffer, LensAndTimeStrataHitWhatEverySampleWouldOnMovingDefocusedGrids) {
    // Moving grids seen through a lens: those whose circle of confusion
    // outgrows their sweep are bounded by the lens strata, the others by
    // the time strata (rasterizeBlurred); either way the same samples hit
    // as testing every one, with fewer tests.
    for (HiderMode mode : {HiderMode::Colour, HiderMode::Depth}) {
        SampleBuffer strata, every;
        SampleBufferConfig c = config(0, 0, 16, 16, 1, 4, 4, true, mode);
        c.perspective = true;
        c.lens = true;
        c.motion = true;
        c.lensScaleX = 40.0f;
        c.lensScaleY = -40.0f;
        c.inverseFocalDistance = 1.0f / 4.0f;
        strata.reset(c);
        c.sampleStrata = false;
        every.reset(c);
        const float times[2] = {0.0f, 1.0f};
        uint64_t id = 1;
        for (float z : {2.0f, 3.5f, 4.0f, 6.0f, 20.0f})
            for (float move : {0.5f, 9.0f}) {  // a little (the lens leads), far (the shutter leads)
                TestGrid g = rectGrid(1.5f + z * 0.3f, 2.5f, 9.0f + z * 0.2f, 11.0f, 3, 4,
                                      [z](float x, float) { return z + 0.05f * x; }, Color(0.5f),
                                      Color(id % 2 ? 1.0f : 0.5f), id);
                ++id;
                const size_t n = g.P.size();
                for (size_t v = 0; v < n; ++v) g.P.push_back({g.P[v].x + move, g.P[v].y + 0.3f * move, g.P[v].z});
                MicroGrid view = g.view();
                view.keyCount = 2;
                view.keyTimes = times;
                strata.sample(view);
                every.sample(view);
            }
        expectSameHitsInFewerTests(strata, every, mode, 1500);
    }
}

TEST(SampleBuffer, LensStrataHitWhatEverySampleWould) {
    for (HiderMode mode : {HiderMode::Colour, HiderMode::Depth}) {
        SampleBuffer strata, every;
        SampleBufferConfig c = config(0, 0, 16, 16, 1, 4, 4, true, mode);
        c.perspective = true;
        c.lens = true;
        c.lensScaleX = 40.0f;  // raster pixels per unit of (1/focaldistance - 1/z) at the lens's rim
        c.lensScaleY = -40.0f;
        c.inverseFocalDistance = 1.0f / 4.0f;
        strata.reset(c);
        c.sampleStrata = false;
        every.reset(c);
        uint64_t id = 1;
        for (float z : {2.0f, 3.5f, 4.0f, 6.0f, 20.0f}) {
            // Tilted in depth, so each grid's corners blur by different amounts.
            TestGrid g = rectGrid(1.5f + z * 0.3f, 2.5f, 9.0f + z * 0.2f, 11.0f, 3, 4,
                                  [z](float x, float) { return z + 0.05f * x; }, Color(0.5f),
                                  Color(id % 2 ? 1.0f : 0.5f), id);
            ++id;
            strata.sample(g.view());
            every.sample(g.view());
        }
        expectSameHitsInFewerTests(strata, every, mode, 1500);
    }
}
