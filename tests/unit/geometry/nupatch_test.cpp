#include "geometry_test_util.h"

#include "umbra/geometry/nupatch.h"
#include "umbra/geometry/patch.h"
#include "umbra/util/rng.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace umbra;
using namespace umbra::geometry;
using namespace umbra::testutil;

namespace {

// A NuPatch record: knots include min and max as the RIB gives them.
std::shared_ptr<scene::PrimitiveRecord> nuRecord(int nu, int uorder, std::vector<float> uknot, float umin, float umax,
                                                 int nv, int vorder, std::vector<float> vknot, float vmin, float vmax,
                                                 std::vector<float> P, bool rational,
                                                 std::vector<ri::Param> extra = {}) {
    std::vector<float> f = uknot;
    f.insert(f.end(), {umin, umax});
    f.insert(f.end(), vknot.begin(), vknot.end());
    f.insert(f.end(), {vmin, vmax});
    extra.push_back(rational ? floatParam("Pw", ri::ParamType::HPoint, std::move(P), ri::StorageClass::Vertex)
                             : pointParam(std::move(P)));
    auto rec = record("NuPatch", std::move(f), std::move(extra));
    rec->intArgs = {nu, uorder, nv, vorder};
    return rec;
}

std::vector<PrimitivePtr> make(std::shared_ptr<scene::PrimitiveRecord> rec, int expectErrors = 0) {
    Diagnostics diag;
    auto prims = makePrimitives(std::move(rec), diag);
    EXPECT_EQ(diag.errorCount(), expectErrors);
    return prims;
}

// Cox-de Boor recursion, straight from the definition (degree p, basis i).
double coxDeBoor(const std::vector<float>& t, int i, int p, double x, int lastSpan) {
    if (p == 0) {
        if (i == lastSpan && x == double(t[size_t(i + 1)])) return 1;  // the closed right end
        return double(t[size_t(i)]) <= x && x < double(t[size_t(i + 1)]) ? 1 : 0;
    }
    double r = 0;
    const double d0 = double(t[size_t(i + p)]) - t[size_t(i)], d1 = double(t[size_t(i + p + 1)]) - t[size_t(i + 1)];
    if (d0 > 0) r += (x - t[size_t(i)]) / d0 * coxDeBoor(t, i, p - 1, x, lastSpan);
    if (d1 > 0) r += (t[size_t(i + p + 1)] - x) / d1 * coxDeBoor(t, i + 1, p - 1, x, lastSpan);
    return r;
}

Vec3 reference(int nu, int uorder, const std::vector<float>& uk, int nv, int vorder, const std::vector<float>& vk,
               const std::vector<float>& P, int dim, double u, double v) {
    int lastU = nu - 1, lastV = nv - 1;
    while (uk[size_t(lastU)] == uk[size_t(lastU + 1)]) --lastU;
    while (vk[size_t(lastV)] == vk[size_t(lastV + 1)]) --lastV;
    double acc[4] = {0, 0, 0, 0};
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i < nu; ++i) {
            const double w = coxDeBoor(uk, i, uorder - 1, u, lastU) * coxDeBoor(vk, j, vorder - 1, v, lastV);
            for (int c = 0; c < dim; ++c) acc[c] += w * P[size_t((j * nu + i) * dim + c)];
        }
    if (dim == 4) return {float(acc[0] / acc[3]), float(acc[1] / acc[3]), float(acc[2] / acc[3])};
    return {float(acc[0]), float(acc[1]), float(acc[2])};
}

std::vector<float> randomNet(uint32_t seed, int nu, int nv, int dim) {
    Rng rng(seed);
    std::vector<float> G;
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i < nu; ++i) {
            const float w = dim == 4 ? 0.5f + rng.uniform() : 1.0f;
            G.insert(G.end(), {(float(i) + rng.uniform() - 0.5f) * w, (float(j) + rng.uniform() - 0.5f) * w,
                               (2 * rng.uniform() - 1) * w});
            if (dim == 4) G.push_back(w);
        }
    return G;
}

float maxDistance(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
    EXPECT_EQ(a.size(), b.size());
    float d = 0;
    for (size_t k = 0; k < std::min(a.size(), b.size()); ++k) d = std::max(d, length(a[k] - b[k]));
    return d;
}

}  // namespace

