#pragma once
// Small fixed-size math types used on every hot path of the renderer.
//
// Conventions (all modules follow them):
//  - Column vectors: a transform is applied as `M * p`, so transforms compose
//    right to left and are named by their spaces: `cameraFromWorld *
//    worldFromObject` is `cameraFromObject`.
//  - RIB matrices are written for row vectors (translation in the last row);
//    the RIB front end transposes them once on input (Mat4::fromRib).
//  - RenderMan's camera space is left-handed: +z looks into the scene,
//    +x right, +y up.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace umbra {

constexpr float kPi = 3.14159265358979323846f;
constexpr float kInfinity = std::numeric_limits<float>::infinity();

inline float radians(float deg) { return deg * (kPi / 180.0f); }
inline float degrees(float rad) { return rad * (180.0f / kPi); }
inline float lerp(float t, float a, float b) { return a + t * (b - a); }
/// The larger singular value of the 2x2 matrix {m[0], m[1]; m[2], m[3]}: the
/// most it stretches a unit vector. Exactly max(|m[0]|, |m[3]|) for a
/// diagonal one; otherwise sigma^2 is the larger eigenvalue of M^T M,
/// (s + sqrt(s^2 - 4 det^2)) / 2 with s the sum of squared entries.
inline float largestSingularValue(const float m[4]) {
    if (m[1] == 0 && m[2] == 0) return std::max(std::abs(m[0]), std::abs(m[3]));
    const double a = m[0], b = m[1], c = m[2], d = m[3];
    const double s = a * a + b * b + c * c + d * d, det = a * d - b * c;
    return float(std::sqrt(0.5 * (s + std::sqrt(std::max(0.0, s * s - 4 * det * det)))));
}
template <typename T> inline T clamp(T x, T lo, T hi) { return x < lo ? lo : (x > hi ? hi : x); }

/// floor(v) as an int in [lo, hi], clamped before the conversion: a float
/// to int conversion out of range is undefined (x86 gives INT_MIN for
/// +-inf), and bounds across the eye plane are infinite. NaN gives lo.
inline int floorToIntClamped(double v, int lo, int hi) {
    if (!(v >= double(lo))) return lo;  // below, or NaN
    if (v >= double(hi)) return hi;
    return int(std::floor(v));
}

/// A 2-D vector or point (raster positions, texture coordinates).
struct Vec2 {
    float x = 0, y = 0;
    constexpr Vec2() = default;
    constexpr Vec2(float x_, float y_) : x(x_), y(y_) {}
    Vec2 operator+(Vec2 b) const { return {x + b.x, y + b.y}; }
    Vec2 operator-(Vec2 b) const { return {x - b.x, y - b.y}; }
    Vec2 operator*(float s) const { return {x * s, y * s}; }
    float operator[](int i) const { return i == 0 ? x : y; }
    float& operator[](int i) { return i == 0 ? x : y; }
};

/// A 3-D point, vector, normal or RGB colour (RenderMan colours have three
/// channels; `Color` is the same type under a name that says what it holds).
struct Vec3 {
    float x = 0, y = 0, z = 0;
    constexpr Vec3() = default;
    constexpr explicit Vec3(float s) : x(s), y(s), z(s) {}
    constexpr Vec3(float x_, float y_, float z_) : x(x_), y(y_), z(z_) {}
    Vec3 operator+(const Vec3& b) const { return {x + b.x, y + b.y, z + b.z}; }
    Vec3 operator-(const Vec3& b) const { return {x - b.x, y - b.y, z - b.z}; }
    Vec3 operator*(const Vec3& b) const { return {x * b.x, y * b.y, z * b.z}; }
    Vec3 operator/(const Vec3& b) const { return {x / b.x, y / b.y, z / b.z}; }
    Vec3 operator*(float s) const { return {x * s, y * s, z * s}; }
    Vec3 operator/(float s) const { float r = 1.0f / s; return {x * r, y * r, z * r}; }
    Vec3 operator-() const { return {-x, -y, -z}; }
    Vec3& operator+=(const Vec3& b) { x += b.x; y += b.y; z += b.z; return *this; }
    Vec3& operator-=(const Vec3& b) { x -= b.x; y -= b.y; z -= b.z; return *this; }
    Vec3& operator*=(const Vec3& b) { x *= b.x; y *= b.y; z *= b.z; return *this; }
    Vec3& operator*=(float s) { x *= s; y *= s; z *= s; return *this; }
    bool operator==(const Vec3& b) const { return x == b.x && y == b.y && z == b.z; }
    bool operator!=(const Vec3& b) const { return !(*this == b); }
    float operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
    float& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
};
inline Vec3 operator*(float s, const Vec3& v) { return v * s; }
using Color = Vec3;

inline float dot(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline float length(const Vec3& v) { return std::sqrt(dot(v, v)); }
inline Vec3 normalize(const Vec3& v) {
    float l = length(v);
    return l > 0 ? v / l : v;
}
inline Vec3 vmin(const Vec3& a, const Vec3& b) { return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)}; }
inline Vec3 vmax(const Vec3& a, const Vec3& b) { return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)}; }

