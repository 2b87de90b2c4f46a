#include "geometry_test_util.h"

#include "umbra/geometry/nupatch.h"
#include "umbra/geometry/trim.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

using namespace umbra;
using namespace umbra::geometry;
using namespace umbra::testutil;

namespace {

// One loop: the 9-point rational circle (order 3) of radius r about (cu, cv).
scene::TrimCurveRecord circleRecord(float cu, float cv, float r) {
    const float h = std::sqrt(0.5f);
    const float cx[9] = {1, 1, 0, -1, -1, -1, 0, 1, 1}, cy[9] = {0, 1, 1, 1, 0, -1, -1, -1, 0};
    const float cw[9] = {1, h, 1, h, 1, h, 1, h, 1};
    scene::TrimCurveRecord rec;
    rec.ncurves = {1};
    rec.order = {3};
    rec.n = {9};
    rec.knot = {0, 0, 0, 0.25f, 0.25f, 0.5f, 0.5f, 0.75f, 0.75f, 1, 1, 1};
    rec.min = {0};
    rec.max = {1};
    for (int i = 0; i < 9; ++i) {
        rec.u.push_back((cu + r * cx[i]) * cw[i]);
        rec.v.push_back((cv + r * cy[i]) * cw[i]);
        rec.w.push_back(cw[i]);
    }
    return rec;
}

// Appends a square loop (one order-2 curve of 5 points) to `rec`.
void addSquare(scene::TrimCurveRecord& rec, float lo, float hi) {
    rec.ncurves.push_back(1);
    rec.order.push_back(2);
    rec.n.push_back(5);
    for (float k : {0, 0, 1, 2, 3, 4, 4}) rec.knot.push_back(k);
    rec.min.push_back(0);
    rec.max.push_back(4);
    const float u[5] = {lo, hi, hi, lo, lo}, v[5] = {lo, lo, hi, hi, lo};
    for (int i = 0; i < 5; ++i) {
        rec.u.push_back(u[i]);
        rec.v.push_back(v[i]);
        rec.w.push_back(1);
    }
}

}  // namespace

TEST(TrimRegion, CircleIsTessellatedOnTheCircle) {
    auto region = TrimRegion::make(circleRecord(0.5f, 0.4f, 0.3f), true);
    const std::vector<float>& s = region->segments();
    EXPECT_EQ(s.size(), size_t(4 * kTrimSegmentsPerSpan * 4));
    for (size_t k = 0; k < s.size(); k += 2) EXPECT_NEAR(std::hypot(s[k] - 0.5f, s[k + 1] - 0.4f), 0.3f, 1e-6f);
}

TEST(TrimRegion, EvenOddAreaIsTheDisk) {
    auto region = TrimRegion::make(circleRecord(0.5f, 0.5f, 0.3f), true);
    const int n = 1000;
    int inside = 0;
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const float u = (float(i) + 0.5f) / n, v = (float(j) + 0.5f) / n;
            inside += region->insideLoops(u, v);
            EXPECT_EQ(region->keeps(u, v), !region->insideLoops(u, v));
        }
    EXPECT_NEAR(double(inside) / (double(n) * n), M_PI * 0.09, M_PI * 0.09 * 1e-3);
}

TEST(TrimRegion, NestedLoopsAndSense) {
    scene::TrimCurveRecord rec;
    addSquare(rec, 0.1f, 0.9f);
    addSquare(rec, 0.4f, 0.6f);
    auto removeInside = TrimRegion::make(rec, true);
    auto keepInside = TrimRegion::make(rec, false);
    EXPECT_TRUE(removeInside->keeps(0.05f, 0.5f));   // outside both
    EXPECT_FALSE(removeInside->keeps(0.2f, 0.5f));   // inside one
    EXPECT_TRUE(removeInside->keeps(0.5f, 0.5f));    // inside both: even
    EXPECT_TRUE(keepInside->keeps(0.2f, 0.5f));
    EXPECT_FALSE(keepInside->keeps(0.5f, 0.5f));
    using Cover = TrimRegion::Cover;
    EXPECT_EQ(removeInside->classify(0.2f, 0.3f, 0.2f, 0.3f), Cover::Removed);
    EXPECT_EQ(removeInside->classify(0.45f, 0.55f, 0.45f, 0.55f), Cover::Kept);
    EXPECT_EQ(removeInside->classify(0.0f, 0.05f, 0.0f, 1.0f), Cover::Kept);
    EXPECT_EQ(removeInside->classify(0.3f, 0.5f, 0.3f, 0.5f), Cover::Mixed);
    EXPECT_EQ(keepInside->classify(0.2f, 0.3f, 0.2f, 0.3f), Cover::Kept);
}

