#include "umbra/scene/scene.h"

#include <cstring>

namespace umbra::scene {

// The RI spec 3.2 basis matrices, stored exactly as the spec prints them:
// a cubic segment is P(u) = [u^3 u^2 u 1] * m * G for a column G of four
// control values, and `step` is how many control points the next segment
// of a patch mesh advances by.
namespace {
Basis make(const float (&v)[4][4], float scale, int step) {
    Basis b;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) b.m[i][j] = v[i][j] * scale;
    b.step = step;
    return b;
}
}  // namespace

Basis Basis::bezier() {
    static const float v[4][4] = {{-1, 3, -3, 1}, {3, -6, 3, 0}, {-3, 3, 0, 0}, {1, 0, 0, 0}};
    return make(v, 1.0f, 3);
}
Basis Basis::bspline() {
    static const float v[4][4] = {{-1, 3, -3, 1}, {3, -6, 3, 0}, {-3, 0, 3, 0}, {1, 4, 1, 0}};
    return make(v, 1.0f / 6.0f, 1);
}
Basis Basis::catmullRom() {
    static const float v[4][4] = {{-1, 3, -3, 1}, {2, -5, 4, -1}, {-1, 0, 1, 0}, {0, 2, 0, 0}};
    return make(v, 0.5f, 1);
}
Basis Basis::hermite() {
    static const float v[4][4] = {{2, 1, -2, 1}, {-3, -2, 3, -1}, {0, 1, 0, 0}, {1, 0, 0, 0}};
    return make(v, 1.0f, 2);
}
Basis Basis::power() {
    static const float v[4][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};
    return make(v, 1.0f, 4);
}

bool Basis::byName(const std::string& name, Basis* out) {
    if (name == "bezier") *out = bezier();
    else if (name == "b-spline" || name == "bspline") *out = bspline();
    else if (name == "catmull-rom" || name == "catmullrom") *out = catmullRom();
    else if (name == "hermite") *out = hermite();
    else if (name == "power") *out = power();
    else return false;
    return true;
}

}  // namespace umbra::scene
