#include "../geometry/geometry_test_util.h"

#include "umbra/dice/reyes.h"
#include "umbra/geometry/primvars.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>

using namespace umbra;
using namespace umbra::dice;
using namespace umbra::geometry;
using namespace umbra::testutil;

namespace {

constexpr float kW = 640, kH = 480;

// A 90-degree perspective camera looking down +z: raster = (320 + 320 x/z, 240 - 320 y/z).
/// An orthographic view of `pixelsPerUnit` pixels a unit, looking down z,
/// whose raster window is [-halfWindow, halfWindow] each way (unbounded by
/// default).
DiceParams orthographic(float pixelsPerUnit, float halfWindow = kInfinity) {
    DiceParams p;
    p.orthographic = true;
    p.rasterFromCamera = Mat4::scale({pixelsPerUnit, pixelsPerUnit, 1});
    p.nearClip = -100;
    p.rasterWindow[0] = p.rasterWindow[2] = -halfWindow;
    p.rasterWindow[1] = p.rasterWindow[3] = halfWindow;
    return p;
}

DiceParams perspective(const Mat4& cameraFromObject = Mat4::identity()) {
    DiceParams p;
    p.cameraFromObject = cameraFromObject;
    Mat4& m = p.rasterFromCamera;
    m = Mat4{};
    m.m[0][0] = kW / 2; m.m[0][2] = kW / 2;
    m.m[1][1] = -kW / 2; m.m[1][2] = kH / 2;
    m.m[2][2] = 1; m.m[2][3] = 0;
    m.m[3][2] = 1; m.m[3][3] = 0;
    p.rasterWindow[0] = 0; p.rasterWindow[1] = kW;
    p.rasterWindow[2] = 0; p.rasterWindow[3] = kH;
    return p;
}

PrimitivePtr quad(Vec3 a, Vec3 b, Vec3 c, Vec3 d) {
    Diagnostics diag;
    auto prims = makePrimitives(record("Polygon", {}, {pointParam({a.x, a.y, a.z, b.x, b.y, b.z, c.x, c.y, c.z, d.x, d.y, d.z})}), diag);
    EXPECT_EQ(prims.size(), 1u);
    return std::move(prims[0]);
}

PrimitivePtr make(const std::string& type, std::vector<float> args) {
    Diagnostics diag;
    auto prims = makePrimitives(record(type, std::move(args)), diag);
    EXPECT_EQ(prims.size(), 1u);
    return std::move(prims[0]);
}

std::vector<Vec3> toRaster(const Grid& g, const DiceParams& p) {
    std::vector<Vec3> r;
    for (const Vec3& q : g.P) r.push_back(p.rasterFromCamera.point(p.cameraFromObject.point(q)));
    return r;
}

// Mean raster length of the u edges and of the v edges of a grid.
void meanEdges(const Grid& g, const DiceParams& p, double* mu, double* mv) {
    const auto r = toRaster(g, p);
    double su = 0, sv = 0;
    for (int j = 0; j <= g.nv; ++j)
        for (int i = 0; i < g.nu; ++i) su += std::hypot(r[size_t(g.index(i + 1, j))].x - r[size_t(g.index(i, j))].x, r[size_t(g.index(i + 1, j))].y - r[size_t(g.index(i, j))].y);
    for (int j = 0; j < g.nv; ++j)
        for (int i = 0; i <= g.nu; ++i) sv += std::hypot(r[size_t(g.index(i, j + 1))].x - r[size_t(g.index(i, j))].x, r[size_t(g.index(i, j + 1))].y - r[size_t(g.index(i, j))].y);
    *mu = su / ((g.nv + 1) * g.nu);
    *mv = sv / ((g.nu + 1) * g.nv);
}

// The REYES loop: bound, cull / split / dice until nothing is left.
int runReyes(std::vector<PrimitivePtr> prims, const DiceParams& p, Diagnostics* diag,
             const std::function<void(const Primitive&, const DiceResult&)>& onDice) {
    std::vector<std::pair<PrimitivePtr, int>> work;
    for (auto& q : prims) work.emplace_back(std::move(q), 0);
    int steps = 0;
    while (!work.empty() && ++steps < 100000) {
        auto [prim, eye] = std::move(work.back());
        work.pop_back();
        const DiceResult r = decide(*prim, p, eye, diag);
        if (r.decision == Decision::Dice) onDice(*prim, r);
        if (r.decision != Decision::Split) continue;
        std::vector<PrimitivePtr> kids;
        prim->split(r.splitU, kids);
        for (auto& k : kids) work.emplace_back(std::move(k), eye + (r.eyeSplit ? 1 : 0));
    }
    return steps;
}

}  // namespace

