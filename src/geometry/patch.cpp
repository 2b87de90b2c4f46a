#include "umbra/geometry/patch.h"

#include <algorithm>
#include <cmath>

namespace umbra::geometry {

namespace {

const SurfaceData& orEmpty(const std::shared_ptr<const SurfaceData>& sd) {
    static const SurfaceData kEmpty;
    return sd ? *sd : kEmpty;
}

// Bound of homogeneous points, divided by w.
void extendHomogeneous(Bound3& b, const float* p, int dim) {
    if (dim == 4 && p[3] != 0) b.extend(Vec3(p[0], p[1], p[2]) / p[3]);
    else b.extend(Vec3(p[0], p[1], p[2]));
}

void divideW(const float* h, int dim, Vec3* out) {
    if (dim == 4) *out = Vec3(h[0], h[1], h[2]) / h[3];
    else *out = Vec3(h[0], h[1], h[2]);
}

/// Whether the bilinear patch of these homogeneous corners (u fastest:
/// (0,0) (1,0) (0,1) (1,1)) is a flat convex quadrilateral. Its edges are
/// straight, so it is then exactly the quadrilateral, whatever its
/// parameterisation, and so is every piece split from it. Corners off the
/// plane by 1e-5 of the quad's size or less count as on it: one
/// micropolygon then stands off the true surface by no more than that.
/// Rational corners (unequal w) are left out.
bool isFlatConvexQuad(const float corner[4][4]) {
    for (int c = 1; c < 4; ++c)
        if (corner[c][3] != corner[0][3]) return false;
    if (!(corner[0][3] != 0)) return false;
    Vec3 q[4];  // around the outline: (0,0) (1,0) (1,1) (0,1)
    const int order[4] = {0, 1, 3, 2};
    for (int k = 0; k < 4; ++k) {
        const float* c = corner[order[k]];
        q[k] = Vec3(c[0], c[1], c[2]) / c[3];
    }
    const Vec3 n = cross(q[2] - q[0], q[3] - q[1]);  // the diagonals span the plane
    const float size = std::max(length(q[2] - q[0]), length(q[3] - q[1]));
    const float nLength = length(n);
    if (!(nLength > 0) || !std::isfinite(nLength) || !(size > 0)) return false;
    const Vec3 unit = n / nLength;
    const Vec3 centre = (q[0] + q[1] + q[2] + q[3]) * 0.25f;
    for (const Vec3& p : q)
        if (!(std::abs(dot(p - centre, unit)) <= 1e-5f * size)) return false;
    // Convex: every turn of the outline is to the same side (collapsed
    // edges, as a triangle's, turn by zero).
    for (int k = 0; k < 4; ++k) {
        const Vec3 in = q[k] - q[(k + 3) % 4], out = q[(k + 1) % 4] - q[k];
        if (dot(cross(in, out), unit) < -1e-6f * size * size) return false;
    }
    return true;
}

}  // namespace

BilinearPatch::BilinearPatch(std::shared_ptr<const scene::PrimitiveRecord> record,
                             std::shared_ptr<const SurfaceData> data, const CornerRefs& refs, const ParamRange& range,
                             const ParamMap& map)
    : Primitive(std::move(record)), m_data(std::move(data)), m_refs(refs), m_range(range), m_map(map) {
    float corner[4][4];
    cornerPositions(corner);
    m_flatQuad = isFlatConvexQuad(corner);
}

void BilinearPatch::cornerPositions(float corner[4][4]) const {
    for (int c = 0; c < 4; ++c) m_data->position(size_t(m_refs.vertex[c]), corner[c]);
}

void BilinearPatch::evalPositions(const std::vector<float>& a, const std::vector<float>& b, Vec3* P) const {
    const int dim = m_data->posDim;
    float corner[4][4];
    cornerPositions(corner);
    for (float bv : b) {
        float L[4], R[4];
        for (int k = 0; k < 4; ++k) {
            L[k] = corner[0][k] + bv * (corner[2][k] - corner[0][k]);
            R[k] = corner[1][k] + bv * (corner[3][k] - corner[1][k]);
        }
        for (float av : a) {
            float h[4];
            for (int k = 0; k < 4; ++k) h[k] = L[k] + av * (R[k] - L[k]);
            divideW(h, dim, P++);
        }
    }
}

Bound3 BilinearPatch::bound() const {
    // A bilinear patch lies in the convex hull of its corners; the
    // sub-range's corners are points of the full patch.
    Bound3 b;
    const std::vector<float> a = {m_range.u0, m_range.u1}, v = {m_range.v0, m_range.v1};
    Vec3 P[4];
    evalPositions(a, v, P);
    for (const Vec3& p : P) b.extend(p);
    return b;
}

void BilinearPatch::split(bool splitU, std::vector<PrimitivePtr>& out) const {
    for (int k = 0; k < 2; ++k)
        out.push_back(std::make_unique<BilinearPatch>(recordPtr(), m_data, m_refs, m_range.half(splitU, k == 1), m_map));
}

Grid BilinearPatch::dice(int nu, int nv) const {
    Grid g;
    std::vector<float> a, b;
    initGrid(g, nu, nv, m_range, m_map, a, b);
    evalPositions(a, b, g.P.data());
    interpolateVars(orEmpty(m_data), m_refs, a, b, false, g);
    return g;
}

void BilinearPatch::dicePositions(int nu, int nv, std::vector<Vec3>& P) const {
    thread_local std::vector<float> a, b;
    m_range.steps(nu, nv, a, b);
    P.resize(size_t(nu + 1) * size_t(nv + 1));
    evalPositions(a, b, P.data());
}

namespace {

// Ascending-power weights A[k][i]: the coefficient of t^k contributed by
// control value i. The spec's matrix multiplies [t^3 t^2 t 1].
void ascending(const scene::Basis& basis, float A[4][4]) {
    for (int k = 0; k < 4; ++k)
        for (int i = 0; i < 4; ++i) A[k][i] = basis.m[3 - k][i];
}

// C[k][l] = sum_ij Au[k][i] Av[l][j] G[i][j] for one component.
void toPower(const float Au[4][4], const float Av[4][4], const float G[4][4], float C[4][4]) {
    float T[4][4];  // T[k][j] = sum_i Au[k][i] G[i][j]
    for (int k = 0; k < 4; ++k)
        for (int j = 0; j < 4; ++j) {
            double s = 0;
            for (int i = 0; i < 4; ++i) s += double(Au[k][i]) * G[i][j];
            T[k][j] = float(s);
        }
    for (int k = 0; k < 4; ++k)
        for (int l = 0; l < 4; ++l) {
            double s = 0;
            for (int j = 0; j < 4; ++j) s += double(Av[l][j]) * T[k][j];
            C[k][l] = float(s);
        }
}

// Q maps ascending power coefficients on [t0, t1] to the Bezier control
// values of that sub-range: substitute t = t0 + h s, then b_i = sum_{k<=i}
// C(i,k) / C(3,k) a_k.
void bezierOfRange(float t0, float t1, double Q[4][4]) {
    static const double binom[4][4] = {{1, 0, 0, 0}, {1, 1, 0, 0}, {1, 2, 1, 0}, {1, 3, 3, 1}};
    const double h = double(t1) - double(t0);
    double T[4][4] = {};  // new coefficient m from old k
    for (int k = 0; k < 4; ++k)
        for (int m = 0; m <= k; ++m) T[m][k] = binom[k][m] * std::pow(double(t0), k - m) * std::pow(h, m);
    for (int i = 0; i < 4; ++i)
        for (int k = 0; k < 4; ++k) {
            double s = 0;
            for (int m = 0; m <= i; ++m) s += binom[i][m] / binom[3][m] * T[m][k];
            Q[i][k] = s;
        }
}

}  // namespace

std::shared_ptr<const BicubicCoeffs> BicubicCoeffs::make(const SurfaceData& sd, const std::array<int, 16>& ctrl,
                                                         const scene::Basis& uBasis, const scene::Basis& vBasis) {
    auto c = std::make_shared<BicubicCoeffs>();
    float Au[4][4], Av[4][4];
    ascending(uBasis, Au);
    ascending(vBasis, Av);
    c->posDim = sd.posDim;
    float G[4][4], C[4][4];
    for (int comp = 0; comp < 4; ++comp) {
        for (int j = 0; j < 4; ++j)
            for (int i = 0; i < 4; ++i) {
                float h[4];
                sd.position(size_t(ctrl[size_t(j * 4 + i)]), h);
                G[i][j] = h[comp];
            }
        toPower(Au, Av, G, C);
        for (int k = 0; k < 4; ++k)
            for (int l = 0; l < 4; ++l) c->pos[k][l][comp] = C[k][l];
    }
    for (size_t vi = 0; vi < sd.vars.size(); ++vi) {
        const PrimVar& v = sd.vars[vi];
        if (v.storage != ri::StorageClass::Vertex) continue;
        Var out{int(vi), std::vector<float>(size_t(16 * v.components))};
        for (int comp = 0; comp < v.components; ++comp) {
            for (int j = 0; j < 4; ++j)
                for (int i = 0; i < 4; ++i) G[i][j] = v.at(size_t(ctrl[size_t(j * 4 + i)]))[comp];
            toPower(Au, Av, G, C);
            for (int k = 0; k < 4; ++k)
                for (int l = 0; l < 4; ++l) out.c[size_t((k * 4 + l) * v.components + comp)] = C[k][l];
        }
        c->vertexVars.push_back(std::move(out));
    }
    return c;
}

void evalBicubicGrid(const float* c, int comps, const std::vector<float>& a, const std::vector<float>& b, float* out) {
    // Per row: collapse v (Horner), leaving a cubic in u per component;
    // per vertex: Horner in u, three multiply-adds per component.
    constexpr int kMax = 16;
    float R[4][kMax];
    for (int base = 0; base < comps; base += kMax) {
        const int n = std::min(kMax, comps - base);
        float* o = out + base;
        for (float bv : b) {
            for (int k = 0; k < 4; ++k)
                for (int q = 0; q < n; ++q) {
                    const float* ck = c + size_t(k * 4) * size_t(comps) + size_t(base + q);
                    R[k][q] = ((ck[3 * comps] * bv + ck[2 * comps]) * bv + ck[comps]) * bv + ck[0];
                }
            for (float av : a) {
                for (int q = 0; q < n; ++q) o[q] = ((R[3][q] * av + R[2][q]) * av + R[1][q]) * av + R[0][q];
                o += comps;
            }
        }
    }
}

BicubicPatch::BicubicPatch(std::shared_ptr<const scene::PrimitiveRecord> record,
                           std::shared_ptr<const SurfaceData> data, std::shared_ptr<const BicubicCoeffs> coeffs,
                           const CornerRefs& refs, const ParamRange& range, const ParamMap& map)
    : Primitive(std::move(record)), m_data(std::move(data)), m_coeffs(std::move(coeffs)), m_refs(refs),
      m_range(range), m_map(map) {}

Vec3 BicubicPatch::evaluate(float u, float v) const {
    float h[4];
    const std::vector<float> a = {u}, b = {v};
    evalBicubicGrid(&m_coeffs->pos[0][0][0], 4, a, b, h);
    Vec3 p;
    divideW(h, m_coeffs->posDim, &p);
    return p;
}

Bound3 BicubicPatch::bound() const {
    double Qu[4][4], Qv[4][4];
    bezierOfRange(m_range.u0, m_range.u1, Qu);
    bezierOfRange(m_range.v0, m_range.v1, Qv);
    const int dim = m_coeffs->posDim;
    Bound3 bnd;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            float p[4];
            for (int comp = 0; comp < 4; ++comp) {
                double s = 0;
                for (int k = 0; k < 4; ++k)
                    for (int l = 0; l < 4; ++l) s += Qu[i][k] * Qv[j][l] * m_coeffs->pos[k][l][comp];
                p[comp] = float(s);
            }
            extendHomogeneous(bnd, p, dim);
        }
    // The conversion rounds in float; grow by a relative epsilon so diced
    // points never land outside.
    const Vec3 d = bnd.diagonal();
    const float pad = 1e-5f * std::max({d.x, d.y, d.z}) + 1e-7f * std::max({std::abs(bnd.min.x), std::abs(bnd.min.y),
                                                                             std::abs(bnd.min.z), std::abs(bnd.max.x),
                                                                             std::abs(bnd.max.y), std::abs(bnd.max.z)});
    bnd.min -= Vec3(pad);
    bnd.max += Vec3(pad);
    return bnd;
}

