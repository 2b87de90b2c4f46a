#include "geometry_test_util.h"

#include "umbra/geometry/quadric.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace umbra;
using namespace umbra::geometry;
using namespace umbra::testutil;

namespace {

PrimitivePtr makeOne(const std::string& type, std::vector<float> args, std::vector<ri::Param> params = {}) {
    Diagnostics diag;
    auto prims = makePrimitives(record(type, std::move(args), std::move(params)), diag);
    EXPECT_EQ(diag.errorCount(), 0);
    EXPECT_EQ(prims.size(), 1u);
    return prims.empty() ? nullptr : std::move(prims[0]);
}

// Angle of (x, y) in [0, 2 pi).
double angleOf(const Vec3& p) {
    double a = std::atan2(double(p.y), double(p.x));
    return a < 0 ? a + 2 * M_PI : a;
}

constexpr double kPiD = M_PI;

}  // namespace

TEST(Quadric, SpherePointsLieOnSphereAndAreaIsFourPiRSquared) {
    auto s = makeOne("Sphere", {2, -2, 2, 360});
    Grid g = s->dice(96, 96);
    for (const Vec3& p : g.P) EXPECT_NEAR(length(p), 2.0f, 1e-5f);
    EXPECT_NEAR(gridArea(g) / (4 * kPiD * 4), 1.0, 0.005);
}

TEST(Quadric, PartialSphereStaysInsideZAndThetaRanges) {
    const float r = 2, zmin = -0.5f, zmax = 1.4f, tmax = 270;
    auto s = makeOne("Sphere", {r, zmin, zmax, tmax});
    Grid g = s->dice(96, 64);
    for (const Vec3& p : g.P) {
        EXPECT_NEAR(length(p), r, 1e-5f);
        EXPECT_GE(p.z, zmin - 1e-5f);
        EXPECT_LE(p.z, zmax + 1e-5f);
        const double a = angleOf(p);
        if (std::hypot(p.x, p.y) > 1e-4) {
            EXPECT_TRUE(a <= radians(tmax) + 1e-4 || a >= 2 * kPiD - 1e-4) << a;
        }
    }
    // A spherical zone has area 2 pi r h; the sweep takes 270/360 of it.
    EXPECT_NEAR(gridArea(g) / (2 * kPiD * r * (zmax - zmin) * 0.75), 1.0, 0.005);
}

TEST(Quadric, CylinderPartialSweepArea) {
    const float r = 1.5f, z0 = -1, z1 = 2, tmax = 120;
    auto c = makeOne("Cylinder", {r, z0, z1, tmax});
    Grid g = c->dice(64, 8);
    for (const Vec3& p : g.P) {
        EXPECT_NEAR(std::hypot(p.x, p.y), r, 1e-5f);
        EXPECT_GE(p.z, z0 - 1e-6f);
        EXPECT_LE(p.z, z1 + 1e-6f);
    }
    EXPECT_NEAR(gridArea(g) / (2 * kPiD * r * (z1 - z0) * (tmax / 360.0)), 1.0, 0.005);
}

TEST(Quadric, ConeLateralAreaAndPoints) {
    const float h = 3, r = 1;
    auto c = makeOne("Cone", {h, r, 360});
    Grid g = c->dice(96, 16);
    for (const Vec3& p : g.P) EXPECT_NEAR(std::hypot(p.x, p.y), r * (1 - p.z / h), 1e-5f);
    EXPECT_NEAR(gridArea(g) / (kPiD * r * std::sqrt(r * r + h * h)), 1.0, 0.005);
}

TEST(Quadric, DiskAreaAndHeight) {
    auto d = makeOne("Disk", {0.5f, 2, 90});
    Grid g = d->dice(64, 4);
    for (const Vec3& p : g.P) {
        EXPECT_FLOAT_EQ(p.z, 0.5f);
        EXPECT_GE(p.x, -1e-6f);
        EXPECT_GE(p.y, -1e-6f);
    }
    EXPECT_NEAR(gridArea(g) / (kPiD * 4 / 4), 1.0, 0.005);
}

