#include "umbra/dice/reyes.h"

#include <cmath>

namespace umbra::dice {

float eyePlaneZ(const DiceParams& p) { return clamp(p.nearClip, 1e-6f, 1e-3f); }

Bound3 cameraBound(const Bound3& objectBound, const DiceParams& p) {
    if (objectBound.empty()) return objectBound;
    Bound3 b = transformBound(p.cameraFromObject, objectBound);
    if (p.displacementBound > 0) {
        b.min -= Vec3(p.displacementBound);
        b.max += Vec3(p.displacementBound);
    }
    return b;
}

bool outsideView(const Bound3& cb, const DiceParams& p) {
    if (cb.empty()) return true;
    if (cb.max.z < p.nearClip || cb.min.z > p.farClip) return true;
    // Raster x >= xmin  <=>  (row0 - xmin * row3) . (p, 1) >= 0 where w > 0:
    // a half-space through the eye, so the test needs no division. Planes
    // with an infinite window edge are skipped.
    const auto& m = p.rasterFromCamera.m;
    for (int side = 0; side < 4; ++side) {
        const float edge = p.rasterWindow[side];
        if (!std::isfinite(edge)) continue;
        const int row = side < 2 ? 0 : 1;
        const float sign = (side & 1) ? -1.0f : 1.0f;  // min edges keep >=, max edges <=
        float h[4];
        for (int k = 0; k < 4; ++k) h[k] = sign * (m[row][k] - edge * m[3][k]);
        bool allOut = true;
        for (int c = 0; c < 8 && allOut; ++c) {
            const Vec3 q = cb.corner(c);
            allOut = h[0] * q.x + h[1] * q.y + h[2] * q.z + h[3] < 0;
        }
        if (allOut) return true;
    }
    return false;
}

Bound3 rasterBound(const Bound3& objectBound, const DiceParams& p) {
    const Bound3 cb = cameraBound(objectBound, p);
    if (cb.empty()) return cb;
    Bound3 r;
    if (!p.orthographic && cb.min.z < eyePlaneZ(p)) {
        r = Bound3({-kInfinity, -kInfinity, cb.min.z}, {kInfinity, kInfinity, cb.max.z});
        return r;
    }
    for (int c = 0; c < 8; ++c) {
        const Vec3 q = p.rasterFromCamera.point(cb.corner(c));
        r.extend(Vec3(q.x, q.y, 0));
    }
    r.min.z = cb.min.z;
    r.max.z = cb.max.z;
    return r;
}

void rasterLengths(const Vec3* R, int nu, int nv, float* lenU, float* lenV) {
    auto dist = [](const Vec3& a, const Vec3& b) { return std::hypot(a.x - b.x, a.y - b.y); };
    float lu = 0, lv = 0;
    for (int j = 0; j <= nv; ++j) {
        float s = 0;
        for (int i = 0; i < nu; ++i) s += dist(R[j * (nu + 1) + i], R[j * (nu + 1) + i + 1]);
        lu = std::max(lu, s);
    }
    for (int i = 0; i <= nu; ++i) {
        float s = 0;
        for (int j = 0; j < nv; ++j) s += dist(R[j * (nu + 1) + i], R[(j + 1) * (nu + 1) + i]);
        lv = std::max(lv, s);
    }
    *lenU = lu;
    *lenV = lv;
}

DiceResult decide(const geometry::Primitive& prim, const Bound3& objectBound, const DiceParams& p, int eyeSplits,
                  Diagnostics* diag) {
    DiceResult res;
    const Bound3 cb = cameraBound(objectBound, p);
    if (outsideView(cb, p)) return res;  // Cull

    if (!p.orthographic && cb.min.z < eyePlaneZ(p)) {
        if (eyeSplits >= p.maxEyeSplits) {
            if (diag)
                diag->warningOnce("dice:eyesplits", prim.record().loc,
                                  "{}: geometry still crosses the eye plane after {} eye splits; culling it "
                                  "(raise Option \"limits\" \"eyesplits\" or move the near clipping plane)",
                                  prim.record().type, p.maxEyeSplits);
            return res;
        }
        res.decision = Decision::Split;
        res.eyeSplit = true;
        // Cut across the parameter whose direction spans more camera z
        // (measured on the test lattice when the piece can be diced).
        res.splitU = true;
        if (prim.diceable()) {
            thread_local std::vector<Vec3> P;
            const int n = std::max(p.testGrid, 1);
            prim.dicePositions(n, n, P);
            float zu = 0, zv = 0;
            for (int j = 0; j <= n; ++j) zu = std::max(zu, std::abs(p.cameraFromObject.point(P[size_t(j * (n + 1) + n)]).z -
                                                                  p.cameraFromObject.point(P[size_t(j * (n + 1))]).z));
            for (int i = 0; i <= n; ++i) zv = std::max(zv, std::abs(p.cameraFromObject.point(P[size_t(n * (n + 1) + i)]).z -
                                                                  p.cameraFromObject.point(P[size_t(i)]).z));
            res.splitU = zu >= zv;
        }
        return res;
    }

    if (!prim.diceable()) {
        res.decision = Decision::Split;
        return res;
    }

    // Measure on the primitive itself: dice a small test lattice, project it
    // and take the longest raster extent along u and along v.
    thread_local std::vector<Vec3> P;
    const int n = std::max(p.testGrid, 1);
    prim.dicePositions(n, n, P);
    const Mat4 rasterFromObject = p.rasterFromCamera * p.cameraFromObject;
    const float zEye = eyePlaneZ(p);
    for (Vec3& q : P) {
        if (p.orthographic) {
            q = rasterFromObject.point(q);
            continue;
        }
        // The bound says z >= zEye; clamp anyway so rounding cannot divide by ~0.
        Vec3 c = p.cameraFromObject.point(q);
        if (c.z < zEye) c.z = zEye;
        q = p.rasterFromCamera.point(c);
    }
    float lenU = 0, lenV = 0;
    rasterLengths(P.data(), n, n, &lenU, &lenV);
    const float side = std::sqrt(std::max(p.shadingRate, 1e-6f));
    // Work in float first: a primitive near the eye can be millions of pixels long.
    const float fu = std::max(1.0f, std::ceil(lenU / side));
    const float fv = std::max(1.0f, std::ceil(lenV / side));
    if (!(fu * fv <= float(std::max(p.gridSize, 1)))) {
        res.decision = Decision::Split;
        res.splitU = !(fv > fu);
        return res;
    }
    res.decision = Decision::Dice;
    res.nu = int(fu);
    res.nv = int(fv);
    return res;
}

}  // namespace umbra::dice
