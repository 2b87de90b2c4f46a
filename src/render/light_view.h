#pragma once
// Depth-map views of lights: the first pass of a shadowed frame (Reeves et
// al. 1987 §3). A light whose "shadowname" is "auto" gets its map rendered
// inside the frame, before the camera pass, from a view derived from the
// light itself:
//   spot lights      perspective from "from" towards "to", the cone
//                    (coneangle + conedeltaangle) filling the map
//   distant lights   orthographic along from->to, fitted to the bound of
//                    every shadow-casting primitive
//   point lights     six perspective faces of a cube around "from", stored
//                    as one multi-part map
// and a resolution from Option "umbra" "shadowmapsize" (default: the larger
// side of the image, as Reeves recommends).

#include "render/frame.h"

#include "umbra/film/film.h"
#include "umbra/geometry/primitive.h"
#include "umbra/shadow/depth_image.h"

#include <array>
#include <optional>
#include <string>
#include <vector>

namespace umbra::render {

/// The kinds of light umbra can derive a depth-map view for.
enum class LightShape { Spot, Distant, Point, Unknown };

/// Where a light is and where it points, in world space, read from its
/// shader parameters (or the shader's defaults).
struct LightGeometry {
    LightShape shape = LightShape::Unknown;
    Vec3 from{0, 0, 0}, to{0, 0, 1};
    float coneAngle = radians(30), coneDelta = radians(5);
};

/// Reads a light's geometry from its record and compiled shader.
LightGeometry lightGeometry(const scene::LightRecord& light, const shading::Shader* shader);

/// The view of a depth pass for `light`, or nothing (with a warning) when
/// umbra cannot derive one. Point lights use cubeFacePasses instead.
std::optional<Pass> lightPass(const LightGeometry& light, const std::vector<geometry::PrimitivePtr>& prims,
                              int resolution, const std::string& name, Diagnostics& diag, const FileLoc& loc);

/// The six 90-degree views of a point light's cube map, in the face order
/// of writeCubeDepthMap (+x -x +y -y +z -z).
std::array<Pass, 6> cubeFacePasses(const LightGeometry& light, int resolution, const std::string& name);

/// A camera at `from` looking at `to` (RenderMan's left-handed camera
/// space: +z along the view, +y as close to world +y as possible).
Mat4 lookAt(const Vec3& from, const Vec3& to);

/// The depth image of a depth-mode film, with the pass's matrices, reduced
/// to one layer by `filter` (see docs/shadows.md for single-layer pixels).
/// A pass that culled the light-facing surfaces of solids already made the
/// nearest remaining surface the second depth (Wang & Molnar's culling), so
/// "second" then stores that.
DepthImage depthImageOf(const film::Film& film, const Pass& pass, DepthFilter filter, float dualOffset);
/// The same, the film's nearest-depth plane becoming the image's (no copy)
/// when the film covers the whole image.
DepthImage depthImageOf(film::Film&& film, const Pass& pass, DepthFilter filter, float dualOffset);

}  // namespace umbra::render