TEST(Quadric, TorusAreaIsFourPiSquaredRr) {
    const float R = 3, r = 0.5f;
    auto t = makeOne("Torus", {R, r, 0, 360, 360});
    Grid g = t->dice(96, 64);
    for (const Vec3& p : g.P) {
        const double rho = std::hypot(p.x, p.y) - R;
        EXPECT_NEAR(std::hypot(rho, double(p.z)), r, 1e-5);
    }
    EXPECT_NEAR(gridArea(g) / (4 * kPiD * kPiD * R * r), 1.0, 0.005);
}

TEST(Quadric, ParaboloidFollowsProfileAndArea) {
    const float rmax = 2, zmin = 0.5f, zmax = 3;
    auto p = makeOne("Paraboloid", {rmax, zmin, zmax, 360});
    Grid g = p->dice(96, 64);
    for (const Vec3& q : g.P) {
        EXPECT_NEAR(q.x * q.x + q.y * q.y, rmax * rmax * q.z / zmax, 1e-4f);
        EXPECT_GE(q.z, zmin - 1e-6f);
    }
    // z = a rho^2: area between radii is pi / (6 a^2) [(1 + 4 a^2 rho^2)^1.5] evaluated at both ends.
    const double a = zmax / (rmax * rmax), r0 = std::sqrt(zmin / a), r1 = rmax;
    const double area = kPiD / (6 * a * a) * (std::pow(1 + 4 * a * a * r1 * r1, 1.5) - std::pow(1 + 4 * a * a * r0 * r0, 1.5));
    EXPECT_NEAR(gridArea(g) / area, 1.0, 0.005);
}

TEST(Quadric, HyperboloidSpecialCasesMatchCylinderAndCone) {
    auto cyl = makeOne("Hyperboloid", {1, 0, -1, 1, 0, 1, 360});
    EXPECT_NEAR(gridArea(cyl->dice(96, 4)) / (2 * kPiD * 2), 1.0, 0.005);
    auto cone = makeOne("Hyperboloid", {1, 0, 0, 0, 0, 1, 360});
    EXPECT_NEAR(gridArea(cone->dice(96, 16)) / (kPiD * std::sqrt(2.0)), 1.0, 0.005);
}

TEST(Quadric, TwistedHyperboloidRingRadiusFollowsTheLine) {
    const Vec3 p1(1, -1, -1), p2(1, 1, 1);
    auto h = makeOne("Hyperboloid", {p1.x, p1.y, p1.z, p2.x, p2.y, p2.z, 360});
    Grid g = h->dice(32, 32);
    for (const Vec3& p : g.P) {
        const float v = (p.z - p1.z) / (p2.z - p1.z);
        const Vec3 q = p1 + (p2 - p1) * v;
        EXPECT_NEAR(std::hypot(p.x, p.y), std::hypot(q.x, q.y), 1e-5f);
    }
    const Bound3 b = h->bound();
    for (const Vec3& p : g.P) EXPECT_TRUE(inside(b, p, 1e-5f));
}

