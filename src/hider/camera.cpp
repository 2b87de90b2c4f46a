#include "umbra/hider/camera.h"

#include <algorithm>
#include <cmath>

namespace umbra::hider {

Camera Camera::fromOptions(const scene::Options& o) {
    Camera c;
    c.xResolution = std::max(1, o.xResolution);
    c.yResolution = std::max(1, o.yResolution);
    c.perspective = o.projection == scene::Projection::Perspective;
    c.tanHalfFov = std::tan(radians(clamp(o.fov, 1e-3f, 179.9f)) * 0.5f);
    float aspect = o.frameAspectRatio > 0 ? o.frameAspectRatio
                                          : float(c.xResolution) * o.pixelAspectRatio / float(c.yResolution);
    if (o.screenWindowSet) {
        for (int i = 0; i < 4; ++i) c.screenWindow[i] = o.screenWindow[i];
    } else if (aspect >= 1) {
        c.screenWindow[0] = -aspect; c.screenWindow[1] = aspect;
        c.screenWindow[2] = -1;      c.screenWindow[3] = 1;
    } else {
        c.screenWindow[0] = -1;          c.screenWindow[1] = 1;
        c.screenWindow[2] = -1 / aspect; c.screenWindow[3] = 1 / aspect;
    }
    for (int i = 0; i < 4; ++i) c.screenLinear[i] = o.screenLinear[i];
    for (int i = 0; i < 2; ++i) c.screenOffset[i] = o.screenOffset[i];
    c.nearClip = o.nearClip;
    c.farClip = o.farClip;
    c.cameraFromWorld = o.cameraFromWorld;
    c.finish();
    return c;
}

void Camera::finish() {
    m_xScale = float(xResolution) / (screenWindow[1] - screenWindow[0]);
    m_yScale = float(yResolution) / (screenWindow[3] - screenWindow[2]);
    m_screenDiagonal = screenLinear[1] == 0 && screenLinear[2] == 0;
    float R[4];
    rasterFromProjected(R);
    m_maxProjectedScale = largestSingularValue(R);
}

Mat4 Camera::screenFromCamera() const {
    // The screen transformation, after the projection.
    Mat4 st;
    st.m[0][0] = screenLinear[0];
    st.m[0][1] = screenLinear[1];
    st.m[1][0] = screenLinear[2];
    st.m[1][1] = screenLinear[3];
    st.m[0][3] = screenOffset[0];
    st.m[1][3] = screenOffset[1];
    if (!perspective) return st;
    // After the divide by w = z: x/(z t), y/(z t), and RenderMan's screen
    // depth f(z-n)/(z(f-n)), which maps [near, far] to [0, 1].
    double n = nearClip, f = farClip;
    Mat4 m;
    m.m[0][0] = 1 / tanHalfFov;
    m.m[1][1] = 1 / tanHalfFov;
    m.m[2][2] = float(f / (f - n));
    m.m[2][3] = float(-f * n / (f - n));
    m.m[3][2] = 1;
    m.m[3][3] = 0;
    return st * m;
}

Mat4 Camera::ndcFromScreen() const {
    Mat4 m;
    float w = screenWindow[1] - screenWindow[0], h = screenWindow[3] - screenWindow[2];
    m.m[0][0] = 1 / w;
    m.m[0][3] = -screenWindow[0] / w;
    m.m[1][1] = -1 / h;
    m.m[1][3] = screenWindow[3] / h;
    return m;
}

Mat4 Camera::rasterFromScreen() const {
    return Mat4::scale({float(xResolution), float(yResolution), 1}) * ndcFromScreen();
}

}  // namespace umbra::hider
