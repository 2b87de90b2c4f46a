#pragma once
// Scenes for the ray-traced shadow tests, built from hand-made primitive
// records (no RIB parser), and an analytic reference for sphere shadows.

#include "support/params.h"
#include "umbra/geometry/primitive.h"
#include "umbra/scene/scene.h"
#include "umbra/util/math.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

namespace umbra::tracetest {

using testsupport::pointParam;

inline std::shared_ptr<scene::PrimitiveRecord> record(const std::string& type, std::vector<float> floatArgs,
                                                      std::vector<ri::Param> params, const Mat4& worldFromObject,
                                                      bool castsShadows = true) {
    auto r = std::make_shared<scene::PrimitiveRecord>();
    r->type = type;
    r->floatArgs = std::move(floatArgs);
    for (auto& p : params) r->params.add(std::move(p));
    r->worldFromObject = worldFromObject;
    auto attrs = std::make_shared<scene::Attributes>();
    attrs->castsShadows = castsShadows;
    r->attributes = attrs;
    r->loc = FileLoc::inFile("trace.rib", 7, 1);
    return r;
}

inline void add(std::vector<geometry::PrimitivePtr>& prims, std::shared_ptr<scene::PrimitiveRecord> rec) {
    Diagnostics diag;
    auto made = geometry::makePrimitives(std::move(rec), diag);
    EXPECT_EQ(diag.errorCount(), 0);
    EXPECT_FALSE(made.empty());
    for (auto& p : made) prims.push_back(std::move(p));
}

/// A full sphere of radius r centred at `centre` (its own z axis along world z).
inline void addSphere(std::vector<geometry::PrimitivePtr>& prims, float r, const Vec3& centre,
                      bool castsShadows = true) {
    add(prims, record("Sphere", {r, -r, r, 360}, {}, Mat4::translate(centre), castsShadows));
}

/// The square |x|, |z| <= half in the plane y = 0.
inline void addGroundPlane(std::vector<geometry::PrimitivePtr>& prims, float half) {
    add(prims, record("Polygon", {},
                      {pointParam({-half, 0, -half, half, 0, -half, half, 0, half, -half, 0, half})}, Mat4{}));
}

/// Distance from `c` to the nearest point of the segment q + t d, t in [0, tmax].
inline double segmentDistance(const Vec3& q, const Vec3& d, double tmax, const Vec3& c) {
    const double dx = d.x, dy = d.y, dz = d.z;
    const double len2 = dx * dx + dy * dy + dz * dz;
    const double wx = c.x - q.x, wy = c.y - q.y, wz = c.z - q.z;
    const double t = std::clamp((wx * dx + wy * dy + wz * dz) / len2, 0.0, tmax);
    const double ex = wx - t * dx, ey = wy - t * dy, ez = wz - t * dz;
    return std::sqrt(ex * ex + ey * ey + ez * ez);
}

}  // namespace umbra::tracetest
