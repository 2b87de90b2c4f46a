#include "umbra/dice/reyes.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace umbra::dice {

float eyePlaneZ(const DiceParams& p) { return clamp(p.nearClip, 1e-6f, 1e-3f); }

namespace {

Bound3 padded(Bound3 b, const DiceParams& p) {
    if (!b.empty() && p.displacementBound > 0) {
        b.min -= Vec3(p.displacementBound);
        b.max += Vec3(p.displacementBound);
    }
    return b;
}

}  // namespace

Bound3 cameraBound(const Bound3& objectBound, const DiceParams& p) {
    if (objectBound.empty()) return objectBound;
    return padded(transformBound(p.cameraFromObject, objectBound), p);
}

Bound3 cameraBound(const geometry::Primitive& prim, const DiceParams& p) {
    return padded(prim.cameraBound(p.cameraFromObject, p.orthographic), p);
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
    return rasterBoundOfCamera(cameraBound(objectBound, p), p);
}

Bound3 rasterBoundOfCamera(const Bound3& cb, const DiceParams& p) {
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

namespace {

// The counts of flatnessCounts() and standOffCounts(): `measure(d, i, j)`
// is how far, in pixels, a second-derivative vector d at lattice point
// (i, j) carries the surface.
template <class Measure>
void bendCounts(const Vec3* Q, int n, float flatness, const Measure& measure, float* countU, float* countV) {
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
        for (int i = 1; i < n; ++i) maxA = std::max(maxA, measure(bendU(i, j), i, j));
    for (int j = 1; j < n; ++j)
        for (int i = 0; i <= n; ++i) maxB = std::max(maxB, measure(bendV(i, j), i, j));
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
            centre = std::max(centre, measure(d, i, j) / 8.0f);
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

}  // namespace

void flatnessCounts(const Vec3* Q, int n, float flatness, float* countU, float* countV) {
    bendCounts(Q, n, flatness, [](const Vec3& d, int, int) { return length(d); }, countU, countV);
}

void standOffCounts(const Vec3* Q, const float* pixelsPerUnit, int n, float standOff, float* countU,
                    float* countV) {
    // Only the part of a bend along the surface normal takes the chord off
    // the surface; the rest slides along it (a plane's lattice, however
    // unevenly spaced, bends nothing off it). Normals from the lattice's
    // central differences; where they vanish (a pole) the whole bend
    // counts.
    thread_local std::vector<Vec3> normals;
    normals.resize(size_t(n + 1) * size_t(n + 1));
    auto at = [&](int i, int j) { return Q[j * (n + 1) + i]; };
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) {
            const Vec3 du = at(std::min(i + 1, n), j) - at(std::max(i - 1, 0), j);
            const Vec3 dv = at(i, std::min(j + 1, n)) - at(i, std::max(j - 1, 0));
            const Vec3 c = cross(du, dv);
            const float len = length(c);
            normals[size_t(j * (n + 1) + i)] = len > 0 && std::isfinite(len) ? c / len : Vec3(0);
        }
    auto measure = [&](const Vec3& d, int i, int j) {
        const size_t k = size_t(j * (n + 1) + i);
        const Vec3& N = normals[k];
        const float off = (N.x == 0 && N.y == 0 && N.z == 0) ? length(d) : std::abs(dot(d, N));
        return off * pixelsPerUnit[k];
    };
    bendCounts(Q, n, standOff, measure, countU, countV);
}

void turningCounts(const Vec3* Q, int n, float maxTurn, float* countU, float* countV) {
    // Total turning of one polyline of the lattice: the angles between its
    // consecutive chords, each taken as |a/|a| - b/|b||, which is
    // 2 sin(angle / 2) (under the angle by at most a third, at a half
    // turn). Chords of no length (a sphere's pole row) turn nothing. The
    // n - 1 corners of n chords miss a chord's share of the turning:
    // scaled by n / (n - 1).
    auto turning = [&](const Vec3* first, int stride) {
        float total = 0;
        Vec3 prev;
        bool have = false;
        for (int k = 0; k < n; ++k) {
            const Vec3 d = first[(k + 1) * stride] - first[k * stride];
            const float len = length(d);
            if (!(len > 0) || !std::isfinite(len)) continue;
            const Vec3 dir = d / len;
            if (have) total += length(dir - prev);
            prev = dir;
            have = true;
        }
        return total;
    };
    float tu = 0, tv = 0;
    for (int j = 0; j <= n; ++j) tu = std::max(tu, turning(Q + j * (n + 1), 1));
    for (int i = 0; i <= n; ++i) tv = std::max(tv, turning(Q + i, n + 1));
    const float scale = n > 1 ? float(n) / float(n - 1) / maxTurn : 0.0f;
    // A tolerance below one keeps a sweep of exactly k * maxTurn at k.
    auto count = [&](float t) { return std::max(1.0f, std::ceil(t * scale - 0.05f)); };
    *countU = count(tu);
    *countV = count(tv);
}

namespace {

/// Area of triangle abc (x and y) clipped to the window xmin xmax ymin ymax.
double clippedTriangleArea(const Vec3& a, const Vec3& b, const Vec3& c, const float window[4]) {
    const auto inside = [&](const Vec3& q) {
        return q.x >= window[0] && q.x <= window[1] && q.y >= window[2] && q.y <= window[3];
    };
    const auto shoelace = [](const double* xs, const double* ys, int n) {
        double twice = 0;
        for (int i = 0, j = n - 1; i < n; j = i++) twice += xs[j] * ys[i] - xs[i] * ys[j];
        return std::abs(twice) * 0.5;
    };
    double xs[9] = {a.x, b.x, c.x}, ys[9] = {a.y, b.y, c.y};
    if (inside(a) && inside(b) && inside(c)) return shoelace(xs, ys, 3);
    // Sutherland-Hodgman against the window's four sides; a triangle gains
    // at most one vertex per side.
    int n = 3;
    for (int side = 0; side < 4 && n > 0; ++side) {
        const bool isX = side < 2;
        const double edge = window[side];
        const double sign = (side % 2 == 0) ? 1.0 : -1.0;  // keep coordinate >= min, <= max
        double ox[9], oy[9];
        int m = 0;
        for (int i = 0; i < n; ++i) {
            const int j = (i + 1) % n;
            const double di = sign * ((isX ? xs[i] : ys[i]) - edge), dj = sign * ((isX ? xs[j] : ys[j]) - edge);
            if (di >= 0) ox[m] = xs[i], oy[m++] = ys[i];
            if ((di >= 0) != (dj >= 0)) {
                const double t = di / (di - dj);
                ox[m] = xs[i] + t * (xs[j] - xs[i]);
                oy[m++] = ys[i] + t * (ys[j] - ys[i]);
            }
        }
        n = m;
        std::copy(ox, ox + m, xs);
        std::copy(oy, oy + m, ys);
    }
    return n >= 3 ? shoelace(xs, ys, n) : 0.0;
}

/// Keeps a split's direction, or turns it when the primitive cannot cut
/// that way (a parameter range at float resolution); false when it can cut
/// neither way, so splitting would make the same piece forever.
bool splittable(const geometry::Primitive& prim, DiceResult& res) {
    if (prim.splitsLeft(res.splitU) > 0) return true;
    res.splitU = !res.splitU;
    return prim.splitsLeft(res.splitU) > 0;
}

/// True when every halving float allows would still leave pieces of this
/// one far larger than the frame (256 times its larger side) along u or v:
/// the piece ends diced coarsely however it is split, and splitting it
/// first only multiplies pieces that all stay in view (the wedges around a
/// pole, a ribbon wider than the frame), which once ran a render out of
/// memory. No picture of ordinary geometry comes near: a ground plane 10^8
/// units long seen from a unit above is within a few thousand pixels.
bool beyondPrecision(const DiceParams& p, float lenU, int splitsLeftU, float lenV, int splitsLeftV) {
    const float frame = std::max(p.rasterWindow[1] - p.rasterWindow[0], p.rasterWindow[3] - p.rasterWindow[2]);
    if (!std::isfinite(frame)) return false;
    const float limit = 256.0f * std::max(frame, 1.0f);
    return std::ldexp(lenU, -splitsLeftU) > limit || std::ldexp(lenV, -splitsLeftV) > limit;
}

/// Counts for a piece too large for one grid that is not to be split:
/// scaled down together until they fit. Its micropolygons are then larger
/// than the shading rate asks (the callers warn); the alternative is a
/// piece that never finishes.
void coarsenToFit(float gridSize, float* fu, float* fv) {
    const float scale = std::sqrt(gridSize / (*fu * *fv));
    if (!(std::isfinite(scale) && scale > 0)) {
        *fu = *fv = std::max(1.0f, std::floor(std::sqrt(gridSize)));
        return;
    }
    // A count that scales below 1 stays 1, and the other takes its share.
    const float u = clamp(std::floor(*fu * scale), 1.0f, gridSize);
    const float v = clamp(std::floor(*fv * scale), 1.0f, std::floor(gridSize / u));
    *fu = std::min(std::max(1.0f, std::floor(*fu)), std::floor(gridSize / v));
    *fv = v;
}

/// True when the piece's split budget (DiceParams::splitBudget) leaves
/// room for two grids at its shading rate.
bool splitAffordable(const DiceParams& p, float gridSize) {
    return p.splitBudget >= 2.0 * double(std::max(p.shadingRate, 1e-6f)) * double(gridSize);
}

void warnPrecision(const geometry::Primitive& prim, Diagnostics* diag) {
    if (diag)
        diag->warningOnce("dice:precision", prim.record().loc,
                          "{}: a piece spans more pixels than float precision lets it be split into; diced "
                          "coarser than the shading rate (are its coordinates corrupt or enormous?)",
                          prim.record().type);
}

/// How a raster region (a bound) meets DiceParams::rasterWindow: its
/// width and height inside the window, and the pixels of the strips one
/// grid's side wide along every side of the window it crosses (a piece
/// reaching into the frame is cut along the edge into pieces about a grid
/// wide, however little of them shows).
struct WindowOverlap {
    double across, down, strips;
    WindowOverlap(const Bound3& r, const DiceParams& p) {
        const float* w = p.rasterWindow;
        const auto inside = [](float lo, float hi, float w0, float w1) {
            return std::max(std::min(double(hi), double(w1)) - std::max(double(lo), double(w0)), 0.0);
        };
        across = inside(r.min.x, r.max.x, w[0], w[1]);
        down = inside(r.min.y, r.max.y, w[2], w[3]);
        const int sidesX = (r.min.x < w[0]) + (r.max.x > w[1]);
        const int sidesY = (r.min.y < w[2]) + (r.max.y > w[3]);
        const double gridSide = std::sqrt(double(std::max(p.gridSize, 1)) * double(std::max(p.shadingRate, 1e-6f)));
        strips = gridSide * (sidesX * down + sidesY * across);
    }
};

void warnBudget(const geometry::Primitive& prim, Diagnostics* diag) {
    if (diag)
        diag->warningOnce("dice:budget", prim.record().loc,
                          "{}: its pieces would cover the frame many times over (a surface folded on itself, "
                          "or corrupt control points); the rest is diced coarser than the shading rate",
                          prim.record().type);
}

}  // namespace

double rasterNeed(const geometry::Primitive& prim, const DiceParams& p) {
    if (!prim.diceable()) return -1;
    const Bound3 cb = p.sweep.empty() ? cameraBound(prim, p) : p.sweep;
    if (!p.orthographic && cb.min.z < eyePlaneZ(p)) return -1;
    thread_local std::vector<Vec3> P;
    // A coarser lattice than decide()'s: a budget needs proportions, not counts.
    const int n = std::max(p.testGrid / 2, 1);
    prim.dicePositions(n, n, P);
    const Mat4 rasterFromObject = p.rasterFromCamera * p.cameraFromObject;
    for (Vec3& q : P) q = rasterFromObject.point(q);
    Bound3 lattice;
    for (const Vec3& q : P) lattice.extend(q);
    double need = WindowOverlap(lattice, p).strips;
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const Vec3 &a = P[size_t(j * (n + 1) + i)], &b = P[size_t(j * (n + 1) + i + 1)];
            const Vec3 &c = P[size_t((j + 1) * (n + 1) + i + 1)], &d = P[size_t((j + 1) * (n + 1) + i)];
            need += clippedTriangleArea(a, b, c, p.rasterWindow) + clippedTriangleArea(a, c, d, p.rasterWindow);
        }
    return std::isfinite(need) ? need : -1;
}