TEST(Dice, MicropolygonsAreAboutShadingRatePixels) {
    for (float rate : {1.0f, 4.0f, 0.5f}) {
        DiceParams p = perspective(Mat4::translate({0, 0, 10}) * Mat4::rotate(40, {0, 1, 0}));
        p.shadingRate = rate;
        p.gridSize = 1 << 20;
        auto q = quad({-0.3f, -0.2f, 0}, {0.3f, -0.2f, 0}, {0.3f, 0.2f, 0}, {-0.3f, 0.2f, 0});
        const DiceResult r = decide(*q, p);
        ASSERT_EQ(r.decision, Decision::Dice);
        double mu, mv;
        meanEdges(q->dice(r.nu, r.nv), p, &mu, &mv);
        EXPECT_NEAR(mu / std::sqrt(rate), 1.0, 0.2) << rate;
        EXPECT_NEAR(mv / std::sqrt(rate), 1.0, 0.2) << rate;
    }
}

TEST(Dice, TooBigSplitsAcrossTheLongerDirection) {
    DiceParams p = perspective(Mat4::translate({0, 0, 10}));
    auto wide = quad({-2, -0.5f, 0}, {2, -0.5f, 0}, {2, 0.5f, 0}, {-2, 0.5f, 0});
    DiceResult r = decide(*wide, p);
    EXPECT_EQ(r.decision, Decision::Split);
    EXPECT_TRUE(r.splitU);
    auto tall = quad({-0.5f, -2, 0}, {0.5f, -2, 0}, {0.5f, 2, 0}, {-0.5f, 2, 0});
    r = decide(*tall, p);
    EXPECT_EQ(r.decision, Decision::Split);
    EXPECT_FALSE(r.splitU);
}

TEST(Dice, APieceWhoseSplitBudgetIsSpentIsDicedIntoOneGridWithAWarning) {
    // A quad 64 x 32 pixels (orthographic, 16 pixels a unit): 2048
    // micropolygons at rate 1, 512 at rate 4, more than a grid of 256.
    // It splits while its budget holds two grids' worth of pixels
    // (2 x rate x 256); with less it is diced into one grid of the same
    // proportions, coarser than the rate, and the user is told once.
    DiceParams p = orthographic(16);
    auto q = quad({-2, -1, 5}, {2, -1, 5}, {2, 1, 5}, {-2, 1, 5});
    for (const float rate : {1.0f, 4.0f}) {
        p.shadingRate = rate;
        const double twoGrids = 2.0 * rate * p.gridSize;
        Diagnostics diag;
        diag.setRecord(true);
        diag.setSink([](const Diagnostic&) {});
        for (const double budget : {double(kInfinity), twoGrids}) {
            p.splitBudget = budget;
            const DiceResult r = decide(*q, p, 0, &diag);
            EXPECT_EQ(r.decision, Decision::Split) << rate << " " << budget;
            EXPECT_TRUE(r.splitU);
        }
        EXPECT_EQ(diag.warningCount(), 0);
        for (const double budget : {twoGrids * 0.99, 0.0}) {
            p.splitBudget = budget;
            const DiceResult r = decide(*q, p, 0, &diag);
            ASSERT_EQ(r.decision, Decision::Dice) << rate << " " << budget;
            EXPECT_LE(r.nu * r.nv, p.gridSize);
            EXPECT_GE(r.nu * r.nv, p.gridSize / 2);  // as fine as one grid allows
            EXPECT_NEAR(r.nu, 2 * r.nv, 1);          // the quad's proportions
        }
        ASSERT_EQ(diag.warningCount(), 1);
        EXPECT_NE(diag.recorded()[0].message.find("would cover the frame many times over"), std::string::npos);
        // A piece that needs no more than one grid's worth of pixels in
        // the frame (the rest of it off the frame) loses nothing by being
        // diced into one grid: no warning.
        Diagnostics quiet;
        quiet.setRecord(true);
        quiet.setSink([](const Diagnostic&) {});
        p.splitBudget = 0;
        p.pieceNeed = rate * p.gridSize;
        EXPECT_EQ(decide(*q, p, 0, &quiet).decision, Decision::Dice);
        EXPECT_EQ(quiet.warningCount(), 0);
        p.pieceNeed = kInfinity;
    }
}