// Grid::N must be unit length and point the way dPdu x dPdv does (measured
// on the grid by differences), for every quadric, also when flipped.
TEST(Quadric, NormalsFollowDpduCrossDpdv) {
    const std::vector<std::pair<std::string, std::vector<float>>> cases = {
        {"Sphere", {1, -1, 1, 360}},        {"Sphere", {1, -0.5f, 0.8f, -200}},
        {"Cylinder", {1, -1, 1, 270}},      {"Cylinder", {1, 1, -1, 270}},
        {"Cone", {2, 1, 300}},              {"Disk", {0, 1, 360}},
        {"Disk", {0, 1, -90}},              {"Paraboloid", {1, 0, 2, 360}},
        {"Hyperboloid", {1, -1, -1, 1, 1, 1, 360}}, {"Torus", {2, 0.5f, -90, 270, 180}},
    };
    for (const auto& [type, args] : cases) {
        auto prim = makeOne(type, args);
        Grid g = prim->dice(16, 16);
        ASSERT_EQ(g.N.size(), g.P.size()) << type;
        for (int j = 1; j < g.nv; ++j)
            for (int i = 1; i < g.nu; ++i) {
                const Vec3 du = g.P[g.index(i + 1, j)] - g.P[g.index(i - 1, j)];
                const Vec3 dv = g.P[g.index(i, j + 1)] - g.P[g.index(i, j - 1)];
                const Vec3 c = normalize(cross(du, dv));
                const Vec3& n = g.N[g.index(i, j)];
                EXPECT_NEAR(length(n), 1.0f, 1e-5f);
                EXPECT_GT(dot(c, n), 0.95f) << type << " " << args[0] << " at " << i << "," << j;
            }
    }
}

TEST(Quadric, PositiveSweepNormalsPointOutward) {
    auto s = makeOne("Sphere", {1, -1, 1, 360});
    Grid g = s->dice(8, 8);
    for (size_t k = 0; k < g.P.size(); ++k) EXPECT_GT(dot(g.N[k], g.P[k]), 0.99f);
}

TEST(Quadric, PartialSweepBoundIsTight) {
    auto s = makeOne("Sphere", {1, 0, 1, 90});
    const Bound3 b = s->bound();
    EXPECT_NEAR(b.min.x, 0, 1e-5);
    EXPECT_NEAR(b.min.y, 0, 1e-5);
    EXPECT_NEAR(b.min.z, 0, 1e-5);
    EXPECT_NEAR(b.max.x, 1, 1e-5);
    EXPECT_NEAR(b.max.y, 1, 1e-5);
    EXPECT_NEAR(b.max.z, 1, 1e-5);
}

// Split children stay inside the parent's bound, their own grids stay
// inside their bounds, and together they cover the parent's area.
TEST(Quadric, SplitChildrenCoverTheParent) {
    const std::vector<std::pair<std::string, std::vector<float>>> cases = {
        {"Sphere", {1.5f, -1, 1.2f, 300}}, {"Torus", {2, 0.7f, 30, 300, 250}},
        {"Cone", {1, 2, -180}},           {"Hyperboloid", {0.5f, 1, 0, 1, 0.2f, 2, 200}},
        {"Paraboloid", {1, 0, 1, 360}},   {"Cylinder", {1, 0, 1, 45}},
    };
    for (const auto& [type, args] : cases) {
        auto prim = makeOne(type, args);
        const Bound3 pb = prim->bound();
        const double area = gridArea(prim->dice(128, 128));
        std::vector<PrimitivePtr> level{};
        prim->split(true, level);
        std::vector<PrimitivePtr> leaves;
        for (auto& c : level) c->split(false, leaves);
        ASSERT_EQ(leaves.size(), 4u);
        double sum = 0;
        for (const auto& c : leaves) {
            const Bound3 cb = c->bound();
            EXPECT_TRUE(inside(pb, cb.min, 1e-5f) && inside(pb, cb.max, 1e-5f)) << type;
            Grid g = c->dice(64, 64);
            for (const Vec3& p : g.P) EXPECT_TRUE(inside(cb, p, 0)) << type;
            sum += gridArea(g);
        }
        EXPECT_NEAR(sum / area, 1.0, 1e-3) << type;
    }
}

