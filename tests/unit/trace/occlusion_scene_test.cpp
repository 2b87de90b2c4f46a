#include "trace_test_util.h"

#include "umbra/trace/occlusion_scene.h"
#include "umbra/util/rng.h"

#include <gtest/gtest.h>

#include <cmath>
#include <thread>
#include <vector>

using namespace umbra;
using namespace umbra::trace;
using namespace umbra::tracetest;

namespace {

constexpr float kR = 1.0f;       // sphere radius
constexpr float kH = 2.0f;       // sphere centre height above the plane y = 0
const Vec3 kUp(0, 1, 0);

// The chord-error limit TessellationOptions gives a primitive.
float toleranceOf(const Bound3& worldBound, const TessellationOptions& o = {}) {
    return std::min(o.absoluteTolerance, o.relativeTolerance * length(worldBound.diagonal()));
}
float sphereTolerance(float r) { return toleranceOf(Bound3(Vec3(-r), Vec3(r))); }

Vec3 planePoint(float d, float azimuth) { return {d * std::cos(azimuth), 0, d * std::sin(azimuth)}; }

// Distance from the axis where the shadow on the plane ends along `azimuth`,
// by bisection between a shadowed and a lit distance.
float boundary(const OcclusionScene& s, const LightTarget& light, float azimuth, float inside, float outside) {
    EXPECT_EQ(s.shadowFraction(planePoint(inside, azimuth), light, &kUp), 1.0f);
    EXPECT_EQ(s.shadowFraction(planePoint(outside, azimuth), light, &kUp), 0.0f);
    for (int k = 0; k < 40; ++k) {
        const float mid = 0.5f * (inside + outside);
        (s.shadowFraction(planePoint(mid, azimuth), light, &kUp) > 0 ? inside : outside) = mid;
    }
    return 0.5f * (inside + outside);
}

std::vector<geometry::PrimitivePtr> sphereOverPlane(bool sphereCasts = true) {
    std::vector<geometry::PrimitivePtr> prims;
    addSphere(prims, kR, Vec3(0, kH, 0), sphereCasts);
    addGroundPlane(prims, 20);
    return prims;
}

}  // namespace

TEST(OcclusionScene, EmptySceneOccludesNothing) {
    const std::vector<geometry::PrimitivePtr> none;
    OcclusionScene s(none);
    EXPECT_EQ(s.triangleCount(), 0u);
    EXPECT_TRUE(s.bound().empty());
    EXPECT_FALSE(s.occluded(Vec3(0, 0, 0), Vec3(0, 10, 0), 1e-4f));
    EXPECT_FALSE(s.occludedAlong(Vec3(0, 0, 0), Vec3(0, 1, 0), 0));
    EXPECT_EQ(s.shadowFraction(Vec3(0, 0, 0), LightTarget::distant(Vec3(0, -1, 0)), &kUp), 0.0f);
    float out[3] = {7, 7, 7};
    const Vec3 P[3] = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 0, 1)};
    s.occludedBatch(3, P, nullptr, LightTarget::point(Vec3(0, 5, 0)), out);
    for (float v : out) EXPECT_EQ(v, 0.0f);
}

TEST(OcclusionScene, TessellationIsWithinToleranceAndPlaneStaysTwoTriangles) {
    std::vector<geometry::PrimitivePtr> plane;
    addGroundPlane(plane, 20);
    OcclusionScene flat(plane);
    EXPECT_EQ(flat.triangleCount(), 2u);
    EXPECT_EQ(flat.maxChordError(), 0.0f);

    OcclusionScene s(sphereOverPlane());
    EXPECT_GT(s.maxChordError(), 0.0f);
    EXPECT_LE(s.maxChordError(), sphereTolerance(kR) * 1.02f);
    EXPECT_NEAR(s.bound().min.x, -20, 1e-5);
    // The chord term dominates the float-precision floor here; a flat scene has only the floor.
    EXPECT_EQ(s.rayEpsilon(), 2 * s.maxChordError());
    EXPECT_FLOAT_EQ(flat.rayEpsilon(), 1e-6f * length(Vec3(40, 0, 40)));

    std::vector<geometry::PrimitivePtr> ball;
    addSphere(ball, kR, Vec3(0, kH, 0));
    OcclusionScene b(ball);
    EXPECT_NEAR(b.bound().max.z, kR, 1e-5);  // the pole (object z is world z) is a vertex
    EXPECT_LE(b.bound().max.y, kH + kR + 1e-5f);
    EXPECT_GE(b.bound().max.y, kH + kR - sphereTolerance(kR));
}

