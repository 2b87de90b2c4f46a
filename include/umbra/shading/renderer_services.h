#pragma once
// The boundary between shaders and the renderer (OSL's RendererServices):
// everything a shader needs that the shading system does not own itself --
// named coordinate systems, shadow maps, attributes and options -- goes
// through this interface, so the shading module never includes the
// renderer's headers.

#include "umbra/util/error.h"
#include "umbra/util/math.h"

#include <cstdint>
#include <string>
#include <vector>

namespace umbra::shading {

class ShadingGrid;

/// The value types of the shading language, as seen from outside.
enum class ValueType { Float, Color, Point, Vector, Normal, Matrix, String };
const char* valueTypeName(ValueType t);
/// Floats per value: 1, 3 or 16 (0 for strings).
int valueTypeFloats(ValueType t);

/// A named uniform value passed across the boundary: an optional
/// "name", value pair of a shadow() call, or the answer to attribute(),
/// option() or rendererinfo().
struct ShadeValue {
    std::string name;
    ValueType type = ValueType::Float;
    std::vector<float> floats;   // valueTypeFloats(type) * array length
    std::vector<std::string> strings;

    float floatOr(float def) const { return floats.empty() ? def : floats[0]; }
};

/// One vectorised shadow() lookup over the active points of a grid. All
/// positions and vectors are in "current" (camera) space.
struct ShadowQuery {
    std::string mapName;
    /// The shadow() call in its shader's source (file, line, column), for
    /// messages; the file is the compiled shader's, alive while it runs.
    const std::string* callFile = nullptr;
    int callLine = 0, callColumn = 0;
    /// Number of points and their vertex indices in the grid.
    int count = 0;
    const int* indices = nullptr;
    /// Per point k in [0, count) (the point at grid vertex indices[k]):
    /// the shadowed position, and the micropolygon footprint as Du(P)*du and
    /// Dv(P)*dv of the shadow() call's point argument. Compact, so that a
    /// renderer can hand them to its lookup without copying.
    const Vec3* P = nullptr;
    const Vec3* dPdu = nullptr;
    const Vec3* dPdv = nullptr;
    /// The shading normal N at each point (second-depth maps).
    const Vec3* N = nullptr;
    /// Inside illuminate()/solar() of a light shader: L at each point (from
    /// the light towards the point, current space), and whether the light
    /// is at infinity (solar). shadow("raytrace", ...) traces towards the
    /// light with them. Null outside those constructs.
    const Vec3* L = nullptr;
    bool lightAtInfinity = false;
    /// The four-point form shadow(name, P1, P2, P3, P4): the corners of the
    /// region; null for the one-point form.
    const Vec3* corners[4] = {nullptr, nullptr, nullptr, nullptr};
    /// The optional parameters of the call ("samples", "width", "swidth",
    /// "twidth", "blur", "bias", "bias0", "bias1", "minsamples", "minsize",
    /// "filter", "method", and any other name, passed through). The standard
    /// shadow lights always pass samples, width, blur, bias, bias0, bias1;
    /// their defaults give bias = bias0 = bias1 = 0, which a service should
    /// read as "use the renderer's default bias".
    std::vector<ShadeValue> params;
    /// A seed for stochastic sampling, from the grid's identity and the call.
    uint32_t seed = 0;
};

/// Services the renderer provides to running shaders. One object may serve
/// every grid; `grid.renderState()` carries the renderer's own per-grid
/// pointer (primitive, attributes). Calls come from many threads at once.
class RendererServices {
public:
    virtual ~RendererServices() = default;

    /// The matrix taking points in the named space to "current" (camera)
    /// space at this grid: "world", "object", "camera", "screen",
    /// "raster", "NDC" or a CoordinateSystem name. "current" and "shader"
    /// are handled by the shading system. False if the space is unknown.
    virtual bool getMatrix(const ShadingGrid& grid, const std::string& space, Mat4* currentFromSpace) = 0;

    /// Fraction in shadow (0 = lit, 1 = fully shadowed) of each queried
    /// point k, written to `result[k]` (k in [0, query.count)).
    /// Returning false means "no such map": shadow() then yields 0
    /// (unshadowed) and the renderer reports the failure (once).
    virtual bool shadow(const ShadingGrid& grid, const ShadowQuery& query, float* result) { return false; }

    /// Where the grid's primitive was given (its RIB file:line:column), for
    /// messages about what its shaders looked up; unknown by default.
    virtual FileLoc primitiveLocation(const ShadingGrid& grid) { return {}; }

    /// attribute("name", var), option("name", var), rendererinfo("name", var):
    /// fill `out` (its type is what the shader asked for) and return true,
    /// or return false when unknown.
    virtual bool attribute(const ShadingGrid& grid, const std::string& name, ShadeValue* out) { return false; }
    virtual bool option(const std::string& name, ShadeValue* out) { return false; }
    virtual bool rendererInfo(const std::string& name, ShadeValue* out);

    /// Output of printf() in shaders (stdout by default).
    virtual void print(const std::string& text);
};

}  // namespace umbra::shading
