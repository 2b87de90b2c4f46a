#pragma once
// Blobby implicit surfaces (RI spec 3.2 §5.6, `Blobby nleaf code floats
// strings`): the surface where a field, built from primitive *leaves*
// (constants, ellipsoids, segment blobs) combined by a small stack-free
// program (add, multiply, max, min, subtract, divide, negate, identity),
// equals a threshold.
//
// Leaf field, as Aqsis 1.8 evaluates it: a leaf maps object space to its
// own unit space by the inverse of its matrix; at squared unit distance r2
// (from the centre, or from the segment) its field is (1 - r2)^3 inside the
// unit sphere and 0 outside. The surface is where the field equals
// 0.421875 = 0.75^3, so a lone ellipsoid's surface is its unit sphere
// scaled by 1/2 (r = 0.5).
//
// How it is diced (docs/rib.md, "Blobby"): a coarse marching-tetrahedra
// pass over the leaves' support, at a lattice pitch of a third of the
// smallest leaf's surface radius, finds *where* the surface is as
// triangles. Each triangle becomes a parametric piece (BlobbyPiece): a
// point of the flat triangle, at (u, v) of a bilinear patch whose v = 1
// edge is collapsed, is moved onto the iso-surface by Newton steps along
// the field's gradient, and the negated gradient is its outward normal.
// The REYES loop then bounds, splits and dices those pieces like any
// parametric surface, so the dicing rate follows the raster size and the
// shading rate, in the camera pass and in depth passes alike.
//
// A depth-map repelling plane (opcode 1003; PRMan Application Note #31)
// is a leaf whose field is a function of a point's height above the
// surface a depth map stores, measured along the map's view axis: strongly
// negative near that surface, 0 from the cut-off height up, so a Blobby
// *adding* it is pushed away from, e.g., a ground. Its map is read once,
// when the Blobby is made, and shared with other Blobbies naming the same
// unchanged file. Having no support of its own, it acts only inside the
// support box of the other leaves (docs/rib.md, "Blobby").

#include "umbra/geometry/primitive.h"
#include "umbra/geometry/primvars.h"

#include <array>
#include <memory>
#include <string>
#include <vector>

namespace umbra {
struct DepthImage;
}

namespace umbra::geometry {

/// Field value where the surface lies (Aqsis's threshold: 0.75^3, which
/// puts a lone leaf's surface at half its unit radius).
constexpr float kBlobbyThreshold = 0.421875f;

/// The field of one Blobby record: leaves and the instructions combining
/// them, evaluated in object space.
class BlobbyField {
public:
    enum class Op {
        Constant, Ellipsoid, Segment, Plane, Skipped, Add, Multiply, Max, Min, Subtract, Divide, Negate, Identity
    };
    /// A repelling plane's depth map and parameters (defined in blobby.cpp).
    struct Plane;
    struct Instruction {
        Op op = Op::Constant;
        int leaf = -1;                // leaf number (order of appearance) for leaf opcodes
        float constant = 0;           // Constant
        Mat4 leafFromObject;          // Ellipsoid, Segment: into the leaf's unit space
        Vec3 a, b;                    // Segment end points (leaf space, divided by the radius)
        Bound3 support;               // Ellipsoid, Segment, Plane: object-space box outside which the leaf is 0
        std::shared_ptr<const Plane> plane;  // Plane
        std::vector<int> operands;    // instruction indices of earlier results
    };

    /// Reads and validates the code, floats and strings of a Blobby record;
    /// reports problems at record.loc ("Blobby: ...") and returns null.
    /// Reads the depth map of each repelling plane (opcode 1003) once; one
    /// that cannot be read is warned at record.loc and contributes 0.
    static std::shared_ptr<const BlobbyField> fromRecord(const scene::PrimitiveRecord& record, Diagnostics& diag);

    /// The field at object-space `p`; `leafValues` (nleaf entries), when
    /// given, receives each leaf's own field there.
    float value(const Vec3& p, float* leafValues = nullptr) const;
    /// The field's gradient at `p` (exact: each leaf's and operation's
    /// derivative; where max or min is tied, the first operand's).
    Vec3 gradient(const Vec3& p) const;
    /// Moves `p` onto the surface by Newton steps along the gradient, each
    /// step at most `maxStep` long. Returns the point; `outward` (unit,
    /// where the field falls) receives the normal there.
    Vec3 project(const Vec3& p, float maxStep, Vec3* outward) const;

    int leafCount() const { return m_leaves; }
    /// The instructions, in order; a leaf's has `leaf` >= 0.
    const std::vector<Instruction>& code() const { return m_code; }
    /// Where the ellipsoid and segment leaves are non-zero (object space);
    /// repelling planes act only inside it.
    const Bound3& support() const { return m_support; }
    /// The smallest surface radius of any non-constant leaf (object units):
    /// what the coarse lattice must resolve.
    float featureSize() const { return m_feature; }

private:
    float evaluate(const Vec3& p, float* leafValues, Vec3* gradient) const;
    /// The code with every instruction that is identically 0 inside
    /// `region` folded away (exact there).
    static std::vector<Instruction> reduce(const std::vector<Instruction>& code, const Bound3& region);
    void buildBlocks();

