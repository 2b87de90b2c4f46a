#pragma once
// Subdivision surfaces: SubdivisionMesh "catmull-clark" and "loop",
// evaluated on their limit surface through OpenSubdiv's Bfr API, one base
// face at a time.
//
// A *base face* is a face of the control mesh as written in the RIB. Its
// limit surface has one parameterization (Bfr::Parameterization): a quad
// over [0,1]^2 with corner k of the face at (0,0), (1,0), (1,1), (0,1) in
// face order; a triangle (Loop) over u, v >= 0, u + v <= 1; an N-gon as N
// quad *sub-faces*, sub-face k having face corner k at its (0,0), the
// midpoint of edge k at (1,0), the face centre at (1,1) and the midpoint
// of edge k-1 at (0,1) (the faces of the Catmull-Clark first level).
//
// Orientation: in each of these, u runs from corner k toward corner k+1,
// so dPdu x dPdv points the way the same face written as a polygon has
// dPdu x dPdv (patch.h): a mesh wound as PointsPolygons has the same
// outward side as those polygons (docs/rib.md "Orientation").
//
// Pieces: SubdivMesh (a range of base faces, split in halves until one
// face), then SubdivFace (one face or sub-face and a ParamRange of it,
// split in halves of the range). Everything a face needs (its Bfr
// surfaces) is built once when the mesh splits into faces and shared by
// every piece of that face.

#include "umbra/geometry/primitive.h"
#include "umbra/geometry/primvars.h"

namespace umbra::geometry {

/// The subdivision topology and data of one SubdivisionMesh record (a
/// Far::TopologyRefiner and a thread-safe Bfr surface factory over it),
/// shared by all of its pieces. Defined in subdivision.cpp.
struct SubdivMeshData;
/// The Bfr surfaces of one base face, shared by the pieces of that face.
struct SubdivFaceSurfaces;

/// A range of base faces of a subdivision mesh. Not diceable: split()
/// halves the range, and a single face becomes its SubdivFace (or its N
/// sub-faces for an N-gon; nothing for a hole).
class SubdivMesh final : public Primitive {
public:
    SubdivMesh(std::shared_ptr<const scene::PrimitiveRecord> record, std::shared_ptr<const SubdivMeshData> mesh,
               int firstFace, int endFace);

    Bound3 bound() const override { return m_bound; }
    void split(bool splitU, std::vector<PrimitivePtr>& out) const override;
    bool diceable() const override { return false; }
    /// Not to be called (diceable() is false); an internal error.
    Grid dice(int nu, int nv) const override;

private:
    std::shared_ptr<const SubdivMeshData> m_mesh;
    int m_first, m_end;
    Bound3 m_bound;
};

/// A rectangle `range` of the limit surface of one base face, or of one
/// sub-face `subFace` (>= 0) of an N-gon in its normalized [0,1]^2.
class SubdivFace final : public Primitive {
public:
    SubdivFace(std::shared_ptr<const scene::PrimitiveRecord> record, std::shared_ptr<const SubdivMeshData> mesh,
               std::shared_ptr<const SubdivFaceSurfaces> surfaces, int face, int subFace, const ParamRange& range);

    /// The bound of the face's patch points (which contain its limit
    /// surface) when the piece covers its whole face or sub-face; for
    /// smaller ranges, that bound clipped to a padded bound of the range's
    /// limit points (see docs/subdivision.md).
    Bound3 bound() const override { return m_bound; }
    /// An N-gon's whole face splits into its N sub-faces; anything else
    /// halves its range.
    void split(bool splitU, std::vector<PrimitivePtr>& out) const override;
    int splitsLeft(bool splitU) const override { return diceable() ? m_range.halvingsLeft(splitU) : kManySplits; }
    bool diceable() const override;
    Grid dice(int nu, int nv) const override;
    void dicePositions(int nu, int nv, std::vector<Vec3>& P) const override;

    /// Limit position (and first derivatives, when dPdu and dPdv are not
    /// null) at (u, v) of this piece's face or sub-face, in the coordinates
    /// `range` is given in.
    Vec3 evaluate(float u, float v, Vec3* dPdu = nullptr, Vec3* dPdv = nullptr) const;

    int face() const { return m_face; }
    int subFace() const { return m_subFace; }
    const ParamRange& range() const { return m_range; }

private:
    // The face's Bfr parameter of (u, v) of this piece's face or sub-face.
    void faceCoord(float u, float v, float uv[2]) const;

    std::shared_ptr<const SubdivMeshData> m_mesh;
    std::shared_ptr<const SubdivFaceSurfaces> m_surfaces;
    int m_face, m_subFace;
    ParamRange m_range;
    Bound3 m_bound;
};

/// Builds the SubdivMesh of a SubdivisionMesh record (scheme, nvertices,
/// vertices, tags, nargs, intargs, floatargs; RI spec 3.2 §5.6), reporting
/// malformed records and unknown tags with the record's location.
///
/// With `blockSide` > 1, a Catmull-Clark mesh whose variables are all of
/// vertex or constant class also gives its regular regions as BicubicBlocks
/// (geometry/patch.h): a face all of whose corners are smooth interior
/// vertices of valence 4 among quads and no holes is exactly the uniform
/// bicubic B-spline patch of the 16 vertices around it, and up to
/// blockSide x blockSide such faces whose parameterisations line up are diced as one grid. A
/// block's grid u, v run over [0, columns] x [0, rows] (face by face, each
/// face's own u, v plus its offset), so the caller allows it only where no
/// shader reads u, v, s or t and nothing displaces (ParameterReaders).
void makeSubdivisionMesh(const std::shared_ptr<const scene::PrimitiveRecord>& record, Diagnostics& diag,
                         std::vector<PrimitivePtr>& out, int blockSide = 0);

}  // namespace umbra::geometry