TEST(OcclusionScene, SphereUnderDistantLightCastsDiskOfItsRadius) {
    OcclusionScene s(sphereOverPlane());
    const LightTarget down = LightTarget::distant(Vec3(0, -1, 0));
    for (int a = 0; a < 24; ++a) {
        const float az = 2 * kPi * a / 24 + 0.01f;
        EXPECT_EQ(s.shadowFraction(planePoint(kR * 0.995f, az), down, &kUp), 1.0f) << az;
        EXPECT_EQ(s.shadowFraction(planePoint(kR * 1.005f, az), down, &kUp), 0.0f) << az;
        EXPECT_EQ(s.shadowFraction(planePoint(kR * 0.3f, az), down, &kUp), 1.0f) << az;
        // Without a normal only the near-hit epsilon keeps the plane from shadowing itself.
        EXPECT_EQ(s.shadowFraction(planePoint(kR * 1.005f, az), down, nullptr), 0.0f) << az;
    }
    // The triangles are inscribed: the disk can only shrink, by at most the tolerance.
    const float tol = sphereTolerance(kR);
    for (float az : {0.0f, 0.3f, 1.1f, 2.0f, 4.4f}) {
        const float b = boundary(s, down, az, 0.9f * kR, 1.1f * kR);
        EXPECT_LE(b, kR + 1e-5f) << az;
        EXPECT_GE(b, kR - tol) << az;
    }
}

TEST(OcclusionScene, SphereUnderPointLightCastsTangentConeCircle) {
    OcclusionScene s(sphereOverPlane());
    const float lightHeight = 5.0f;
    const LightTarget light = LightTarget::point(Vec3(0, lightHeight, 0));
    // The cone from the light tangent to the sphere has half-angle asin(r / (H - h)).
    const double alpha = std::asin(double(kR) / (lightHeight - kH));
    const float radius = float(lightHeight * std::tan(alpha));
    for (int a = 0; a < 24; ++a) {
        const float az = 2 * kPi * a / 24 + 0.02f;
        EXPECT_EQ(s.shadowFraction(planePoint(radius * 0.995f, az), light, &kUp), 1.0f) << az;
        EXPECT_EQ(s.shadowFraction(planePoint(radius * 1.005f, az), light, &kUp), 0.0f) << az;
    }
    // A silhouette shrunk by the tolerance moves the shadow's edge by at most
    // that much, magnified by the projection from the sphere to the plane.
    const float slack = sphereTolerance(kR) * lightHeight / float((lightHeight - kH) * std::cos(alpha)) * 1.5f;
    for (float az : {0.0f, 0.7f, 2.5f, 3.9f}) {
        const float b = boundary(s, light, az, 0.9f * radius, 1.1f * radius);
        EXPECT_LE(b, radius + 1e-4f) << az;
        EXPECT_GE(b, radius - slack) << az;
    }
}

// Any plane point, any light: the reference is the segment (or ray)
// towards the light passing within r of the sphere's centre.
TEST(OcclusionScene, AgreesWithAnalyticSphereForObliqueLights) {
    OcclusionScene s(sphereOverPlane());
    const Vec3 centre(0, kH, 0);
    struct Case {
        LightTarget light;
        const char* name;
    };
    const Case cases[] = {{LightTarget::distant(Vec3(0.4f, -1, 0.3f)), "distant"},
                          {LightTarget::point(Vec3(-1.5f, 4.0f, 0.8f)), "point"},
                          {LightTarget::point(Vec3(0.5f, 2.5f, -2.0f)), "low point"}};
    for (uint32_t ci = 0; ci < 3; ++ci) {
        const Case& c = cases[ci];
        Rng rng(hashKeys(17, ci));
        int shadowed = 0, lit = 0;
        for (int k = 0; k < 3000; ++k) {
            const Vec3 P(rng.uniform() * 8 - 4, 0, rng.uniform() * 8 - 4);
            const Vec3 d = c.light.atInfinity ? c.light.v : c.light.v - P;
            const double dist = segmentDistance(P, d, c.light.atInfinity ? 1e30 : 1.0, centre);
            if (std::abs(dist - kR) < 0.005 * kR) continue;
            const float expected = dist < kR ? 1.0f : 0.0f;
            ASSERT_EQ(s.shadowFraction(P, c.light, &kUp), expected) << c.name << " at " << P.x << "," << P.z;
            (expected > 0 ? shadowed : lit)++;
        }
        EXPECT_GT(shadowed, 50) << c.name;
        EXPECT_GT(lit, 50) << c.name;
    }
}

