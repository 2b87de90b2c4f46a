#include "umbra/geometry/nupatch.h"

#include <algorithm>
#include <cmath>
#include <tuple>

namespace umbra::geometry {

namespace {

// Blossom weights of a B-spline of degree p on knot span i (t[i] < t[i+1]):
// W[m] is the weight of control value i-p+m in the blossom at x[0..p-1]
// (de Boor's algorithm with a different argument at each level).
void bsplineBlossom(const float* t, int p, int i, const double* x, double* W) {
    double d[32][32];  // d[m]: weights of the m-th point at the current level
    for (int m = 0; m <= p; ++m)
        for (int k = 0; k <= p; ++k) d[m][k] = m == k ? 1.0 : 0.0;
    for (int r = 1; r <= p; ++r)
        for (int m = p; m >= r; --m) {
            const int j = i - p + m;
            const double a = (x[r - 1] - double(t[j])) / (double(t[j + p + 1 - r]) - double(t[j]));
            for (int k = 0; k <= p; ++k) d[m][k] = (1 - a) * d[m - 1][k] + a * d[m][k];
        }
    for (int k = 0; k <= p; ++k) W[k] = d[p][k];
}

// E[j][m]: Bezier point j of span i over [t[i], t[i+1]] from control value
// i-p+m: the blossom at (t[i] repeated p-j times, t[i+1] j times).
void extraction(const float* t, int p, int i, std::vector<double>& E) {
    E.assign(size_t((p + 1) * (p + 1)), 0.0);
    double x[32];
    for (int j = 0; j <= p; ++j) {
        for (int r = 0; r < p; ++r) x[r] = r < p - j ? t[i] : t[i + 1];
        bsplineBlossom(t, p, i, x, &E[size_t(j * (p + 1))]);
    }
}

// S[j][m]: Bezier point j over the sub-range [r0, r1] of [0, 1] from point
// m over [0, 1] (de Casteljau's blossom at r0 x (p-j), r1 x j).
void subRange(int p, double r0, double r1, std::vector<double>& S) {
    S.assign(size_t((p + 1) * (p + 1)), 0.0);
    double d[32][32];
    for (int j = 0; j <= p; ++j) {
        for (int m = 0; m <= p; ++m)
            for (int k = 0; k <= p; ++k) d[m][k] = m == k ? 1.0 : 0.0;
        for (int r = 1; r <= p; ++r) {
            const double x = r <= p - j ? r0 : r1;
            for (int m = 0; m <= p - r; ++m)
                for (int k = 0; k <= p; ++k) d[m][k] = (1 - x) * d[m][k] + x * d[m + 1][k];
        }
        for (int k = 0; k <= p; ++k) S[size_t(j * (p + 1) + k)] = d[0][k];
    }
}

// Bernstein polynomials of degree n at t into B[0..n].
void bernstein(int n, float t, float* B) {
    B[0] = 1;
    for (int k = 1; k <= n; ++k) {
        float saved = 0;
        for (int j = 0; j < k; ++j) {
            const float tmp = B[j];
            B[j] = saved + (1 - t) * tmp;
            saved = t * tmp;
        }
        B[k] = saved;
    }
}

// Evaluates a Bezier net of `comps` floats per point ((dv+1) rows of du+1)
// over the parameters a (columns) x b (rows), row after row into `out`.
void evalBezierGrid(const float* c, int comps, int du, int dv, const std::vector<float>& a, const std::vector<float>& b,
                    float* out) {
    thread_local std::vector<float> Bu, R;
    float Bv[32];
    Bu.resize(a.size() * size_t(du + 1));
    for (size_t i = 0; i < a.size(); ++i) bernstein(du, a[i], &Bu[i * size_t(du + 1)]);
    R.resize(size_t((du + 1) * comps));
    for (float bv : b) {
        bernstein(dv, bv, Bv);
        std::fill(R.begin(), R.end(), 0.0f);
        for (int l = 0; l <= dv; ++l) {
            const float* row = c + size_t(l * (du + 1) * comps);
            for (int k = 0; k < (du + 1) * comps; ++k) R[size_t(k)] += Bv[l] * row[k];
        }
        for (size_t i = 0; i < a.size(); ++i) {
            const float* w = &Bu[i * size_t(du + 1)];
            for (int q = 0; q < comps; ++q) {
                float s = 0;
                for (int k = 0; k <= du; ++k) s += w[k] * R[size_t(k * comps + q)];
                out[q] = s;
            }
            out += comps;
        }
    }
}

void divideW(const float* h, int dim, Vec3* out) {
    if (dim == 4)
        *out = Vec3(h[0], h[1], h[2]) / h[3];
    else
        *out = Vec3(h[0], h[1], h[2]);
}

const SurfaceData& orEmpty(const std::shared_ptr<const SurfaceData>& sd) {
    static const SurfaceData kEmpty;
    return sd ? *sd : kEmpty;
}

}  // namespace

NuPatch::NuPatch(std::shared_ptr<const scene::PrimitiveRecord> record, std::shared_ptr<const SurfaceData> data,
                 std::shared_ptr<const BezierSpan> span, const CornerRefs& refs, const ParamRange& range,
                 const ParamMap& map, std::shared_ptr<const TrimRegion> trim)
    : Primitive(std::move(record)),
      m_data(std::move(data)),
      m_span(std::move(span)),
      m_refs(refs),
      m_range(range),
      m_map(map),
      m_trim(std::move(trim)) {
    if (m_trim)
        m_cover =
            m_trim->classify(m_map.uOffset + m_map.uScale * m_range.u0, m_map.uOffset + m_map.uScale * m_range.u1,
                             m_map.vOffset + m_map.vScale * m_range.v0, m_map.vOffset + m_map.vScale * m_range.v1);
}

Vec3 NuPatch::evaluate(float a, float b) const {
    float h[4];
    evalBezierGrid(m_span->pos.data(), 4, m_span->degU, m_span->degV, {a}, {b}, h);
    Vec3 p;
    divideW(h, m_span->posDim, &p);
    return p;
}

Bound3 NuPatch::bound() const {
    const int du = m_span->degU, dv = m_span->degV, nu1 = du + 1, nv1 = dv + 1;
    std::vector<double> Su, Sv;
    subRange(du, m_range.u0, m_range.u1, Su);
    subRange(dv, m_range.v0, m_range.v1, Sv);
    // T[l][i] = sum_k Su[i][k] pos[l][k]; then net[j][i] = sum_l Sv[j][l] T[l][i].
    std::vector<double> T(size_t(nv1 * nu1 * 4), 0.0);
    for (int l = 0; l < nv1; ++l)
        for (int i = 0; i < nu1; ++i)
            for (int k = 0; k < nu1; ++k)
                for (int c = 0; c < 4; ++c)
                    T[size_t((l * nu1 + i) * 4 + c)] +=
                        Su[size_t(i * nu1 + k)] * double(m_span->pos[size_t((l * nu1 + k) * 4 + c)]);
    Bound3 bnd;
    for (int j = 0; j < nv1; ++j)
        for (int i = 0; i < nu1; ++i) {
            double h[4] = {0, 0, 0, 0};
            for (int l = 0; l < nv1; ++l)
                for (int c = 0; c < 4; ++c) h[c] += Sv[size_t(j * nv1 + l)] * T[size_t((l * nu1 + i) * 4 + c)];
            if (m_span->posDim == 4 && h[3] != 0)
                bnd.extend(Vec3(float(h[0] / h[3]), float(h[1] / h[3]), float(h[2] / h[3])));
            else
                bnd.extend(Vec3(float(h[0]), float(h[1]), float(h[2])));
        }
    // Float rounding in the conversions: pad by a relative epsilon.
    const Vec3 d = bnd.diagonal();
    const float mag = std::max({std::abs(bnd.min.x), std::abs(bnd.min.y), std::abs(bnd.min.z), std::abs(bnd.max.x),
                                std::abs(bnd.max.y), std::abs(bnd.max.z)});
    const float pad = 1e-5f * std::max({d.x, d.y, d.z}) + 1e-6f * mag;
    bnd.min -= Vec3(pad);
    bnd.max += Vec3(pad);
    return bnd;
}

void NuPatch::split(bool splitU, std::vector<PrimitivePtr>& out) const {
    for (int k = 0; k < 2; ++k)
        out.push_back(std::make_unique<NuPatch>(recordPtr(), m_data, m_span, m_refs, m_range.half(splitU, k == 1),
                                                m_map, m_trim));
}

Grid NuPatch::dice(int nu, int nv) const {
    Grid g;
    std::vector<float> a, b;
    initGrid(g, nu, nv, m_range, m_map, a, b);
    const size_t n = g.P.size();
    const BezierSpan& sp = *m_span;
    thread_local std::vector<float> h;
    h.resize(n * 4);
    evalBezierGrid(sp.pos.data(), 4, sp.degU, sp.degV, a, b, h.data());
    for (size_t k = 0; k < n; ++k) divideW(&h[k * 4], sp.posDim, &g.P[k]);
    const SurfaceData& sd = orEmpty(m_data);
    interpolateVars(sd, m_refs, a, b, true, g);
    for (const BezierSpan::Var& cv : sp.vertexVars) {
        const PrimVar& v = sd.vars[size_t(cv.index)];
        if (v.isNormal) {
            g.N.resize(n);
            evalBezierGrid(cv.c.data(), 3, sp.degU, sp.degV, a, b, &g.N[0].x);
        } else {
            GridVar& gv = addGridVar(g, v, true);
            evalBezierGrid(cv.c.data(), v.components, sp.degU, sp.degV, a, b, gv.data.data());
        }
    }
    if (g.N.empty() && sp.degU > 0 && sp.degV > 0) {
        // The nets of d/da (degree degU - 1 along a) and d/db: n times the
        // differences of neighbouring control points.
        const int du = sp.degU, dv = sp.degV;
        thread_local std::vector<float> netA, netB, ha, hb;
        netA.resize(size_t((dv + 1) * du * 4));
        netB.resize(size_t(dv * (du + 1) * 4));
        auto at = [&](int l, int k) { return &sp.pos[size_t((l * (du + 1) + k) * 4)]; };
        for (int l = 0; l <= dv; ++l)
            for (int k = 0; k < du; ++k)
                for (int c = 0; c < 4; ++c)
                    netA[size_t((l * du + k) * 4 + c)] = float(du) * (at(l, k + 1)[c] - at(l, k)[c]);
        for (int l = 0; l < dv; ++l)
            for (int k = 0; k <= du; ++k)
                for (int c = 0; c < 4; ++c)
                    netB[size_t((l * (du + 1) + k) * 4 + c)] = float(dv) * (at(l + 1, k)[c] - at(l, k)[c]);
        ha.resize(n * 4);
        hb.resize(n * 4);
        evalBezierGrid(netA.data(), 4, du - 1, dv, a, b, ha.data());
        evalBezierGrid(netB.data(), 4, du, dv - 1, a, b, hb.data());
        setDerivativeNormals(g, h.data(), ha.data(), hb.data(), sp.posDim, m_map);
    }
    return g;
}

void NuPatch::dicePositions(int nu, int nv, std::vector<Vec3>& P) const {
    thread_local std::vector<float> a, b, h;
    m_range.steps(nu, nv, a, b);
    const size_t n = size_t(nu + 1) * size_t(nv + 1);
    P.resize(n);
    h.resize(n * 4);
    evalBezierGrid(m_span->pos.data(), 4, m_span->degU, m_span->degV, a, b, h.data());
    for (size_t k = 0; k < n; ++k) divideW(&h[k * 4], m_span->posDim, &P[k]);
}

namespace {

// Bezier net of one span for values of `comps` floats fetched by `get(k)`
// (control point k = j * nu + i): net[b][a] = sum Ev[b][l] Eu[a][m] C[iv-q+l][iu-p+m].
template <typename Get>
std::vector<float> spanNet(int nu, int p, int q, int iu, int iv, const std::vector<double>& Eu,
                           const std::vector<double>& Ev, int comps, Get get) {
    const int nu1 = p + 1, nv1 = q + 1;
    std::vector<double> T(size_t(nv1 * nu1 * comps), 0.0);  // T[l][a]: u done
    for (int l = 0; l < nv1; ++l)
        for (int m = 0; m < nu1; ++m) {
            const float* c = get(size_t((iv - q + l) * nu + (iu - p + m)));
            for (int a = 0; a < nu1; ++a) {
                const double w = Eu[size_t(a * nu1 + m)];
                if (w == 0) continue;
                for (int k = 0; k < comps; ++k) T[size_t((l * nu1 + a) * comps + k)] += w * double(c[k]);
            }
        }
    std::vector<float> out(size_t(nv1 * nu1 * comps), 0.0f);
    for (int bb = 0; bb < nv1; ++bb)
        for (int a = 0; a < nu1; ++a)
            for (int k = 0; k < comps; ++k) {
                double s = 0;
                for (int l = 0; l < nv1; ++l) s += Ev[size_t(bb * nv1 + l)] * T[size_t((l * nu1 + a) * comps + k)];
                out[size_t((bb * nu1 + a) * comps + k)] = float(s);
            }
    return out;
}

// Checks one direction's knots and range; true when usable.
bool checkKnots(const scene::PrimitiveRecord& rec, const char* dir, int n, int order, const float* knots, float tmin,
                float tmax, Diagnostics& diag) {
    const int p = order - 1;
    for (int k = 0; k + 1 < n + order; ++k)
        if (!(knots[k] <= knots[k + 1])) {
            diag.error(rec.loc, "NuPatch: {}knot must not decrease, but value {} is {} and value {} is {}", dir, k,
                       knots[k], k + 1, knots[k + 1]);
            return false;
        }
    if (!(knots[p] < knots[n])) {
        diag.error(rec.loc, "NuPatch: {}knot leaves no parameter range ({}knot[{}] = {}knot[{}] = {})", dir, dir, p,
                   dir, n, knots[p]);
        return false;
    }
    if (!(tmin < tmax) || tmin < knots[p] || tmax > knots[n]) {
        diag.error(rec.loc, "NuPatch: {0}min {0}max are {1} {2}, expected {0}min < {0}max within [{3}, {4}]", dir, tmin,
                   tmax, knots[p], knots[n]);
        return false;
    }
    return true;
}

}  // namespace

void makeNuPatches(std::shared_ptr<const scene::PrimitiveRecord> rec, Diagnostics& diag,
                   std::vector<PrimitivePtr>& out) {
    if (rec->intArgs.size() != 4) {
        diag.error(rec->loc, "NuPatch: expected 4 integer arguments (nu uorder nv vorder), got {}",
                   rec->intArgs.size());
        return;
    }
    const int nu = rec->intArgs[0], uorder = rec->intArgs[1], nv = rec->intArgs[2], vorder = rec->intArgs[3];
    constexpr int kMaxOrder = 31;
    for (auto [n, order, dir] : {std::tuple{nu, uorder, "u"}, std::tuple{nv, vorder, "v"}}) {
        if (order < 1 || order > kMaxOrder || n < order) {
            diag.error(rec->loc,
                       "NuPatch: n{0} {0}order are {1} {2}, expected 1 <= {0}order <= {3} and n{0} >= {0}order", dir, n,
                       order, kMaxOrder);
            return;
        }
    }
    const size_t expected = size_t(nu + uorder + 2 + nv + vorder + 2);
    if (rec->floatArgs.size() != expected) {
        diag.error(rec->loc,
                   "NuPatch: expected {} + {} uknot values, umin umax, {} + {} vknot values, vmin vmax ({} "
                   "floats), got {}",
                   nu, uorder, nv, vorder, expected, rec->floatArgs.size());
        return;
    }
    const float* uk = rec->floatArgs.data();
    const float umin = uk[nu + uorder], umax = uk[nu + uorder + 1];
    const float* vk = uk + nu + uorder + 2;
    const float vmin = vk[nv + vorder], vmax = vk[nv + vorder + 1];
    if (!checkKnots(*rec, "u", nu, uorder, uk, umin, umax, diag) ||
        !checkKnots(*rec, "v", nv, vorder, vk, vmin, vmax, diag))
        return;
    const int p = uorder - 1, q = vorder - 1;
    const int segU = nu - p, segV = nv - q;  // segments, zero-length ones included
    ClassCounts counts;
    counts.uniform = size_t(segU) * size_t(segV);
    counts.uniformWhat = "one per segment, (nu-uorder+1)*(nv-vorder+1)";
    counts.varying = counts.faceVarying = size_t(segU + 1) * size_t(segV + 1);
    counts.varyingWhat = counts.faceVaryingWhat = "one per segment corner, (nu-uorder+2)*(nv-vorder+2)";
    counts.vertex = size_t(nu) * size_t(nv);
    counts.vertexWhat = "one per control point, nu*nv";
    auto sd = readSurfaceData(*rec, counts, true, diag);
    if (!sd) return;
    if (sd->posDim == 4)
        for (size_t k = 0; k < sd->posCount; ++k)
            if (!(sd->pos[k * 4 + 3] > 0)) {
                diag.error(rec->loc, "NuPatch: \"Pw\" weight of control point {} is {}, expected a positive weight", k,
                           sd->pos[k * 4 + 3]);
                return;
            }

    const auto trim = rec->attributes ? trimRegionOf(*rec->attributes) : nullptr;
    std::vector<std::vector<double>> Eu(static_cast<size_t>(segU)), Ev(static_cast<size_t>(segV));
    for (int s = 0; s < segU; ++s)
        if (uk[p + s] < uk[p + s + 1]) extraction(uk, p, p + s, Eu[size_t(s)]);
    for (int s = 0; s < segV; ++s)
        if (vk[q + s] < vk[q + s + 1]) extraction(vk, q, q + s, Ev[size_t(s)]);

    for (int sv = 0; sv < segV; ++sv) {
        const float v0 = vk[q + sv], v1 = vk[q + sv + 1];
        const float c0 = std::max(v0, vmin), c1 = std::min(v1, vmax);
        if (!(v0 < v1) || !(c0 < c1)) continue;
        for (int su = 0; su < segU; ++su) {
            const float u0 = uk[p + su], u1 = uk[p + su + 1];
            const float a0 = std::max(u0, umin), a1 = std::min(u1, umax);
            if (!(u0 < u1) || !(a0 < a1)) continue;
            auto span = std::make_shared<BezierSpan>();
            span->degU = p;
            span->degV = q;
            span->posDim = sd->posDim;
            span->pos = spanNet(nu, p, q, p + su, q + sv, Eu[size_t(su)], Ev[size_t(sv)], 4, [&](size_t k) {
                thread_local float h[4];
                sd->position(k, h);
                return static_cast<const float*>(h);
            });
            for (size_t vi = 0; vi < sd->vars.size(); ++vi) {
                const PrimVar& var = sd->vars[vi];
                if (var.storage != ri::StorageClass::Vertex) continue;
                span->vertexVars.push_back({int(vi), spanNet(nu, p, q, p + su, q + sv, Eu[size_t(su)], Ev[size_t(sv)],
                                                             var.components, [&](size_t k) { return var.at(k); })});
            }
            CornerRefs refs;
            for (int c = 0; c < 4; ++c) {
                const int cu = c & 1, cv = c >> 1;
                refs.varying[c] = refs.faceVarying[c] = (sv + cv) * (segU + 1) + su + cu;
            }
            refs.uniform = sv * segU + su;
            const ParamRange range{(a0 - u0) / (u1 - u0), (a1 - u0) / (u1 - u0), (c0 - v0) / (v1 - v0),
                                   (c1 - v0) / (v1 - v0)};
            const ParamMap map{u0, u1 - u0, v0, v1 - v0};
            out.push_back(std::make_unique<NuPatch>(rec, sd, std::move(span), refs, range, map, trim));
        }
    }
}

}  // namespace umbra::geometry