TEST(Quadric, SpindleTorusWedgesAreBoundedByTheirOwnSector) {
    // Major radius 0.5 < minor radius 2: for cos(phi) < -1/4 the profile
    // radius is negative and the point lies across the axis. A thin wedge
    // of that part is bounded by its own sector turned by half a turn, not
    // by the whole disc: otherwise splitting never shrinks such wedges.
    auto torus = makeOne("Torus", {0.5f, 2, 0, 360, 360});
    std::vector<PrimitivePtr> pieces{};
    torus->split(false, pieces);  // phi in [0, 180] and [180, 360]
    for (auto& half : pieces) {
        PrimitivePtr piece = std::move(half);
        for (int k = 0; k < 6; ++k) {  // theta in [0, 1/64 of a turn]
            std::vector<PrimitivePtr> wedges;
            piece->split(true, wedges);
            piece = std::move(wedges[0]);
        }
        const Bound3 b = piece->bound();
        for (const Vec3& p : piece->dice(16, 64).P) EXPECT_TRUE(inside(b, p, 0)) << p.x << " " << p.y << " " << p.z;
        // The wedge spans 5.6 degrees at radii up to 2.5: far narrower
        // than the 5-unit disc in y.
        EXPECT_LT(b.max.y - b.min.y, 0.6f);
    }
}

TEST(Quadric, SplitKeepsGlobalParameters) {
    auto s = makeOne("Sphere", {1, -1, 1, 360});
    std::vector<PrimitivePtr> halves;
    s->split(true, halves);
    Grid g = halves[1]->dice(4, 2);
    EXPECT_FLOAT_EQ(g.u.front(), 0.5f);
    EXPECT_FLOAT_EQ(g.u[size_t(g.nu)], 1.0f);
    EXPECT_FLOAT_EQ(g.du, 0.125f);
    EXPECT_FLOAT_EQ(g.dv, 0.5f);
    const GridVar* sv = g.find("s");
    ASSERT_NE(sv, nullptr);
    EXPECT_FLOAT_EQ(sv->at(0)[0], 0.5f);
}

TEST(Quadric, VaryingColourInterpolatesCornersBilinearly) {
    const std::vector<float> cs = {1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1};
    auto s = makeOne("Cylinder", {1, 0, 1, 360},
                     {floatParam("Cs", ri::ParamType::Color, cs, ri::StorageClass::Varying),
                      floatParam("Ka", ri::ParamType::Float, {0.25f}, ri::StorageClass::Uniform)});
    Grid g = s->dice(5, 3);
    const GridVar* c = g.find("Cs");
    ASSERT_NE(c, nullptr);
    ASSERT_TRUE(c->perVertex);
    for (int k = 0; k < g.vertexCount(); ++k) {
        const float u = g.u[size_t(k)], v = g.v[size_t(k)];
        for (int ch = 0; ch < 3; ++ch) {
            const float want = (1 - u) * (1 - v) * cs[size_t(ch)] + u * (1 - v) * cs[size_t(3 + ch)] +
                               (1 - u) * v * cs[size_t(6 + ch)] + u * v * cs[size_t(9 + ch)];
            EXPECT_NEAR(c->at(k)[ch], want, 1e-6f);
        }
    }
    const GridVar* ka = g.find("Ka");
    ASSERT_NE(ka, nullptr);
    EXPECT_FALSE(ka->perVertex);
    EXPECT_EQ(ka->data, std::vector<float>{0.25f});
    const GridVar* os = g.find("Os");  // from the attributes
    ASSERT_NE(os, nullptr);
    EXPECT_EQ(os->data, (std::vector<float>{1, 1, 1}));
}

TEST(Quadric, MalformedArgumentsAreReportedWithLocation) {
    Diagnostics diag;
    diag.setRecord(true);
    diag.setSink([](const Diagnostic&) {});
    auto prims = makePrimitives(record("Sphere", {1, -1, 1}), diag);
    EXPECT_TRUE(prims.empty());
    ASSERT_EQ(diag.recorded().size(), 1u);
    EXPECT_EQ(diag.recorded()[0].str(), "test.rib:3:1: error: Sphere: expected 4 arguments (radius zmin zmax thetamax), got 3");

    prims = makePrimitives(record("Torus", {1, 0.5f, 0, 360, 360},
                                  {floatParam("Cs", ri::ParamType::Color, {1, 0, 0}, ri::StorageClass::Varying)}),
                           diag);
    EXPECT_EQ(prims.size(), 1u);  // the bad variable is dropped, the torus kept
    ASSERT_EQ(diag.recorded().size(), 2u);
    EXPECT_EQ(diag.recorded()[1].message, "Torus: \"Cs\" has 1 values, expected 4 (one per corner)");
}