double boundNeed(const Bound3& rasterBound, const DiceParams& p) {
    if (rasterBound.empty()) return 0;
    const WindowOverlap o(rasterBound, p);
    return o.across * o.down + o.strips;
}

DiceResult decide(const geometry::Primitive& prim, const DiceParams& p, int eyeSplits, Diagnostics* diag) {
    DiceResult res;
    const Bound3 cb = p.sweep.empty() ? cameraBound(prim, p) : p.sweep;
    if (outsideView(cb, p)) return res;  // Cull

    if (!p.orthographic && cb.min.z < eyePlaneZ(p)) {
        // A group of items (points) comes down to single items in finitely
        // many splits: it is split past the limit, which stops surfaces
        // that would split forever. (A point cloud around a point light
        // crosses its cube faces' planes everywhere; cut at ten splits, the
        // groups still across them were culled, their shadows lost.)
        int itemsU = 0, itemsV = 0;
        const bool items = prim.fixedCounts(&itemsU, &itemsV);
        if (eyeSplits >= p.maxEyeSplits && !items) {
            // A piece that moves across the plane stays across it however
            // finely it is cut: more splits would not help.
            if (diag && !p.sweep.empty())
                diag->warningOnce("dice:eyemotionsplits", prim.record().loc,
                                  "{}: geometry moves across the eye plane during the shutter; culling what "
                                  "still crosses it after {} eye splits",
                                  prim.record().type, p.maxEyeSplits);
            else if (diag)
                diag->warningOnce("dice:eyesplits", prim.record().loc,
                                  "{}: geometry still crosses the eye plane after {} eye splits; culling it "
                                  "(raise Option \"limits\" \"eyesplits\" or move the near clipping plane)",
                                  prim.record().type, p.maxEyeSplits);
            return res;
        }
        res.decision = Decision::Split;
        res.eyeSplit = true;
        // Cut across the parameter whose direction spans more camera z
        // (measured on the test lattice when the piece can be diced). The
        // span is each row's (column's) whole z range, not the difference of
        // its ends: a full turn of a sphere or a cylinder around the eye
        // ends where it began, and a half turn's ends can lie level while
        // its middle sweeps behind the eye; splitting the other parameter
        // forever would leave the piece across the eye plane at the limit.
        res.splitU = true;
        if (prim.diceable()) {
            thread_local std::vector<Vec3> P;
            const int n = std::max(p.testGrid, 1);
            prim.dicePositions(n, n, P);
            auto z = [&](int i, int j) { return p.cameraFromObject.point(P[size_t(j * (n + 1) + i)]).z; };
            float zu = 0, zv = 0;
            for (int j = 0; j <= n; ++j) {
                float lo = kInfinity, hi = -kInfinity;
                for (int i = 0; i <= n; ++i) lo = std::min(lo, z(i, j)), hi = std::max(hi, z(i, j));
                zu = std::max(zu, hi - lo);
            }
            for (int i = 0; i <= n; ++i) {
                float lo = kInfinity, hi = -kInfinity;
                for (int j = 0; j <= n; ++j) lo = std::min(lo, z(i, j)), hi = std::max(hi, z(i, j));
                zv = std::max(zv, hi - lo);
            }
            res.splitU = zu >= zv;
        }
        if (!splittable(prim, res)) {
            // (A piece that moves across the plane, a single point, say,
            // beside a point light, cannot be split out of it.)
            if (diag && !p.sweep.empty())
                diag->warningOnce("dice:eyemotion", prim.record().loc,
                                  "{}: a piece that cannot be split further moves across the eye plane during the "
                                  "shutter; culling it",
                                  prim.record().type);
            else if (diag)
                diag->warningOnce("dice:eyeprecision", prim.record().loc,
                                  "{}: geometry crosses the eye plane in a piece too small to split in float "
                                  "precision; culling it (are its coordinates corrupt or enormous?)",
                                  prim.record().type);
            return DiceResult{};
        }
        return res;
    }

    if (!prim.diceable()) {
        res.decision = Decision::Split;
        return res;
    }
    int fixedU = 0, fixedV = 0;
    if (prim.fixedCounts(&fixedU, &fixedV)) {
        const bool fits = float(fixedU) * float(fixedV) <= float(std::max(p.gridSize, 1));
        res.decision = fits ? Decision::Dice : Decision::Split;
        res.nu = fits ? fixedU : 0;
        res.nv = fits ? fixedV : 0;
        return res;
    }

    // Measure on the primitive itself: dice a small test lattice, project it
    // and take the longest raster extent along u and along v. (As seen from
    // this camera: a curve's ribbon turns to face it.)
    thread_local std::vector<Vec3> P;
    const int n = std::max(p.testGrid, 1);
    prim.dicePositionsInView(n, n, geometry::ViewContext::ofCamera(p.cameraFromObject.inverse(), p.orthographic), P);
    const Mat4 rasterFromObject = p.rasterFromCamera * p.cameraFromObject;
    const float zEye = eyePlaneZ(p);
    // Flatness is measured in pixel space: raster x and y, and camera depth
    // in pixel widths.
    thread_local std::vector<Vec3> pixelSpace, cameraSpace;
    const bool flat = p.flatness > 0 || p.maxStandOff > 0;
    if (flat) pixelSpace.resize(P.size());
    cameraSpace.resize(P.size());
    float nearest = kInfinity;
    for (size_t k = 0; k < P.size(); ++k) {
        Vec3& q = P[k];
        Vec3 c = p.cameraFromObject.point(q);
        cameraSpace[k] = c;
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
    float flatU = kInfinity, flatV = kInfinity;  // no finer than this (depth passes)
    float standU = 1, standV = 1;                // no coarser than this (GeometricApproximation)
    if (flat) {
        // A camera unit spans S / w pixels, w = z under perspective (the
        // lattice's nearest point has the widest scale), 1 when orthographic.
        // (The larger singular value of the x/y part when a screen
        // transformation rotates or shears.)
        const auto& m = p.rasterFromCamera.m;
        const float xy[4] = {m[0][0], m[0][1], m[1][0], m[1][1]};
        const float S = largestSingularValue(xy);
        const float scale = S / std::abs(m[3][2] * nearest + m[3][3]);
        for (Vec3& v : pixelSpace) v.z *= scale;
        if (p.flatness > 0) flatnessCounts(pixelSpace.data(), n, p.flatness, &flatU, &flatV);
        if (p.maxStandOff > 0) {
            thread_local std::vector<float> pixelsPerUnit;
            pixelsPerUnit.resize(cameraSpace.size());
            for (size_t k = 0; k < cameraSpace.size(); ++k)
                pixelsPerUnit[k] = S / std::abs(m[3][2] * std::max(cameraSpace[k].z, zEye) + m[3][3]);
            standOffCounts(cameraSpace.data(), pixelsPerUnit.data(), n, p.maxStandOff, &standU, &standV);
            // Unprojectable points (NaN) give no bound: the rate alone decides.
            if (!std::isfinite(standU) || !std::isfinite(standV)) standU = standV = 1;
        }
    }
    float lenU = 0, lenV = 0;
    rasterLengths(P.data(), n, n, &lenU, &lenV);
    const float side = std::sqrt(std::max(p.shadingRate, 1e-6f));
    // Work in float first: a primitive near the eye can be millions of pixels long.
    float fu = std::max({1.0f, std::min(std::ceil(lenU / side), flatU), standU});
    float fv = std::max({1.0f, std::min(std::ceil(lenV / side), flatV), standV});
    const float gridSize = float(std::max(p.gridSize, 1));
    if (!(fu * fv <= gridSize)) {
        res.decision = Decision::Split;
        res.splitU = !(fv > fu);
        // A count along a direction that cannot be split any more is final
        // (cutting the other way cannot bring it down), so splitting is
        // worth it only while that count alone fits a grid.
        const int leftU = prim.splitsLeft(true), leftV = prim.splitsLeft(false);
        const bool canU = leftU > 0, canV = leftV > 0;
        if (!(res.splitU ? canU : canV)) res.splitU = !res.splitU;
        const bool worthIt = (canU || canV) && (canU || fu <= gridSize) && (canV || fv <= gridSize) &&
                             !beyondPrecision(p, lenU, leftU, lenV, leftV);
        if (!worthIt)
            warnPrecision(prim, diag);
        else if (!splitAffordable(p, gridSize)) {
            if (p.pieceNeed > double(gridSize) * double(std::max(p.shadingRate, 1e-6f)))
                warnBudget(prim, diag);
        } else {
            return res;
        }
        coarsenToFit(gridSize, &fu, &fv);
    }
    // However coarse the rate, a curved primitive keeps enough
    // micropolygons for none of their edges to turn by more than maxTurn:
    // at ShadingRate 1000 a sphere is blocky, not a 1x1 grid whose corners
    // lie on one meridian and cover nothing. Flat primitives turn nothing
    // and keep their counts. The lattice's turning is at most n half
    // turns, so counts at that many or more need no measuring. The
    // minimum never makes a grid exceed gridSize (it gives way first), so
    // it never causes a split.
    const float turnCap = std::ceil(float(n) * kPi / std::max(p.maxTurn, 1e-3f));
    if (p.maxTurn > 0 && std::min(fu, fv) < turnCap) {
        float tu, tv;
        turningCounts(cameraSpace.data(), n, p.maxTurn, &tu, &tv);
        float mu = std::max(fu, tu), mv = std::max(fv, tv);
        while (mu * mv > gridSize && (mu > fu || mv > fv)) {
            if (mu > fu && (mu >= mv || !(mv > fv)))
                mu -= 1;
            else
                mv -= 1;
        }
        fu = mu;
        fv = mv;
    }
    if (p.binary) {
        const float bu = std::exp2(std::ceil(std::log2(fu))), bv = std::exp2(std::ceil(std::log2(fv)));
        if (bu * bv > gridSize) {
            res.decision = Decision::Split;
            res.splitU = !(bv > bu);
            if (splittable(prim, res) && splitAffordable(p, gridSize)) return res;
        } else {
            fu = bu;
            fv = bv;
        }
    }
    res.decision = Decision::Dice;
    res.nu = int(fu);
    res.nv = int(fv);
    return res;
}

}  // namespace umbra::dice
