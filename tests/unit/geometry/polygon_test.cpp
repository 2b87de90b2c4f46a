#include "geometry_test_util.h"

#include "umbra/geometry/polygon.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>

using namespace umbra;
using namespace umbra::geometry;
using namespace umbra::testutil;

namespace {

std::vector<PrimitivePtr> makeAll(std::shared_ptr<scene::PrimitiveRecord> rec, Diagnostics* out = nullptr) {
    Diagnostics diag;
    auto prims = makePrimitives(std::move(rec), out ? *out : diag);
    if (!out) {
        EXPECT_EQ(diag.errorCount(), 0);
    }
    return prims;
}

// Shoelace area of a planar loop in the xy plane.
double loopArea(const std::vector<float>& xyz) {
    double a = 0;
    const size_t n = xyz.size() / 3;
    for (size_t i = 0; i < n; ++i) {
        const size_t j = (i + 1) % n;
        a += double(xyz[3 * i]) * xyz[3 * j + 1] - double(xyz[3 * j]) * xyz[3 * i + 1];
    }
    return 0.5 * a;
}

double cross2d(const Vec2& a, const Vec2& b) { return double(a.x) * b.y - double(a.y) * b.x; }

}  // namespace

TEST(Polygon, QuadIsOneDiceableBilinearPatchWithDefaultST) {
    auto prims = makeAll(record("Polygon", {}, {pointParam({0, 0, 0, 2, 0, 0, 2, 1, 0, 0, 1, 0})}));
    ASSERT_EQ(prims.size(), 1u);
    EXPECT_TRUE(prims[0]->diceable());
    Grid g = prims[0]->dice(4, 2);
    EXPECT_NEAR(gridArea(g), 2.0, 1e-6);
    const GridVar* s = g.find("s");
    const GridVar* t = g.find("t");
    ASSERT_TRUE(s && t);
    for (int k = 0; k < g.vertexCount(); ++k) {
        EXPECT_FLOAT_EQ(g.P[size_t(k)].x, 2 * g.u[size_t(k)]);
        EXPECT_FLOAT_EQ(g.P[size_t(k)].y, g.v[size_t(k)]);
        EXPECT_EQ(s->at(k)[0], g.u[size_t(k)]);
        EXPECT_EQ(t->at(k)[0], g.v[size_t(k)]);
    }
    // Counter-clockwise in xy: dPdu x dPdv along +z, like the polygon's winding.
    EXPECT_GT(cross(g.P[1] - g.P[0], g.P[size_t(g.nu + 1)] - g.P[0]).z, 0);
}

TEST(Polygon, ConvexPentagonSplitsIntoPiecesOfEqualTotalArea) {
    std::vector<float> P;
    for (int k = 0; k < 5; ++k) {
        const float a = 2 * kPi * float(k) / 5;
        P.insert(P.end(), {std::cos(a), std::sin(a), 1});
    }
    auto prims = makeAll(record("Polygon", {}, {pointParam(P)}));
    ASSERT_EQ(prims.size(), 1u);
    EXPECT_FALSE(prims[0]->diceable());
    auto pieces = splitToDiceable(std::move(prims));
    EXPECT_EQ(pieces.size(), 2u);  // a quad and a triangle
    EXPECT_NEAR(totalArea(pieces, 4), 2.5 * std::sin(2 * M_PI / 5), 1e-5);
    for (const auto& p : pieces) {
        Grid g = p->dice(3, 3);
        for (const Vec3& q : g.P) EXPECT_FLOAT_EQ(q.z, 1);
        EXPECT_GT(cross(g.P[1] - g.P[0], g.P[size_t(g.nu + 1)] - g.P[0]).z, -1e-6f);
    }
}

