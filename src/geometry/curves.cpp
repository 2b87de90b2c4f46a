#include "umbra/geometry/curves.h"
#include "umbra/geometry/quadric.h"
#include "umbra/util/motion.h"

#include <algorithm>
#include <cmath>

namespace umbra::geometry {

namespace {

// A unit vector perpendicular to unit `d`.
Vec3 anyPerpendicular(const Vec3& d) {
    const Vec3 up = std::abs(d.y) < 0.9f ? Vec3(0, 1, 0) : Vec3(1, 0, 0);
    return normalize(cross(d, up));
}

// The unit side of a ribbon at centre c with tangent T (see curves.h).
Vec3 ribbonSide(const Vec3& T, const Vec3& toward, const Vec3* N, bool insideOut) {
    Vec3 s = N ? cross(*N, T) : cross(toward, T);
    float l = length(s);
    if (!(l > 1e-20f)) {
        // Seen along the tangent (or N along it): any side will do.
        float lt = length(T);
        return lt > 0 ? anyPerpendicular(T / lt) : Vec3(1, 0, 0);
    }
    s = s / l;
    return (!N && insideOut) ? -s : s;
}

const PrimVar* findVar(const SurfaceData& sd, const char* name, int* index) {
    for (size_t k = 0; k < sd.vars.size(); ++k)
        if (sd.vars[k].name == name) {
            *index = int(k);
            return &sd.vars[k];
        }
    *index = -1;
    return nullptr;
}

}  // namespace

int CurveSet::control(int c, int s, int i) const {
    const Curve& cv = curves[size_t(c)];
    const int k = cubic ? s * vstep + i : s + i;
    return cv.vertexStart + k % cv.vertexCount;
}

int CurveSet::varyingEnd(int c, int s, int end) const {
    const Curve& cv = curves[size_t(c)];
    const int n = periodic ? cv.segments : cv.segments + 1;
    return cv.varyingStart + (s + end) % n;
}

template <class At>
void CurveSet::evalVertex(int c, int s, float t, int comps, At at, float* out, float* deriv) const {
    if (!cubic) {
        const float* a = at(control(c, s, 0));
        const float* b = at(control(c, s, 1));
        for (int k = 0; k < comps; ++k) {
            out[k] = a[k] + t * (b[k] - a[k]);
            if (deriv) deriv[k] = b[k] - a[k];
        }
        return;
    }
    const float tp[4] = {1, t, t * t, t * t * t};
    const float dp[4] = {0, 1, 2 * t, 3 * t * t};
    const float* cv[4];
    for (int i = 0; i < 4; ++i) cv[i] = at(control(c, s, i));
    for (int k = 0; k < comps; ++k) {
        double v = 0, d = 0;
        for (int p = 0; p < 4; ++p) {
            double coeff = 0;
            for (int i = 0; i < 4; ++i) coeff += double(basis[p][i]) * cv[i][k];
            v += coeff * tp[p];
            d += coeff * dp[p];
        }
        out[k] = float(v);
        if (deriv) deriv[k] = float(d);
    }
}

CurveSegment::CurveSegment(std::shared_ptr<const scene::PrimitiveRecord> record, std::shared_ptr<const CurveSet> set,
                           int curve, int segment, float t0, float t1)
    : Primitive(std::move(record)), m_set(std::move(set)), m_curve(curve), m_segment(segment), m_t0(t0), m_t1(t1) {}

Vec3 CurveSegment::centre(float t, Vec3* tangent) const {
    const SurfaceData& sd = *m_set->data;
    // Homogeneous positions (Pw) interpolate in 4D and divide after.
    // evalVertex asks for the controls in order, each once.
    float h[4], dh[4], ctrl[4][4];
    const int n = m_set->cubic ? 4 : 2;
    for (int i = 0; i < n; ++i) sd.position(size_t(m_set->control(m_curve, m_segment, i)), ctrl[i]);
    int idx = 0;
    auto atCopy = [&](int) -> const float* { return ctrl[idx++]; };
    m_set->evalVertex(m_curve, m_segment, t, 4, atCopy, h, dh);
    const float w = h[3];
    Vec3 p(h[0] / w, h[1] / w, h[2] / w);
    if (tangent) *tangent = (Vec3(dh[0], dh[1], dh[2]) - p * dh[3]) / w;
    return p;
}

float CurveSegment::width(float t) const {
    const CurveSet& cs = *m_set;
    if (cs.widthVar < 0) return cs.constantWidth;
    const PrimVar& v = cs.data->vars[size_t(cs.widthVar)];
    if (v.storage == ri::StorageClass::Vertex) {
        float w;
        cs.evalVertex(m_curve, m_segment, t, 1, [&](int k) { return v.at(size_t(k)); }, &w, nullptr);
        return w;
    }
    const float a = v.at(size_t(cs.varyingEnd(m_curve, m_segment, 0)))[0];
    const float b = v.at(size_t(cs.varyingEnd(m_curve, m_segment, 1)))[0];
    return a + t * (b - a);
}

Bound3 CurveSegment::bound() const {
    // A cubic on [t0, t1] lies in the hull of its Bezier control points
    // p(t0), p(t0) + h p'(t0) / 3, p(t1) - h p'(t1) / 3, p(t1); so does
    // its width (the same construction on one component).
    const float h = m_t1 - m_t0;
    Bound3 b;
    Vec3 T0, T1;
    const Vec3 p0 = centre(m_t0, &T0), p1 = centre(m_t1, &T1);
    b.extend(p0);
    b.extend(p1);
    if (m_set->cubic) {
        b.extend(p0 + T0 * (h / 3));
        b.extend(p1 - T1 * (h / 3));
    }
    float wmax = std::max(std::abs(width(m_t0)), std::abs(width(m_t1)));
    const CurveSet& cs = *m_set;
    if (cs.cubic && cs.widthVar >= 0 && cs.data->vars[size_t(cs.widthVar)].storage == ri::StorageClass::Vertex) {
        const PrimVar& v = cs.data->vars[size_t(cs.widthVar)];
        float w0, d0, w1, d1;
        auto at = [&](int k) { return v.at(size_t(k)); };
        cs.evalVertex(m_curve, m_segment, m_t0, 1, at, &w0, &d0);
        cs.evalVertex(m_curve, m_segment, m_t1, 1, at, &w1, &d1);
        wmax = std::max({wmax, std::abs(w0 + d0 * h / 3), std::abs(w1 - d1 * h / 3)});
    }
    const float r = 0.5f * wmax;
    b.min = b.min - Vec3(r, r, r);
    b.max = b.max + Vec3(r, r, r);
    return b;
}

void CurveSegment::split(bool, std::vector<PrimitivePtr>& out) const {
    const float m = 0.5f * (m_t0 + m_t1);
    out.push_back(std::make_unique<CurveSegment>(recordPtr(), m_set, m_curve, m_segment, m_t0, m));
    out.push_back(std::make_unique<CurveSegment>(recordPtr(), m_set, m_curve, m_segment, m, m_t1));
}

void CurveSegment::dicePositions(int nu, int nv, std::vector<Vec3>& P) const {
    P.resize(size_t(nu + 1) * size_t(nv + 1));
    for (int i = 0; i <= nu; ++i) {
        const float t = paramAt(i, nu);
        const Vec3 c = centre(t);
        for (int j = 0; j <= nv; ++j) P[size_t(j * (nu + 1) + i)] = c;
    }
}

void CurveSegment::dicePositionsInView(int nu, int nv, const ViewContext& view, std::vector<Vec3>& P) const {
    P.resize(size_t(nu + 1) * size_t(nv + 1));
    const bool insideOut = attributes().insideOut;
    for (int i = 0; i <= nu; ++i) {
        const float t = paramAt(i, nu);
        Vec3 T;
        const Vec3 c = centre(t, &T);
        const Vec3 side = ribbonSide(T, view.toward(c), nullptr, insideOut);
        const float w = width(t);
        for (int j = 0; j <= nv; ++j) P[size_t(j * (nu + 1) + i)] = c - side * (w * (float(j) / float(nv) - 0.5f));
    }
}

Grid CurveSegment::diceInView(int nu, int nv, const ViewContext& view) const {
    const CurveSet& cs = *m_set;
    const SurfaceData& sd = *cs.data;
    const CurveSet::Curve& cv = cs.curves[size_t(m_curve)];
    Grid g;
    std::vector<float> a, b;
    ParamMap map{float(m_segment) / float(cv.segments), 1.0f / float(cv.segments), 0, 1};
    initGrid(g, nu, nv, ParamRange{m_t0, m_t1, 0, 1}, map, a, b);

    CornerRefs refs;
    for (int c = 0; c < 4; ++c) {
        const int end = c & 1;
        refs.varying[c] = refs.faceVarying[c] = cs.varyingEnd(m_curve, m_segment, end);
        refs.vertex[c] = cs.control(m_curve, m_segment, end);  // linear curves only
    }
    refs.uniform = m_curve;
    interpolateVars(sd, refs, a, b, cs.cubic, g);
    if (cs.cubic) {
        // Vertex-class variables (N too) go through the basis like P.
        for (const PrimVar& v : sd.vars) {
            if (v.storage != ri::StorageClass::Vertex) continue;
            std::vector<float> col(size_t(v.components));
            float* dst;
            if (v.isNormal) g.N.resize(size_t(g.vertexCount()));
            GridVar* gv = v.isNormal ? nullptr : &addGridVar(g, v, true);
            for (int i = 0; i <= nu; ++i) {
                cs.evalVertex(m_curve, m_segment, a[size_t(i)], v.components, [&](int k) { return v.at(size_t(k)); },
                              col.data(), nullptr);
                for (int j = 0; j <= nv; ++j) {
                    const size_t k = size_t(g.index(i, j));
                    dst = v.isNormal ? &g.N[k].x : gv->data.data() + k * size_t(v.components);
                    std::copy(col.begin(), col.begin() + std::min(v.components, v.isNormal ? 3 : v.components), dst);
                }
            }
        }
    }
    const bool oriented = !g.N.empty();
    const bool insideOut = attributes().insideOut;
    for (int i = 0; i <= nu; ++i) {
        Vec3 T;
        const Vec3 c = centre(a[size_t(i)], &T);
        const float w = width(a[size_t(i)]);
        const Vec3 toward = view.toward(c);
        const Vec3 side = ribbonSide(T, toward, oriented ? &g.N[size_t(i)] : nullptr, insideOut);
        // Across the ribbon against `side`: once transposed below, dPdu
        // (across) x dPdv (along) is the outward side ribbonSide() chose.
        for (int j = 0; j <= nv; ++j) g.P[size_t(g.index(i, j))] = c - side * (w * (b[size_t(j)] - 0.5f));
    }
    // RI Spec 3.2: on a curve u runs across the width and v along the
    // length (hair shaders colour root to tip by v), as Pixie and Aqsis
    // have it; the grid was built along the curve, so it is transposed.
    g.transpose();
    for (GridVar& var : g.vars) {
        if (var.name == "s" && !sd.hasS) var.data = g.u;
        if (var.name == "t" && !sd.hasT) var.data = g.v;
    }
    return g;
}

float PointSet::width(int k) const {
    if (widthVar < 0) return constantWidth;
    return data->vars[size_t(widthVar)].at(size_t(k))[0];
}

PointGroup::PointGroup(std::shared_ptr<const scene::PrimitiveRecord> record, std::shared_ptr<const PointSet> set,
                       int first, int count)
    : Primitive(std::move(record)), m_set(std::move(set)), m_first(first), m_count(count) {}

namespace {

/// How far past width/sqrt(2) a disc's square reaches in object space: a
/// square of camera-space half side r * cbrt(volume scale) reaches
/// cbrt(volume scale) / (least scale) times further there than under a
/// similarity (1). Over the transform's keys; a camera that does not
/// scale uniformly is not accounted for.
float discReach(const scene::PrimitiveRecord& rec) {
    std::vector<Mat4> transforms{rec.worldFromObject};
    if (rec.worldFromObjectMotion)
        for (float t : rec.worldFromObjectMotion->keyTimes()) transforms.push_back(rec.worldFromObjectMotion->at(t));
    float reach = 1;
    for (const Mat4& m : transforms) {
        const float least = smallestSingularValue3(m), volume = std::abs(m.det3());
        if (least > 0) reach = std::max(reach, std::cbrt(volume) / least);
    }
    return reach < 1.001f ? 1.0f : reach * 1.001f;  // similarities exactly as before
}

}  // namespace

Bound3 PointGroup::bound() const {
    Bound3 b;
    const float reach = discReach(record());
    for (int k = m_first; k < m_first + m_count; ++k) {
        const Vec3 p = m_set->data->point(size_t(k));
        // A square of side w facing any way stays within w/sqrt(2) of its centre.
        const float r = 0.7072f * std::abs(m_set->width(k)) * reach;
        b.extend(p - Vec3(r, r, r));
        b.extend(p + Vec3(r, r, r));
    }
    return b;
}

Bound3 PointGroup::cameraBound(const Mat4& cameraFromObject, bool) const {
    // diceInView lays each square out along the camera's x and y axes with
    // half side r = w/2 x cameraPerObject: in camera space, the centre
    // +-r in x and y at the centre's depth. The margin covers the rounding
    // of laying it out in object space and carrying it here.
    const float volume = std::abs(cameraFromObject.det3());
    const float cameraPerObject = volume > 0 ? std::cbrt(volume) : 1.0f;
    Bound3 b;
    for (int k = m_first; k < m_first + m_count; ++k) {
        const Vec3 c = cameraFromObject.point(m_set->data->point(size_t(k)));
        const float r = 0.5f * std::abs(m_set->width(k)) * cameraPerObject;
        const float slack = 1e-4f * r + 1e-5f * (std::abs(c.x) + std::abs(c.y) + std::abs(c.z));
        b.extend(c - Vec3(r + slack, r + slack, slack));
        b.extend(c + Vec3(r + slack, r + slack, slack));
    }
    return b;
}

void PointGroup::split(bool, std::vector<PrimitivePtr>& out) const {
    if (m_count < 2) {
        out.push_back(std::make_unique<PointGroup>(recordPtr(), m_set, m_first, m_count));
        return;
    }
    const int h = m_count / 2;
    out.push_back(std::make_unique<PointGroup>(recordPtr(), m_set, m_first, h));
    out.push_back(std::make_unique<PointGroup>(recordPtr(), m_set, m_first + h, m_count - h));
}

bool PointGroup::fixedCounts(int* nu, int* nv) const {
    *nu = 2 * m_count - 1;
    *nv = 1;
    return true;
}

void PointGroup::dicePositions(int nu, int nv, std::vector<Vec3>& P) const {
    // The centres, spread over the lattice's columns (only what the eye
    // split needs: where the points lie in depth).
    P.resize(size_t(nu + 1) * size_t(nv + 1));
    for (int i = 0; i <= nu; ++i) {
        const int k = m_first + std::min(m_count - 1, i * m_count / (nu + 1));
        const Vec3 p = m_set->data->point(size_t(k));
        for (int j = 0; j <= nv; ++j) P[size_t(j * (nu + 1) + i)] = p;
    }
}

Grid PointGroup::diceInView(int, int, const ViewContext& view) const {
    const SurfaceData& sd = *m_set->data;
    Grid g;
    g.nu = 2 * m_count - 1;
    g.nv = 1;
    g.discs = true;
    const size_t n = size_t(g.vertexCount());
    g.P.resize(n);
    g.u.resize(n);
    g.v.resize(n);
    g.du = g.dv = 1;
    const float sign = attributes().insideOut ? -1.0f : 1.0f;
    for (int q = 0; q < m_count; ++q) {
        const int k = m_first + q;
        const Vec3 c = sd.point(size_t(k));
        // Discs lie parallel to the image plane, their normal the camera's
        // axis towards the eye, as Pixie and Aqsis shade them: a distant
        // light lights every particle of a wide view alike. Their sides are
        // the camera's axes, so a disc stays round under a non-uniform
        // Scale (it was squashed into a dash, where both peers draw
        // circles), its radius the width scaled by the transform's volume
        // scale (the size there is the spec's silence: Pixie's discs are
        // smaller, Aqsis takes the x scale).
        const float r = 0.5f * m_set->width(k) * view.cameraPerObject;
        const Vec3 e = view.towardEye;
        // The outward side faces the eye: dPdu x dPdv along e.
        const Vec3 ax = view.imageX;
        Vec3 bx = view.imageY;
        if (dot(cross(ax, bx), e) < 0) bx = -bx;
        bx = bx * sign;
        for (int j = 0; j <= 1; ++j)
            for (int di = 0; di <= 1; ++di) {
                const size_t vi = size_t(g.index(2 * q + di, j));
                g.P[vi] = c + ax * (r * float(2 * di - 1)) + bx * (r * float(2 * j - 1));
                g.u[vi] = float(di);
                g.v[vi] = float(j);
            }
    }
    for (const PrimVar& v : sd.vars) {
        const bool perPoint = v.storage == ri::StorageClass::Vertex || v.storage == ri::StorageClass::Varying ||
                              v.storage == ri::StorageClass::FaceVarying || v.storage == ri::StorageClass::FaceVertex;
        if (v.isNormal) {
            // The discs face the eye; a supplied "N" is the shading normal
            // (RI Spec 3.2: "N" overrides it on every primitive), as Pixie
            // and Aqsis shade it.
            g.N.resize(n);
            for (size_t vi = 0; vi < n; ++vi) {
                const int column = int(vi % size_t(g.nu + 1));
                const float* s = v.at(perPoint ? size_t(m_first + column / 2) : 0);
                g.N[vi] = Vec3(s[0], s[1], s[2]);
            }
            continue;
        }
        GridVar& gv = addGridVar(g, v, perPoint);
        if (!perPoint) {
            const float* s = v.at(0);
            std::copy(s, s + v.components, gv.data.begin());
            continue;
        }
        for (size_t vi = 0; vi < n; ++vi) {
            const int column = int(vi % size_t(g.nu + 1));
            const float* s = v.at(size_t(m_first + column / 2));
            std::copy(s, s + v.components, gv.data.begin() + long(vi) * v.components);
        }
    }
    addDefaultVars(sd, g);
    return g;
}

void makeCurves(const std::shared_ptr<const scene::PrimitiveRecord>& rec, Diagnostics& diag,
                std::vector<PrimitivePtr>& out) {
    const auto& sa = rec->stringArgs;
    if (sa.size() != 2 || rec->intArrays.size() != 1) {
        diag.error(rec->loc, "Curves: expected type, nvertices and wrap, got {} strings and {} integer arrays",
                   sa.size(), rec->intArrays.size());
        return;
    }
    auto set = std::make_shared<CurveSet>();
    if (sa[0] == "cubic") set->cubic = true;
    else if (sa[0] != "linear") {
        diag.error(rec->loc, "Curves: type must be \"linear\" or \"cubic\", got \"{}\"", sa[0]);
        return;
    }
    if (sa[1] == "periodic") set->periodic = true;
    else if (sa[1] != "nonperiodic") {
        diag.error(rec->loc, "Curves: wrap must be \"periodic\" or \"nonperiodic\", got \"{}\"", sa[1]);
        return;
    }
    const scene::Basis basis = rec->attributes ? rec->attributes->vBasis : scene::Basis::bezier();
    set->vstep = std::max(1, basis.step);
    for (int k = 0; k < 4; ++k)
        for (int i = 0; i < 4; ++i) set->basis[k][i] = basis.m[3 - k][i];  // the spec's matrix multiplies [t^3 t^2 t 1]
    long vertices = 0, varying = 0;
    for (size_t c = 0; c < rec->intArrays[0].size(); ++c) {
        const int n = rec->intArrays[0][c];
        int segs = 0;
        if (!set->cubic) {
            if (n >= 2) segs = set->periodic ? n : n - 1;
        } else if (set->periodic) {
            if (n >= set->vstep && n % set->vstep == 0) segs = n / set->vstep;
        } else if (n >= 4 && (n - 4) % set->vstep == 0) {
            segs = (n - 4) / set->vstep + 1;
        }
        if (segs == 0) {
            diag.error(rec->loc, "Curves: curve {} has {} vertices, expected {}", c, n,
                       !set->cubic         ? "at least 2"
                       : set->periodic     ? "a positive multiple of the v step"
                                           : "4 plus a multiple of the v step");
            return;
        }
        set->curves.push_back({int(vertices), n, int(varying), segs});
        vertices += n;
        varying += set->periodic ? segs : segs + 1;
    }
    ClassCounts counts;
    counts.uniform = set->curves.size();
    counts.uniformWhat = "one per curve";
    counts.varying = counts.faceVarying = size_t(varying);
    counts.varyingWhat = counts.faceVaryingWhat = "one per segment end";
    counts.vertex = size_t(vertices);
    counts.vertexWhat = "one per control vertex";
    set->data = readSurfaceData(*rec, counts, true, diag);
    if (!set->data) return;
    const SurfaceData& sd = *set->data;
    if (const PrimVar* w = findVar(sd, "width", &set->widthVar); w && w->storage != ri::StorageClass::Vertex &&
                                                                   w->storage != ri::StorageClass::Varying) {
        if (w->storage == ri::StorageClass::Constant) set->constantWidth = w->at(0)[0];
        set->widthVar = -1;
    }
    int cw = -1;
    if (const PrimVar* w = findVar(sd, "constantwidth", &cw); w && set->widthVar < 0) set->constantWidth = w->at(0)[0];
    for (size_t k = 0; k < sd.vars.size(); ++k)
        if (sd.vars[k].isNormal) set->normalVar = int(k);
    for (size_t c = 0; c < set->curves.size(); ++c)
        for (int s = 0; s < set->curves[c].segments; ++s)
            out.push_back(std::make_unique<CurveSegment>(rec, set, int(c), s));
}

namespace {

/// PRMan's `Points ... "uniform string type" "sphere"`: each point is a
/// Sphere of radius width/2 centred on it, a record of its own (the Points'
/// transform times a translation to the point, as `Translate` then
/// `Sphere r -r r 360` would give) whose primitive variables are the
/// point's values as constants. Deformation blur moves each sphere with
/// its point (a moving translation over the shapes' times).
void makePointSpheres(const std::shared_ptr<const scene::PrimitiveRecord>& rec, const PointSet& set, long n,
                      Diagnostics& diag, std::vector<PrimitivePtr>& out) {
    const ri::Param* P = rec->params.find("P");
    std::vector<const ri::Param*> shapeP;
    for (const scene::PrimitiveRecord& shape : rec->shapes) {
        const ri::Param* sp = shape.params.find("P");
        if (!sp || sp->floats.size() != P->floats.size()) {
            diag.warningOnce("points-sphere:motion", rec->loc, "Points: a moving shape without the same \"P\" "
                             "count; the spheres are drawn at the first shape");
            shapeP.clear();
            break;
        }
        shapeP.push_back(sp);
    }
    ClassCounts counts;  // a quadric's: one uniform, four corners
    counts.uniform = 1;
    counts.uniformWhat = "one for the surface";
    counts.vertex = counts.varying = counts.faceVarying = 4;
    counts.vertexWhat = counts.faceVaryingWhat = "one per corner";
    for (long i = 0; i < n; ++i) {
        const float r = 0.5f * set.width(int(i));
        if (!(r > 0)) continue;  // a point without width draws nothing
        auto sphere = std::make_shared<scene::PrimitiveRecord>(rec->derived("Sphere"));
        sphere->floatArgs = {r, -r, r, 360.0f};
        const Vec3 at(P->floats[size_t(i) * 3], P->floats[size_t(i) * 3 + 1], P->floats[size_t(i) * 3 + 2]);
        sphere->worldFromObject = rec->worldFromObject * Mat4::translate(at);
        if (rec->worldFromObjectMotion || !shapeP.empty()) {
            auto motion = std::make_shared<MotionTransform>(rec->worldFromObjectMotion ? *rec->worldFromObjectMotion
                                                                                      : MotionTransform(rec->worldFromObject));
            if (shapeP.empty()) {
                motion->postMultiply(Mat4::translate(at));
            } else {
                std::vector<Mat4> keys{Mat4::translate(at)};
                for (const ri::Param* sp : shapeP)
                    keys.push_back(Mat4::translate(
                        Vec3(sp->floats[size_t(i) * 3], sp->floats[size_t(i) * 3 + 1], sp->floats[size_t(i) * 3 + 2])));
                motion->postMultiplyMoving(rec->shapeTimes, keys);
            }
            sphere->worldFromObjectMotion = std::move(motion);
        }
        // The point's primitive variables, as the sphere's constants.
        for (const ri::Param& p : rec->params.params()) {
            const std::string& name = p.decl.name;
            if (name == "P" || name == "Pw" || name == "N" || name == "width" || name == "constantwidth" ||
                !ri::isFloatType(p.decl.type))
                continue;
            // Only the point's values are copied: a copy of the whole
            // array per point cost time and memory quadratic in the points.
            ri::Param q;
            q.decl = p.decl;
            q.loc = p.loc;
            const ri::StorageClass st = p.decl.storage;
            if (st == ri::StorageClass::Varying || st == ri::StorageClass::Vertex ||
                st == ri::StorageClass::FaceVarying || st == ri::StorageClass::FaceVertex) {
                const size_t e = size_t(p.decl.elementSize());
                if (e == 0 || p.floats.size() < (size_t(i) + 1) * e) continue;  // counts were checked already
                q.decl.storage = ri::StorageClass::Constant;
                q.floats.assign(p.floats.begin() + long(size_t(i) * e), p.floats.begin() + long((size_t(i) + 1) * e));
            } else {
                q.floats = p.floats;  // constant or uniform: one value
            }
            sphere->params.add(std::move(q));
        }
        QuadricShape shape;
        if (!Quadric::shapeFromRecord(*sphere, &shape, diag)) continue;
        auto sd = readSurfaceData(*sphere, counts, false, diag);
        if (!sd) continue;
        out.push_back(std::make_unique<Quadric>(sphere, shape, std::move(sd)));
    }
}

}  // namespace

void makePoints(const std::shared_ptr<const scene::PrimitiveRecord>& rec, Diagnostics& diag,
                std::vector<PrimitivePtr>& out) {
    long n = -1;
    for (const ri::Param& p : rec->params.params())
        if (p.decl.name == "P" && p.decl.elementSize() > 0) n = long(p.floats.size() / size_t(p.decl.elementSize()));
    if (n < 1) {
        diag.error(rec->loc, "Points: expected \"P\" with at least 1 point");
        return;
    }
    ClassCounts counts;
    counts.uniform = 1;
    counts.uniformWhat = "one for the points";
    counts.varying = counts.vertex = counts.faceVarying = size_t(n);
    counts.varyingWhat = counts.vertexWhat = counts.faceVaryingWhat = "one per point";
    auto set = std::make_shared<PointSet>();
    set->data = readSurfaceData(*rec, counts, true, diag);
    if (!set->data) return;
    if (const PrimVar* w = findVar(*set->data, "width", &set->widthVar); w && w->storage == ri::StorageClass::Constant) {
        set->constantWidth = w->at(0)[0];
        set->widthVar = -1;
    } else if (w && w->storage == ri::StorageClass::Uniform) {
        set->constantWidth = w->at(0)[0];
        set->widthVar = -1;
    }
    int cw = -1;
    if (const PrimVar* w = findVar(*set->data, "constantwidth", &cw); w && set->widthVar < 0)
        set->constantWidth = w->at(0)[0];
    // PRMan's point types: "particle" (the default) and "disk" without N
    // are these discs facing the eye; "sphere" true spheres.
    std::string type = "particle";
    if (const ri::Param* t = rec->params.find("type"); t && t->decl.type == ri::ParamType::String && !t->strings.empty())
        type = t->stringAt(0);
    if (type == "sphere" && rec->params.find("P")) {
        makePointSpheres(rec, *set, n, diag, out);
        return;
    }
    if (type == "disk" && rec->params.find("N"))
        diag.warningOnce("points-type:disk-N", rec->loc, "Points: discs oriented by \"N\" (type \"disk\") are not "
                         "supported; drawn facing the camera, shaded by \"N\"");
    else if (type != "particle" && type != "disk" && type != "sphere")
        diag.warningOnce("points-type:" + type, rec->loc, "Points: type \"{}\" is not supported (expected "
                         "\"particle\", \"disk\" or \"sphere\"); drawn as discs facing the camera", type);
    out.push_back(std::make_unique<PointGroup>(rec, std::move(set), 0, int(n)));
}

}  // namespace umbra::geometry
