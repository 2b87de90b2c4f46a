#pragma once
// Builders for primitive records in tests (the RIB parser is not involved),
// and measurements of diced grids computed independently of the code under test.

#include "support/params.h"
#include "umbra/geometry/grid.h"
#include "umbra/geometry/primitive.h"
#include "umbra/scene/scene.h"

#include <memory>
#include <string>
#include <vector>

namespace umbra::testutil {

using testsupport::floatParam;
using testsupport::pointParam;

inline std::shared_ptr<scene::PrimitiveRecord> record(const std::string& type, std::vector<float> floatArgs = {},
                                                      std::vector<ri::Param> params = {}) {
    auto r = std::make_shared<scene::PrimitiveRecord>();
    r->type = type;
    r->floatArgs = std::move(floatArgs);
    for (auto& p : params) r->params.add(std::move(p));
    r->attributes = std::make_shared<scene::Attributes>();
    r->loc = FileLoc::inFile("test.rib", 3, 1);
    return r;
}

/// Sum of micropolygon areas (each cell as two triangles).
inline double gridArea(const geometry::Grid& g) {
    double a = 0;
    for (int j = 0; j < g.nv; ++j)
        for (int i = 0; i < g.nu; ++i) {
            const Vec3 p00 = g.P[g.index(i, j)], p10 = g.P[g.index(i + 1, j)];
            const Vec3 p01 = g.P[g.index(i, j + 1)], p11 = g.P[g.index(i + 1, j + 1)];
            a += 0.5 * double(length(cross(p10 - p00, p11 - p00))) + 0.5 * double(length(cross(p11 - p00, p01 - p00)));
        }
    return a;
}

/// Splits every non-diceable primitive until all are diceable.
inline std::vector<geometry::PrimitivePtr> splitToDiceable(std::vector<geometry::PrimitivePtr> prims) {
    std::vector<geometry::PrimitivePtr> done;
    while (!prims.empty()) {
        geometry::PrimitivePtr p = std::move(prims.back());
        prims.pop_back();
        if (p->diceable()) done.push_back(std::move(p));
        else p->split(true, prims);
    }
    return done;
}

inline double totalArea(const std::vector<geometry::PrimitivePtr>& prims, int n) {
    double a = 0;
    for (const auto& p : prims) a += gridArea(p->dice(n, n));
    return a;
}

inline bool inside(const Bound3& b, const Vec3& p, float eps) {
    return p.x >= b.min.x - eps && p.y >= b.min.y - eps && p.z >= b.min.z - eps && p.x <= b.max.x + eps &&
           p.y <= b.max.y + eps && p.z <= b.max.z + eps;
}

}  // namespace umbra::testutil