TEST(Polygon, GeneralPolygonWithHolesHasAreaOfOutlineMinusHoles) {
    const std::vector<float> outer = {0, 0, 0, 4, 0, 0, 4, 4, 0, 0, 4, 0};
    const std::vector<float> hole1 = {1, 1, 0, 1, 2, 0, 2, 2, 0, 2, 1, 0};                  // clockwise
    const std::vector<float> hole2 = {2.5f, 2.5f, 0, 3.5f, 2.5f, 0, 3.5f, 3.5f, 0, 2.5f, 3.5f, 0};  // counter-clockwise
    std::vector<float> P = outer;
    P.insert(P.end(), hole1.begin(), hole1.end());
    P.insert(P.end(), hole2.begin(), hole2.end());
    auto rec = record("GeneralPolygon", {}, {pointParam(P)});
    rec->intArrays = {{4, 4, 4}};
    auto pieces = splitToDiceable(makeAll(rec));
    const double want = loopArea(outer) - std::abs(loopArea(hole1)) - std::abs(loopArea(hole2));
    EXPECT_NEAR(totalArea(pieces, 2), want, 1e-4);
    // No piece covers a hole's centre: every triangle keeps the outline's winding (+z).
    for (const auto& p : pieces) {
        Grid g = p->dice(1, 1);
        const Vec3 n = cross(g.P[1] - g.P[0], g.P[2] - g.P[0]) + cross(g.P[3] - g.P[1], g.P[2] - g.P[1]);
        EXPECT_GE(n.z, -1e-6f);
    }
}

TEST(Polygon, ConcaveOutlineIsTriangulated) {
    // An L shape (area 3) with the reflex corner at (1, 1), wound clockwise.
    std::vector<float> P = {0, 0, 0, 0, 2, 0, 1, 2, 0, 1, 1, 0, 2, 1, 0, 2, 0, 0};
    auto rec = record("GeneralPolygon", {}, {pointParam(P)});
    rec->intArrays = {{6}};
    auto pieces = splitToDiceable(makeAll(rec));
    EXPECT_NEAR(totalArea(pieces, 2), 3.0, 1e-5);
    for (const auto& p : pieces) {
        Grid g = p->dice(1, 1);
        EXPECT_LE(cross(g.P[1] - g.P[0], g.P[2] - g.P[0]).z, 1e-6f);  // clockwise kept
    }
}

TEST(Polygon, TriangulationOfAComb) {
    // A comb with three teeth, 3D plane x + y + z = 1 tilted: area is preserved by projection ratios.
    std::vector<Vec3> pts;
    const std::vector<Vec2> xy = {{0, 0}, {5, 0}, {5, 3}, {4, 3}, {4, 1}, {3, 1}, {3, 3}, {2, 3}, {2, 1}, {1, 1}, {1, 3}, {0, 3}};
    for (const Vec2& q : xy) pts.push_back({q.x, q.y, 1 - q.x - q.y});
    std::vector<std::array<int, 3>> tris;
    EXPECT_TRUE(triangulatePolygon(pts, {int(pts.size())}, tris));
    EXPECT_EQ(tris.size(), pts.size() - 2);
    double projected = 0;
    for (const auto& t : tris) {
        const double a = cross2d(xy[size_t(t[1])] - xy[size_t(t[0])], xy[size_t(t[2])] - xy[size_t(t[0])]);
        EXPECT_GT(a, 0);
        projected += 0.5 * a;
    }
    EXPECT_NEAR(projected, 5 * 3 - 2 * (1 * 2), 1e-6);  // 5x3 minus two 1x2 notches
}

