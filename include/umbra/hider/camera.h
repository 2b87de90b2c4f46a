#pragma once
// The viewing transforms of one render (the camera pass or a light's depth
// pass), built from RenderMan's options.
//
// Spaces, RenderMan's names:
//   camera  - the eye at the origin looking down +z, +y up, left-handed
//   screen  - after the projection: perspective divides x,y by z*tan(fov/2)
//             (fov spans the shorter image side), then the screen
//             transformation (transforms given before Projection), a 2D
//             affine map of x and y (scale, rotation, shear, mirror,
//             offset); z is RenderMan's screen
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
    /// The screen transformation, applied to projected x, y:
    ///   screen x = a x + b y + tx,  screen y = c x + d y + ty
    /// with screenLinear = {a, b, c, d}, screenOffset = {tx, ty}; a negative
    /// determinant mirrors the image.
    float screenLinear[4] = {1, 0, 0, 1};
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
        if (m_screenDiagonal) {
            x = x * screenLinear[0] + screenOffset[0];
            y = y * screenLinear[3] + screenOffset[1];
        } else {
            const float px = x;
            x = screenLinear[0] * px + screenLinear[1] * y + screenOffset[0];
            y = screenLinear[2] * px + screenLinear[3] * y + screenOffset[1];
        }
        return {(x - screenWindow[0]) * m_xScale, (screenWindow[3] - y) * m_yScale, pCamera.z};
    }
    /// Raster pixels per camera-space unit at depth z (1 for orthographic
    /// depth-independence): converts a world length at depth z to pixels,
    /// at most (the longest axis of the screen transformation's stretch).
    float pixelsPerUnit(float z) const {
        float s = perspective ? 1.0f / (z * tanHalfFov) : 1.0f;
        return s * m_maxProjectedScale;
    }

    /// Raster pixels per screen unit along x and y (y is flipped by rasterOf).
    float rasterScaleX() const { return m_xScale; }
    float rasterScaleY() const { return m_yScale; }
    /// Raster pixels per projected unit (before the screen transformation):
    /// raster (x, y) offset = R * projected offset, R = {xx, xy, yx, yy}
    /// (raster y runs down, so the y row is negated). Diagonal unless the
    /// screen transformation rotates or shears.
    void rasterFromProjected(float R[4]) const {
        R[0] = m_xScale * screenLinear[0];
        R[1] = m_xScale * screenLinear[1];
        R[2] = -m_yScale * screenLinear[2];
        R[3] = -m_yScale * screenLinear[3];
    }
    /// The most raster pixels one projected unit spans in any direction:
    /// the larger singular value of rasterFromProjected (max(|xx|, |yy|)
    /// when diagonal).
    float maxProjectedScale() const { return m_maxProjectedScale; }
    /// True when the screen transformation neither rotates nor shears.
    bool screenDiagonal() const { return m_screenDiagonal; }
    /// True when the screen transformation mirrors the image (det < 0).
    bool screenMirrors() const { return screenLinear[0] * screenLinear[3] - screenLinear[1] * screenLinear[2] < 0; }

    /// Projective matrices for the shading language's named spaces.
    Mat4 screenFromCamera() const;
    Mat4 ndcFromScreen() const;
    Mat4 rasterFromScreen() const;
    Mat4 rasterFromCamera() const { return rasterFromScreen() * screenFromCamera(); }

    void finish();  // computes the cached scales; call after changing fields

private:
    float m_xScale = 1, m_yScale = 1;  // raster pixels per screen unit
    float m_maxProjectedScale = 1;
    bool m_screenDiagonal = true;      // screenLinear[1] == screenLinear[2] == 0
};

}  // namespace umbra::hider
