#include "geometry_test_util.h"

#include "umbra/geometry/patch.h"
#include "umbra/util/rng.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace umbra;
using namespace umbra::geometry;
using namespace umbra::testutil;

namespace {

std::shared_ptr<scene::PrimitiveRecord> patchRecord(const std::string& kind, std::vector<float> P,
                                                    const scene::Basis& basis = scene::Basis::bezier(),
                                                    std::vector<ri::Param> extra = {}) {
    extra.push_back(pointParam(std::move(P)));
    auto rec = record("Patch", {}, std::move(extra));
    rec->stringArgs = {kind};
    auto attrs = std::make_shared<scene::Attributes>();
    attrs->uBasis = attrs->vBasis = basis;
    rec->attributes = attrs;
    return rec;
}

PrimitivePtr makeOne(std::shared_ptr<scene::PrimitiveRecord> rec) {
    Diagnostics diag;
    auto prims = makePrimitives(std::move(rec), diag);
    EXPECT_EQ(diag.errorCount(), 0);
    EXPECT_EQ(prims.size(), 1u);
    return prims.empty() ? nullptr : std::move(prims[0]);
}

// Reference evaluation straight from the spec's definition:
// P(u, v) = sum_ij B_i(u) B_j(v) G_ij with B_i(t) = [t^3 t^2 t 1] M column i.
double basisWeight(const scene::Basis& b, int i, double t) {
    return t * t * t * b.m[0][i] + t * t * b.m[1][i] + t * b.m[2][i] + b.m[3][i];
}
Vec3 reference(const std::vector<float>& G, const scene::Basis& b, double u, double v, int dim = 3) {
    double acc[4] = {0, 0, 0, 0};
    for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) {
            const double w = basisWeight(b, i, u) * basisWeight(b, j, v);
            for (int c = 0; c < dim; ++c) acc[c] += w * G[size_t((j * 4 + i) * dim + c)];
        }
    if (dim == 4) return {float(acc[0] / acc[3]), float(acc[1] / acc[3]), float(acc[2] / acc[3])};
    return {float(acc[0]), float(acc[1]), float(acc[2])};
}

std::vector<float> randomControlPoints(uint32_t seed, int dim = 3) {
    Rng rng(seed);
    std::vector<float> G;
    for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) {
            G.insert(G.end(), {float(i) + rng.uniform() - 0.5f, float(j) + rng.uniform() - 0.5f, 2 * rng.uniform() - 1});
            if (dim == 4) G.push_back(0.5f + rng.uniform());
        }
    return G;
}

}  // namespace

TEST(Patch, BilinearInterpolatesCorners) {
    const std::vector<float> P = {0, 0, 0, 1, 0, 1, 0, 2, 0, 3, 2, 1};
    auto p = makeOne(patchRecord("bilinear", P));
    Grid g = p->dice(3, 5);
    for (int k = 0; k < g.vertexCount(); ++k) {
        const float u = g.u[size_t(k)], v = g.v[size_t(k)];
        for (int c = 0; c < 3; ++c) {
            const float want = (1 - u) * (1 - v) * P[size_t(c)] + u * (1 - v) * P[size_t(3 + c)] +
                               (1 - u) * v * P[size_t(6 + c)] + u * v * P[size_t(9 + c)];
            EXPECT_NEAR(g.P[size_t(k)][c], want, 1e-6f);
        }
    }
}

TEST(Patch, BezierWithEvenlySpacedControlPointsReproducesAPlane) {
    auto plane = [](float x, float y) { return 0.5f * x - 0.25f * y + 1; };
    std::vector<float> G;
    for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) G.insert(G.end(), {i / 3.0f, j / 3.0f, plane(i / 3.0f, j / 3.0f)});
    auto p = makeOne(patchRecord("bicubic", G));
    Grid g = p->dice(7, 5);
    for (int k = 0; k < g.vertexCount(); ++k) {
        const Vec3 q = g.P[size_t(k)];
        EXPECT_NEAR(q.x, g.u[size_t(k)], 1e-6f);
        EXPECT_NEAR(q.y, g.v[size_t(k)], 1e-6f);
        EXPECT_NEAR(q.z, plane(q.x, q.y), 1e-6f);
    }
}

TEST(Patch, BSplineOfUniformGridCoversTheInterior) {
    std::vector<float> G;
    for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) G.insert(G.end(), {float(i), float(j), 0});
    auto p = makeOne(patchRecord("bicubic", G, scene::Basis::bspline()));
    Grid g = p->dice(4, 4);
    for (int k = 0; k < g.vertexCount(); ++k) {
        EXPECT_NEAR(g.P[size_t(k)].x, 1 + g.u[size_t(k)], 1e-6f);
        EXPECT_NEAR(g.P[size_t(k)].y, 1 + g.v[size_t(k)], 1e-6f);
        EXPECT_NEAR(g.P[size_t(k)].z, 0, 1e-6f);
    }
}