// Two quads sharing the edge (1,0)-(1,1): six shared vertices, a vertex
// colour, a uniform float per face and facevarying st per face corner.
TEST(PointsPolygons, SharedVerticesFaceVaryingAndUniform) {
    const std::vector<float> P = {0, 0, 0, 1, 0, 0, 2, 0, 0, 0, 1, 0, 1, 1, 0, 2, 1, 0};
    const std::vector<float> h = {0, 10, 20, 30, 40, 50};  // per vertex
    const std::vector<float> st = {0, 0, 0.5f, 0, 0.5f, 1, 0, 1,  // face 0 corners
                                   0.5f, 0, 1, 0, 1, 1, 0.5f, 1};  // face 1 corners
    auto rec = record("PointsPolygons", {},
                      {pointParam(P), floatParam("h", ri::ParamType::Float, h, ri::StorageClass::Vertex),
                       floatParam("id", ri::ParamType::Float, {7, 9}, ri::StorageClass::Uniform),
                       floatParam("st", ri::ParamType::Float, st, ri::StorageClass::FaceVarying, 2)});
    rec->intArrays = {{4, 4}, {0, 1, 4, 3, 1, 2, 5, 4}};
    auto prims = makeAll(rec);
    ASSERT_EQ(prims.size(), 1u);
    EXPECT_FALSE(prims[0]->diceable());
    const Bound3 b = prims[0]->bound();
    EXPECT_EQ(b.min, Vec3(0, 0, 0));
    EXPECT_EQ(b.max, Vec3(2, 1, 0));
    auto faces = splitToDiceable(std::move(prims));
    ASSERT_EQ(faces.size(), 2u);
    int seen = 0;
    for (const auto& f : faces) {
        Grid g = f->dice(2, 2);
        const GridVar* id = g.find("id");
        const GridVar* hv = g.find("h");
        const GridVar* s = g.find("s");
        const GridVar* t = g.find("t");
        ASSERT_TRUE(id && hv && s && t);
        EXPECT_FALSE(id->perVertex);
        const bool second = g.P[0].x > 0.5f;
        seen |= second ? 2 : 1;
        EXPECT_EQ(id->data[0], second ? 9.0f : 7.0f);
        for (int k = 0; k < g.vertexCount(); ++k) {
            const Vec3 p = g.P[size_t(k)];
            // h is bilinear over the face: h = 10 x + 30 y on this layout.
            EXPECT_NEAR(hv->at(k)[0], 10 * p.x + 30 * p.y, 1e-5f);
            // st was laid out as s = x / 2, t = y.
            EXPECT_NEAR(s->at(k)[0], p.x / 2, 1e-6f);
            EXPECT_NEAR(t->at(k)[0], p.y, 1e-6f);
        }
    }
    EXPECT_EQ(seen, 3);
}

TEST(PointsPolygons, WrongPointCountIsReported) {
    Diagnostics diag;
    diag.setRecord(true);
    diag.setSink([](const Diagnostic&) {});
    auto rec = record("PointsPolygons", {}, {pointParam(std::vector<float>(15, 0.0f))});
    rec->intArrays = {{4, 4}, {0, 1, 2, 3, 4, 5, 6, 7}};
    auto prims = makeAll(rec, &diag);
    EXPECT_TRUE(prims.empty());
    ASSERT_EQ(diag.recorded().size(), 1u);
    EXPECT_EQ(diag.recorded()[0].str(), "test.rib:3:1: error: PointsPolygons: \"P\" has 5 values, expected 8 (one per vertex)");
}

TEST(PointsPolygons, IndexArrayMismatchIsReported) {
    Diagnostics diag;
    diag.setRecord(true);
    diag.setSink([](const Diagnostic&) {});
    auto rec = record("PointsPolygons", {}, {pointParam(std::vector<float>(12, 0.0f))});
    rec->intArrays = {{3, 3}, {0, 1, 2, 3}};
    EXPECT_TRUE(makeAll(rec, &diag).empty());
    ASSERT_EQ(diag.recorded().size(), 1u);
    EXPECT_EQ(diag.recorded()[0].message, "PointsPolygons: vertices has 4 indices, expected 6 (the sum of nverts)");
}