TEST(Quadric, SweepsBeyondOneTurnAreClampedWithALocatedWarning) {
    // thetamax 1e30 would leave u * thetamax no precision; each quadric's
    // sweep is clamped to 360 degrees (or -360) and warned about once.
    struct Case {
        const char* type;
        std::vector<float> args;
        float expectedThetaMax;  // radians
    };
    const Case cases[] = {
        {"Sphere", {1, -1, 1, 1e30f}, 2 * kPi},
        {"Cylinder", {1, -1, 1, -1e30f}, -2 * kPi},
        {"Cone", {1, 1, 720}, 2 * kPi},
        {"Disk", {0, 1, -400}, -2 * kPi},
        {"Paraboloid", {1, 0.1f, 1, 1e30f}, 2 * kPi},
        {"Hyperboloid", {1, 0, -1, 0, 1, 1, 1e30f}, 2 * kPi},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.type);
        Diagnostics diag;
        diag.setRecord(true);
        diag.setSink([](const Diagnostic&) {});
        auto rec = record(c.type, c.args);
        QuadricShape shape;
        ASSERT_TRUE(Quadric::shapeFromRecord(*rec, &shape, diag));
        EXPECT_FLOAT_EQ(shape.thetaMax, c.expectedThetaMax);
        ASSERT_EQ(diag.recorded().size(), 1u);
        EXPECT_EQ(diag.recorded()[0].severity, Severity::Warning);
        EXPECT_EQ(diag.recorded()[0].str().rfind(fmt::format("test.rib:3:1: warning: {}: thetamax ", c.type), 0), 0u)
            << diag.recorded()[0].str();
        // The clamped sweep is an ordinary one: its bound is finite.
        auto prims = makePrimitives(rec, diag);
        ASSERT_EQ(prims.size(), 1u);
        EXPECT_TRUE(std::isfinite(prims[0]->bound().max.x));
        EXPECT_EQ(diag.recorded().size(), 1u);  // made again: not warned again
    }
    // The torus: both ends of phi, and their distance, as well as thetamax.
    Diagnostics diag;
    diag.setRecord(true);
    diag.setSink([](const Diagnostic&) {});
    QuadricShape shape;
    ASSERT_TRUE(Quadric::shapeFromRecord(*record("Torus", {1, 0.25f, -300, 1e30f, 1e30f}), &shape, diag));
    EXPECT_FLOAT_EQ(shape.thetaMax, 2 * kPi);
    EXPECT_FLOAT_EQ(shape.phi0, radians(-300.0f));
    EXPECT_FLOAT_EQ(shape.phi1, radians(60.0f));  // clamped to 360, then to one turn past phimin
    ASSERT_EQ(diag.recorded().size(), 3u);
    EXPECT_EQ(diag.recorded()[0].str(),
              "test.rib:3:1: warning: Torus: phimax 1e+30 is outside [-360, 360] degrees; clamped to 360");
    EXPECT_EQ(diag.recorded()[1].str(),
              "test.rib:3:1: warning: Torus: phimin -300 to phimax 360 sweeps more than 360 degrees; phimax clamped "
              "to 60");
    EXPECT_EQ(diag.recorded()[2].message, "Torus: thetamax 1e+30 is outside [-360, 360] degrees; clamped to 360");
    // Within range: no warning, the angles as given.
    Diagnostics quiet;
    ASSERT_TRUE(Quadric::shapeFromRecord(*record("Sphere", {1, -1, 1, -360}), &shape, quiet));
    EXPECT_FLOAT_EQ(shape.thetaMax, -2 * kPi);
    EXPECT_EQ(quiet.warningCount(), 0);
}
