#include "umbra/util/motion.h"

#include <algorithm>
#include <cmath>

namespace umbra {

namespace {

/// The upper 3x3 of m as a Mat4 (translation and bottom row cleared).
Mat4 linearPart(const Mat4& m) {
    Mat4 r;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) r.m[i][j] = m.m[i][j];
    return r;
}

/// Unit quaternion (w, x, y, z) of a proper rotation matrix (Shoemake).
void quaternionOf(const Mat4& r, float q[4]) {
    const auto& m = r.m;
    const float trace = m[0][0] + m[1][1] + m[2][2];
    if (trace > 0) {
        const float s = std::sqrt(trace + 1.0f) * 2.0f;
        q[0] = 0.25f * s;
        q[1] = (m[2][1] - m[1][2]) / s;
        q[2] = (m[0][2] - m[2][0]) / s;
        q[3] = (m[1][0] - m[0][1]) / s;
    } else if (m[0][0] > m[1][1] && m[0][0] > m[2][2]) {
        const float s = std::sqrt(1.0f + m[0][0] - m[1][1] - m[2][2]) * 2.0f;
        q[0] = (m[2][1] - m[1][2]) / s;
        q[1] = 0.25f * s;
        q[2] = (m[0][1] + m[1][0]) / s;
        q[3] = (m[0][2] + m[2][0]) / s;
    } else if (m[1][1] > m[2][2]) {
        const float s = std::sqrt(1.0f + m[1][1] - m[0][0] - m[2][2]) * 2.0f;
        q[0] = (m[0][2] - m[2][0]) / s;
        q[1] = (m[0][1] + m[1][0]) / s;
        q[2] = 0.25f * s;
        q[3] = (m[1][2] + m[2][1]) / s;
    } else {
        const float s = std::sqrt(1.0f + m[2][2] - m[0][0] - m[1][1]) * 2.0f;
        q[0] = (m[1][0] - m[0][1]) / s;
        q[1] = (m[0][2] + m[2][0]) / s;
        q[2] = (m[1][2] + m[2][1]) / s;
        q[3] = 0.25f * s;
    }
    const float n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int k = 0; k < 4; ++k) q[k] /= n;
}

Mat4 rotationOf(const float q[4]) {
    const float w = q[0], x = q[1], y = q[2], z = q[3];
    Mat4 r;
    r.m[0][0] = 1 - 2 * (y * y + z * z);
    r.m[0][1] = 2 * (x * y - w * z);
    r.m[0][2] = 2 * (x * z + w * y);
    r.m[1][0] = 2 * (x * y + w * z);
    r.m[1][1] = 1 - 2 * (x * x + z * z);
    r.m[1][2] = 2 * (y * z - w * x);
    r.m[2][0] = 2 * (x * z - w * y);
    r.m[2][1] = 2 * (y * z + w * x);
    r.m[2][2] = 1 - 2 * (x * x + y * y);
    return r;
}

float quaternionDot(const float a[4], const float b[4]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
}

}  // namespace

bool skewMatrix(float angleDeg, const Vec3& d1, const Vec3& d2, Mat4* m) {
    // Shear along d2 in proportion to the distance along e (d1 made
    // perpendicular to d2), so that d1 turns by `angle` towards d2:
    // p' = p + k (e . p) d2n with k = tan(alpha + angle) - tan(alpha),
    // alpha being d1's angle from e.
    if (length(d2) == 0) return false;
    const Vec3 d2n = normalize(d2);
    const Vec3 perp = d1 - d2n * dot(d1, d2n);
    const float x = length(perp), y = dot(d1, d2n);
    const float target = std::atan2(y, x) + radians(angleDeg);
    if (!(x > 0) || !(std::fabs(target) < kPi / 2)) return false;
    const float k = std::tan(target) - y / x;
    const Vec3 e = perp / x;
    *m = Mat4();
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) m->m[i][j] += k * d2n[i] * e[j];
    return true;
}

TransformRequest TransformRequest::between(const TransformRequest& a, const TransformRequest& b, float f) {
    TransformRequest r = a;
    for (int k = 0; k < 7; ++k) r.p[k] = a.p[k] + f * (b.p[k] - a.p[k]);
    switch (a.kind) {
    case Kind::Translate: r.matrix = Mat4::translate(Vec3(r.p[0], r.p[1], r.p[2])); break;
    case Kind::Rotate: r.matrix = Mat4::rotate(r.p[0], Vec3(r.p[1], r.p[2], r.p[3])); break;
    case Kind::Scale: r.matrix = Mat4::scale(Vec3(r.p[0], r.p[1], r.p[2])); break;
    case Kind::Skew:
        // Each key is a valid skew, and so is every angle between two.
        if (!skewMatrix(r.p[0], Vec3(r.p[1], r.p[2], r.p[3]), Vec3(r.p[4], r.p[5], r.p[6]), &r.matrix))
            r.matrix = f < 0.5f ? a.matrix : b.matrix;
        break;
    case Kind::Matrix: break;  // never moved by its parameters (sameMotion): decomposed instead
    }
    return r;
}

