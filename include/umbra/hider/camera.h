#pragma once
// The viewing transforms of one render (the camera pass or a light's depth
// pass), built from RenderMan's options.
//
// Spaces, RenderMan's names:
//   camera  - the eye at the origin looking down +z, +y up, left-handed
//   screen  - after the projection: perspective divides x,y by z*tan(fov/2)
//             (fov spans the shorter image side), then the screen
//             transformation (transforms given before Projection) scales and
//             offsets x and y; z is RenderMan's screen
//             depth, [near, far] -> [0, 1]. The hider and the depth maps do
//             not use it: they compare camera-space z, carried alongside.
//   NDC     - the screen window mapped to [0,1]^2, y down
//   raster  - NDC scaled by the resolution: pixel (i,j) covers [i,i+1)x[j,j+1)

#include <cmath>

#include "umbra/scene/scene.h"
#include "umbra/util/math.h"

namespace umbra::hider {

/// A pinhole or orthographic camera and its raster mapping.
struct Camera {
    bool perspective = false;
    float tanHalfFov = 1;            // perspective only
    float screenWindow[4] = {-1, 1, -1, 1};  // left right bottom top
    /// The screen transformation: screen x = sx * projected x + tx (and y);
    /// a negative scale mirrors the image.
    float screenScale[2] = {1, 1};
    float screenOffset[2] = {0, 0};
    int xResolution = 640, yResolution = 480;
    float nearClip = 1e-10f, farClip = 1e30f;
    Mat4 cameraFromWorld;

    /// RenderMan's camera from the frame options: frame aspect and default
    /// screen window (the shorter side spans [-1,1]).
    static Camera fromOptions(const scene::Options& o);

    /// Camera space -> (raster x, raster y, camera z). Only meaningful for
    /// points in front of the eye (z > 0) when perspective.
    Vec3 rasterOf(const Vec3& pCamera) const {
        float x = pCamera.x, y = pCamera.y;
        if (perspective) {
            float s = 1.0f / (pCamera.z * tanHalfFov);
            x *= s;
            y *= s;
        }
        x = x * screenScale[0] + screenOffset[0];
        y = y * screenScale[1] + screenOffset[1];
        return {(x - screenWindow[0]) * m_xScale, (screenWindow[3] - y) * m_yScale, pCamera.z};
    }
    /// Raster pixels per camera-space unit at depth z (1 for orthographic
    /// depth-independence): converts a world length at depth z to pixels.
    float pixelsPerUnit(float z) const {
        float s = perspective ? 1.0f / (z * tanHalfFov) : 1.0f;
        return s * m_xScale * std::abs(screenScale[0]);
    }

    /// Raster pixels per screen unit along x and y (y is flipped by rasterOf).
    float rasterScaleX() const { return m_xScale; }
    float rasterScaleY() const { return m_yScale; }
    /// Raster pixels per projected unit (before the screen transformation)
    /// along x and y, signed: negative where the screen transform mirrors.
    float projectedScaleX() const { return m_xScale * screenScale[0]; }
    float projectedScaleY() const { return m_yScale * screenScale[1]; }

    /// Projective matrices for the shading language's named spaces.
    Mat4 screenFromCamera() const;
    Mat4 ndcFromScreen() const;
    Mat4 rasterFromScreen() const;
    Mat4 rasterFromCamera() const { return rasterFromScreen() * screenFromCamera(); }

    void finish();  // computes the cached scales; call after changing fields

private:
    float m_xScale = 1, m_yScale = 1;  // raster pixels per screen unit
};

}  // namespace umbra::hider
