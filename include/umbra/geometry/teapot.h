#pragma once
// The Newell teapot that `Geometry "teapot"` draws, as Aqsis does: the 28
// bicubic Bezier patches of the original and a flat bottom of 4 more, z up,
// standing on z = 0 and 3 tall, the spout towards +x and the handle
// towards -x; the plane y = 0 is its plane of symmetry.

#include "umbra/util/math.h"

namespace umbra::geometry {

constexpr int kTeapotPatchCount = 32;

/// Control point k (0..15; row k / 4 along v, column k % 4 along u, as a
/// `Patch "bicubic"` lists them) of teapot patch `patch`, object space.
Vec3 teapotControlPoint(int patch, int k);

}  // namespace umbra::geometry
