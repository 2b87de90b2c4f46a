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

/// A transform request as the RIB gave it. A motion block whose keys are
/// all one kind of request (Translate, Rotate about one axis, Scale, Skew
/// between the same vectors) moves that request's parameters linearly, as
/// RI Spec 3.2 says: a Rotate from 0 to 270 degrees turns three quarters of
/// a turn, a Scale from 1 to -1 flattens through 0 instead of tumbling, a
/// Skew from 0 to 60 stays a shear. Other blocks interpolate their key
/// matrices, decomposed (below).
struct TransformRequest {
    enum class Kind { Matrix, Translate, Rotate, Scale, Skew };
    Kind kind = Kind::Matrix;
    /// Translate dx dy dz; Rotate angle (degrees) and axis; Scale sx sy sz;
    /// Skew angle (degrees), d1, d2.
    float p[7] = {};
    Mat4 matrix;  // the request's own matrix

    static TransformRequest of(const Mat4& m) { return {Kind::Matrix, {}, m}; }
    /// The request of the same kind with parameters (1 - f) a + f b (a
    /// and b moving the same request: sameMotion).
    static TransformRequest between(const TransformRequest& a, const TransformRequest& b, float f);
    /// Whether a and b differ only in the parameters a block moves.
    static bool sameMotion(const TransformRequest& a, const TransformRequest& b);
};

/// The Skew request's matrix (RI Spec 3.2): d1 turned by `angleDeg` towards
/// d2. False when d1 and d2 are parallel or the skewed vector would reach
/// 90 degrees from d1's perpendicular.
bool skewMatrix(float angleDeg, const Vec3& d1, const Vec3& d2, Mat4* m);

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
    explicit MotionTransform(const Mat4& fixed) { m_factors.push_back({{}, {fixed}, {}, {}}); }

    bool moving() const;
    /// The transform at time t (clamped to each factor's keys).
    Mat4 at(float t) const;
    /// this * m (a transform request after the motion block).
    void postMultiply(const Mat4& m);
    /// m * this (e.g. an instance's transform before its definition's).
    void preMultiply(const Mat4& m);
    /// this * m, m moving too: its factors follow this one's (an instance
    /// moving, and a piece of its definition moving inside it).
    void postMultiply(const MotionTransform& m);
    /// Appends a moving factor: this * keys(t).
    void postMultiplyMoving(const std::vector<float>& times, const std::vector<Mat4>& keys);
    /// The same for a block's requests: by their parameters when every key
    /// moves the same request (TransformRequest::sameMotion), else by
    /// their matrices.
    void postMultiplyMoving(const std::vector<float>& times, const std::vector<TransformRequest>& keys);
    /// Every key time of every moving factor, ascending, without repeats.
    std::vector<float> keyTimes() const;
    /// The largest angle any one factor turns through between times t0 and
    /// t1: how finely a piecewise-linear path must sample it.
    float turnBetween(float t0, float t1) const;

private:
    struct Factor {
        std::vector<float> times;   // empty: fixed
        std::vector<Mat4> keys;     // one (fixed) or one per time
        std::vector<DecomposedTransform> parts;  // per key, when moving by matrices
        std::vector<TransformRequest> requests;  // per key, when moving by parameters
    };
    std::vector<Factor> m_factors;
};

}  // namespace umbra