TEST(Patch, CatmullRomInterpolatesMiddleControlPoints) {
    const std::vector<float> G = randomControlPoints(7);
    auto p = makeOne(patchRecord("bicubic", G, scene::Basis::catmullRom()));
    Grid g = p->dice(1, 1);
    auto ctrl = [&](int i, int j) { return Vec3(G[size_t((j * 4 + i) * 3)], G[size_t((j * 4 + i) * 3 + 1)], G[size_t((j * 4 + i) * 3 + 2)]); };
    const int ij[4][2] = {{1, 1}, {2, 1}, {1, 2}, {2, 2}};
    for (int c = 0; c < 4; ++c) {
        const Vec3 d = g.P[size_t(c)] - ctrl(ij[c][0], ij[c][1]);
        EXPECT_LT(length(d), 1e-5f) << c;
    }
}

TEST(Patch, EveryBasisMatchesTheSpecFormulaAndStaysInItsBound) {
    const scene::Basis bases[] = {scene::Basis::bezier(), scene::Basis::bspline(), scene::Basis::catmullRom(),
                                  scene::Basis::hermite(), scene::Basis::power()};
    uint32_t seed = 1;
    for (const scene::Basis& b : bases) {
        const std::vector<float> G = randomControlPoints(seed++);
        auto p = makeOne(patchRecord("bicubic", G, b));
        const Bound3 pb = p->bound();
        Grid g = p->dice(9, 7);
        for (int k = 0; k < g.vertexCount(); ++k) {
            const Vec3 want = reference(G, b, g.u[size_t(k)], g.v[size_t(k)]);
            EXPECT_LT(length(g.P[size_t(k)] - want), 2e-5f * std::max(1.0f, length(want))) << seed;
            EXPECT_TRUE(inside(pb, g.P[size_t(k)], 0)) << seed;
        }
        std::vector<PrimitivePtr> halves, quarters;
        p->split(false, halves);
        for (auto& h : halves) h->split(true, quarters);
        for (const auto& q : quarters) {
            const Bound3 qb = q->bound();
            EXPECT_TRUE(inside(pb, qb.min, 1e-4f) && inside(pb, qb.max, 1e-4f)) << seed;
            Grid gq = q->dice(5, 5);
            for (int k = 0; k < gq.vertexCount(); ++k) {
                EXPECT_TRUE(inside(qb, gq.P[size_t(k)], 0)) << seed;
                const Vec3 want = reference(G, b, gq.u[size_t(k)], gq.v[size_t(k)]);
                EXPECT_LT(length(gq.P[size_t(k)] - want), 2e-5f * std::max(1.0f, length(want)));
            }
        }
    }
}

TEST(Patch, RationalBicubicDividesByW) {
    const std::vector<float> G = randomControlPoints(42, 4);
    auto rec = record("Patch", {}, {floatParam("Pw", ri::ParamType::HPoint, G, ri::StorageClass::Vertex)});
    rec->stringArgs = {"bicubic"};
    auto p = makeOne(rec);
    Grid g = p->dice(6, 6);
    const Bound3 b = p->bound();
    for (int k = 0; k < g.vertexCount(); ++k) {
        const Vec3 want = reference(G, scene::Basis::bezier(), g.u[size_t(k)], g.v[size_t(k)], 4);
        EXPECT_LT(length(g.P[size_t(k)] - want), 1e-5f);
        EXPECT_TRUE(inside(b, g.P[size_t(k)], 0));
    }
}

TEST(Patch, PzIsAHeightFieldOverTheUnitSquare) {
    auto rec = record("Patch", {}, {floatParam("Pz", ri::ParamType::Float, {0, 1, 2, 3}, ri::StorageClass::Vertex)});
    rec->stringArgs = {"bilinear"};
    Grid g = makeOne(rec)->dice(2, 2);
    for (int k = 0; k < g.vertexCount(); ++k) {
        const float u = g.u[size_t(k)], v = g.v[size_t(k)];
        EXPECT_FLOAT_EQ(g.P[size_t(k)].x, u);
        EXPECT_FLOAT_EQ(g.P[size_t(k)].y, v);
        EXPECT_NEAR(g.P[size_t(k)].z, u * (1 - v) * 1 + (1 - u) * v * 2 + u * v * 3, 1e-6f);
    }
}

