#pragma once
// Polygons: Polygon, GeneralPolygon, PointsPolygons, PointsGeneralPolygons.
//
// A polygon is not diced directly. Each face is reduced to pieces a grid
// can cover (BilinearPatch): a triangle becomes a bilinear patch with one
// collapsed edge, a convex quad a bilinear patch, a convex n-gon a fan of
// quads (and one triangle when n is odd), and a concave face or a face
// with holes the triangles of a triangulation: ear clipping up to 64
// vertices, a plane sweep into monotone pieces (O(n log n)) above that. Vertex and
// varying variables are indexed through the face's vertex indices,
// facevarying ones through its face-corner numbers, uniform ones by face.

#include "umbra/geometry/patch.h"
#include "umbra/geometry/primitive.h"
#include "umbra/geometry/primvars.h"

#include <array>

namespace umbra::geometry {

/// The faces of one polygon record: for each face its loops (the first is
/// the outline, the rest holes) and the vertex index of each corner.
struct PolygonFaces {
    std::vector<int> faceLoopStart;    // per face, into loopSize; one extra entry at the end
    std::vector<int> loopSize;         // corners per loop
    std::vector<int> faceCornerStart;  // per face, into `vertices` (= its first facevarying index); one extra entry
    std::vector<int> vertices;         // vertex index of each face corner, faces one after another

    int faceCount() const { return int(faceCornerStart.size()) - 1; }
};

/// A range of faces of a polygon record. Not diceable: split() halves the
/// range, and a single face splits into its pieces.
class PolygonMesh final : public Primitive {
public:
    PolygonMesh(std::shared_ptr<const scene::PrimitiveRecord> record, std::shared_ptr<const SurfaceData> data,
                std::shared_ptr<const PolygonFaces> faces, int firstFace, int endFace);

    Bound3 bound() const override { return m_bound; }
    void split(bool splitU, std::vector<PrimitivePtr>& out) const override;
    bool diceable() const override { return false; }
    /// Not to be called (diceable() is false); an internal error.
    Grid dice(int nu, int nv) const override;

private:
    std::shared_ptr<const SurfaceData> m_data;
    std::shared_ptr<const PolygonFaces> m_faces;
    int m_first, m_end;
    Bound3 m_bound;
};

/// Appends the pieces of face `f`; false (nothing appended) when the face
/// is degenerate (fewer than three corners or no area). A face that is not
/// a simple polygon is warned about through `diag` when there is one (at
/// scene build time; splits during the render pass none).
bool appendFacePieces(const std::shared_ptr<const scene::PrimitiveRecord>& record,
                      const std::shared_ptr<const SurfaceData>& data, const PolygonFaces& faces, int f,
                      std::vector<PrimitivePtr>& out, Diagnostics* diag = nullptr);

/// Largest polygon (all loops together) triangulated by ear clipping,
/// which is simple and cheap there; larger ones take the plane sweep.
constexpr size_t kEarClippingMaxVertices = 64;

/// Triangulates a planar polygon with holes: up to kEarClippingMaxVertices
/// by ear clipping (holes first bridged to the outline), above that in
/// O(n log n) by a plane sweep into y-monotone pieces, each cut by a stack
/// walk, the result checked against the polygon's area. `points` holds the
/// loops one after another, `loopSizes` their lengths (first = outline).
/// Triangles index `points` and keep the outline's winding. Returns false
/// when the input is not a simple polygon (edges crossing or repeated,
/// holes outside): ear clipping keeps the triangles it found, the sweep
/// gives a fan of the outline from its first vertex.
bool triangulatePolygon(const std::vector<Vec3>& points, const std::vector<int>& loopSizes,
                        std::vector<std::array<int, 3>>& triangles);

}  // namespace umbra::geometry