TEST(Dice, RasterNeedIsTheAreaInTheWindowAndAStripAlongEachSideCrossed) {
    // A quad 64 x 32 pixels (orthographic, 16 pixels a unit, x from -32
    // to 32). Inside the window its need is its area; across the window's
    // left side (x = 0) it is the part inside, 32 x 32, and a strip a
    // grid's side wide (sqrt(256 x rate 1) = 16) along the 32 pixels of
    // that side. Its two halves add up to it, and so would any tiling.
    DiceParams p = orthographic(16, 100);
    auto q = quad({-2, -1, 5}, {2, -1, 5}, {2, 1, 5}, {-2, 1, 5});
    EXPECT_NEAR(rasterNeed(*q, p), 64.0 * 32.0, 1e-3);
    p.rasterWindow[0] = 0;
    EXPECT_NEAR(rasterNeed(*q, p), 32.0 * 32.0 + 16.0 * 32.0, 1e-3);
    std::vector<PrimitivePtr> halves;
    q->split(true, halves);
    ASSERT_EQ(halves.size(), 2u);
    EXPECT_NEAR(rasterNeed(*halves[0], p) + rasterNeed(*halves[1], p), rasterNeed(*q, p), 1e-3);
    // A rectangle facing the camera fills its bound, so the most its bound
    // can need is what it needs; a larger shading rate widens the strip
    // to a grid's side at that rate, sqrt(256 x 4) = 32.
    EXPECT_NEAR(boundNeed(rasterBound(q->bound(), p), p), 32.0 * 32.0 + 16.0 * 32.0, 1e-3);
    p.shadingRate = 4;
    EXPECT_NEAR(boundNeed(rasterBound(q->bound(), p), p), 32.0 * 32.0 + 32.0 * 32.0, 1e-3);
    EXPECT_NEAR(rasterNeed(*q, p), 32.0 * 32.0 + 32.0 * 32.0, 1e-3);
    p.shadingRate = 1;
    EXPECT_EQ(boundNeed(Bound3{}, p), 0.0);
    // A quad seen edge-on, inside the window, needs nothing.
    auto edgeOn = quad({-2, -1, 5}, {2, -1, 5}, {2, -1, 6}, {-2, -1, 6});
    p.rasterWindow[0] = -100;
    EXPECT_NEAR(rasterNeed(*edgeOn, p), 0.0, 1e-3);
    // Not measurable: behind a perspective eye.
    DiceParams persp = perspective(Mat4::translate({0, 0, -5.5f}));
    EXPECT_LT(rasterNeed(*q, persp), 0);
}

TEST(Dice, LoopRespectsGridSizeAndShadingRateOnASphere) {
    DiceParams p = perspective(Mat4::translate({0.5f, 0, 6}));
    p.shadingRate = 2;
    p.gridSize = 64;
    int grids = 0;
    runReyes([] { std::vector<PrimitivePtr> v; v.push_back(make("Sphere", {1, -1, 1, 360})); return v; }(), p, nullptr,
             [&](const Primitive& prim, const DiceResult& r) {
                 ++grids;
                 EXPECT_LE(r.nu * r.nv, p.gridSize);
                 Grid g = prim.dice(r.nu, r.nv);
                 const auto ras = toRaster(g, p);
                 float lu, lv;
                 rasterLengths(ras.data(), g.nu, g.nv, &lu, &lv);
                 // The longest row and column, shared among nu (nv) edges, come out near sqrt(rate).
                 EXPECT_LE(lu / float(g.nu), std::sqrt(p.shadingRate) * 1.2f);
                 EXPECT_LE(lv / float(g.nv), std::sqrt(p.shadingRate) * 1.2f);
             });
    EXPECT_GT(grids, 4);
}

TEST(Dice, CullsOutsideTheViewAndTheClippingRange) {
    auto sphere = make("Sphere", {1, -1, 1, 360});
    DiceParams behind = perspective(Mat4::translate({0, 0, -10}));
    EXPECT_EQ(decide(*sphere, behind).decision, Decision::Cull);
    DiceParams right = perspective(Mat4::translate({30, 0, 10}));
    EXPECT_EQ(decide(*sphere, right).decision, Decision::Cull);
    DiceParams above = perspective(Mat4::translate({0, 30, 10}));
    EXPECT_EQ(decide(*sphere, above).decision, Decision::Cull);
    DiceParams far = perspective(Mat4::translate({0, 0, 100}));
    far.farClip = 50;
    EXPECT_EQ(decide(*sphere, far).decision, Decision::Cull);
    DiceParams near = perspective(Mat4::translate({0, 0, 3}));
    near.nearClip = 5;
    EXPECT_EQ(decide(*sphere, near).decision, Decision::Cull);
    // In view, it is not culled; displacement padding can bring it back in.
    DiceParams in = perspective(Mat4::translate({0, 0, 100}));
    EXPECT_NE(decide(*sphere, in).decision, Decision::Cull);
    DiceParams edge = perspective(Mat4::translate({0, 0, -1.5f}));
    edge.orthographic = false;
    EXPECT_EQ(decide(*sphere, edge).decision, Decision::Cull);
    edge.displacementBound = 1;
    EXPECT_NE(decide(*sphere, edge).decision, Decision::Cull);
}

