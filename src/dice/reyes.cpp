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

void flatnessCounts(const Vec3* Q, int n, float flatness, float* countU, float* countV) {
    // Second differences of the lattice (step 1/n) times n^2 are the
    // surface's second derivatives: A = P_uu, B = P_vv and, per cell, the
    // twist C = P_uv. Cut into Nu x Nv cells, a u edge's chord is off the
    // surface by |A| / (8 Nu^2) at its middle, a v edge's by |B| / (8 Nv^2),
    // and a cell's centre, which its triangles reach along the diagonal, by
    // |A / Nu^2 + 2 C / (Nu Nv) + B / Nv^2| / 8. Each is held to 3/4 of the
    // flatness: the margin covers what a coarse lattice misses.
    auto at = [&](int i, int j) { return Q[j * (n + 1) + i]; };
    const float nn = float(n) * float(n);
    const float limit = 0.75f * flatness;
    auto bendU = [&](int i, int j) { return (at(i - 1, j) - at(i, j) * 2.0f + at(i + 1, j)) * nn; };
    auto bendV = [&](int i, int j) { return (at(i, j - 1) - at(i, j) * 2.0f + at(i, j + 1)) * nn; };
    auto twist = [&](int i, int j) { return (at(i + 1, j + 1) - at(i + 1, j) - at(i, j + 1) + at(i, j)) * nn; };
    float maxA = 0, maxB = 0;
    for (int j = 0; j <= n; ++j)
        for (int i = 1; i < n; ++i) maxA = std::max(maxA, length(bendU(i, j)));
    for (int j = 1; j < n; ++j)
        for (int i = 0; i <= n; ++i) maxB = std::max(maxB, length(bendV(i, j)));
    // NaN (unprojectable points) gives no bound: the rate alone decides.
    auto count = [&](float bend) {
        const float c = std::ceil(std::sqrt(bend / (8.0f * limit)));
        return c >= 1 ? c : (bend >= 0 ? 1.0f : kInfinity);
    };
    float cu = count(maxA), cv = count(maxB);
    float centre = 0;  // the worst centre stand-off at cu x cv
    for (int j = 1; j < n; ++j)
        for (int i = 1; i < n; ++i) {
            const Vec3 d = bendU(i, j) / (cu * cu) + twist(i, j) * (2.0f / (cu * cv)) + bendV(i, j) / (cv * cv);
            centre = std::max(centre, length(d) / 8.0f);
        }
    if (!(centre >= 0)) {
        cu = cv = kInfinity;
    } else if (centre > limit) {
        // Every term falls with the square of a common scale.
        const float grow = std::sqrt(centre / limit);
        cu = std::ceil(cu * grow);
        cv = std::ceil(cv * grow);
    }
    *countU = cu;
    *countV = cv;
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
    // Flatness is measured in pixel space: raster x and y, and camera depth
    // in pixel widths.
    thread_local std::vector<Vec3> pixelSpace;
    const bool flat = p.flatness > 0;
    if (flat) pixelSpace.resize(P.size());
    float nearest = kInfinity;
    for (size_t k = 0; k < P.size(); ++k) {
        Vec3& q = P[k];
        Vec3 c = p.cameraFromObject.point(q);
        if (p.orthographic) {
            q = rasterFromObject.point(q);
        } else {
            // The bound says z >= zEye; clamp anyway so rounding cannot divide by ~0.
            if (c.z < zEye) c.z = zEye;
            q = p.rasterFromCamera.point(c);
        }
        if (flat) {
            pixelSpace[k] = Vec3(q.x, q.y, c.z);
            nearest = std::min(nearest, c.z);
        }
    }
    float flatU = kInfinity, flatV = kInfinity;
    if (flat) {
        // A camera unit spans S / w pixels, w = z under perspective (the
        // lattice's nearest point has the widest scale), 1 when orthographic.
        const auto& m = p.rasterFromCamera.m;
        const float S = std::max(std::abs(m[0][0]), std::abs(m[1][1]));
        const float scale = S / std::abs(m[3][2] * nearest + m[3][3]);
        for (Vec3& v : pixelSpace) v.z *= scale;
        flatnessCounts(pixelSpace.data(), n, p.flatness, &flatU, &flatV);
    }
    float lenU = 0, lenV = 0;
    rasterLengths(P.data(), n, n, &lenU, &lenV);
    const float side = std::sqrt(std::max(p.shadingRate, 1e-6f));
    // Work in float first: a primitive near the eye can be millions of pixels long.
    const float fu = std::max(1.0f, std::min(std::ceil(lenU / side), flatU));
    const float fv = std::max(1.0f, std::min(std::ceil(lenV / side), flatV));
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