/// An axis-aligned box; empty when min > max on any axis.
struct Bound3 {
    Vec3 min{kInfinity, kInfinity, kInfinity};
    Vec3 max{-kInfinity, -kInfinity, -kInfinity};
    constexpr Bound3() = default;
    constexpr Bound3(const Vec3& lo, const Vec3& hi) : min(lo), max(hi) {}
    bool empty() const { return min.x > max.x || min.y > max.y || min.z > max.z; }
    void extend(const Vec3& p) { min = vmin(min, p); max = vmax(max, p); }
    void extend(const Bound3& b) { min = vmin(min, b.min); max = vmax(max, b.max); }
    Vec3 corner(int i) const { return {(i & 1) ? max.x : min.x, (i & 2) ? max.y : min.y, (i & 4) ? max.z : min.z}; }
    Vec3 diagonal() const { return max - min; }
};

/// A 4x4 matrix applied to column vectors (see the conventions above).
struct Mat4 {
    float m[4][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};

    static Mat4 identity() { return Mat4{}; }
    /// From 16 numbers in RIB order (row-vector convention, row major).
    static Mat4 fromRib(const float* v) {
        Mat4 r;
        for (int i = 0; i < 4; ++i)
            for (int j = 0; j < 4; ++j) r.m[j][i] = v[i * 4 + j];
        return r;
    }
    /// To 16 numbers in RIB order (row-vector convention), the inverse of fromRib.
    void toRib(float* v) const {
        for (int i = 0; i < 4; ++i)
            for (int j = 0; j < 4; ++j) v[i * 4 + j] = m[j][i];
    }
    static Mat4 translate(const Vec3& t) {
        Mat4 r;
        r.m[0][3] = t.x; r.m[1][3] = t.y; r.m[2][3] = t.z;
        return r;
    }
    static Mat4 scale(const Vec3& s) {
        Mat4 r;
        r.m[0][0] = s.x; r.m[1][1] = s.y; r.m[2][2] = s.z;
        return r;
    }
    /// Rotation by `angleDeg` degrees about `axis`, counter-clockwise when
    /// looking down the axis towards the origin in a right-handed frame (the
    /// RIB `Rotate` request's matrix).
    static Mat4 rotate(float angleDeg, const Vec3& axis) {
        Vec3 a = normalize(axis);
        float s = std::sin(radians(angleDeg)), c = std::cos(radians(angleDeg));
        Mat4 r;
        r.m[0][0] = a.x * a.x + (1 - a.x * a.x) * c;
        r.m[0][1] = a.x * a.y * (1 - c) - a.z * s;
        r.m[0][2] = a.x * a.z * (1 - c) + a.y * s;
        r.m[1][0] = a.x * a.y * (1 - c) + a.z * s;
        r.m[1][1] = a.y * a.y + (1 - a.y * a.y) * c;
        r.m[1][2] = a.y * a.z * (1 - c) - a.x * s;
        r.m[2][0] = a.x * a.z * (1 - c) - a.y * s;
        r.m[2][1] = a.y * a.z * (1 - c) + a.x * s;
        r.m[2][2] = a.z * a.z + (1 - a.z * a.z) * c;
        return r;
    }
    Mat4 operator*(const Mat4& b) const {
        Mat4 r;
        for (int i = 0; i < 4; ++i)
            for (int j = 0; j < 4; ++j) {
                double s = 0;
                for (int k = 0; k < 4; ++k) s += double(m[i][k]) * b.m[k][j];
                r.m[i][j] = float(s);
            }
        return r;
    }
    bool operator==(const Mat4& b) const {
        for (int i = 0; i < 4; ++i)
            for (int j = 0; j < 4; ++j)
                if (m[i][j] != b.m[i][j]) return false;
        return true;
    }
    Mat4 transposed() const {
        Mat4 r;
        for (int i = 0; i < 4; ++i)
            for (int j = 0; j < 4; ++j) r.m[i][j] = m[j][i];
        return r;
    }
    /// The inverse; a singular matrix gives a matrix of zeros and `ok=false`.
    Mat4 inverse(bool* ok = nullptr) const;

    /// Applies the full projective transform, dividing by w.
    Vec3 point(const Vec3& p) const {
        float x = m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z + m[0][3];
        float y = m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z + m[1][3];
        float z = m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z + m[2][3];
        float w = m[3][0] * p.x + m[3][1] * p.y + m[3][2] * p.z + m[3][3];
        if (w == 1.0f) return {x, y, z};
        return {x / w, y / w, z / w};
    }
    /// Applies the upper 3x3 only (directions).
    Vec3 vector(const Vec3& v) const {
        return {m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
                m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
                m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z};
    }
    /// Transforms a normal by this matrix, given its inverse (normals go by
    /// the inverse transpose).
    static Vec3 normal(const Mat4& inverse, const Vec3& n) {
        const auto& a = inverse.m;
        return {a[0][0] * n.x + a[1][0] * n.y + a[2][0] * n.z,
                a[0][1] * n.x + a[1][1] * n.y + a[2][1] * n.z,
                a[0][2] * n.x + a[1][2] * n.y + a[2][2] * n.z};
    }
    /// Determinant of the upper 3x3: negative when the transform flips handedness.
    float det3() const {
        return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
               m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
               m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    }
};

/// Transforms the eight corners of `b` by `M` (projective) and bounds them.
Bound3 transformBound(const Mat4& M, const Bound3& b);

/// The smallest singular value of the upper 3x3 of `m`: the least it
/// stretches a unit vector (the square root of M^T M's least eigenvalue).
float smallestSingularValue3(const Mat4& m);

}  // namespace umbra
