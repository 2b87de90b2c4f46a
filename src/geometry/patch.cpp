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
            for (int l = 0; l < 4; ++l) {
                c->pos[k][l][comp] = C[k][l];
                // d/du of sum C[k][l] u^k v^l: (k+1) C[k+1][l] at power k.
                c->posDu[k][l][comp] = k < 3 ? float(k + 1) * C[k + 1][l] : 0.0f;
                c->posDv[k][l][comp] = l < 3 ? float(l + 1) * C[k][l + 1] : 0.0f;
            }
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

void evalBicubicRect(const float* c, int comps, const float* a, int na, const float* b, int nb, float* out,
                     size_t rowStride) {
    // Per row: collapse v (Horner), leaving a cubic in u per component;
    // per vertex: Horner in u, three multiply-adds per component.
    constexpr int kMax = 16;
    float R[4][kMax];
    for (int base = 0; base < comps; base += kMax) {
        const int n = std::min(kMax, comps - base);
        for (int row = 0; row < nb; ++row) {
            const float bv = b[row];
            float* o = out + size_t(row) * rowStride + size_t(base);
            for (int k = 0; k < 4; ++k)
                for (int q = 0; q < n; ++q) {
                    const float* ck = c + size_t(k * 4) * size_t(comps) + size_t(base + q);
                    R[k][q] = ((ck[3 * comps] * bv + ck[2 * comps]) * bv + ck[comps]) * bv + ck[0];
                }
            for (int col = 0; col < na; ++col) {
                const float av = a[col];
                for (int q = 0; q < n; ++q) o[q] = ((R[3][q] * av + R[2][q]) * av + R[1][q]) * av + R[0][q];
                o += comps;
            }
        }
    }
}