namespace {

// Attribute "umbra" "patchblock" [0]: a bicubic mesh diced patch by patch,
// one primitive per patch, as these tests count and check them
// (patch_blocks_test.cpp checks the blocks against them).
void patchByPatch(scene::Attributes& attrs) {
    ri::Param side;
    side.decl.name = "patchblock";
    side.decl.type = ri::ParamType::Integer;
    side.ints = {0};
    attrs.user["umbra:patchblock"] = side;
}

std::shared_ptr<scene::PrimitiveRecord> meshRecord(const std::string& kind, int nu, const std::string& uwrap, int nv,
                                                   const std::string& vwrap, const scene::Basis& basis,
                                                   std::vector<ri::Param> extra = {}) {
    std::vector<float> P;
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i < nu; ++i) P.insert(P.end(), {float(i), float(j), float(i * j % 3)});
    extra.push_back(pointParam(P));
    auto rec = record("PatchMesh", {}, std::move(extra));
    rec->stringArgs = {kind, uwrap, vwrap};
    rec->intArgs = {nu, nv};
    auto attrs = std::make_shared<scene::Attributes>();
    attrs->uBasis = attrs->vBasis = basis;
    patchByPatch(*attrs);
    rec->attributes = attrs;
    return rec;
}

size_t countPatches(std::shared_ptr<scene::PrimitiveRecord> rec) {
    Diagnostics diag;
    auto prims = makePrimitives(std::move(rec), diag);
    EXPECT_EQ(diag.errorCount(), 0);
    return prims.size();
}

}  // namespace

TEST(PatchMesh, PatchCountsFollowWrapAndStep) {
    const auto bez = scene::Basis::bezier(), bsp = scene::Basis::bspline();
    // Bicubic nonperiodic: (n - 4) / step + 1; periodic: n / step.
    EXPECT_EQ(countPatches(meshRecord("bicubic", 7, "nonperiodic", 4, "nonperiodic", bez)), 2u * 1u);
    EXPECT_EQ(countPatches(meshRecord("bicubic", 10, "nonperiodic", 7, "nonperiodic", bez)), 3u * 2u);
    EXPECT_EQ(countPatches(meshRecord("bicubic", 6, "periodic", 9, "periodic", bez)), 2u * 3u);
    EXPECT_EQ(countPatches(meshRecord("bicubic", 8, "periodic", 5, "nonperiodic", bsp)), 8u * 2u);
    // Bilinear nonperiodic: n - 1; periodic: n.
    EXPECT_EQ(countPatches(meshRecord("bilinear", 3, "nonperiodic", 4, "nonperiodic", bez)), 2u * 3u);
    EXPECT_EQ(countPatches(meshRecord("bilinear", 3, "periodic", 4, "nonperiodic", bez)), 3u * 3u);
}

TEST(PatchMesh, BadSizeIsReported) {
    Diagnostics diag;
    diag.setRecord(true);
    diag.setSink([](const Diagnostic&) {});
    auto prims = makePrimitives(meshRecord("bicubic", 6, "nonperiodic", 4, "nonperiodic", scene::Basis::bezier()), diag);
    EXPECT_TRUE(prims.empty());
    ASSERT_EQ(diag.recorded().size(), 1u);
    EXPECT_EQ(diag.recorded()[0].message,
              "PatchMesh: nu is 6, expected 4 plus a multiple of the step for a nonperiodic bicubic mesh with ustep 3");
}

TEST(PatchMesh, PeriodicBSplineTubeIsClosedAndContinuous) {
    // A ring of 8 control points around z, 4 rows up: periodic in u.
    std::vector<float> P;
    for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 8; ++i) {
            const float a = 2 * kPi * float(i) / 8;
            P.insert(P.end(), {std::cos(a), std::sin(a), float(j)});
        }
    auto rec = record("PatchMesh", {}, {pointParam(P)});
    rec->stringArgs = {"bicubic", "periodic", "nonperiodic"};
    rec->intArgs = {8, 4};
    auto attrs = std::make_shared<scene::Attributes>();
    attrs->uBasis = attrs->vBasis = scene::Basis::bspline();
    patchByPatch(*attrs);
    rec->attributes = attrs;
    Diagnostics diag;
    auto prims = makePrimitives(rec, diag);
    ASSERT_EQ(prims.size(), 8u);
    for (size_t k = 0; k < prims.size(); ++k) {
        Grid a = prims[k]->dice(4, 4), b = prims[(k + 1) % prims.size()]->dice(4, 4);
        for (int j = 0; j <= 4; ++j) EXPECT_LT(length(a.P[size_t(a.index(4, j))] - b.P[size_t(b.index(0, j))]), 1e-5f);
        // u runs over the whole mesh, patch by patch.
        EXPECT_FLOAT_EQ(a.u[0], float(k) / 8);
    }
}