TEST(Dice, NotDiceableSplits) {
    std::vector<float> P;
    for (int k = 0; k < 6; ++k) P.insert(P.end(), {std::cos(float(k)), std::sin(float(k)), 5});
    Diagnostics diag;
    auto prims = makePrimitives(record("Polygon", {}, {pointParam(P)}), diag);
    ASSERT_EQ(prims.size(), 1u);
    EXPECT_EQ(decide(*prims[0], perspective()).decision, Decision::Split);
}

TEST(Dice, EyeSplitsStraddlingGeometryThenCullsWithOneWarning) {
    DiceParams p = perspective();
    p.maxEyeSplits = 6;
    // A ground plane from behind the camera to in front of it; v runs along z.
    auto ground = quad({-1, -1, -5}, {1, -1, -5}, {1, -1, 5}, {-1, -1, 5});
    const DiceResult first = decide(*ground, p);
    EXPECT_EQ(first.decision, Decision::Split);
    EXPECT_TRUE(first.eyeSplit);
    EXPECT_FALSE(first.splitU);

    auto loop = [&](PrimitivePtr prim, Diagnostics& diag) {
        int grids = 0;
        std::vector<PrimitivePtr> prims;
        prims.push_back(std::move(prim));
        const int steps = runReyes(std::move(prims), p, &diag, [&](const Primitive& piece, const DiceResult& r) {
            ++grids;
            Grid g = piece.dice(r.nu, r.nv);
            for (const Vec3& q : g.P) EXPECT_GE(q.z, eyePlaneZ(p));
            for (const Vec3& q : toRaster(g, p)) EXPECT_TRUE(std::isfinite(q.x) && std::isfinite(q.y));
        });
        EXPECT_LT(steps, 100000);
        EXPECT_GT(grids, 0);
    };
    // Where the ground crosses the eye plane it is below the view (visible
    // only from z = 4/3 on), so the frustum test culls it: no warning.
    Diagnostics quiet;
    quiet.setSink([](const Diagnostic&) {});
    loop(std::move(ground), quiet);
    EXPECT_EQ(quiet.warningCount(), 0);

    // A plane just below eye level stays in view where it crosses the eye
    // plane: after the eye-split limit the straddling piece is culled, once warned.
    Diagnostics diag;
    diag.setRecord(true);
    diag.setSink([](const Diagnostic&) {});
    loop(quad({-1, -0.001f, -5}, {1, -0.001f, -5}, {1, -0.001f, 5}, {-1, -0.001f, 5}), diag);
    ASSERT_EQ(diag.warningCount(), 1);
    EXPECT_NE(diag.recorded()[0].message.find("eye plane after 6 eye splits"), std::string::npos);
}

TEST(Dice, PiecesBeyondFloatResolutionAreDicedCoarselyWithOneWarning) {
    // A quad 2 * 10^12 units across in a 100-pixels-a-unit orthographic
    // view needs 2^48 pixels' worth of halvings each way; float's [0, 1]
    // halves about 24 times, after which a split's pieces equal their
    // parent. Even 23 halvings leave pieces 2 * 10^7 pixels long, so the
    // quad is diced coarsely at once (every piece would stay in view and be
    // coarse anyway). A quad 2 * 10^8 across runs out of halvings only near
    // the view, where the last pieces are diced coarsely; the rest split
    // and are culled as usual.
    DiceParams p = orthographic(100, 100);
    for (const float size : {1e12f, 1e8f}) {
        Diagnostics diag;
        diag.setRecord(true);
        diag.setSink([](const Diagnostic&) {});
        std::vector<PrimitivePtr> prims;
        prims.push_back(quad({-size, -size, 5}, {size, -size, 5}, {size, size, 5}, {-size, size, 5}));
        int grids = 0;
        const int steps = runReyes(std::move(prims), p, &diag, [&](const Primitive& piece, const DiceResult& r) {
            ++grids;
            EXPECT_LE(r.nu * r.nv, p.gridSize);
        });
        EXPECT_LT(steps, size > 1e10f ? 2 : 2000) << size;
        EXPECT_GT(grids, 0) << size;
        ASSERT_EQ(diag.warningCount(), 1) << size;
        EXPECT_NE(diag.recorded()[0].message.find("float precision"), std::string::npos);
    }
}

