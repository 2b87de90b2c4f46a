// The camera's screen transformation: a 2D affine map after the projection
// (RI Spec 3.2), consistent between rasterOf, the projective matrices the
// shading language and dicing use, and the scales that bound dicing.

#include "umbra/hider/camera.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>

using namespace umbra;
using namespace umbra::hider;

namespace {

Camera camera(bool perspective, const std::array<float, 4>& linear, float tx, float ty) {
    scene::Options o;
    o.xResolution = 64;
    o.yResolution = 48;
    o.projection = perspective ? scene::Projection::Perspective : scene::Projection::Orthographic;
    o.fov = 50;
    for (int i = 0; i < 4; ++i) o.screenLinear[i] = linear[i];
    o.screenOffset[0] = tx;
    o.screenOffset[1] = ty;
    o.nearClip = 0.1f;
    o.farClip = 100;
    return Camera::fromOptions(o);
}

}  // namespace

TEST(Camera, RasterOfAppliesTheScreenTransformationAfterTheProjection) {
    const float c = std::cos(0.5f), s = std::sin(0.5f);
    const std::array<float, 4> turnAndShear = {1.5f * c, -s + 0.3f, 1.5f * s, c};
    for (bool perspective : {true, false}) {
        const Camera cam = camera(perspective, turnAndShear, 0.2f, -0.1f);
        EXPECT_FALSE(cam.screenDiagonal());
        const Camera plain = camera(perspective, {1, 0, 0, 1}, 0, 0);
        const Mat4 raster = cam.rasterFromCamera();
        for (const Vec3 p : {Vec3(0.3f, -0.2f, 2), Vec3(-1, 0.7f, 5), Vec3(0, 0, 1)}) {
            // The projected point, recovered from the plain camera's raster.
            const Vec3 q = plain.rasterOf(p);
            const float w = 64 / (2 * 4.0f / 3), h = 48 / 2.0f;  // pixels per screen unit
            const float px = q.x / w - 4.0f / 3, py = 1 - q.y / h;
            const float sx = turnAndShear[0] * px + turnAndShear[1] * py + 0.2f;
            const float sy = turnAndShear[2] * px + turnAndShear[3] * py - 0.1f;
            const Vec3 r = cam.rasterOf(p);
            EXPECT_NEAR(r.x, (sx + 4.0f / 3) * w, 1e-3f);
            EXPECT_NEAR(r.y, (1 - sy) * h, 1e-3f);
            EXPECT_EQ(r.z, p.z);
            const Vec3 m = raster.point(p);
            EXPECT_NEAR(m.x, r.x, 1e-3f);
            EXPECT_NEAR(m.y, r.y, 1e-3f);
        }
    }
}

TEST(Camera, ProjectedScaleIsTheLargerSingularValue) {
    // Diagonal: the larger per-axis scale, as before a rotation was kept.
    const Camera still = camera(false, {-2, 0, 0, 0.5f}, 0, 0);
    EXPECT_TRUE(still.screenDiagonal());
    EXPECT_TRUE(still.screenMirrors());
    EXPECT_EQ(still.maxProjectedScale(), 2 * still.rasterScaleX());
    EXPECT_EQ(still.pixelsPerUnit(3), 2 * still.rasterScaleX());
    // A turn keeps lengths: a rotation of a scale by 2 stretches by 2.
    const float c = std::cos(0.7f), s = std::sin(0.7f);
    const Camera turned = camera(false, {2 * c, -2 * s, 2 * s, 2 * c}, 0, 0);
    EXPECT_FALSE(turned.screenMirrors());
    EXPECT_NEAR(turned.maxProjectedScale(), 2 * turned.rasterScaleX(), 1e-4f);
    // A shear [1 1; 0 1] stretches by the golden ratio.
    const Camera sheared = camera(true, {1, 1, 0, 1}, 0, 0);
    EXPECT_NEAR(sheared.maxProjectedScale(), 0.5f * (1 + std::sqrt(5.0f)) * sheared.rasterScaleX(), 1e-4f);
    EXPECT_NEAR(sheared.pixelsPerUnit(2), sheared.maxProjectedScale() / (2 * sheared.tanHalfFov), 1e-4f);
    // A mirror is a negative determinant, whichever axis it flips.
    EXPECT_TRUE(camera(false, {0, 1, 1, 0}, 0, 0).screenMirrors());
    const float m[4] = {3, 0, 4, 0};  // rank one: stretches (1, 0) to length 5
    EXPECT_NEAR(largestSingularValue(m), 5.0f, 1e-5f);
}
