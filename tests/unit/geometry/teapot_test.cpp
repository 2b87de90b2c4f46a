// Geometry "teapot": the data's symmetry, its Bezier patches whatever the
// current Basis, and a bottom that closes the body.

#include "geometry_test_util.h"

#include "umbra/geometry/teapot.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace umbra;
using namespace umbra::geometry;
using umbra::testutil::record;

namespace {

std::vector<PrimitivePtr> teapot(const scene::Basis& basis) {
    auto rec = record("Geometry");
    rec->stringArgs = {"teapot"};
    auto attrs = std::make_shared<scene::Attributes>();
    attrs->uBasis = attrs->vBasis = basis;
    rec->attributes = attrs;
    Diagnostics diag;
    auto prims = makePrimitives(rec, diag);
    EXPECT_EQ(diag.errorCount() + diag.warningCount(), 0);
    return prims;
}

}  // namespace

TEST(Teapot, ControlPointsAreMirroredAcrossTheSpoutPlane) {
    // The teapot is symmetric about y = 0 (spout and handle lie in it):
    // every control point's mirror image is a control point too.
    std::vector<Vec3> points;
    for (int p = 0; p < kTeapotPatchCount; ++p)
        for (int k = 0; k < 16; ++k) points.push_back(teapotControlPoint(p, k));
    for (const Vec3& q : points) {
        bool mirrored = false;
        for (const Vec3& r : points) mirrored |= length(r - Vec3{q.x, -q.y, q.z}) < 1e-6f;
        EXPECT_TRUE(mirrored) << q.x << " " << q.y << " " << q.z;
    }
}

TEST(Teapot, BezierPatchesWhateverTheBasisStandOnZeroAndAreThreeTall) {
    // Under a B-spline Basis the surface would not reach its corner control
    // points: the lid's top (0, 0, 3) and the bottom's centre (0, 0, 0)
    // are reached only if the patches are Bezier, as the data are.
    auto prims = teapot(scene::Basis::bspline());
    ASSERT_EQ(prims.size(), size_t(kTeapotPatchCount));
    float zmin = 1e9f, zmax = -1e9f;
    for (const auto& p : prims)
        for (const Vec3& q : p->dice(8, 8).P) {
            zmin = std::min(zmin, q.z);
            zmax = std::max(zmax, q.z);
        }
    EXPECT_NEAR(zmin, 0.0f, 1e-6f);
    EXPECT_NEAR(zmax, 3.0f, 1e-6f);
}

TEST(Teapot, BottomClosesTheBody) {
    // Bottom patch 28 + q shares its outer edge (v = 0) with the lower edge
    // (v = 1) of body patch 8 + q: no gap to see through.
    auto prims = teapot(scene::Basis::bezier());
    ASSERT_EQ(prims.size(), size_t(kTeapotPatchCount));
    const int n = 8;
    for (int q = 0; q < 4; ++q) {
        const Grid body = prims[size_t(8 + q)]->dice(n, n), bottom = prims[size_t(28 + q)]->dice(n, n);
        for (int i = 0; i <= n; ++i) {
            const Vec3 a = body.P[body.index(i, n)], b = bottom.P[bottom.index(i, 0)];
            EXPECT_LT(length(a - b), 1e-6f) << "quarter " << q << " vertex " << i;
            EXPECT_NEAR(b.z, 0.0f, 1e-6f);
        }
    }
}