TEST(PatchMesh, VariablesOfEveryClass) {
    // 7 x 4 bezier mesh: 2 x 1 patches, 3 x 2 varying values.
    const int nu = 7, nv = 4;
    std::vector<float> h;  // vertex class: equal to the control point's x, so it must follow P.x
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i < nu; ++i) h.push_back(float(i));
    auto rec = meshRecord("bicubic", nu, "nonperiodic", nv, "nonperiodic", scene::Basis::bezier(),
                          {floatParam("h", ri::ParamType::Float, h, ri::StorageClass::Vertex),
                           floatParam("w", ri::ParamType::Float, {0, 1, 2, 10, 11, 12}, ri::StorageClass::Varying),
                           floatParam("id", ri::ParamType::Float, {5, 6}, ri::StorageClass::Uniform),
                           floatParam("k", ri::ParamType::Float, {3}, ri::StorageClass::Constant)});
    Diagnostics diag;
    auto prims = makePrimitives(rec, diag);
    ASSERT_EQ(diag.errorCount(), 0);
    ASSERT_EQ(prims.size(), 2u);
    for (int p = 0; p < 2; ++p) {
        Grid g = prims[size_t(p)]->dice(3, 3);
        const GridVar* hv = g.find("h");
        const GridVar* w = g.find("w");
        const GridVar* id = g.find("id");
        const GridVar* k = g.find("k");
        ASSERT_TRUE(hv && w && id && k);
        EXPECT_EQ(id->data[0], p == 0 ? 5.0f : 6.0f);
        EXPECT_EQ(k->data[0], 3.0f);
        for (int q = 0; q < g.vertexCount(); ++q) {
            EXPECT_NEAR(hv->at(q)[0], g.P[size_t(q)].x, 1e-5f);
            // Varying: bilinear over this patch's corners (p, p+1) x (row 0, row 1).
            const float a = g.u[size_t(q)] * 2 - float(p), b = g.v[size_t(q)];
            const float want = (1 - b) * (float(p) + a) + b * (10 + float(p) + a);
            EXPECT_NEAR(w->at(q)[0], want, 1e-5f);
        }
    }
}

TEST(Patch, FlatQuadOnlyForFlatConvexStraightEdgedPatches) {
    // A depth pass dices flat quads as one micropolygon, which is exact
    // only for a flat, convex outline with straight edges.
    auto flat = [](std::vector<float> P, int dim = 3) {
        auto rec = dim == 3 ? patchRecord("bilinear", std::move(P))
                            : record("Patch", {}, {floatParam("Pw", ri::ParamType::HPoint, std::move(P),
                                                              ri::StorageClass::Vertex)});
        rec->stringArgs = {"bilinear"};
        auto p = makeOne(rec);
        return p && p->flatQuad();
    };
    // Corners in patch order (0,0) (1,0) (0,1) (1,1).
    EXPECT_TRUE(flat({0, 0, 0, 2, 0, 0, 0, 1, 0, 2, 1, 0}));          // a rectangle
    EXPECT_TRUE(flat({0, 0, 5, 2, 0.5f, 7.5f, -1, 1, 5, 3, 2, 10}));  // a tilted convex quad: z = 5 + x + y
    EXPECT_TRUE(flat({0, 0, 0, 2, 0, 0, 1, 1, 0, 1, 1, 0}));          // a triangle (collapsed edge)
    EXPECT_FALSE(flat({0, 0, 0, 2, 0, 0, 0, 1, 0, 2, 1, 0.01f}));     // twisted: a saddle
    EXPECT_FALSE(flat({0, 0, 0, 2, 0, 0, 0, 2, 0, 0.5f, 0.5f, 0}));   // flat but a dart (reflex corner)
    EXPECT_FALSE(flat({0, 0, 0, 1, 0, 0, 2, 0, 0, 3, 0, 0}));         // collinear: no plane
    EXPECT_FALSE(flat({0, 0, 0, 1, 1, 0, 0, 1, 0, 1, 0, 1, 2, 2, 0, 2}, 4));  // rational: a flat square, unequal w
    EXPECT_TRUE(flat({0, 0, 0, 2, 2, 0, 0, 2, 0, 2, 0, 2, 2, 2, 0, 2}, 4));   // homogeneous, equal w

    // Split pieces of a flat quad are flat quads; bicubic patches never are.
    std::vector<PrimitivePtr> pieces;
    makeOne(patchRecord("bilinear", {0, 0, 5, 2, 0.5f, 7.5f, -1, 1, 5, 3, 2, 10}))->split(true, pieces);
    ASSERT_EQ(pieces.size(), 2u);
    for (const auto& piece : pieces) EXPECT_TRUE(piece->flatQuad());
    std::vector<float> G;
    for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) G.insert(G.end(), {i / 3.0f, j / 3.0f, 0});
    EXPECT_FALSE(makeOne(patchRecord("bicubic", G))->flatQuad());
}