void evalBicubicGrid(const float* c, int comps, const std::vector<float>& a, const std::vector<float>& b, float* out) {
    evalBicubicRect(c, comps, a.data(), int(a.size()), b.data(), int(b.size()), out, a.size() * size_t(comps));
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

Bound3 bicubicHullBound(const BicubicCoeffs& coeffs, const ParamRange& range) {
    double Qu[4][4], Qv[4][4];
    bezierOfRange(range.u0, range.u1, Qu);
    bezierOfRange(range.v0, range.v1, Qv);
    const int dim = coeffs.posDim;
    Bound3 bnd;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            float p[4];
            for (int comp = 0; comp < 4; ++comp) {
                double s = 0;
                for (int k = 0; k < 4; ++k)
                    for (int l = 0; l < 4; ++l) s += Qu[i][k] * Qv[j][l] * coeffs.pos[k][l][comp];
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

Bound3 BicubicPatch::bound() const { return bicubicHullBound(*m_coeffs, m_range); }

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
    if (g.N.empty()) {
        thread_local std::vector<float> ha, hb;
        ha.resize(n * 4);
        hb.resize(n * 4);
        evalBicubicGrid(&m_coeffs->posDu[0][0][0], 4, a, b, ha.data());
        evalBicubicGrid(&m_coeffs->posDv[0][0][0], 4, a, b, hb.data());
        setDerivativeNormals(g, h.data(), ha.data(), hb.data(), dim, m_map);
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

// ---------------------------------------------------------------------------
// Blocks of bicubic patches

bool BicubicPatchArray::blockable(const SurfaceData& sd) {
    for (const PrimVar& v : sd.vars)
        if (v.storage == ri::StorageClass::Uniform || v.storage == ri::StorageClass::FaceVarying ||
            v.storage == ri::StorageClass::FaceVertex)
            return false;
    return true;
}

BicubicBlock::BicubicBlock(std::shared_ptr<const scene::PrimitiveRecord> record,
                           std::shared_ptr<const BicubicPatchArray> patches, int i0, int j0, int i1, int j1)
    : Primitive(std::move(record)), m_patches(std::move(patches)), m_i0(i0), m_j0(j0), m_i1(i1), m_j1(j1) {
    for (int j = j0; j < j1; ++j)
        for (int i = i0; i < i1; ++i) m_bound.extend(m_patches->bounds[m_patches->index(i, j)]);
}

void BicubicBlock::appendPiece(const std::shared_ptr<const scene::PrimitiveRecord>& record,
                               const std::shared_ptr<const BicubicPatchArray>& patches, int i0, int j0, int i1, int j1,
                               std::vector<PrimitivePtr>& out) {
    if (i1 - i0 == 1 && j1 - j0 == 1) {
        const size_t k = patches->index(i0, j0);
        out.push_back(std::make_unique<BicubicPatch>(record, patches->sd, patches->coeffs[k], patches->refs[k],
                                                     ParamRange{}, patches->map(i0, j0)));
        return;
    }
    out.push_back(std::make_unique<BicubicBlock>(record, patches, i0, j0, i1, j1));
}

void BicubicBlock::appendBlocks(const std::shared_ptr<const scene::PrimitiveRecord>& record,
                                const std::shared_ptr<const BicubicPatchArray>& patches, int maxSide,
                                std::vector<PrimitivePtr>& out) {
    maxSide = std::max(maxSide, 1);
    const int bu = (patches->columns + maxSide - 1) / maxSide, bv = (patches->rows + maxSide - 1) / maxSide;
    for (int q = 0; q < bv; ++q)
        for (int p = 0; p < bu; ++p)
            appendPiece(record, patches, patches->columns * p / bu, patches->rows * q / bv,
                        patches->columns * (p + 1) / bu, patches->rows * (q + 1) / bv, out);
}

void BicubicBlock::split(bool splitU, std::vector<PrimitivePtr>& out) const {
    // Across u as asked when the block is more than one patch wide, else
    // across v; a block one patch wide and tall is never made (appendPiece).
    const bool acrossU = columns() > 1 && (splitU || rows() == 1);
    if (acrossU) {
        const int m = m_i0 + columns() / 2;
        appendPiece(recordPtr(), m_patches, m_i0, m_j0, m, m_j1, out);
        appendPiece(recordPtr(), m_patches, m, m_j0, m_i1, m_j1, out);
    } else {
        const int m = m_j0 + rows() / 2;
        appendPiece(recordPtr(), m_patches, m_i0, m_j0, m_i1, m, out);
        appendPiece(recordPtr(), m_patches, m_i0, m, m_i1, m_j1, out);
    }
}

namespace {

/// Where the n + 1 lattice values of one direction of a block `count`
/// patches long fall: value k at k * count / n patch widths, on patch
/// min(floor, count - 1) at the local parameter `local[k]` (computed in
/// integers, so patch edges are hit exactly); `first[p]` is the first
/// value on patch p (first[count] = n + 1).
void blockLattice(int count, int n, std::vector<int>& first, std::vector<float>& local) {
    first.assign(size_t(count) + 1, n + 1);
    local.resize(size_t(n) + 1);
    for (int k = n; k >= 0; --k) {
        const long num = long(count) * long(k);
        const int p = std::min(int(num / n), count - 1);
        local[size_t(k)] = float(num - long(p) * n) / float(n);
        first[size_t(p)] = k;
    }
    // Patches no value falls on start where the next one does.
    for (int p = count - 1; p >= 0; --p) first[size_t(p)] = std::min(first[size_t(p)], first[size_t(p) + 1]);
}

// Bilinear interpolation of `comps` floats from four corners over na x nb
// values, rows `rowStride` floats apart.
void bilerpRect(const float* c0, const float* c1, const float* c2, const float* c3, int comps, const float* a, int na,
                const float* b, int nb, float* out, size_t rowStride) {
    for (int row = 0; row < nb; ++row) {
        const float bv = b[row];
        float* o = out + size_t(row) * rowStride;
        for (int col = 0; col < na; ++col) {
            const float av = a[col];
            for (int k = 0; k < comps; ++k) {
                const float L = c0[k] + bv * (c2[k] - c0[k]), R = c1[k] + bv * (c3[k] - c1[k]);
                o[k] = L + av * (R - L);
            }
            o += comps;
        }
    }
}

struct BlockLattice {
    std::vector<int> firstU, firstV;
    std::vector<float> a, b;
};

}  // namespace

void BicubicBlock::positions(int nu, int nv, Vec3* P, std::vector<float>& h) const {
    lattice(nu, nv, &BicubicCoeffs::pos, h);
    const int dim = m_patches->coeffs[0]->posDim;
    const size_t n = size_t(nu + 1) * size_t(nv + 1);
    for (size_t k = 0; k < n; ++k) divideW(&h[k * 4], dim, &P[k]);
}

void BicubicBlock::lattice(int nu, int nv, float (BicubicCoeffs::*table)[4][4][4], std::vector<float>& h) const {
    thread_local BlockLattice L;
    blockLattice(columns(), nu, L.firstU, L.a);
    blockLattice(rows(), nv, L.firstV, L.b);
    const size_t n = size_t(nu + 1) * size_t(nv + 1);
    h.resize(n * 4);
    const size_t stride = size_t(nu + 1) * 4;
    for (int q = 0; q < rows(); ++q) {
        const int r0 = L.firstV[size_t(q)], r1 = L.firstV[size_t(q) + 1];
        if (r1 <= r0) continue;
        for (int p = 0; p < columns(); ++p) {
            const int c0 = L.firstU[size_t(p)], c1 = L.firstU[size_t(p) + 1];
            if (c1 <= c0) continue;
            const BicubicCoeffs& c = *m_patches->coeffs[m_patches->index(m_i0 + p, m_j0 + q)];
            evalBicubicRect(&(c.*table)[0][0][0], 4, &L.a[size_t(c0)], c1 - c0, &L.b[size_t(r0)], r1 - r0,
                            &h[size_t(r0) * stride + size_t(c0) * 4], stride);
        }
    }
}

void BicubicBlock::dicePositions(int nu, int nv, std::vector<Vec3>& P) const {
    P.resize(size_t(nu + 1) * size_t(nv + 1));
    thread_local std::vector<float> h;
    positions(nu, nv, P.data(), h);
}

Grid BicubicBlock::dice(int nu, int nv) const {
    const BicubicPatchArray& pa = *m_patches;
    const SurfaceData& sd = orEmpty(pa.sd);
    Grid g;
    g.nu = nu;
    g.nv = nv;
    const size_t n = size_t(g.vertexCount());
    g.P.resize(n);
    thread_local std::vector<float> h;  // the homogeneous positions, for the normals below
    positions(nu, nv, g.P.data(), h);
    BlockLattice L;
    blockLattice(columns(), nu, L.firstU, L.a);
    blockLattice(rows(), nv, L.firstV, L.b);
    // The patch each column and row falls on, as an index into the array.
    std::vector<int> colPatch(size_t(nu) + 1), rowPatch(size_t(nv) + 1);
    for (int p = 0; p < columns(); ++p)
        for (int k = L.firstU[size_t(p)]; k < L.firstU[size_t(p) + 1]; ++k) colPatch[size_t(k)] = m_i0 + p;
    for (int q = 0; q < rows(); ++q)
        for (int k = L.firstV[size_t(q)]; k < L.firstV[size_t(q) + 1]; ++k) rowPatch[size_t(k)] = m_j0 + q;
    g.u.resize(n);
    g.v.resize(n);
    g.du = float(columns()) / float(nu) * pa.uScale;
    g.dv = float(rows()) / float(nv) * pa.vScale;
    for (int j = 0, k = 0; j <= nv; ++j) {
        const float gv = pa.map(0, rowPatch[size_t(j)]).vOffset + pa.vScale * L.b[size_t(j)];
        for (int i = 0; i <= nu; ++i, ++k) {
            g.u[size_t(k)] = pa.map(colPatch[size_t(i)], 0).uOffset + pa.uScale * L.a[size_t(i)];
            g.v[size_t(k)] = gv;
        }
    }
    // Calls f(patch index, c0, c1, r0, r1) for every patch of the block
    // some grid vertex falls on.
    auto forPatches = [&](auto&& f) {
        for (int q = 0; q < rows(); ++q) {
            const int r0 = L.firstV[size_t(q)], r1 = L.firstV[size_t(q) + 1];
            if (r1 <= r0) continue;
            for (int p = 0; p < columns(); ++p) {
                const int c0 = L.firstU[size_t(p)], c1 = L.firstU[size_t(p) + 1];
                if (c1 > c0) f(pa.index(m_i0 + p, m_j0 + q), c0, c1, r0, r1);
            }
        }
    };
    const size_t rowVerts = size_t(nu) + 1;
    // Varying variables, bilinear across each patch from its corners, as
    // interpolateVars does patch by patch; constant ones as one value.
    // (Uniform and facevarying never reach a block: blockable().)
    for (const PrimVar& v : sd.vars) {
        if (v.storage == ri::StorageClass::Vertex) continue;
        const bool varying = v.storage == ri::StorageClass::Varying;
        float* dst = nullptr;
        if (v.isNormal) {
            g.N.resize(n);
            if (!varying) {
                const float* c = v.at(0);
                std::fill(g.N.begin(), g.N.end(), Vec3(c[0], c[1], c[2]));
                continue;
            }
            dst = &g.N[0].x;
        } else if (!varying) {
            GridVar& gv = addGridVar(g, v, false);
            const float* c = v.at(0);
            std::copy(c, c + v.components, gv.data.begin());
            continue;
        } else {
            dst = addGridVar(g, v, true).data.data();
        }
        const int comps = std::min(v.components, 64);
        forPatches([&](size_t k, int c0, int c1, int r0, int r1) {
            const int* corners = pa.refs[k].varying;
            float c[4][64];
            for (int q = 0; q < 4; ++q)
                for (int e = 0; e < comps; ++e) c[q][e] = v.at(size_t(corners[q]))[e];
            bilerpRect(c[0], c[1], c[2], c[3], comps, &L.a[size_t(c0)], c1 - c0, &L.b[size_t(r0)], r1 - r0,
                       dst + (size_t(r0) * rowVerts + size_t(c0)) * size_t(v.components), rowVerts * size_t(v.components));
        });
    }
    addDefaultVars(sd, g);
    // Vertex variables with the basis, as BicubicPatch::dice does (every
    // patch's coefficients list them in the same order).
    const std::vector<BicubicCoeffs::Var>& vertexVars = pa.coeffs[0]->vertexVars;
    for (size_t vi = 0; vi < vertexVars.size(); ++vi) {
        const PrimVar& v = sd.vars[size_t(vertexVars[vi].index)];
        const int comps = v.isNormal ? 3 : v.components;
        float* dst;
        if (v.isNormal) {
            g.N.resize(n);
            dst = &g.N[0].x;
        } else {
            dst = addGridVar(g, v, true).data.data();
        }
        forPatches([&](size_t k, int c0, int c1, int r0, int r1) {
            evalBicubicRect(pa.coeffs[k]->vertexVars[vi].c.data(), comps, &L.a[size_t(c0)], c1 - c0,
                            &L.b[size_t(r0)], r1 - r0, dst + (size_t(r0) * rowVerts + size_t(c0)) * size_t(comps),
                            rowVerts * size_t(comps));
        });
    }
    if (g.N.empty()) {
        thread_local std::vector<float> ha, hb;
        lattice(nu, nv, &BicubicCoeffs::posDu, ha);
        lattice(nu, nv, &BicubicCoeffs::posDv, hb);
        setDerivativeNormals(g, h.data(), ha.data(), hb.data(), pa.coeffs[0]->posDim, pa.map(0, 0));
    }
    return g;
}

}  // namespace umbra::geometry