TEST(OcclusionScene, SphereDoesNotShadowItsLitSide) {
    OcclusionScene s(sphereOverPlane());
    const Vec3 centre(0, kH, 0);
    const LightTarget lights[] = {LightTarget::distant(Vec3(0.3f, -1, 0.2f)), LightTarget::point(Vec3(2, 6, -1))};
    for (const LightTarget& light : lights) {
        Rng rng(hashKeys(5, light.atInfinity ? 1u : 2u));
        for (int k = 0; k < 2000; ++k) {
            // A point on the true sphere, where a camera grid would shade it.
            const float z = rng.uniform() * 2 - 1, phi = rng.uniform() * 2 * kPi;
            const float rho = std::sqrt(std::max(0.0f, 1 - z * z));
            const Vec3 n(rho * std::cos(phi), z, rho * std::sin(phi));
            const Vec3 P = centre + n * kR;
            const Vec3 L = light.atInfinity ? light.v : normalize(light.v - P);
            const float facing = dot(n, L);
            if (std::abs(facing) < 0.02f) continue;  // grazing: N.L makes the light vanish there anyway
            EXPECT_EQ(s.shadowFraction(P, light, &n), facing > 0 ? 0.0f : 1.0f) << facing;
        }
    }
}

TEST(OcclusionScene, NonCastersAreLeftOut) {
    OcclusionScene s(sphereOverPlane(false));
    EXPECT_EQ(s.triangleCount(), 2u);  // only the plane
    const LightTarget down = LightTarget::distant(Vec3(0, -1, 0));
    for (float d : {0.0f, 0.5f, 0.99f})
        EXPECT_EQ(s.shadowFraction(planePoint(d, 0.3f), down, &kUp), 0.0f);
    EXPECT_FALSE(s.occluded(Vec3(0, 0.5f, 0), Vec3(0, 10, 0), 1e-4f));
}

TEST(OcclusionScene, SegmentsStopShortOfTheirEnds) {
    OcclusionScene s(sphereOverPlane());
    const float eps = s.rayEpsilon();
    // Ends just below the sphere's lowest point: nothing between.
    EXPECT_FALSE(s.occluded(Vec3(0, 0.01f, 0), Vec3(0, kH - kR - 0.01f, 0), eps));
    // Passes through the sphere.
    EXPECT_TRUE(s.occluded(Vec3(0, 0.01f, 0), Vec3(0, kH + kR + 0.5f, 0), eps));
    // Runs beside it.
    EXPECT_FALSE(s.occluded(Vec3(kR * 1.01f, 0.01f, 0), Vec3(kR * 1.01f, 10, 0), eps));
    // Starts on the sphere's lowest point and leaves downwards: the epsilon skips its own surface.
    EXPECT_FALSE(s.occludedAlong(Vec3(0, kH - kR, 0), Vec3(0, -1, 0), eps, kH - kR - eps));
    // The same from above stops at the plane only when tfar reaches it.
    EXPECT_TRUE(s.occludedAlong(Vec3(3, 1, 0), Vec3(0, -1, 0), eps, 2));
    EXPECT_FALSE(s.occludedAlong(Vec3(3, 1, 0), Vec3(0, -1, 0), eps, 0.5f));
    // A light sitting on the plane does not shadow itself.
    EXPECT_EQ(s.shadowFraction(Vec3(5, 1, 0), LightTarget::point(Vec3(5, 0, 0)), nullptr), 0.0f);
}

TEST(OcclusionScene, BatchMatchesSingleQueriesAndThreadsAgree) {
    OcclusionScene s(sphereOverPlane());
    const int n = 4000;
    std::vector<Vec3> P(n), N(n, kUp);
    Rng rng(99);
    for (Vec3& p : P) p = Vec3(rng.uniform() * 6 - 3, 0, rng.uniform() * 6 - 3);
    const LightTarget light = LightTarget::point(Vec3(0.3f, 6, -0.2f));
    std::vector<float> single(n);
    for (int i = 0; i < n; ++i) single[size_t(i)] = s.shadowFraction(P[size_t(i)], light, &N[size_t(i)]);
    int shadowed = 0;
    for (float v : single) shadowed += v > 0;
    EXPECT_GT(shadowed, 100);
    EXPECT_LT(shadowed, n - 100);

    std::vector<float> a(n, -1), b(n, -1);
    std::thread ta([&] { s.occludedBatch(n, P.data(), N.data(), light, a.data()); });
    std::thread tb([&] {
        for (int i = n - 1; i >= 0; --i) b[size_t(i)] = s.shadowFraction(P[size_t(i)], light, &N[size_t(i)]);
    });
    ta.join();
    tb.join();
    EXPECT_EQ(a, single);
    EXPECT_EQ(b, single);
}