TEST(Dice, ParamRangesHalveUntilFloatCannotTellTheirHalvesApart) {
    for (const bool upper : {false, true}) {
        ParamRange r;
        EXPECT_EQ(r.halvingsLeft(true), 23);  // 2^-23 of [0, 1]
        int halvings = 0;
        while (r.halvingsLeft(true) > 0 && halvings < 100) {
            const ParamRange h = r.half(true, upper);
            EXPECT_LT(h.u1 - h.u0, r.u1 - r.u0);
            EXPECT_LT(h.u0, h.u1);
            EXPECT_EQ(h.halvingsLeft(true), r.halvingsLeft(true) - 1);
            r = h;
            ++halvings;
        }
        EXPECT_EQ(halvings, 23) << upper;
        EXPECT_EQ(r.halvingsLeft(false), 23);  // the other direction is untouched
    }
}

TEST(Dice, OrthographicNeverEyeSplits) {
    DiceParams p;
    p.orthographic = true;
    p.rasterFromCamera = Mat4::scale({100, 100, 1});
    p.nearClip = -100;  // orthographic: z below the eye is fine
    auto ground = quad({-1, -1, -5}, {1, -1, -5}, {1, -1, 5}, {-1, -1, 5});
    const DiceResult r = decide(*ground, p);
    EXPECT_FALSE(r.eyeSplit);
    EXPECT_NE(r.decision, Decision::Cull);
}

TEST(Dice, RasterBoundContainsTheProjectedSurface) {
    DiceParams p = perspective(Mat4::translate({1, 0.5f, 8}) * Mat4::rotate(30, {1, 0, 0}));
    auto torus = make("Torus", {1, 0.3f, 0, 360, 360});
    const Bound3 rb = rasterBound(torus->bound(), p);
    for (const Vec3& q : toRaster(torus->dice(64, 32), p)) {
        EXPECT_GE(q.x, rb.min.x - 1e-3f);
        EXPECT_LE(q.x, rb.max.x + 1e-3f);
        EXPECT_GE(q.y, rb.min.y - 1e-3f);
        EXPECT_LE(q.y, rb.max.y + 1e-3f);
    }
    DiceParams straddle = perspective(Mat4::translate({0, 0, 0.1f}));
    const Bound3 sb = rasterBound(torus->bound(), straddle);
    EXPECT_EQ(sb.min.x, -kInfinity);
    EXPECT_EQ(sb.max.y, kInfinity);
}

namespace {

// The largest distance, in pixel space (raster x, y; camera depth in pixel
// widths at that depth), between a surface diced nu x nv and the surface
// itself, at the middle of every micropolygon edge and at every cell's
// centre, which the hider's triangles reach along the cell's diagonal.
float worstStandOff(const Primitive& prim, const DiceParams& p, int nu, int nv) {
    const float S = p.rasterFromCamera.m[0][0];
    auto raster = [&](const Vec3& object) { return p.rasterFromCamera.point(p.cameraFromObject.point(object)); };
    const Grid coarse = prim.dice(nu, nv), fine = prim.dice(2 * nu, 2 * nv);
    auto at = [](const Grid& g, int i, int j) { return g.P[size_t(g.index(i, j))]; };
    float worst = 0;
    auto check = [&](const Vec3& a, const Vec3& b, const Vec3& truth) {
        // Depth in pixel widths at the true point's depth.
        const Vec3 ca = p.cameraFromObject.point(a), cb = p.cameraFromObject.point(b), ct = p.cameraFromObject.point(truth);
        const float zScale = S / ct.z;
        const Vec3 ra = raster(a), rb = raster(b), rt = raster(truth);
        const Vec3 off((ra.x + rb.x) / 2 - rt.x, (ra.y + rb.y) / 2 - rt.y, ((ca.z + cb.z) / 2 - ct.z) * zScale);
        worst = std::max(worst, length(off));
    };
    for (int j = 0; j <= nv; ++j)
        for (int i = 0; i < nu; ++i) check(at(coarse, i, j), at(coarse, i + 1, j), at(fine, 2 * i + 1, 2 * j));
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i <= nu; ++i) check(at(coarse, i, j), at(coarse, i, j + 1), at(fine, 2 * i, 2 * j + 1));
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i < nu; ++i) check(at(coarse, i, j), at(coarse, i + 1, j + 1), at(fine, 2 * i + 1, 2 * j + 1));
    return worst;
}

