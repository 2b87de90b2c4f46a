#pragma once
// Transforms that move during the shutter (MotionBegin/MotionEnd around
// transform requests, RI spec 3.2 §4.3 "Motion"), and how they are
// interpolated between their keys.
//
// A key matrix is decomposed as T R S (translation, rotation, stretch: the
// polar decomposition, Shoemake & Duff 1992); between two keys the
// translation and stretch are interpolated linearly and the rotation along
// the great arc (quaternion slerp). So `MotionBegin [0 1] Rotate 0 0 0 1
// Rotate 90 0 0 1 MotionEnd` turns a bar through a quarter circle, where
// interpolating the matrices' entries would shrink it along the chord.
// Rotations between two keys take the shorter way round (a key every half
// turn or less says more).

#include "umbra/util/math.h"

#include <vector>

namespace umbra {

/// A matrix split for interpolation: M = translate(t) * rotation(q) * stretch.
struct DecomposedTransform {
    Vec3 translation;
    float q[4] = {1, 0, 0, 0};  // unit quaternion w, x, y, z
    Mat4 stretch;               // symmetric 3x3 (may carry a reflection); its row 3 / column 3 are identity
    Mat4 projective;            // the bottom row of M when it is not affine (kept as given); else identity row
    bool affine = true;
};

DecomposedTransform decompose(const Mat4& m);
/// Interpolates between two decomposed keys, f in [0, 1].
Mat4 interpolate(const DecomposedTransform& a, const DecomposedTransform& b, float f);
/// The angle, in radians, the rotation turns through between two keys.
float rotationAngle(const DecomposedTransform& a, const DecomposedTransform& b);

/// A transform that may move: a product of factors, each a fixed matrix or
/// the keys of one motion block (times ascending, one matrix per time).
/// Each moving factor is interpolated on its own, so a fixed transform after
/// it is not folded into its keys: `MotionBegin Rotate..MotionEnd Translate 2
/// 0 0` orbits on the circle of radius 2, where folding would move the
/// translation along the chord. Neighbouring fixed transforms merge.
class MotionTransform {
public:
    MotionTransform() = default;
    explicit MotionTransform(const Mat4& fixed) { m_factors.push_back({{}, {fixed}, {}}); }

    bool moving() const;
    /// The transform at time t (clamped to each factor's keys).
    Mat4 at(float t) const;
    /// this * m (a transform request after the motion block).
    void postMultiply(const Mat4& m);
    /// m * this (e.g. an instance's transform before its definition's).
    void preMultiply(const Mat4& m);
    /// Appends a moving factor: this * keys(t).
    void postMultiplyMoving(const std::vector<float>& times, const std::vector<Mat4>& keys);
    /// Every key time of every moving factor, ascending, without repeats.
    std::vector<float> keyTimes() const;
    /// The largest angle any one factor turns through between times t0 and
    /// t1: how finely a piecewise-linear path must sample it.
    float turnBetween(float t0, float t1) const;

private:
    struct Factor {
        std::vector<float> times;   // empty: fixed
        std::vector<Mat4> keys;     // one (fixed) or one per time
        std::vector<DecomposedTransform> parts;  // per key, when moving
    };
    std::vector<Factor> m_factors;
};

}  // namespace umbra