TEST(NuPatch, BezierKnotsEqualBicubicPatch) {
    for (int dim : {3, 4}) {
        const std::vector<float> G = randomNet(7 + uint32_t(dim), 4, 4, dim);
        const std::vector<float> knots = {0, 0, 0, 0, 1, 1, 1, 1};
        auto nu = make(nuRecord(4, 4, knots, 0, 1, 4, 4, knots, 0, 1, G, dim == 4));
        auto patchRec =
            record("Patch", {},
                   {dim == 4 ? floatParam("Pw", ri::ParamType::HPoint, G, ri::StorageClass::Vertex) : pointParam(G)});
        patchRec->stringArgs = {"bicubic"};
        auto patch = make(patchRec);
        ASSERT_EQ(nu.size(), 1u);
        ASSERT_EQ(patch.size(), 1u);
        const Grid a = nu[0]->dice(9, 7), b = patch[0]->dice(9, 7);
        EXPECT_LT(maxDistance(a.P, b.P), 2e-5f) << "dim " << dim;
        for (size_t k = 0; k < a.u.size(); ++k) {
            EXPECT_FLOAT_EQ(a.u[k], b.u[k]);
            EXPECT_FLOAT_EQ(a.v[k], b.v[k]);
        }
        std::vector<Vec3> P;
        nu[0]->dicePositions(9, 7, P);
        EXPECT_LT(maxDistance(P, a.P), 1e-6f);
    }
}

TEST(NuPatch, AnyOrderMatchesCoxDeBoor) {
    // Order 3 in u with a double interior knot, order 5 in v, rational.
    const int nu = 6, uorder = 3, nv = 7, vorder = 5;
    const std::vector<float> uk = {0, 0, 0, 0.3f, 0.6f, 0.6f, 1.5f, 1.5f, 1.5f};
    const std::vector<float> vk = {-1, -1, -1, -1, -1, 0, 0.5f, 2, 2, 2, 2, 2};
    const std::vector<float> G = randomNet(11, nu, nv, 4);
    auto prims = make(nuRecord(nu, uorder, uk, 0, 1.5f, nv, vorder, vk, -1, 2, G, true));
    EXPECT_EQ(prims.size(), 3u * 3u);  // non-empty spans
    for (const auto& p : prims) {
        const Grid g = p->dice(5, 4);
        const Bound3 b = p->bound();
        for (size_t k = 0; k < g.P.size(); ++k) {
            const Vec3 r = reference(nu, uorder, uk, nv, vorder, vk, G, 4, g.u[k], g.v[k]);
            EXPECT_LT(length(g.P[k] - r), 2e-5f) << "u " << g.u[k] << " v " << g.v[k];
            EXPECT_TRUE(inside(b, g.P[k], 1e-5f));
        }
        std::vector<PrimitivePtr> halves;
        p->split(true, halves);
        for (const auto& h : halves) {
            const Grid hg = h->dice(3, 3);
            const Bound3 hb = h->bound();
            for (const Vec3& q : hg.P) EXPECT_TRUE(inside(hb, q, 1e-5f));
        }
    }
}

TEST(NuPatch, PartialRangeIsTheSubPatch) {
    const int n = 5, order = 4;
    const std::vector<float> k = {0, 0, 0, 0, 1, 2, 2, 2, 2};
    const std::vector<float> G = randomNet(3, n, n, 3);
    auto prims = make(nuRecord(n, order, k, 0.25f, 1.5f, n, order, k, 0.5f, 2, G, false));
    ASSERT_EQ(prims.size(), 4u);
    float umin = 10, umax = -10, vmin = 10, vmax = -10;
    for (const auto& p : prims) {
        const Grid g = p->dice(4, 4);
        for (size_t i = 0; i < g.P.size(); ++i) {
            umin = std::min(umin, g.u[i]);
            umax = std::max(umax, g.u[i]);
            vmin = std::min(vmin, g.v[i]);
            vmax = std::max(vmax, g.v[i]);
            EXPECT_LT(length(g.P[i] - reference(n, order, k, n, order, k, G, 3, g.u[i], g.v[i])), 2e-5f);
        }
    }
    EXPECT_FLOAT_EQ(umin, 0.25f);
    EXPECT_FLOAT_EQ(umax, 1.5f);
    EXPECT_FLOAT_EQ(vmin, 0.5f);
    EXPECT_FLOAT_EQ(vmax, 2.0f);
}

TEST(NuPatch, RationalSphereIsRound) {
    // The 9-point circle (order 3, weights sqrt(2)/2 at the corners) in v,
    // a half circle (5 points) in the profile, revolved.
    const float h = std::sqrt(2.0f) / 2;
    const float cx[9] = {1, 1, 0, -1, -1, -1, 0, 1, 1}, cy[9] = {0, 1, 1, 1, 0, -1, -1, -1, 0};
    const float cw[9] = {1, h, 1, h, 1, h, 1, h, 1};
    const float pr[5] = {0, 1, 1, 1, 0}, pz[5] = {-1, -1, 0, 1, 1}, pw[5] = {1, h, 1, h, 1};
    std::vector<float> Pw;
    for (int j = 0; j < 5; ++j)
        for (int i = 0; i < 9; ++i) {
            const float w = cw[i] * pw[j];
            Pw.insert(Pw.end(), {cx[i] * pr[j] * w, cy[i] * pr[j] * w, pz[j] * w, w});
        }
    const std::vector<float> uk = {0, 0, 0, 0.25f, 0.25f, 0.5f, 0.5f, 0.75f, 0.75f, 1, 1, 1};
    const std::vector<float> vk = {0, 0, 0, 0.5f, 0.5f, 1, 1, 1};
    auto prims = make(nuRecord(9, 3, uk, 0, 1, 5, 3, vk, 0, 1, Pw, true));
    EXPECT_EQ(prims.size(), 8u);
    for (const auto& p : prims)
        for (const Vec3& q : p->dice(8, 8).P) EXPECT_NEAR(length(q), 1.0f, 2e-6f);
    EXPECT_NEAR(totalArea(prims, 32), 4 * M_PI, 4 * M_PI * 2e-3);
}