// The largest distance, in pixels at its depth, from a surface diced nu x
// nv to the surface itself along the surface's normal (what the RI Spec's
// flatness bounds): at the middle of every micropolygon edge and at every
// cell's centre, against the surface diced twice as finely, whose
// neighbouring points give the normal there.
float worstNormalStandOff(const Primitive& prim, const DiceParams& p, int nu, int nv) {
    const float S = p.rasterFromCamera.m[0][0];
    const Grid coarse = prim.dice(nu, nv), fine = prim.dice(2 * nu, 2 * nv);
    auto cam = [&](const Grid& g, int i, int j) {
        i = std::clamp(i, 0, g.nu);
        j = std::clamp(j, 0, g.nv);
        return p.cameraFromObject.point(g.P[size_t(g.index(i, j))]);
    };
    float worst = 0;
    auto check = [&](const Vec3& a, const Vec3& b, int fi, int fj) {
        const Vec3 t = cam(fine, fi, fj);
        const Vec3 n = cross(cam(fine, fi + 1, fj) - cam(fine, fi - 1, fj), cam(fine, fi, fj + 1) - cam(fine, fi, fj - 1));
        const float len = length(n);
        const Vec3 off = (a + b) * 0.5f - t;
        const float d = len > 0 ? std::abs(dot(off, n / len)) : length(off);
        worst = std::max(worst, d * S / t.z);
    };
    for (int j = 0; j <= nv; ++j)
        for (int i = 0; i < nu; ++i) check(cam(coarse, i, j), cam(coarse, i + 1, j), 2 * i + 1, 2 * j);
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i <= nu; ++i) check(cam(coarse, i, j), cam(coarse, i, j + 1), 2 * i, 2 * j + 1);
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i < nu; ++i) check(cam(coarse, i, j), cam(coarse, i + 1, j + 1), 2 * i + 1, 2 * j + 1);
    return worst;
}

}  // namespace

TEST(Dice, FlatnessDicesSmoothSurfacesCoarselyWithinTheirStandOff) {
    // Depth passes bound how far a micropolygon may stand off its surface
    // instead of dicing at the shading rate: a sphere 64 pixels in radius
    // needs about pi sqrt(64 / (2 * 0.25)) = 36 edges around for chords
    // within a quarter pixel, where rate 4 gives 200. Each grid is checked
    // against the surface itself, diced twice as finely.
    struct Case {
        const char* name;
        PrimitivePtr prim;
    };
    Case cases[] = {
        {"sphere", make("Sphere", {1, -1, 1, 360})},
        {"torus", make("Torus", {1, 0.3f, 0, 360, 360})},
        {"cylinder", make("Cylinder", {0.5f, -1, 1, 360})},
        {"saddle", nullptr},
    };
    {
        Diagnostics diag;
        auto rec = record("Patch", {}, {pointParam({-1, -1, 0, 1, -1, 0.6f, -1, 1, 0.6f, 1, 1, 0})});
        rec->stringArgs = {"bilinear"};
        auto prims = makePrimitives(rec, diag);
        ASSERT_EQ(prims.size(), 1u);
        cases[3].prim = std::move(prims[0]);
    }
    for (auto& c : cases) {
        DiceParams p = perspective(Mat4::translate({0.1f, 0.2f, 5}) * Mat4::rotate(40, {1, 0.3f, 0}));
        p.shadingRate = 4;
        p.gridSize = 1 << 20;
        const DiceResult byRate = decide(*c.prim, p);
        for (float flatness : {0.25f, 0.05f}) {
            p.flatness = flatness;
            const DiceResult r = decide(*c.prim, p);
            ASSERT_EQ(r.decision, Decision::Dice) << c.name;
            EXPECT_LE(r.nu, byRate.nu) << c.name;  // never finer than the rate
            EXPECT_LE(r.nv, byRate.nv) << c.name;
            // Where the rate caps a direction the grid is the rate's, which
            // may stand off further; at a quarter pixel none is capped.
            const bool capped = r.nu == byRate.nu || r.nv == byRate.nv;
            if (flatness == 0.25f) {
                EXPECT_FALSE(capped) << c.name;
                EXPECT_LT(r.nu * r.nv, byRate.nu * byRate.nv / 3) << c.name;
            }
            if (!capped) {
                EXPECT_LE(worstStandOff(*c.prim, p, r.nu, r.nv), flatness) << c.name << " " << r.nu << "x" << r.nv;
            }
        }
    }
}

