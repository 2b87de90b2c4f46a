// Curve segments diced against closed forms: a cubic Bezier's centreline,
// a periodic curve's closure, and the ribbon's orientation towards the eye.

#include "geometry_test_util.h"

#include "umbra/geometry/curves.h"

#include <gtest/gtest.h>

using namespace umbra;
using namespace umbra::geometry;

namespace {

std::shared_ptr<scene::PrimitiveRecord> curves(const std::string& type, const std::string& wrap,
                                               std::vector<int> nverts, std::vector<float> P, float width) {
    auto r = testutil::record("Curves", {}, {testutil::pointParam(std::move(P)),
                                              testutil::floatParam("constantwidth", ri::ParamType::Float, {width},
                                                                   ri::StorageClass::Constant)});
    r->type = "Curves";
    r->stringArgs = {type, wrap};
    r->intArrays = {std::move(nverts)};
    return r;
}

Vec3 bezier(const Vec3 p[4], float t) {
    const float s = 1 - t;
    return p[0] * (s * s * s) + p[1] * (3 * s * s * t) + p[2] * (3 * s * t * t) + p[3] * (t * t * t);
}

TEST(CurveSegment, CubicBezierCentrelineMatchesTheFormula) {
    const Vec3 c[4] = {{0, 0, 0}, {1, 2, 0}, {2, -2, 1}, {3, 0, 0}};
    auto rec = curves("cubic", "nonperiodic", {4}, {0, 0, 0, 1, 2, 0, 2, -2, 1, 3, 0, 0}, 0.1f);
    Diagnostics diag;
    auto prims = makePrimitives(rec, diag);
    ASSERT_EQ(prims.size(), 1u);
    ViewContext view;
    view.orthographic = false;
    view.eye = {1.5f, 0, -10};
    const int nu = 16;
    Grid g = prims[0]->diceInView(nu, 1, view);
    ASSERT_EQ(g.vertexCount(), 2 * (nu + 1));
    // RI Spec 3.2: u runs across the width, v along the curve.
    ASSERT_EQ(g.nu, 1);
    ASSERT_EQ(g.nv, nu);
    for (int j = 0; j <= nu; ++j) {
        const Vec3 a = g.P[size_t(g.index(0, j))], b = g.P[size_t(g.index(1, j))];
        const Vec3 want = bezier(c, float(j) / float(nu));
        EXPECT_LT(length((a + b) * 0.5f - want), 1e-5f) << j;
        EXPECT_NEAR(length(b - a), 0.1f, 1e-5f) << j;
        EXPECT_NEAR(g.v[size_t(g.index(0, j))], float(j) / float(nu), 1e-6f) << j;
        EXPECT_EQ(g.u[size_t(g.index(0, j))], 0.0f);
        EXPECT_EQ(g.u[size_t(g.index(1, j))], 1.0f);
        // The outward side (dPdu x dPdv) faces the eye.
        if (j < nu) {
            const Vec3 n = cross(b - a, g.P[size_t(g.index(0, j + 1))] - a);
            EXPECT_GT(dot(n, view.eye - a), 0) << j;
        }
    }
    // The bound holds the ribbon.
    const Bound3 bd = prims[0]->bound();
    for (const Vec3& p : g.P) {
        EXPECT_GE(p.x, bd.min.x);
        EXPECT_LE(p.x, bd.max.x);
        EXPECT_GE(p.y, bd.min.y);
        EXPECT_LE(p.y, bd.max.y);
    }
}

TEST(CurveSegment, PeriodicCurveCloses) {
    // Periodic B-spline over 5 control points: 5 segments, the last ending
    // where the first starts.
    auto rec = curves("cubic", "periodic", {5}, {1, 0, 0, 0, 1, 0, -1, 0, 0, 0, -1, 0, 0.5f, -0.5f, 0}, 0.01f);
    rec->attributes = std::make_shared<scene::Attributes>();
    auto attrs = std::make_shared<scene::Attributes>(*rec->attributes);
    attrs->vBasis = scene::Basis::bspline();
    attrs->vBasis.step = 1;
    rec->attributes = attrs;
    Diagnostics diag;
    auto prims = makePrimitives(rec, diag);
    ASSERT_EQ(prims.size(), 5u);
    auto* first = dynamic_cast<CurveSegment*>(prims.front().get());
    auto* last = dynamic_cast<CurveSegment*>(prims.back().get());
    ASSERT_TRUE(first && last);
    EXPECT_LT(length(first->centre(0) - last->centre(1)), 1e-6f);
    for (size_t k = 0; k + 1 < prims.size(); ++k) {
        auto* a = dynamic_cast<CurveSegment*>(prims[k].get());
        auto* b = dynamic_cast<CurveSegment*>(prims[k + 1].get());
        EXPECT_LT(length(a->centre(1) - b->centre(0)), 1e-6f) << k;
    }
}

TEST(CurveSegment, BadVertexCountIsAnError) {
    auto rec = curves("cubic", "nonperiodic", {5}, std::vector<float>(15, 0.0f), 0.1f);
    Diagnostics diag;
    diag.setRecord(true);
    EXPECT_TRUE(makePrimitives(rec, diag).empty());
    EXPECT_EQ(diag.errorCount(), 1);
}

}  // namespace