bool TransformRequest::sameMotion(const TransformRequest& a, const TransformRequest& b) {
    if (a.kind != b.kind || a.kind == Kind::Matrix) return false;
    auto same = [&](int from, int to) {
        for (int k = from; k < to; ++k)
            if (a.p[k] != b.p[k]) return false;
        return true;
    };
    switch (a.kind) {
    case Kind::Rotate: {
        // One axis (any length): the angle alone moves.
        const Vec3 x(a.p[1], a.p[2], a.p[3]), y(b.p[1], b.p[2], b.p[3]);
        return same(1, 4) || (length(cross(normalize(x), normalize(y))) < 1e-6f && dot(x, y) > 0);
    }
    case Kind::Skew: return same(1, 7);
    default: return true;
    }
}

DecomposedTransform decompose(const Mat4& m) {
    DecomposedTransform d;
    d.translation = {m.m[0][3], m.m[1][3], m.m[2][3]};
    d.affine = m.m[3][0] == 0 && m.m[3][1] == 0 && m.m[3][2] == 0 && m.m[3][3] == 1;
    for (int j = 0; j < 4; ++j) d.projective.m[3][j] = m.m[3][j];
    Mat4 a = linearPart(m);
    // A reflection cannot be a rotation: it goes with the stretch.
    const bool reflects = a.det3() < 0;
    if (reflects)
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) a.m[i][j] = -a.m[i][j];
    // Polar decomposition by averaging with the inverse transpose: R
    // converges quadratically for any non-singular matrix.
    Mat4 r = a;
    for (int iter = 0; iter < 50; ++iter) {
        bool ok = true;
        const Mat4 inverseTranspose = r.inverse(&ok).transposed();
        if (!ok) {
            r = Mat4();  // singular: no rotation, everything in the stretch
            break;
        }
        Mat4 next;
        float change = 0;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) {
                next.m[i][j] = 0.5f * (r.m[i][j] + inverseTranspose.m[i][j]);
                change = std::max(change, std::abs(next.m[i][j] - r.m[i][j]));
            }
        r = next;
        if (change < 1e-7f) break;
    }
    quaternionOf(r, d.q);
    // S = R^-1 A = R^T A, with the reflection put back.
    d.stretch = r.transposed() * a;
    if (reflects)
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) d.stretch.m[i][j] = -d.stretch.m[i][j];
    return d;
}

float rotationAngle(const DecomposedTransform& a, const DecomposedTransform& b) {
    const float c = std::min(1.0f, std::abs(quaternionDot(a.q, b.q)));
    return 2.0f * std::acos(c);
}

Mat4 interpolate(const DecomposedTransform& a, const DecomposedTransform& b, float f) {
    // Slerp the shorter way round.
    float qb[4] = {b.q[0], b.q[1], b.q[2], b.q[3]};
    float cosine = quaternionDot(a.q, qb);
    if (cosine < 0) {
        for (float& v : qb) v = -v;
        cosine = -cosine;
    }
    float q[4];
    if (cosine > 0.9995f) {
        for (int k = 0; k < 4; ++k) q[k] = a.q[k] + f * (qb[k] - a.q[k]);
    } else {
        const float theta = std::acos(cosine);
        const float wa = std::sin((1 - f) * theta) / std::sin(theta), wb = std::sin(f * theta) / std::sin(theta);
        for (int k = 0; k < 4; ++k) q[k] = wa * a.q[k] + wb * qb[k];
    }
    const float n = std::sqrt(quaternionDot(q, q));
    for (float& v : q) v /= n;
    Mat4 s;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) s.m[i][j] = a.stretch.m[i][j] + f * (b.stretch.m[i][j] - a.stretch.m[i][j]);
    Mat4 m = rotationOf(q) * s;
    const Vec3 t = a.translation + (b.translation - a.translation) * f;
    m.m[0][3] = t.x;
    m.m[1][3] = t.y;
    m.m[2][3] = t.z;
    for (int j = 0; j < 4; ++j) m.m[3][j] = a.projective.m[3][j] + f * (b.projective.m[3][j] - a.projective.m[3][j]);
    return m;
}