TEST(Dice, GeometricFlatnessDicesCurvedSurfacesFinerThanACoarseRate) {
    // GeometricApproximation "flatness" at ShadingRate 1000: the rate alone
    // leaves a sphere 64 pixels in radius 8 x 4 (the turning floor), whose
    // chords stand off it by pixels; the flatness floor dices it until
    // none stands off by more than the flatness along the normal, checked
    // against the surface itself diced twice as finely. Flat surfaces gain
    // nothing.
    struct Case {
        const char* name;
        PrimitivePtr prim;
    };
    Case cases[] = {
        {"sphere", make("Sphere", {1, -1, 1, 360})},
        {"torus", make("Torus", {1, 0.3f, 0, 360, 360})},
        {"cylinder", make("Cylinder", {0.5f, -1, 1, 360})},
    };
    for (auto& c : cases) {
        DiceParams p = perspective(Mat4::translate({0.1f, 0.2f, 5}) * Mat4::rotate(40, {1, 0.3f, 0}));
        p.shadingRate = 1000;
        p.gridSize = 1 << 20;
        const DiceResult byRate = decide(*c.prim, p);
        ASSERT_EQ(byRate.decision, Decision::Dice) << c.name;
        EXPECT_GT(worstNormalStandOff(*c.prim, p, byRate.nu, byRate.nv), 2.0f) << c.name;
        for (float flatness : {0.5f, 0.1f}) {
            p.maxStandOff = flatness;
            const DiceResult r = decide(*c.prim, p);
            ASSERT_EQ(r.decision, Decision::Dice) << c.name;
            EXPECT_GE(r.nu, byRate.nu) << c.name;  // never coarser than the rate
            EXPECT_GE(r.nv, byRate.nv) << c.name;
            EXPECT_LE(worstNormalStandOff(*c.prim, p, r.nu, r.nv), flatness) << c.name << " " << r.nu << "x" << r.nv;
        }
        // A fine rate already dices within the stand-off: flatness adds nothing.
        p.shadingRate = 0.25f;
        p.maxStandOff = 0;
        const DiceResult fine = decide(*c.prim, p);
        p.maxStandOff = 0.5f;
        const DiceResult same = decide(*c.prim, p);
        EXPECT_EQ(same.nu, fine.nu) << c.name;
        EXPECT_EQ(same.nv, fine.nv) << c.name;
    }
    // Flat surfaces: a polygon and a planar bilinear patch, tilted, dice
    // exactly as without flatness at any rate.
    Diagnostics diag;
    auto rec = record("Patch", {}, {pointParam({-1, -1, 0, 1, -1, 0.5f, -1, 1, -0.5f, 1, 1, 0})});
    rec->stringArgs = {"bilinear"};
    auto patch = makePrimitives(rec, diag);
    ASSERT_EQ(patch.size(), 1u);
    PrimitivePtr flats[] = {quad({-1, -1, 0}, {1, -1, 0}, {1, 1, 0.5f}, {-1, 1, 0.5f}), std::move(patch[0])};
    for (auto& prim : flats) {
        for (float rate : {1000.0f, 64.0f, 1.0f}) {
            DiceParams p = perspective(Mat4::translate({0.1f, 0.2f, 4}) * Mat4::rotate(30, {1, 0.3f, 0}));
            p.shadingRate = rate;
            const DiceResult before = decide(*prim, p);
            p.maxStandOff = 0.5f;
            const DiceResult after = decide(*prim, p);
            EXPECT_EQ(after.decision, before.decision) << rate;
            EXPECT_EQ(after.nu, before.nu) << rate;
            EXPECT_EQ(after.nv, before.nv) << rate;
        }
    }
}

TEST(Dice, TurningCountsFollowHowFarTheSurfaceTurns) {
    // On the 8 x 8 test lattice: a sphere turns a full circle along u and a
    // half along v (8 and 4 edges at 45 degrees each); a quarter cylinder
    // a quarter turn along u and nothing along v; a flat quad nothing.
    struct Case {
        const char* name;
        PrimitivePtr prim;
        float u, v;
    };
    Case cases[] = {
        {"sphere", make("Sphere", {1, -1, 1, 360}), 8, 4},
        {"quarter cylinder", make("Cylinder", {1, -1, 1, 90}), 2, 1},
        {"quad", quad({-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}), 1, 1},
    };
    for (auto& c : cases) {
        std::vector<Vec3> P;
        c.prim->dicePositions(8, 8, P);
        // Angles do not change with a rotation and a uniform scale.
        for (Vec3& q : P) q = (Mat4::rotate(30, {1, 2, 3}) * Mat4::scale({3, 3, 3})).point(q);
        float u = 0, v = 0;
        turningCounts(P.data(), 8, kPi / 4, &u, &v);
        EXPECT_EQ(u, c.u) << c.name;
        EXPECT_EQ(v, c.v) << c.name;
    }
}

