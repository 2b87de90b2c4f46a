#pragma once
// Internal to the geometry module: where the C binding (geometry/ri.h) sends
// a DynamicLoad DSO's calls while its Subdivide runs.

#include "umbra/ri/target.h"
#include "umbra/util/error.h"

namespace umbra::geometry {

/// While alive, this thread's Ri calls go to `target` (a procedural's
/// expansion), located at `loc` and reported to `diag`.
class RiCallbackScope {
public:
    RiCallbackScope(ri::Target& target, Diagnostics& diag, const FileLoc& loc);
    ~RiCallbackScope();
    RiCallbackScope(const RiCallbackScope&) = delete;
    RiCallbackScope& operator=(const RiCallbackScope&) = delete;
};

}  // namespace umbra::geometry