bool MotionTransform::moving() const {
    for (const Factor& f : m_factors)
        if (!f.times.empty()) return true;
    return false;
}

Mat4 MotionTransform::at(float t) const {
    Mat4 r;
    for (const Factor& f : m_factors) {
        if (f.times.empty()) {
            r = r * f.keys[0];
            continue;
        }
        const size_t n = f.times.size();
        if (t <= f.times[0]) {
            r = r * f.keys[0];
        } else if (t >= f.times[n - 1]) {
            r = r * f.keys[n - 1];
        } else {
            size_t k = size_t(std::upper_bound(f.times.begin(), f.times.end(), t) - f.times.begin()) - 1;
            const float span = f.times[k + 1] - f.times[k];
            const float u = span > 0 ? (t - f.times[k]) / span : 0.0f;
            r = r * (f.requests.empty() ? interpolate(f.parts[k], f.parts[k + 1], u)
                                        : TransformRequest::between(f.requests[k], f.requests[k + 1], u).matrix);
        }
    }
    return r;
}

void MotionTransform::postMultiply(const Mat4& m) {
    if (!m_factors.empty() && m_factors.back().times.empty())
        m_factors.back().keys[0] = m_factors.back().keys[0] * m;
    else
        m_factors.push_back({{}, {m}, {}, {}});
}

void MotionTransform::preMultiply(const Mat4& m) {
    if (!m_factors.empty() && m_factors.front().times.empty())
        m_factors.front().keys[0] = m * m_factors.front().keys[0];
    else
        m_factors.insert(m_factors.begin(), Factor{{}, {m}, {}, {}});
}

void MotionTransform::postMultiply(const MotionTransform& m) {
    for (const Factor& f : m.m_factors) {
        if (f.times.empty())
            postMultiply(f.keys[0]);
        else
            m_factors.push_back(f);
    }
}

void MotionTransform::postMultiplyMoving(const std::vector<float>& times, const std::vector<Mat4>& keys) {
    if (keys.size() == 1 || times.size() < 2) {
        if (!keys.empty()) postMultiply(keys[0]);
        return;
    }
    Factor f{times, keys, {}, {}};
    for (const Mat4& k : keys) f.parts.push_back(decompose(k));
    m_factors.push_back(std::move(f));
}

void MotionTransform::postMultiplyMoving(const std::vector<float>& times, const std::vector<TransformRequest>& keys) {
    bool parametric = keys.size() > 1 && times.size() >= 2;
    for (size_t k = 1; k < keys.size() && parametric; ++k) parametric = TransformRequest::sameMotion(keys[0], keys[k]);
    if (!parametric) {
        std::vector<Mat4> matrices;
        for (const TransformRequest& r : keys) matrices.push_back(r.matrix);
        postMultiplyMoving(times, matrices);
        return;
    }
    Factor f{times, {}, {}, keys};
    for (const TransformRequest& r : keys) f.keys.push_back(r.matrix);
    m_factors.push_back(std::move(f));
}

std::vector<float> MotionTransform::keyTimes() const {
    std::vector<float> times;
    for (const Factor& f : m_factors) times.insert(times.end(), f.times.begin(), f.times.end());
    std::sort(times.begin(), times.end());
    times.erase(std::unique(times.begin(), times.end()), times.end());
    return times;
}

float MotionTransform::turnBetween(float t0, float t1) const {
    float most = 0;
    for (const Factor& f : m_factors) {
        if (f.times.empty()) continue;
        // Each key segment overlapping [t0, t1] turns in proportion to its share.
        for (size_t k = 0; k + 1 < f.times.size(); ++k) {
            const float a = std::max(t0, f.times[k]), b = std::min(t1, f.times[k + 1]);
            const float span = f.times[k + 1] - f.times[k];
            if (!(b > a) || !(span > 0)) continue;
            float turn;
            if (f.requests.empty()) {
                turn = rotationAngle(f.parts[k], f.parts[k + 1]);
            } else {
                // A Rotate turns by its angle's change; a Skew's vector
                // turns by its angle's. Translate and Scale move each point
                // along a line.
                const TransformRequest::Kind kind = f.requests[k].kind;
                const bool turns = kind == TransformRequest::Kind::Rotate || kind == TransformRequest::Kind::Skew;
                turn = turns ? radians(std::abs(f.requests[k + 1].p[0] - f.requests[k].p[0])) : 0.0f;
            }
            most = std::max(most, turn * (b - a) / span);
        }
    }
    return most;
}

}  // namespace umbra