TEST(Dice, HugeShadingRateStillDicesACurvedSurfaceIntoSeveralMicropolygons) {
    // At ShadingRate 1000 (micropolygons 32 pixels on a side) the rate
    // alone dices a sphere 20 pixels across into a grid whose corners lie
    // on one meridian: its projection covers nothing. The turning floor
    // keeps 8 x 4, which covers most of the sphere's disk; a flat quad
    // keeps what the rate gives it.
    DiceParams p = perspective(Mat4::translate({0, 0, 32}) * Mat4::rotate(70, {1, 0, 0}));
    p.shadingRate = 1000;
    auto sphere = make("Sphere", {1, -1, 1, 360});
    // The silhouette's area: a convex closed grid covers it twice, front and back.
    auto silhouette = [&](const DiceResult& r) {
        const auto ras = toRaster(sphere->dice(r.nu, r.nv), p);
        double twice = 0;
        for (int j = 0; j < r.nv; ++j)
            for (int i = 0; i < r.nu; ++i) {
                const Vec3& a = ras[size_t(j * (r.nu + 1) + i)];
                const Vec3& b = ras[size_t(j * (r.nu + 1) + i + 1)];
                const Vec3& c = ras[size_t((j + 1) * (r.nu + 1) + i + 1)];
                const Vec3& d = ras[size_t((j + 1) * (r.nu + 1) + i)];
                auto tri = [](const Vec3& x, const Vec3& y, const Vec3& z) {
                    return 0.5 * std::abs(double((y.x - x.x) * (z.y - x.y) - (y.y - x.y) * (z.x - x.x)));
                };
                twice += tri(a, b, c) + tri(a, c, d);
            }
        return twice / 2;
    };
    const double disk = M_PI * 10 * 10;  // radius 320 / 32 pixels
    DiceResult r = decide(*sphere, p);
    ASSERT_EQ(r.decision, Decision::Dice);
    EXPECT_EQ(r.nu, 8);
    EXPECT_EQ(r.nv, 4);
    EXPECT_GT(silhouette(r), 0.75 * disk);
    auto q = quad({-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0});
    const DiceResult withFloor = decide(*q, p);
    // Without the floor, the old answer.
    p.maxTurn = 0;
    r = decide(*sphere, p);
    ASSERT_EQ(r.decision, Decision::Dice);
    EXPECT_LT(silhouette(r), 0.05 * disk) << r.nu << "x" << r.nv;
    const DiceResult noFloor = decide(*q, p);
    EXPECT_EQ(withFloor.nu, noFloor.nu);
    EXPECT_EQ(withFloor.nv, noFloor.nv);
    // The floor gives way to gridSize rather than forcing a split.
    p.maxTurn = kPi / 4;
    p.gridSize = 16;
    r = decide(*sphere, p);
    ASSERT_EQ(r.decision, Decision::Dice);
    EXPECT_LE(r.nu * r.nv, 16);
    EXPECT_GE(r.nu * r.nv, 12);
}

TEST(Dice, BinaryDicingGivesPowersOfTwo) {
    // Attribute "dice" "binary": the same sphere, every grid's counts a
    // power of two and never finer than the plain dicing asked for.
    DiceParams p = perspective(Mat4::translate({0.5f, 0, 6}));
    p.shadingRate = 2;
    p.gridSize = 64;
    auto counts = [&](bool binary) {
        p.binary = binary;
        std::vector<std::pair<int, int>> out;
        runReyes([] { std::vector<PrimitivePtr> v; v.push_back(make("Sphere", {1, -1, 1, 360})); return v; }(), p,
                 nullptr, [&](const Primitive&, const DiceResult& r) { out.emplace_back(r.nu, r.nv); });
        return out;
    };
    const auto plain = counts(false), binary = counts(true);
    ASSERT_FALSE(binary.empty());
    bool anyNotPow2 = false;
    for (auto [nu, nv] : plain) anyNotPow2 = anyNotPow2 || (nu & (nu - 1)) != 0 || (nv & (nv - 1)) != 0;
    EXPECT_TRUE(anyNotPow2);  // else this test could not fail
    for (auto [nu, nv] : binary) {
        EXPECT_EQ(nu & (nu - 1), 0) << nu;
        EXPECT_EQ(nv & (nv - 1), 0) << nv;
        EXPECT_LE(nu * nv, p.gridSize);
    }
}
