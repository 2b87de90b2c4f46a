#include "umbra/geometry/quadric.h"

#include <cmath>

namespace umbra::geometry {

namespace {

// Rotates a profile point about z by the angle whose cosine/sine are c, s.
inline Vec3 rotateZ(const Vec3& q, float c, float s) { return {q.x * c - q.y * s, q.x * s + q.y * c, q.z}; }

// Box around the solid of revolution of the profile box {rho in [rlo, rhi],
// z in [zlo, zhi]} swept over theta in [ta, tb] (radians). Extremes of
// rho*cos(theta) and rho*sin(theta) lie at the ends of the sweep, at the
// axis-aligned angles inside it, and at rlo or rhi.
Bound3 sectorBound(float ta, float tb, float rlo, float rhi, float zlo, float zhi) {
    if (ta > tb) std::swap(ta, tb);
    Bound3 b;
    // cos(pi/2) in float is -4e-8: a pole is on the axis, not across it.
    if (rlo < 0 && rlo > -1e-6f * std::abs(rhi)) rlo = 0;
    if (tb - ta >= 2 * kPi) {
        const float R = std::max(std::abs(rlo), std::abs(rhi));
        b = Bound3({-R, -R, zlo}, {R, R, zhi});
    } else if (rlo < 0) {
        // A negative profile radius (a spindle torus's inner part) puts the
        // point across the axis, at angle theta + pi: the sector turned by
        // half a turn. Bounding it by the whole disc instead kept every
        // wedge of that part at the disc, so splitting never shrank them
        // and a spindle torus around the camera took 72,000 grids.
        b = sectorBound(ta + kPi, tb + kPi, std::max(-rhi, 0.0f), -rlo, zlo, zhi);
        if (rhi > 0) b.extend(sectorBound(ta, tb, 0, rhi, zlo, zhi));
        return b;
    } else {
        auto add = [&](float c, float s) {
            b.extend(Vec3(rlo * c, rlo * s, zlo));
            b.extend(Vec3(rhi * c, rhi * s, zlo));
        };
        add(std::cos(ta), std::sin(ta));
        add(std::cos(tb), std::sin(tb));
        static const float kc[4] = {1, 0, -1, 0}, ks[4] = {0, 1, 0, -1};
        for (int k = int(std::ceil(ta / (0.5f * kPi))); float(k) * 0.5f * kPi < tb; ++k) {
            const int m = ((k % 4) + 4) % 4;
            add(kc[m], ks[m]);
        }
        b.min.z = zlo;
        b.max.z = zhi;
    }
    // Float trig on the dicing side may land an ulp outside the exact box.
    const Vec3 d = b.diagonal();
    const float pad = 1e-6f * std::max({d.x, d.y, d.z, std::abs(b.max.x), std::abs(b.max.y), std::abs(b.max.z),
                                         std::abs(b.min.x), std::abs(b.min.y), std::abs(b.min.z)}) +
                      1e-30f;
    b.min -= Vec3(pad);
    b.max += Vec3(pad);
    return b;
}

}  // namespace

void QuadricShape::profile(float v, Vec3* q, Vec3* n) const {
    switch (kind) {
    case QuadricKind::Sphere: {
        const float phi = phi0 + v * (phi1 - phi0), c = std::cos(phi), s = std::sin(phi);
        *q = {radius * c, 0, radius * s};
        *n = {c, 0, s};
        return;
    }
    case QuadricKind::Cylinder:
        *q = {radius, 0, z0 + v * (z1 - z0)};
        *n = {1, 0, 0};
        return;
    case QuadricKind::Cone:  // z0 holds the height
        *q = {radius * (1 - v), 0, v * z0};
        *n = {z0, 0, radius};
        return;
    case QuadricKind::Disk:
        *q = {radius * (1 - v), 0, z0};
        *n = {0, 0, 1};
        return;
    case QuadricKind::Paraboloid: {
        // x^2 + y^2 = rmax^2 z / zmax: the gradient (2 rho, -rmax^2 / zmax)
        // stays finite at the vertex where dPdv does not.
        const float z = z0 + v * (z1 - z0);
        const float rho = radius * std::sqrt(std::max(z / paraZMax, 0.0f));
        *q = {rho, 0, z};
        *n = {2 * rho, 0, -radius * radius / paraZMax};
        return;
    }
    case QuadricKind::Hyperboloid: {
        const Vec3 d = p2 - p1;
        *q = p1 + d * v;
        *n = cross(Vec3(-q->y, q->x, 0), d);
        if (dot(*n, *n) <= 1e-12f * std::max(dot(d, d), 1e-30f) * std::max(dot(d, d), 1e-30f)) {
            // On the axis the sweep is degenerate: take the limit from inside the segment.
            const Vec3 q2 = p1 + d * (v < 0.5f ? v + 1e-3f : v - 1e-3f);
            *n = cross(Vec3(-q2.y, q2.x, 0), d);
        }
        return;
    }
    case QuadricKind::Torus: {
        const float phi = phi0 + v * (phi1 - phi0), c = std::cos(phi), s = std::sin(phi);
        *q = {majorRadius + radius * c, 0, radius * s};
        *n = {c, 0, s};
        return;
    }
    }
}

Vec3 QuadricShape::point(float u, float v) const {
    Vec3 q, n;
    profile(v, &q, &n);
    const float t = u * thetaMax;
    return rotateZ(q, std::cos(t), std::sin(t));
}

Vec3 QuadricShape::normal(float u, float v) const {
    Vec3 q, n;
    profile(v, &q, &n);
    const float t = u * thetaMax;
    return normalize(rotateZ(n, std::cos(t), std::sin(t))) * orient;
}

Bound3 QuadricShape::bound(const ParamRange& r) const {
    // Candidate v values: the ends and the profile's interior extremes.
    float vs[16];
    int nv = 0;
    vs[nv++] = r.v0;
    vs[nv++] = r.v1;
    const float vlo = std::min(r.v0, r.v1), vhi = std::max(r.v0, r.v1);
    auto addPhi = [&](float phi) {
        if (phi1 == phi0 || nv >= 16) return;
        const float v = (phi - phi0) / (phi1 - phi0);
        if (v > vlo && v < vhi) vs[nv++] = v;
    };
    if (kind == QuadricKind::Sphere) addPhi(0);
    if (kind == QuadricKind::Torus) {
        const float a = std::min(phi0, phi1), b = std::max(phi0, phi1);
        for (int k = int(std::ceil(a / (0.5f * kPi))); float(k) * 0.5f * kPi < b && nv < 16; ++k)
            addPhi(float(k) * 0.5f * kPi);
    }
    float ta = r.u0 * thetaMax, tb = r.u1 * thetaMax;
    if (kind == QuadricKind::Hyperboloid) {
        // rho(v) is smallest where the line passes closest to the axis.
        const Vec3 d = p2 - p1;
        const float dd = d.x * d.x + d.y * d.y;
        if (dd > 0) {
            const float t = -(p1.x * d.x + p1.y * d.y) / dd;
            if (t > vlo && t < vhi) vs[nv++] = t;
        }
    }
    float rlo = kInfinity, rhi = -kInfinity, zlo = kInfinity, zhi = -kInfinity;
    for (int k = 0; k < nv; ++k) {
        Vec3 q, n;
        profile(vs[k], &q, &n);
        const float rho = kind == QuadricKind::Hyperboloid ? std::sqrt(q.x * q.x + q.y * q.y) : q.x;
        rlo = std::min(rlo, rho);
        rhi = std::max(rhi, rho);
        zlo = std::min(zlo, q.z);
        zhi = std::max(zhi, q.z);
    }
    if (kind == QuadricKind::Hyperboloid) {
        // The profile point's own angle moves monotonically (by less than pi)
        // along the line; widen the sweep by it, or take the whole circle
        // when the line crosses the axis.
        Vec3 qa, qb, n;
        profile(r.v0, &qa, &n);
        profile(r.v1, &qb, &n);
        if (rlo <= 1e-6f * rhi) {
            ta = 0;
            tb = 2 * kPi;
        } else {
            const float a0 = std::atan2(qa.y, qa.x);
            float delta = std::atan2(qb.y, qb.x) - a0;
            if (delta > kPi) delta -= 2 * kPi;
            if (delta < -kPi) delta += 2 * kPi;
            if (ta > tb) std::swap(ta, tb);
            ta += std::min(a0, a0 + delta);
            tb += std::max(a0, a0 + delta);
        }
    }
    return sectorBound(ta, tb, rlo, rhi, zlo, zhi);
}

bool Quadric::shapeFromRecord(const scene::PrimitiveRecord& rec, QuadricShape* s, Diagnostics& diag) {
    const std::string& t = rec.type;
    const auto& a = rec.floatArgs;
    // A sweep beyond one turn only retraces the surface, and a huge one
    // (1e30 degrees) leaves u * thetamax no precision, so splitting never
    // makes the pieces small: angles are clamped to [-360, 360] degrees, as
    // PRMan and Aqsis effectively do (docs/rib.md, "Limits"). Non-finite
    // values pass through to the check below. Reported at the first
    // request of each kind and argument, so a scene of many such spheres
    // gives one line (and the ray-tracing scene, which makes the
    // primitives again, none).
    auto angle = [&](const char* name, float deg) {
        if (!std::isfinite(deg) || std::abs(deg) <= kMaxSweepDegrees) return deg;
        const float clamped = std::copysign(kMaxSweepDegrees, deg);
        diag.warningOnce(fmt::format("quadric-sweep:{}:{}", t, name), rec.loc,
                         "{}: {} {} is outside [-360, 360] degrees; clamped to {}", t, name, deg, clamped);
        return clamped;
    };
    auto expect = [&](size_t n, const char* names) {
        if (a.size() == n) return true;
        diag.error(rec.loc, "{}: expected {} arguments ({}), got {}", t, n, names, a.size());
        return false;
    };
    if (t == "Sphere") {
        if (!expect(4, "radius zmin zmax thetamax")) return false;
        s->kind = QuadricKind::Sphere;
        s->radius = a[0];
        if (a[0] == 0) {
            s->phi0 = s->phi1 = 0;
        } else {
            // RI spec: phimin = asin(zmin / radius) when zmin > -radius, else -90 degrees.
            s->phi0 = std::asin(clamp(a[1] / a[0], -1.0f, 1.0f));
            s->phi1 = std::asin(clamp(a[2] / a[0], -1.0f, 1.0f));
        }
        s->thetaMax = radians(angle("thetamax", a[3]));
    } else if (t == "Cylinder") {
        if (!expect(4, "radius zmin zmax thetamax")) return false;
        s->kind = QuadricKind::Cylinder;
        s->radius = a[0];
        s->z0 = a[1];
        s->z1 = a[2];
        s->thetaMax = radians(angle("thetamax", a[3]));
    } else if (t == "Cone" || t == "Disk") {
        if (!expect(3, t == "Cone" ? "height radius thetamax" : "height radius thetamax")) return false;
        s->kind = t == "Cone" ? QuadricKind::Cone : QuadricKind::Disk;
        s->z0 = a[0];
        s->radius = a[1];
        s->thetaMax = radians(angle("thetamax", a[2]));
    } else if (t == "Paraboloid") {
        if (!expect(4, "rmax zmin zmax thetamax")) return false;
        if (a[2] == 0) {
            diag.error(rec.loc, "Paraboloid: zmax must not be 0 (the radius is rmax at zmax), got zmin {} zmax {}",
                       a[1], a[2]);
            return false;
        }
        float z0 = a[1];
        if (z0 / a[2] < 0) {
            // Past 0 the radius rmax sqrt(z / zmax) is not real: the surface
            // is the part from 0 to zmax, as Pixie and Aqsis draw it.
            diag.warningOnce(fmt::format("paraboloid:{}", rec.loc.str()), rec.loc,
                             "Paraboloid: zmin {} lies past 0 from zmax {}; drawn from 0 (the radius is not real "
                             "beyond)", a[1], a[2]);
            z0 = 0;
        }
        s->kind = QuadricKind::Paraboloid;
        s->radius = a[0];
        s->z0 = z0;
        s->z1 = a[2];
        s->paraZMax = a[2];
        s->thetaMax = radians(angle("thetamax", a[3]));
    } else if (t == "Hyperboloid") {
        if (!expect(7, "x1 y1 z1 x2 y2 z2 thetamax")) return false;
        s->kind = QuadricKind::Hyperboloid;
        s->p1 = {a[0], a[1], a[2]};
        s->p2 = {a[3], a[4], a[5]};
        s->thetaMax = radians(angle("thetamax", a[6]));
    } else if (t == "Torus") {
        if (!expect(5, "majorradius minorradius phimin phimax thetamax")) return false;
        s->kind = QuadricKind::Torus;
        s->majorRadius = a[0];
        s->radius = a[1];
        float phiMin = angle("phimin", a[2]), phiMax = angle("phimax", a[3]);
        if (std::abs(phiMax - phiMin) > kMaxSweepDegrees) {
            // Each end within a turn, yet up to two turns apart.
            const float clamped = phiMin + std::copysign(kMaxSweepDegrees, phiMax - phiMin);
            diag.warningOnce("quadric-sweep:Torus:phi", rec.loc,
                             "Torus: phimin {} to phimax {} sweeps more than 360 degrees; phimax clamped to {}",
                             phiMin, phiMax, clamped);
            phiMax = clamped;
        }
        s->phi0 = radians(phiMin);
        s->phi1 = radians(phiMax);
        s->thetaMax = radians(angle("thetamax", a[4]));
    } else {
        diag.error(rec.loc, "{}: not a quadric", t);
        return false;
    }
    for (float x : a)
        if (!std::isfinite(x)) {
            diag.error(rec.loc, "{}: arguments must be finite numbers", t);
            return false;
        }
    // Orientation: compare the closed-form normal with dPdu x dPdv measured
    // by central differences inside the domain, where the map is regular.
    s->orient = 1;
    const float h = 1e-3f;
    const Vec3 du = s->point(0.5f + h, 0.5f) - s->point(0.5f - h, 0.5f);
    const Vec3 dv = s->point(0.5f, 0.5f + h) - s->point(0.5f, 0.5f - h);
    if (dot(cross(du, dv), s->normal(0.5f, 0.5f)) < 0) s->orient = -1;
    return true;
}

Quadric::Quadric(std::shared_ptr<const scene::PrimitiveRecord> record, const QuadricShape& shape,
                 std::shared_ptr<const SurfaceData> data, const ParamRange& range)
    : Primitive(std::move(record)), m_shape(shape), m_data(std::move(data)), m_range(range) {}

Bound3 Quadric::bound() const { return m_shape.bound(m_range); }

void Quadric::split(bool splitU, std::vector<PrimitivePtr>& out) const {
    for (int k = 0; k < 2; ++k)
        out.push_back(std::make_unique<Quadric>(recordPtr(), m_shape, m_data, m_range.half(splitU, k == 1)));
}

void Quadric::evalGrid(int nu, int nv, const std::vector<float>& a, const std::vector<float>& b, Vec3* P,
                       Vec3* N) const {
    // One cos/sin per column and one profile per row: no trig per vertex.
    thread_local std::vector<float> cs, sn;
    cs.resize(size_t(nu) + 1);
    sn.resize(size_t(nu) + 1);
    for (int i = 0; i <= nu; ++i) {
        const float t = a[size_t(i)] * m_shape.thetaMax;
        cs[size_t(i)] = std::cos(t);
        sn[size_t(i)] = std::sin(t);
    }
    for (int j = 0; j <= nv; ++j) {
        Vec3 q, n;
        m_shape.profile(b[size_t(j)], &q, &n);
        n = normalize(n) * m_shape.orient;
        const size_t row = size_t(j) * size_t(nu + 1);
        for (int i = 0; i <= nu; ++i) {
            P[row + size_t(i)] = rotateZ(q, cs[size_t(i)], sn[size_t(i)]);
            if (N) N[row + size_t(i)] = rotateZ(n, cs[size_t(i)], sn[size_t(i)]);
        }
    }
}

Grid Quadric::dice(int nu, int nv) const {
    Grid g;
    std::vector<float> a, b;
    initGrid(g, nu, nv, m_range, ParamMap{}, a, b);
    g.N.resize(g.P.size());
    g.ownNormals = true;
    evalGrid(nu, nv, a, b, g.P.data(), g.N.data());
    static const SurfaceData kEmpty;
    interpolateVars(m_data ? *m_data : kEmpty, CornerRefs{}, a, b, false, g);
    return g;
}

void Quadric::dicePositions(int nu, int nv, std::vector<Vec3>& P) const {
    thread_local std::vector<float> a, b;
    m_range.steps(nu, nv, a, b);
    P.resize(size_t(nu + 1) * size_t(nv + 1));
    evalGrid(nu, nv, a, b, P.data(), nullptr);
}

}  // namespace umbra::geometry