    std::vector<Instruction> m_code;
    /// The support cut into blocks, each with its reduced code, so a point
    /// visits only the leaves near it; m_outside for points beyond them.
    std::vector<std::vector<Instruction>> m_blocks;
    std::vector<Instruction> m_outside;
    int m_blockCount[3] = {0, 0, 0};
    Vec3 m_blockSize{1, 1, 1};
    int m_leaves = 0;
    Bound3 m_support;
    float m_feature = kInfinity;
};

/// The coarse triangles of a Blobby and what its pieces share.
struct BlobbyMeshData {
    std::shared_ptr<const BlobbyField> field;
    std::shared_ptr<const SurfaceData> vars;       // per-leaf vertex/varying, uniform, constant
    std::vector<std::array<Vec3, 3>> triangles;    // on the surface, wound so (b-a) x (c-a) points outward
    std::vector<float> pad;                        // per triangle: how far its surface may stand off the flat triangle
    float maxStep = 1;                             // the lattice pitch: the longest Newton step
};

/// Polygonises `field` coarsely (see the file comment). The lattice has at
/// most `maxCells` cells along an axis; when the leaves ask for more, it is
/// capped with a warning at record.loc.
std::shared_ptr<BlobbyMeshData> polygonizeBlobby(const scene::PrimitiveRecord& record,
                                                 std::shared_ptr<const BlobbyField> field, int maxCells,
                                                 Diagnostics& diag);

/// A range of a Blobby's coarse triangles. Not diceable: split() halves
/// the range, and one triangle becomes a BlobbyPiece.
class BlobbyMesh final : public Primitive {
public:
    BlobbyMesh(std::shared_ptr<const scene::PrimitiveRecord> record, std::shared_ptr<const BlobbyMeshData> data,
               int first, int end);
    Bound3 bound() const override { return m_bound; }
    void split(bool splitU, std::vector<PrimitivePtr>& out) const override;
    bool diceable() const override { return false; }
    /// Not to be called (diceable() is false); an internal error.
    Grid dice(int nu, int nv) const override;

private:
    std::shared_ptr<const BlobbyMeshData> m_data;
    int m_first, m_end;
    Bound3 m_bound;
};

/// One coarse triangle (or a parametric part of it) projected onto the
/// iso-surface: a bilinear patch with corners a, b, c, c (RenderMan corner
/// order), each point moved onto the surface.
class BlobbyPiece final : public Primitive {
public:
    BlobbyPiece(std::shared_ptr<const scene::PrimitiveRecord> record, std::shared_ptr<const BlobbyMeshData> data,
                int triangle, const ParamRange& range);
    Bound3 bound() const override;
    void split(bool splitU, std::vector<PrimitivePtr>& out) const override;
    int splitsLeft(bool splitU) const override { return m_range.halvingsLeft(splitU); }
    Grid dice(int nu, int nv) const override;
    void dicePositions(int nu, int nv, std::vector<Vec3>& P) const override;

private:
    Vec3 flatPoint(float u, float v) const;
    std::shared_ptr<const BlobbyMeshData> m_data;
    int m_triangle;
    ParamRange m_range;
};

/// Makes the primitive of a Blobby record (none when it is malformed,
/// reported through `diag`, or has no surface).
void makeBlobby(std::shared_ptr<const scene::PrimitiveRecord> record, Diagnostics& diag,
                std::vector<PrimitivePtr>& out);

/// The coarse triangles of `from` carried to another shape of a deforming
/// Blobby, whose field is `to` (same leaves, in the same order): each corner
/// moves with the ellipsoid and segment leaves it belongs to, weighted by
/// their fields there, and is projected onto `to`'s surface. The first
/// shape's triangles (its topology) serve every shape, so the pieces pair
/// up; blobs that merge or part within the shutter keep the first shape's
/// topology. Null when the leaves differ (`why` says how).
std::shared_ptr<BlobbyMeshData> carryBlobbyMesh(const BlobbyMeshData& from, std::shared_ptr<const BlobbyField> to,
                                                std::string* why);

/// Makes the primitive of a deforming Blobby (MotionBegin around it:
/// `record` is the first shape, record->shapes the others): one
/// DeformingPrimitive whose shapes are the first shape's triangles carried
/// to each (carryBlobbyMesh). A shape whose leaves differ from the first's
/// is reported and the first shape renders unblurred.
void makeDeformingBlobby(std::shared_ptr<const scene::PrimitiveRecord> record, Diagnostics& diag,
                         std::vector<PrimitivePtr>& out);

}  // namespace umbra::geometry
