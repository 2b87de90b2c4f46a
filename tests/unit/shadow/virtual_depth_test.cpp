// Wang & Molnar's virtual samples: for a planar receiver, the depth of the
// tangent plane at each texel centre must be the exact depth of the plane
// there, under perspective and orthographic lights. The exact value is
// computed independently: the ray through the texel centre, intersected
// with the plane in double precision.

#include "shadow_test_util.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace umbra;

namespace {

struct Vec3d {
    double x, y, z;
};
Vec3d toD(const Vec3& v) { return {v.x, v.y, v.z}; }

/// A light at `from` looking at the origin, +y up (left-handed camera).
Mat4 lightLookingAtOrigin(const Vec3& from) {
    Vec3 z = normalize(-from);
    Vec3 x = normalize(cross(Vec3(0, 1, 0), z));
    Vec3 y = cross(z, x);
    Mat4 r;
    const Vec3 axes[3] = {x, y, z};
    for (int i = 0; i < 3; ++i) {
        r.m[i][0] = axes[i].x;
        r.m[i][1] = axes[i].y;
        r.m[i][2] = axes[i].z;
    }
    return r * Mat4::translate(-from);
}

/// NDC (x right, y down, [0,1]^2) from light camera space.
Mat4 ndcFromCamera(bool perspective, float halfSize) {
    Mat4 screen;  // screen window [-1,1]^2
    if (perspective) {
        const float t = halfSize, n = 0.1f, f = 1000.0f;
        screen.m[0][0] = 1 / t;
        screen.m[1][1] = 1 / t;
        screen.m[2][2] = f / (f - n);
        screen.m[2][3] = -f * n / (f - n);
        screen.m[3][2] = 1;
        screen.m[3][3] = 0;
    } else {
        screen = Mat4::scale({1 / halfSize, 1 / halfSize, 1});
    }
    Mat4 ndc;
    ndc.m[0][0] = 0.5f;
    ndc.m[0][3] = 0.5f;
    ndc.m[1][1] = -0.5f;
    ndc.m[1][3] = 0.5f;
    return ndc * screen;
}

/// The light camera-space depth where the ray through texel (x, y)'s
/// centre meets the plane through P0 with normal N (world space), all in
/// double precision: the ray is built from the projection's own definition
/// (screen window [-halfSize, halfSize]^2), not from the map's matrices.
double exactPlaneDepth(const ShadowMap& map, bool perspective, float halfSize, int x, int y, const Vec3& P0,
                       const Vec3& N) {
    const auto& L = map.lightFromWorld().m;
    auto toLight = [&](const Vec3d& p, double w) {
        Vec3d r;
        r.x = L[0][0] * p.x + L[0][1] * p.y + L[0][2] * p.z + w * L[0][3];
        r.y = L[1][0] * p.x + L[1][1] * p.y + L[1][2] * p.z + w * L[1][3];
        r.z = L[2][0] * p.x + L[2][1] * p.y + L[2][2] * p.z + w * L[2][3];
        return r;
    };
    // The light transform is a rotation and a translation: normals go like
    // directions (w = 0).
    const Vec3d p0 = toLight(toD(P0), 1), n = toLight(toD(N), 0);
    const double sx = (2.0 * (x + 0.5) / map.width() - 1.0) * halfSize;
    const double sy = (1.0 - 2.0 * (y + 0.5) / map.height()) * halfSize;
    if (perspective) {
        // Camera-space ray s * (sx, sy, 1): its depth is s.
        return (p0.x * n.x + p0.y * n.y + p0.z * n.z) / (sx * n.x + sy * n.y + n.z);
    }
    // Orthographic: the ray (sx, sy, s).
    return (p0.x * n.x + p0.y * n.y + p0.z * n.z - sx * n.x - sy * n.y) / n.z;
}

void checkPlane(bool perspective) {
    DepthImage img(64, 64);
    for (float& z : img.z) z = 5.0f;  // content is irrelevant to the plane
    img.filter = DepthFilter::Second;
    img.projection = perspective ? Projection::Perspective : Projection::Orthographic;
    img.lightFromWorld = lightLookingAtOrigin({1.5f, 6.0f, -2.0f});
    const float halfSize = perspective ? 0.6f : 3.0f;
    img.ndcFromWorld = ndcFromCamera(perspective, halfSize) * img.lightFromWorld;
    auto map = test::writeAndOpen(img, perspective ? "virtual-persp.shd" : "virtual-ortho.shd");
    ASSERT_TRUE(map);

    // A tilted receiver plane through P0.
    const Vec3 P0(0.3f, 0.2f, -0.1f), N = normalize(Vec3(0.2f, 1.0f, 0.35f));
    ShadowMap::TangentPlane plane = map->tangentPlane(P0, N, map->lightFromWorld());
    ASSERT_TRUE(plane.valid);
    double worst = 0;
    for (int y = 4; y < 60; y += 7)
        for (int x = 4; x < 60; x += 5) {
            const double exact = exactPlaneDepth(*map, perspective, halfSize, x, y, P0, N);
            const double virt = map->virtualDepth(plane, x, y);
            worst = std::max(worst, std::abs(virt - exact) / std::abs(exact));
        }
    // Float precision: the plane goes through three float matrix products
    // and an inverse, so allow a few dozen units in the last place (the
    // lookup itself compares with a slack of 1e-4).
    EXPECT_LT(worst, 4e-6) << (perspective ? "perspective" : "orthographic");
}

}  // namespace

TEST(VirtualSamples, PlaneDepthsExactUnderPerspective) { checkPlane(true); }
TEST(VirtualSamples, PlaneDepthsExactUnderOrthographic) { checkPlane(false); }