TEST(PointsGeneralPolygons, FaceWithHoleAndPlainTriangle) {
    // Face 0: a 3x3 square with a 1x1 hole; face 1: a triangle of area 0.5.
    const std::vector<float> P = {0, 0, 0, 3, 0, 0, 3, 3, 0, 0, 3, 0, 1, 1, 0, 2, 1, 0, 2, 2, 0, 1, 2, 0,
                                  4, 0, 0, 5, 0, 0, 4, 1, 0};
    auto rec = record("PointsGeneralPolygons", {}, {pointParam(P)});
    rec->intArrays = {{2, 1}, {4, 4, 3}, {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10}};
    auto pieces = splitToDiceable(makeAll(rec));
    EXPECT_NEAR(totalArea(pieces, 2), 9 - 1 + 0.5, 1e-5);
}

namespace {

// Every piece, split down to diceable ones in the same order, diced 3 x 2.
std::vector<Grid> dicedPieces(std::vector<PrimitivePtr> prims) {
    std::vector<Grid> grids;
    for (auto& top : prims) {
        std::vector<PrimitivePtr> one;
        one.push_back(std::move(top));
        for (const auto& p : splitToDiceable(std::move(one))) grids.push_back(p->dice(3, 2));
    }
    return grids;
}

/// Checks a triangulation of the loops `xy` (outline counter-clockwise,
/// holes either way) and returns its area: every triangle turns
/// counter-clockwise and, when `edgesExact`, every outline and hole edge is
/// used once in its own direction (holes' reversed) and every other edge
/// twice, once each way. Positive triangles whose boundary is the polygon's
/// cover its inside once and nothing outside.
double checkTriangulation(const std::vector<Vec2>& xy, const std::vector<int>& loopSizes,
                          const std::vector<std::array<int, 3>>& tris, bool edgesExact) {
    std::map<std::pair<int, int>, int> uses;
    double area = 0;
    for (const auto& t : tris) {
        const Vec2 &p = xy[size_t(t[0])], &q = xy[size_t(t[1])], &r = xy[size_t(t[2])];
        const double a = (double(q.x) - p.x) * (double(r.y) - p.y) - (double(q.y) - p.y) * (double(r.x) - p.x);
        EXPECT_GT(a, 0);
        area += 0.5 * a;
        for (int k = 0; k < 3; ++k) ++uses[{t[size_t(k)], t[size_t((k + 1) % 3)]}];
    }
    if (!edgesExact) return area;
    int start = 0;
    for (size_t l = 0; l < loopSizes.size(); start += loopSizes[l], ++l) {
        double loop = 0;
        for (int k = 0; k < loopSizes[l]; ++k) {
            const Vec2 &a = xy[size_t(start + k)], &b = xy[size_t(start + (k + 1) % loopSizes[l])];
            loop += cross2d(a, b);
        }
        const bool reversed = l > 0 && loop > 0;
        for (int k = 0; k < loopSizes[l]; ++k) {
            int a = start + k, b = start + (k + 1) % loopSizes[l];
            if (reversed) std::swap(a, b);
            auto it = uses.find({a, b});
            EXPECT_TRUE(it != uses.end() && it->second == 1) << "boundary edge " << a << "-" << b;
            EXPECT_EQ(uses.count({b, a}), 0u) << "boundary edge used backwards " << a << "-" << b;
            if (it != uses.end()) uses.erase(it);
        }
    }
    for (const auto& [e, count] : uses) {
        EXPECT_EQ(count, 1) << e.first << "-" << e.second;
        EXPECT_EQ(uses.count({e.second, e.first}), 1u) << "interior edge without its twin " << e.first << "-" << e.second;
    }
    return area;
}

double shoelace(const std::vector<Vec2>& xy, int start, int size) {
    double a = 0;
    for (int k = 0; k < size; ++k) a += cross2d(xy[size_t(start + k)], xy[size_t(start + (k + 1) % size)]);
    return 0.5 * a;
}

std::vector<Vec3> inPlane(const std::vector<Vec2>& xy) {
    std::vector<Vec3> pts;
    for (const Vec2& q : xy) pts.push_back({q.x, q.y, 0});
    return pts;
}

/// A star of n vertices about the origin, radii alternating 1 and 0.3.
std::vector<Vec2> star(int n) {
    std::vector<Vec2> xy;
    for (int k = 0; k < n; ++k) {
        const double a = 2 * M_PI * k / n, r = k % 2 ? 0.3 : 1.0;
        xy.push_back({float(r * std::cos(a)), float(r * std::sin(a))});
    }
    return xy;
}

}  // namespace