TEST(NuPatch, VaryingAndUniformArePerSegment) {
    // Two segments in u (knots 0 0 0 1 2 2 2 for 4 points of order 3):
    // varying has 3 x 2 values, uniform 2.
    const std::vector<float> uk = {0, 0, 0, 1, 2, 2, 2}, vk = {0, 0, 1, 1};
    const std::vector<float> P = randomNet(5, 4, 2, 3);
    auto rec = nuRecord(4, 3, uk, 0, 2, 2, 2, vk, 0, 1, P, false,
                        {floatParam("a", ri::ParamType::Float, {0, 10, 20, 1, 11, 21}, ri::StorageClass::Varying),
                         floatParam("k", ri::ParamType::Float, {5, 7}, ri::StorageClass::Uniform)});
    auto prims = make(rec);
    ASSERT_EQ(prims.size(), 2u);
    for (const auto& p : prims) {
        const Grid g = p->dice(2, 2);
        const GridVar* a = g.find("a");
        const GridVar* k = g.find("k");
        ASSERT_TRUE(a && k);
        for (int i = 0; i < g.vertexCount(); ++i) EXPECT_NEAR(*a->at(i), 10 * g.u[size_t(i)] + g.v[size_t(i)], 1e-5f);
        EXPECT_EQ(*k->at(0), g.u[0] < 1 ? 5.0f : 7.0f);
    }
}

TEST(NuPatch, MalformedRecordsAreReported) {
    const std::vector<float> P = randomNet(1, 4, 4, 3);
    const std::vector<float> k = {0, 0, 0, 0, 1, 1, 1, 1}, bad = {0, 0, 0, 1, 0, 1, 1, 1};
    EXPECT_TRUE(make(nuRecord(4, 4, bad, 0, 1, 4, 4, k, 0, 1, P, false), 1).empty());
    EXPECT_TRUE(make(nuRecord(4, 4, k, 0, 2, 4, 4, k, 0, 1, P, false), 1).empty());
    EXPECT_TRUE(make(nuRecord(4, 5, k, 0, 1, 4, 4, k, 0, 1, P, false), 1).empty());
    auto rec = nuRecord(4, 4, k, 0, 1, 4, 4, k, 0, 1, P, false);
    rec->floatArgs.pop_back();
    EXPECT_TRUE(make(rec, 1).empty());
}

TEST(NuPatch, VertexVariablesFollowTheBSplineBasis) {
    // A vertex-class colour on a rational order-3 x order-2 patch: the
    // polynomial B-spline combination of the control values (not divided
    // by the weights, as for Patch).
    const int nu = 5, nv = 3;
    const std::vector<float> uk = {0, 0, 0, 1, 2, 3, 3, 3}, vk = {0, 0, 0.5f, 1, 1};
    const std::vector<float> G = randomNet(21, nu, nv, 4);
    std::vector<float> c, cx;
    for (int k = 0; k < nu * nv; ++k) {
        c.insert(c.end(), {float(k), float(k * k) * 0.1f, 1.0f - float(k)});
        cx.insert(cx.end(), {float(k), float(k * k) * 0.1f, 1.0f - float(k), 1.0f});
    }
    auto prims = make(nuRecord(nu, 3, uk, 0, 3, nv, 2, vk, 0, 1, G, true,
                               {floatParam("Cs", ri::ParamType::Color, c, ri::StorageClass::Vertex)}));
    ASSERT_EQ(prims.size(), 6u);
    for (const auto& p : prims) {
        const Grid g = p->dice(3, 2);
        const GridVar* cs = g.find("Cs");
        ASSERT_TRUE(cs);
        for (int i = 0; i < g.vertexCount(); ++i) {
            const Vec3 r = reference(nu, 3, uk, nv, 2, vk, cx, 4, g.u[size_t(i)], g.v[size_t(i)]);
            for (int k = 0; k < 3; ++k) EXPECT_NEAR(cs->at(i)[k], (&r.x)[k], 1e-4f * (1 + std::abs((&r.x)[k])));
        }
    }
}
