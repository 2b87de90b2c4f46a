#pragma once
// The Newell teapot that `Geometry "teapot"` draws, as PRMan and Aqsis do:
// bicubic Bezier patches, z up, standing on z = 0 and 3.15 tall, the spout
// towards +x and the handle towards -x; the plane y = 0 is its plane of
// symmetry.

#include "umbra/util/math.h"

namespace umbra::geometry {

constexpr int kTeapotPatchCount = 32;

/// Control point k (0..15; row k / 4 along v, column k % 4 along u, as a
/// `Patch "bicubic"` lists them) of teapot patch `patch`, object space.
Vec3 teapotControlPoint(int patch, int k);

}  // namespace umbra::geometry