// PRMan's `Points ... "uniform string type" "sphere"`: one Sphere record per
// point, its centre the point, its radius half the width, its primitive
// variables the point's own values as constants (and only those: a copy of
// every point's values per sphere made memory quadratic in the points).
TEST(PointSpheres, OneSphereRecordPerPointHoldingOnlyItsOwnValues) {
    const int n = 500;
    std::vector<float> P, width, Cs;
    for (int i = 0; i < n; ++i) {
        P.insert(P.end(), {float(i), float(2 * i), -float(i)});
        width.push_back(0.5f + 0.01f * float(i));
        Cs.insert(Cs.end(), {float(i) / n, 0.5f, 1.0f - float(i) / n});
    }
    ri::Param type;
    type.decl.name = "type";
    type.decl.type = ri::ParamType::String;
    type.decl.storage = ri::StorageClass::Uniform;
    type.strings = {"sphere"};
    auto rec = testutil::record(
        "Points", {},
        {testutil::pointParam(P), testutil::floatParam("width", ri::ParamType::Float, width, ri::StorageClass::Varying),
         testutil::floatParam("Cs", ri::ParamType::Color, Cs, ri::StorageClass::Varying), type});
    Diagnostics diag;
    diag.setQuiet(true);
    auto prims = makePrimitives(rec, diag);
    EXPECT_EQ(diag.errorCount(), 0);
    ASSERT_EQ(prims.size(), size_t(n));
    size_t stored = 0;
    for (int i = 0; i < n; ++i) {
        const scene::PrimitiveRecord& s = prims[size_t(i)]->record();
        EXPECT_EQ(s.type, "Sphere");
        const float r = 0.5f * width[size_t(i)];
        ASSERT_EQ(s.floatArgs.size(), 4u);
        EXPECT_EQ(s.floatArgs[0], r);
        EXPECT_EQ(s.floatArgs[1], -r);
        EXPECT_EQ(s.floatArgs[2], r);
        EXPECT_EQ(s.floatArgs[3], 360.0f);
        const Vec3 c = s.worldFromObject.point({0, 0, 0});
        EXPECT_EQ(c, Vec3(P[size_t(3 * i)], P[size_t(3 * i + 1)], P[size_t(3 * i + 2)])) << i;
        const ri::Param* cs = s.params.find("Cs");
        ASSERT_NE(cs, nullptr);
        EXPECT_EQ(cs->decl.storage, ri::StorageClass::Constant);
        ASSERT_EQ(cs->floats.size(), 3u);
        EXPECT_EQ(cs->floats[0], Cs[size_t(3 * i)]);
        EXPECT_EQ(s.params.find("P"), nullptr);
        EXPECT_EQ(s.params.find("width"), nullptr);
        for (const ri::Param& p : s.params.params()) stored += p.floats.capacity();
    }
    EXPECT_LE(stored, size_t(n) * 8);  // about 3 floats a sphere, not 3 n
}