TEST(OcclusionScene, SplitPiecesMeetWithoutCracks) {
    // A hemisphere cap (one layer, so a crack would let light through),
    // with a grid side so small that it is split into many pieces.
    std::vector<geometry::PrimitivePtr> prims;
    add(prims, record("Sphere", {kR, 0, kR, 360}, {}, Mat4{}));
    TessellationOptions opts;
    opts.maxGridSide = 8;
    OcclusionScene split(prims, opts);
    OcclusionScene whole(prims);
    EXPECT_EQ(split.maxChordError(), whole.maxChordError());
    EXPECT_GE(split.triangleCount(), whole.triangleCount());
    // Rays along +z through the cap, on the planes where u was cut (theta =
    // 2 pi k / 64 covers every power-of-two cut) and at every radius.
    int misses = 0;
    for (int k = 0; k < 64; ++k) {
        const float th = 2 * kPi * k / 64;
        for (int j = 1; j < 200; ++j) {
            const float rho = kR * 0.98f * j / 200;
            const Vec3 from(rho * std::cos(th), rho * std::sin(th), -1);
            misses += !split.occludedAlong(from, Vec3(0, 0, 1), 0);
        }
    }
    EXPECT_EQ(misses, 0);
}

TEST(OcclusionScene, PolygonMeshBlockerIsWatertight) {
    // A 2x2 quad mesh at y = 1 covering |x|, |z| <= 1, split face by face.
    std::vector<float> P;
    for (int j = 0; j < 3; ++j)
        for (int i = 0; i < 3; ++i) P.insert(P.end(), {float(i - 1), 1.0f, float(j - 1)});
    auto rec = record("PointsPolygons", {}, {pointParam(P)}, Mat4{});
    rec->intArrays = {{4, 4, 4, 4}, {0, 1, 4, 3, 1, 2, 5, 4, 3, 4, 7, 6, 4, 5, 8, 7}};
    std::vector<geometry::PrimitivePtr> prims;
    add(prims, rec);
    addGroundPlane(prims, 5);
    OcclusionScene s(prims);
    EXPECT_EQ(s.triangleCount(), 4u * 2u + 2u);  // planar faces need one micropolygon each
    const LightTarget down = LightTarget::distant(Vec3(0, -1, 0));
    // Inside, including exactly under the shared edges and the shared centre vertex.
    for (float x : {-0.99f, -0.5f, 0.0f, 0.5f, 0.99f})
        for (float z : {-0.99f, -0.25f, 0.0f, 0.75f, 0.99f})
            EXPECT_EQ(s.shadowFraction(Vec3(x, 0, z), down, &kUp), 1.0f) << x << "," << z;
    for (float x : {-1.01f, 1.01f, 3.0f})
        EXPECT_EQ(s.shadowFraction(Vec3(x, 0, 0.3f), down, &kUp), 0.0f) << x;
}

TEST(OcclusionScene, WorldRecordEntryPointMakesPrimitives) {
    scene::WorldRecord world;
    world.primitives.push_back(*record("Sphere", {kR, -kR, kR, 360}, {}, Mat4::translate(Vec3(0, kH, 0))));
    world.primitives.push_back(*record("Sphere", {-1}, {}, Mat4{}));  // malformed: reported, left out
    Diagnostics diag;
    diag.setSink([](const Diagnostic&) {});
    auto s = buildOcclusionScene(world, diag);
    EXPECT_EQ(diag.errorCount(), 1);
    ASSERT_TRUE(s);
    EXPECT_EQ(s->shadowFraction(Vec3(0.5f, 0, 0), LightTarget::distant(Vec3(0, -1, 0)), &kUp), 1.0f);
    EXPECT_EQ(s->shadowFraction(Vec3(1.5f, 0, 0), LightTarget::distant(Vec3(0, -1, 0)), &kUp), 0.0f);
}