TEST(PolygonRun, DicesExactlyAsItsPolygonsAsSeparateRecords) {
    // A triangle, a convex quad, a convex pentagon, a concave hexagon and a
    // degenerate (zero-area) quad, as the builder would merge them.
    const std::vector<std::vector<float>> polygons = {
        {0, 0, 0, 1, 0, 0, 0, 1, 0},
        {2, 0, 0, 3, 0, 0.5f, 3, 1, 0, 2, 1, 0.25f},
        {4, 0, 0, 5, 0, 0, 5.5f, 0.5f, 0, 5, 1, 0, 4, 1, 0},
        {6, 0, 0, 8, 0, 0, 8, 2, 0, 7.5f, 2, 0, 7.5f, 0.5f, 0, 6, 0.5f, 0},
        {9, 0, 0, 9, 0, 0, 9, 0, 0, 9, 0, 0},
    };
    std::vector<PrimitivePtr> separate;
    std::vector<float> all;
    std::vector<int> nverts;
    for (const auto& xyz : polygons) {
        for (auto& p : makeAll(record("Polygon", {}, {pointParam(xyz)}))) separate.push_back(std::move(p));
        all.insert(all.end(), xyz.begin(), xyz.end());
        nverts.push_back(int(xyz.size() / 3));
    }
    auto run = record("Polygon", {}, {pointParam(all)});
    run->intArrays = {nverts};
    std::vector<PrimitivePtr> merged = makeAll(run);
    ASSERT_EQ(merged.size(), separate.size());
    for (size_t k = 0; k < merged.size(); ++k) {
        EXPECT_EQ(merged[k]->diceable(), separate[k]->diceable()) << k;
        EXPECT_EQ(merged[k]->bound().min, separate[k]->bound().min) << k;
        EXPECT_EQ(merged[k]->bound().max, separate[k]->bound().max) << k;
    }
    const std::vector<Grid> a = dicedPieces(std::move(merged)), b = dicedPieces(std::move(separate));
    ASSERT_EQ(a.size(), b.size());
    ASSERT_GE(a.size(), 7u);
    for (size_t k = 0; k < a.size(); ++k) {
        EXPECT_EQ(a[k].P, b[k].P) << k;
        EXPECT_EQ(a[k].N, b[k].N) << k;
        EXPECT_EQ(a[k].u, b[k].u) << k;
        EXPECT_EQ(a[k].v, b[k].v) << k;
        ASSERT_EQ(a[k].vars.size(), b[k].vars.size()) << k;
        for (size_t i = 0; i < a[k].vars.size(); ++i) {
            EXPECT_EQ(a[k].vars[i].name, b[k].vars[i].name);
            EXPECT_EQ(a[k].vars[i].data, b[k].vars[i].data) << k << " " << a[k].vars[i].name;
        }
    }
}

TEST(PolygonRun, PointCountDisagreeingWithTheCountsIsReported) {
    auto run = record("Polygon", {}, {pointParam({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0})});
    run->intArrays = {{3, 3}};
    Diagnostics diag;
    diag.setRecord(true);
    diag.setSink([](const Diagnostic&) {});
    EXPECT_TRUE(makeAll(run, &diag).empty());
    ASSERT_EQ(diag.recorded().size(), 1u);
    EXPECT_NE(diag.recorded()[0].str().find("test.rib:3:1"), std::string::npos) << diag.recorded()[0].str();
}

