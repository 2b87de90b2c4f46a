#pragma once
// Exact reference shadows: shadow rays traced with Embree against a fine
// world-space tessellation of every shadow-casting primitive.
//
// This is the measuring stick for depth-map shadows (issue 5) and the
// engine behind shadow("raytrace", Ps, ...), as Pixie offers it. It answers
// one question per ray: is anything between a point and a light?
//
// Tessellation. Each primitive is diced in WORLD space finely enough that
// the distance between the true surface and its triangles (the chord
// error) stays below a tolerance (TessellationOptions): the rate is chosen
// from second differences of a test lattice of world positions. Vertices
// lie on the true surface, so a convex blocker's triangles lie inside it by
// at most the tolerance and its shadow shrinks by at most that much. A
// primitive whose rate exceeds maxGridSide is split into halves that all
// keep the same per-piece rate, so the pieces' grids meet vertex to vertex
// (no T-junction cracks a ray could slip through). The faces of a split
// mesh choose their rates one by one: planar faces meet exactly, but two
// curved faces diced at different rates may leave a sliver no wider than
// the tolerance along their shared edge. Displacement shaders and
// motion blur are not applied: the reference sees the undisplaced surface.
// Rays hit both sides of every triangle: `Sides 1` and solids do not cull
// shadow casters, as in RenderMan's ray-traced shadows.
//
// Self-intersection. A shadow ray starts on the surface it shades, and that
// surface's triangles may pass a chord error above or below the point. Rays
// therefore start `epsilon` along the surface normal on the side facing the
// light (when the caller passes a normal) and ignore hits closer than
// `epsilon`. The default epsilon (rayEpsilon()) is twice the largest chord
// error of the tessellation, and at least 1e-6 of the scene's extent (its
// diagonal or largest coordinate: float precision); for a point on a convex surface facing the light this offset
// clears its own triangles whatever the ray's angle.

#include "umbra/geometry/primitive.h"
#include "umbra/scene/scene.h"
#include "umbra/util/error.h"
#include "umbra/util/math.h"

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

namespace umbra::trace {

/// How finely OcclusionScene tessellates. The chord-error limit of a
/// primitive is min(absoluteTolerance, relativeTolerance * the diagonal of
/// its world-space bound), but never below 1e-6 of that diagonal (float
/// precision); the pieces of a split primitive inherit its limit. The
/// defaults keep a unit sphere's triangles within 3.5e-4 of it, far below
/// one pixel at 512x512.
struct TessellationOptions {
    float relativeTolerance = 1e-4f;
    float absoluteTolerance = kInfinity;   // world units
    int maxGridSide = 256;                 // micropolygons along u or v diced at once; more splits
    /// Cap on the micropolygons of one diceable primitive (or one face of a
    /// split mesh); past it the rate is lowered with a warning rather than
    /// exhausting memory.
    int64_t maxMicropolygonsPerPrimitive = int64_t(1) << 22;
    int testLattice = 16;                  // lattice (per side) on which curvature is measured
};

/// A dicing rate and the chord error it is expected to leave.
struct DiceRate {
    int nu = 1, nv = 1;
    float chordError = 0;                  // world units, estimated
};

/// Chooses the dicing rate of a surface from an (m+1) x (m+1) lattice of its
/// WORLD-space positions (row after row, u fastest, as Grid stores them)
/// so that the estimated chord error of the micropolygons' triangles,
/// h^2 |P_uu| / 8 + h^2 |P_vv| / 8 + h_u h_v |P_uv| / 4 with the derivatives
/// taken from the lattice's second differences, is at most `tolerance`.
DiceRate chooseDiceRate(const Vec3* lattice, int m, float tolerance);

/// Where a shadow ray goes: to a light's position (point and spot lights)
/// or towards a light at infinity (distant lights). World space.
struct LightTarget {
    Vec3 v;                  // position, or unit direction from the scene towards the light
    bool atInfinity = false;

    static LightTarget point(const Vec3& worldPosition) { return {worldPosition, false}; }
    /// `lightDirection` is the direction the light travels (distantlight's
    /// `to - from`); shadow rays go the opposite way.
    static LightTarget distant(const Vec3& lightDirection) { return {normalize(-lightDirection), true}; }
};

/// A committed Embree scene of the shadow casters of one world, queried
/// for exact shadow-ray visibility. Built once; every query is const and
/// safe to call from any number of threads at once.
class OcclusionScene {
public:
    /// Tessellates `primitives` (object space, placed by their records'
    /// worldFromObject), skipping those whose attributes say castsShadows =
    /// false, and builds the acceleration structure. `diag` (optional) gets
    /// warnings about primitives left out or coarsened, and Embree errors.
    explicit OcclusionScene(const std::vector<geometry::PrimitivePtr>& primitives,
                            const TessellationOptions& options = {}, Diagnostics* diag = nullptr);
    ~OcclusionScene();
    OcclusionScene(const OcclusionScene&) = delete;
    OcclusionScene& operator=(const OcclusionScene&) = delete;

    /// True when a triangle lies on the segment from `from` to `to` (world
    /// space), ignoring the first and last `tnearEpsilon` world units of it.
    bool occluded(const Vec3& from, const Vec3& to, float tnearEpsilon) const;
    /// True when a triangle lies on the ray from `from` along `direction`
    /// (any length) between `tnearEpsilon` and `tfar` world units.
    bool occludedAlong(const Vec3& from, const Vec3& direction, float tnearEpsilon, float tfar = kInfinity) const;

    /// 1 when `P` is in shadow from `light`, 0 when it sees it. `N`
    /// (optional, any length or orientation) is the surface normal at P:
    /// the ray starts `epsilon` off the surface on the side facing the
    /// light. A negative epsilon means rayEpsilon().
    float shadowFraction(const Vec3& P, const LightTarget& light, const Vec3* N = nullptr,
                         float epsilon = -1) const;
    /// shadowFraction for `count` points at once (N may be null), written to
    /// outShadowed[0..count). Rays to one light from one grid are coherent
    /// and traced as a stream.
    void occludedBatch(int count, const Vec3* P, const Vec3* N, const LightTarget& light, float* outShadowed,
                       float epsilon = -1) const;

    /// The default ray offset (see the file comment), world units.
    float rayEpsilon() const { return m_rayEpsilon; }
    /// Largest estimated chord error of any primitive's tessellation, world units.
    float maxChordError() const { return m_maxChordError; }
    size_t triangleCount() const { return m_indices.size() / 3; }
    size_t vertexCount() const { return m_vertexCount; }
    /// World-space bound of the triangles (empty without any).
    const Bound3& bound() const { return m_bound; }

private:
    struct Embree;
    std::unique_ptr<Embree> m_embree;
    std::vector<float> m_vertices;     // x y z per vertex, plus one float of padding Embree reads past the end
    std::vector<uint32_t> m_indices;   // three per triangle
    size_t m_vertexCount = 0;
    Bound3 m_bound;
    float m_rayEpsilon = 0;
    float m_maxChordError = 0;
};

/// Makes the primitives of every record of `world` (malformed records are
/// reported to `diag` and left out) and builds their OcclusionScene: the
/// quality study's entry point when no renderer has made primitives yet.
std::unique_ptr<OcclusionScene> buildOcclusionScene(const scene::WorldRecord& world, Diagnostics& diag,
                                                    const TessellationOptions& options = {});

}  // namespace umbra::trace