void BicubicPatch::split(bool splitU, std::vector<PrimitivePtr>& out) const {
    for (int k = 0; k < 2; ++k)
        out.push_back(std::make_unique<BicubicPatch>(recordPtr(), m_data, m_coeffs, m_refs,
                                                     m_range.half(splitU, k == 1), m_map));
}

Grid BicubicPatch::dice(int nu, int nv) const {
    Grid g;
    std::vector<float> a, b;
    initGrid(g, nu, nv, m_range, m_map, a, b);
    const size_t n = g.P.size();
    const int dim = m_coeffs->posDim;
    thread_local std::vector<float> h;
    h.resize(n * 4);
    evalBicubicGrid(&m_coeffs->pos[0][0][0], 4, a, b, h.data());
    for (size_t k = 0; k < n; ++k) divideW(&h[k * 4], dim, &g.P[k]);
    const SurfaceData& sd = orEmpty(m_data);
    interpolateVars(sd, m_refs, a, b, true, g);
    for (const BicubicCoeffs::Var& cv : m_coeffs->vertexVars) {
        const PrimVar& v = sd.vars[size_t(cv.index)];
        if (v.isNormal) {
            g.N.resize(n);
            evalBicubicGrid(cv.c.data(), 3, a, b, &g.N[0].x);
        } else {
            GridVar& gv = addGridVar(g, v, true);
            evalBicubicGrid(cv.c.data(), v.components, a, b, gv.data.data());
        }
    }
    return g;
}

void BicubicPatch::dicePositions(int nu, int nv, std::vector<Vec3>& P) const {
    thread_local std::vector<float> a, b, h;
    m_range.steps(nu, nv, a, b);
    const size_t n = size_t(nu + 1) * size_t(nv + 1);
    P.resize(n);
    h.resize(n * 4);
    evalBicubicGrid(&m_coeffs->pos[0][0][0], 4, a, b, h.data());
    for (size_t k = 0; k < n; ++k) divideW(&h[k * 4], m_coeffs->posDim, &P[k]);
}

}  // namespace umbra::geometry