TEST(PolygonSweep, StarOfAHundredThousandVertices) {
    const std::vector<Vec2> xy = star(100000);
    std::vector<std::array<int, 3>> tris;
    ASSERT_TRUE(triangulatePolygon(inPlane(xy), {int(xy.size())}, tris));
    EXPECT_EQ(tris.size(), xy.size() - 2);
    EXPECT_NEAR(checkTriangulation(xy, {int(xy.size())}, tris, true), shoelace(xy, 0, int(xy.size())), 1e-9);
}

TEST(PolygonSweep, CombAndZigzagOfAHundredThousandVertices) {
    // A comb: 25,000 teeth 1 wide and 10 high on a base 1 high, each tooth
    // four vertices, walked counter-clockwise; and a zigzag strip.
    std::vector<Vec2> comb;
    const int teeth = 25000;
    for (int k = teeth - 1; k >= 0; --k) {
        const float x = 2.0f * float(k);
        comb.insert(comb.end(), {{x + 1, 11}, {x, 11}, {x, 1}, {x - 1, 1}});
    }
    comb.front().x = 2.0f * teeth;  // the last tooth's right side runs to the base's corner
    comb.push_back({-1, 0});
    comb.push_back({2.0f * teeth, 0});
    std::rotate(comb.begin(), comb.end() - 2, comb.end());
    ASSERT_GT(shoelace(comb, 0, int(comb.size())), 0);
    std::vector<std::array<int, 3>> tris;
    ASSERT_TRUE(triangulatePolygon(inPlane(comb), {int(comb.size())}, tris));
    EXPECT_NEAR(checkTriangulation(comb, {int(comb.size())}, tris, true), shoelace(comb, 0, int(comb.size())), 1e-6);

    std::vector<Vec2> zigzag;
    const int n = 50000;
    for (int k = 0; k < n; ++k) zigzag.push_back({float(k), k % 2 ? 1.0f : 0.0f});
    for (int k = n - 1; k >= 0; --k) zigzag.push_back({float(k), k % 2 ? 3.0f : 2.0f});
    tris.clear();
    ASSERT_TRUE(triangulatePolygon(inPlane(zigzag), {int(zigzag.size())}, tris));
    EXPECT_NEAR(checkTriangulation(zigzag, {int(zigzag.size())}, tris, true), shoelace(zigzag, 0, int(zigzag.size())),
                1e-6);
}

TEST(PolygonSweep, ManyHolesEitherWinding) {
    // A 400-gon of radius 20 with a 10 x 10 grid of square holes, half of
    // them wound each way, one a diamond touching no other.
    std::vector<Vec2> xy;
    for (int k = 0; k < 400; ++k) {
        const double a = 2 * M_PI * k / 400;
        xy.push_back({float(20 * std::cos(a)), float(20 * std::sin(a))});
    }
    std::vector<int> loops = {400};
    double expected = shoelace(xy, 0, 400);
    for (int i = 0; i < 10; ++i)
        for (int j = 0; j < 10; ++j) {
            const float x = -12.5f + 2.5f * float(i), y = -12.5f + 2.5f * float(j);
            std::vector<Vec2> sq = {{x, y}, {x + 1, y}, {x + 1, y + 1}, {x, y + 1}};
            if (i == 3 && j == 4) sq = {{x + 0.5f, y}, {x + 1, y + 0.5f}, {x + 0.5f, y + 1}, {x, y + 0.5f}};
            if ((i + j) % 2) std::reverse(sq.begin(), sq.end());
            expected -= std::abs(shoelace(sq, 0, 4));
            xy.insert(xy.end(), sq.begin(), sq.end());
            loops.push_back(4);
        }
    std::vector<std::array<int, 3>> tris;
    ASSERT_TRUE(triangulatePolygon(inPlane(xy), loops, tris));
    EXPECT_EQ(tris.size(), xy.size() + 2 * 100 - 2);  // n + 2 holes - 2
    EXPECT_NEAR(checkTriangulation(xy, loops, tris, true), expected, 1e-9);
}