TEST(TrimRegion, RangesFarPastTheLoopsAreClassifiedWithoutOverflow) {
    // A corrupt NuPatch's pieces (a fuzzer's) reached v = 2.5e37, and the
    // band index overflowed int (undefined behaviour, caught by UBSan).
    // Ranges reaching any distance past the loops, or NaN, classify as the
    // bands at their ends do.
    scene::TrimCurveRecord rec;
    addSquare(rec, 0.4f, 0.6f);
    auto region = TrimRegion::make(rec, true);
    using Cover = TrimRegion::Cover;
    EXPECT_EQ(region->classify(0.45f, 0.55f, 0.45f, 2.5e37f), Cover::Mixed);     // crosses the top edge
    EXPECT_EQ(region->classify(0.45f, 0.55f, -2.5e37f, 0.55f), Cover::Mixed);    // and the bottom one
    EXPECT_EQ(region->classify(0.0f, 0.1f, -2.5e37f, 2.5e37f), Cover::Kept);     // beside the loop
    EXPECT_EQ(region->classify(0.0f, 0.1f, -kInfinity, kInfinity), Cover::Kept);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    EXPECT_EQ(region->classify(0.0f, 0.1f, nan, nan), region->keeps(0.05f, nan) ? Cover::Kept : Cover::Removed);
}

TEST(TrimRegion, NuPatchPiecesKnowWhetherTheTrimReachesThem) {
    // A flat NuPatch of 4 x 4 spans over [0,1]^2 with a hole of radius 0.3
    // about the centre ("sense" "outside": one loop alone would keep only
    // its disk): the spans touching the middle four knots' square
    // (0.25..0.75) are crossed, the corner spans are untouched.
    std::vector<float> P, knots = {0, 0, 0.25f, 0.5f, 0.75f, 1, 1};
    for (int j = 0; j < 5; ++j)
        for (int i = 0; i < 5; ++i) P.insert(P.end(), {float(i) / 4, float(j) / 4, 0});
    std::vector<float> f = knots;
    f.insert(f.end(), {0, 1});
    f.insert(f.end(), knots.begin(), knots.end());
    f.insert(f.end(), {0, 1});
    auto rec = record("NuPatch", f, {pointParam(P)});
    rec->intArgs = {5, 2, 5, 2};
    auto attrs = std::make_shared<scene::Attributes>();
    attrs->trimCurves = std::make_shared<scene::TrimCurveRecord>(circleRecord(0.5f, 0.5f, 0.3f));
    ri::Param sense;
    sense.strings = {"outside"};
    attrs->user["trimcurve:sense"] = sense;
    rec->attributes = attrs;
    Diagnostics diag;
    auto prims = makePrimitives(rec, diag);
    ASSERT_EQ(prims.size(), 16u);
    int crossed = 0, whole = 0;
    for (const auto& p : prims) {
        EXPECT_FALSE(p->trimmedAway());
        (p->trimRegion() ? crossed : whole) += 1;
    }
    EXPECT_EQ(crossed, 12);  // every span but the four corners
    EXPECT_EQ(whole, 4);
    // Split a crossed span finely: the pieces well inside the hole are culled.
    std::vector<PrimitivePtr> pieces, next;
    for (auto& p : prims)
        if (p->trimRegion()) pieces.push_back(std::move(p));
    for (int level = 0; level < 6; ++level) {
        next.clear();
        for (const auto& p : pieces) p->split(level % 2 == 0, next);
        pieces.swap(next);
    }
    int away = 0;
    for (const auto& p : pieces) away += p->trimmedAway();
    EXPECT_GT(away, 0);
}

// A zero weight (found by fuzz_render: `TrimCurve ... [1 1 0]`) puts a
// curve point at infinity or NaN: its segments are dropped, and the rest
// of the region still trims where it did.
TEST(TrimRegion, AZeroWeightDropsItsSegmentsAndKeepsTheRest) {
    scene::TrimCurveRecord rec;
    addSquare(rec, 0.2f, 0.8f);
    rec.ncurves.push_back(1);  // a triangle with one point of weight 0
    rec.order.push_back(2);
    rec.n.push_back(3);
    for (float k : {0, 0, 1, 2, 2}) rec.knot.push_back(k);
    rec.min.push_back(0);
    rec.max.push_back(2);
    const float u[3] = {0.2f, 0.8f, 0.2f}, v[3] = {0.2f, 0.5f, 0.8f}, w[3] = {1, 1, 0};
    for (int i = 0; i < 3; ++i) {
        rec.u.push_back(u[i]);
        rec.v.push_back(v[i]);
        rec.w.push_back(w[i]);
    }
    auto region = TrimRegion::make(rec, true);
    for (float c : region->segments()) ASSERT_TRUE(std::isfinite(c));
    EXPECT_FALSE(region->insideLoops(0.1f, 0.1f));
    EXPECT_FALSE(region->insideLoops(0.9f, 0.5f));
    EXPECT_FALSE(region->insideLoops(std::nanf(""), 0.5f));
}