TEST(OcclusionScene, TransformedSphereCastsEllipse) {
    // Scaled by (2, 0.5, 1) about its centre: under a light straight down the
    // shadow is the ellipse (x / 2r)^2 + (z / r)^2 < 1.
    std::vector<geometry::PrimitivePtr> prims;
    add(prims, record("Sphere", {kR, -kR, kR, 360}, {},
                      Mat4::translate(Vec3(0, kH, 0)) * Mat4::scale(Vec3(2, 0.5f, 1))));
    addGroundPlane(prims, 20);
    OcclusionScene s(prims);
    const LightTarget down = LightTarget::distant(Vec3(0, -1, 0));
    for (int a = 0; a < 32; ++a) {
        const float az = 2 * kPi * a / 32 + 0.05f;
        // Distance from the axis to the ellipse along this azimuth.
        const float c = std::cos(az), sn = std::sin(az);
        const float edge = 1 / std::sqrt(c * c / (4 * kR * kR) + sn * sn / (kR * kR));
        EXPECT_EQ(s.shadowFraction(planePoint(edge * 0.995f, az), down, &kUp), 1.0f) << az;
        EXPECT_EQ(s.shadowFraction(planePoint(edge * 1.005f, az), down, &kUp), 0.0f) << az;
    }
}

TEST(OcclusionScene, AbsoluteToleranceBoundsTheError) {
    // The smaller limit applies: lift the relative one out of the way.
    TessellationOptions coarse;
    coarse.relativeTolerance = 1.0f;
    coarse.absoluteTolerance = 0.01f;
    OcclusionScene fine(sphereOverPlane());
    OcclusionScene s(sphereOverPlane(), coarse);
    EXPECT_LT(s.triangleCount() * 4, fine.triangleCount());
    EXPECT_LE(s.maxChordError(), 0.01f * 1.02f);
    const LightTarget down = LightTarget::distant(Vec3(0, -1, 0));
    for (float az : {0.1f, 1.3f, 2.9f}) {
        const float b = boundary(s, down, az, 0.9f * kR, 1.1f * kR);
        EXPECT_LE(b, kR + 1e-5f);
        EXPECT_GE(b, kR - 0.01f);
    }
}

TEST(OcclusionScene, MicropolygonCapLowersTheRateWithAWarning) {
    TessellationOptions capped;
    capped.maxMicropolygonsPerPrimitive = 1000;
    std::vector<geometry::PrimitivePtr> prims;
    addSphere(prims, kR, Vec3(0, kH, 0));
    Diagnostics diag;
    diag.setRecord(true);
    diag.setSink([](const Diagnostic&) {});
    OcclusionScene s(prims, capped, &diag);
    EXPECT_LE(s.triangleCount(), 2000u);
    EXPECT_GT(s.triangleCount(), 1000u);
    ASSERT_EQ(diag.recorded().size(), 1u);
    const std::string msg = diag.recorded()[0].str();
    EXPECT_EQ(msg.rfind("trace.rib:7:1: warning: Sphere needs ", 0), 0u) << msg;
    EXPECT_NE(msg.find("(maxMicropolygonsPerPrimitive)"), std::string::npos) << msg;
    // Coarser, but still a sphere's shadow away from the edge.
    EXPECT_EQ(s.shadowFraction(planePoint(0.9f * kR, 0.4f), LightTarget::distant(Vec3(0, -1, 0)), &kUp), 1.0f);
    EXPECT_EQ(s.shadowFraction(planePoint(1.1f * kR, 0.4f), LightTarget::distant(Vec3(0, -1, 0)), &kUp), 0.0f);
}

TEST(OcclusionScene, FlatDiskKeepsItsRoundRim) {
    // A disk is flat, so only its rim's curvature asks for micropolygons.
    std::vector<geometry::PrimitivePtr> prims;
    add(prims, record("Disk", {0, kR, 360}, {}, Mat4::translate(Vec3(0, kH, 0)) * Mat4::rotate(-90, Vec3(1, 0, 0))));
    OcclusionScene s(prims);
    const LightTarget down = LightTarget::distant(Vec3(0, -1, 0));
    const float tol = toleranceOf(Bound3(Vec3(-kR, -kR, 0), Vec3(kR, kR, 0)));
    for (float az : {0.05f, 0.9f, 2.2f, 3.3f, 5.0f}) {
        EXPECT_EQ(s.shadowFraction(planePoint(kR * 0.995f, az), down, &kUp), 1.0f) << az;
        EXPECT_EQ(s.shadowFraction(planePoint(kR * 1.005f, az), down, &kUp), 0.0f) << az;
        const float b = boundary(s, down, az, 0.9f * kR, 1.1f * kR);
        EXPECT_LE(b, kR + 1e-5f);
        EXPECT_GE(b, kR - tol);
    }
}