TEST(PolygonSweep, CollinearRunsKeepTheArea) {
    // A 3 x 2 rectangle with 50 vertices on each side: straight runs,
    // horizontal ones among them.
    std::vector<Vec2> xy;
    for (int k = 0; k < 50; ++k) xy.push_back({3.0f * float(k) / 50, 0});
    for (int k = 0; k < 50; ++k) xy.push_back({3, 2.0f * float(k) / 50});
    for (int k = 0; k < 50; ++k) xy.push_back({3 - 3.0f * float(k) / 50, 2});
    for (int k = 0; k < 50; ++k) xy.push_back({0, 2 - 2.0f * float(k) / 50});
    std::vector<std::array<int, 3>> tris;
    ASSERT_TRUE(triangulatePolygon(inPlane(xy), {200}, tris));
    EXPECT_NEAR(checkTriangulation(xy, {200}, tris, false), 6.0, 1e-5);
}

TEST(PolygonSweep, NotSimpleFallsBackToAFanAndSaysSo) {
    // A figure eight (its outline crosses itself) and a loop of one
    // repeated point: no crash, no hang, a fan of the outline.
    std::vector<Vec2> eight;
    for (int k = 0; k < 200; ++k) {
        const double a = 2 * M_PI * k / 200;
        eight.push_back({float(std::sin(a)), float(std::sin(a) * std::cos(a))});
    }
    std::vector<std::array<int, 3>> tris;
    EXPECT_FALSE(triangulatePolygon(inPlane(eight), {200}, tris));
    EXPECT_EQ(tris.size(), 198u);
    EXPECT_EQ(tris[5], (std::array<int, 3>{0, 6, 7}));
    tris.clear();
    std::vector<Vec2> same(100, Vec2(1, 2));
    EXPECT_FALSE(triangulatePolygon(inPlane(same), {100}, tris));

    // Through the Polygon request: a located warning.
    std::vector<float> P;
    for (int k = 0; k < 200; ++k) {
        const double a = 2 * M_PI * k / 200;
        // Tilted so the figure eight still has a dominant plane.
        P.insert(P.end(), {float(std::cos(a)), float(std::sin(2 * a)), float(0.1 * std::cos(a))});
    }
    Diagnostics diag;
    diag.setRecord(true);
    diag.setSink([](const Diagnostic&) {});
    auto prims = makeAll(record("Polygon", {}, {pointParam(P)}), &diag);
    ASSERT_EQ(diag.recorded().size(), 1u);
    EXPECT_NE(diag.recorded()[0].str().find("is not a simple polygon"), std::string::npos) << diag.recorded()[0].str();
}

TEST(PolygonSweep, RandomStarShapedPolygonsWithAHole) {
    // 200 polygons of 65 to 600 vertices, star-shaped about the origin
    // with random radii (so simple), around a small square hole; a fixed
    // seed keeps them the same on every machine.
    std::mt19937 rng(20);
    std::uniform_real_distribution<double> radius(0.2, 1.0);
    std::uniform_int_distribution<int> count(65, 600);
    for (int round = 0; round < 200; ++round) {
        std::vector<Vec2> xy;
        const int n = count(rng);
        for (int k = 0; k < n; ++k) {
            const double a = 2 * M_PI * k / n, r = radius(rng);
            xy.push_back({float(r * std::cos(a)), float(r * std::sin(a))});
        }
        xy.insert(xy.end(), {{-0.1f, -0.1f}, {-0.1f, 0.1f}, {0.1f, 0.1f}, {0.1f, -0.1f}});
        const std::vector<int> loops = {n, 4};
        std::vector<std::array<int, 3>> tris;
        ASSERT_TRUE(triangulatePolygon(inPlane(xy), loops, tris)) << "round " << round;
        EXPECT_NEAR(checkTriangulation(xy, loops, tris, true), shoelace(xy, 0, n) - 0.04, 1e-6) << "round " << round;
        if (HasFailure()) break;
    }
}
