#pragma once
// Parametric patches: bilinear (also every polygon face once reduced to
// quads and triangles) and bicubic with any RenderMan basis (RI spec 3.2
// §5.5), single or from a PatchMesh.
//
// Orientation: dPdu x dPdv follows the right-hand rule over corners
// 0 -> 1 -> 3 -> 2 (see primvars.h for the corner layout); a polygon face
// (p0 p1 p2 ...) becomes corners (p0, p1, p3, p2), so dPdu x dPdv has the
// direction of the polygon's (p1 - p0) x (p2 - p0). Grid::N is left empty
// unless the record gives "N": the renderer derives normals from P.

#include "umbra/geometry/primitive.h"
#include "umbra/geometry/primvars.h"

#include <array>

namespace umbra::geometry {

/// A bilinear patch over four corners (possibly with two coinciding: a
/// triangle), or a split piece of one.
class BilinearPatch final : public Primitive {
public:
    BilinearPatch(std::shared_ptr<const scene::PrimitiveRecord> record, std::shared_ptr<const SurfaceData> data,
                  const CornerRefs& refs, const ParamRange& range = {}, const ParamMap& map = {});

    Bound3 bound() const override;
    void split(bool splitU, std::vector<PrimitivePtr>& out) const override;
    int splitsLeft(bool splitU) const override { return m_range.halvingsLeft(splitU); }
    Grid dice(int nu, int nv) const override;
    void dicePositions(int nu, int nv, std::vector<Vec3>& P) const override;
    bool flatQuad() const override { return m_flatQuad; }

    const CornerRefs& corners() const { return m_refs; }
    const ParamRange& range() const { return m_range; }

private:
    void evalPositions(const std::vector<float>& a, const std::vector<float>& b, Vec3* P) const;
    /// The homogeneous corner positions, read from the shared data rather
    /// than kept: a scene of 10^6 polygons holds 10^6 patches at once.
    void cornerPositions(float corner[4][4]) const;

    std::shared_ptr<const SurfaceData> m_data;
    CornerRefs m_refs;
    ParamRange m_range;
    ParamMap m_map;
    bool m_flatQuad = false;
};

/// A bicubic patch converted once to the power basis: each value is
/// sum_{k,l} c[k][l] u^k v^l on the patch's own [0,1]^2. Shared by every
/// split piece of the patch.
struct BicubicCoeffs {
    int posDim = 3;
    float pos[4][4][4];            // [k][l][component], homogeneous when posDim == 4
    float posDu[4][4][4];          // the same of d/du and d/dv (the top power 0)
    float posDv[4][4][4];
    struct Var {
        int index;                 // into SurfaceData::vars
        std::vector<float> c;      // [k][l][component], 16 * components
    };
    std::vector<Var> vertexVars;   // vertex-class variables, interpolated with the basis like P

    /// From 16 control values per variable (u varying fastest, as the RIB
    /// gives them) picked by `ctrl` from the record's arrays.
    static std::shared_ptr<const BicubicCoeffs> make(const SurfaceData& sd, const std::array<int, 16>& ctrl,
                                                     const scene::Basis& uBasis, const scene::Basis& vBasis);
};

/// A bicubic patch (or a split piece of one).
class BicubicPatch final : public Primitive {
public:
    BicubicPatch(std::shared_ptr<const scene::PrimitiveRecord> record, std::shared_ptr<const SurfaceData> data,
                 std::shared_ptr<const BicubicCoeffs> coeffs, const CornerRefs& refs, const ParamRange& range = {},
                 const ParamMap& map = {});

    /// The convex hull bound: the sub-range's coefficients re-expressed as
    /// Bezier control points, which contain the surface whatever the
    /// original basis (for rational patches: when all weights are positive).
    Bound3 bound() const override;
    void split(bool splitU, std::vector<PrimitivePtr>& out) const override;
    int splitsLeft(bool splitU) const override { return m_range.halvingsLeft(splitU); }
    Grid dice(int nu, int nv) const override;
    void dicePositions(int nu, int nv, std::vector<Vec3>& P) const override;

    /// Object-space point at (u, v) of the patch's own domain.
    Vec3 evaluate(float u, float v) const;
    const ParamRange& range() const { return m_range; }

private:
    std::shared_ptr<const SurfaceData> m_data;
    std::shared_ptr<const BicubicCoeffs> m_coeffs;
    CornerRefs m_refs;
    ParamRange m_range;
    ParamMap m_map;
};

/// A rectangular array of adjacent bicubic patches of one record, row
/// after row (patch (i, j) at j * columns + i), e.g. the patches of a
/// bicubic PatchMesh: what BicubicBlock pieces share. Patch (i, j) reports
/// u = (i + a) * uScale, v = (j + b) * vScale at its own (a, b).
struct BicubicPatchArray {
    std::shared_ptr<const SurfaceData> sd;
    int columns = 0, rows = 0;
    std::vector<std::shared_ptr<const BicubicCoeffs>> coeffs;
    std::vector<CornerRefs> refs;
    std::vector<Bound3> bounds;  // each patch's hull bound (BicubicPatch::bound of the whole patch)
    float uScale = 1, vScale = 1;

    size_t index(int i, int j) const { return size_t(j) * size_t(columns) + size_t(i); }
    ParamMap map(int i, int j) const { return {float(i) * uScale, uScale, float(j) * vScale, vScale}; }
    /// Whether a block of these patches interpolates every variable of `sd`
    /// exactly as its patches would one by one: no uniform (one value per
    /// patch) and no facevarying (four per patch, discontinuous across
    /// patch edges) variables, which a single grid cannot carry.
    static bool blockable(const SurfaceData& sd);
};

/// A block of adjacent whole patches [i0, i1) x [j0, j1) of a
/// BicubicPatchArray (same basis) treated as one primitive: its bound is
/// the union of its patches' hull bounds, it splits across its longer side
/// (as asked, when it can) into sub-blocks and, once one patch, into that
/// BicubicPatch's halves, and it dices into one grid spanning the block.
/// Grid vertex i along u lies at i * (i1 - i0) / nu patch widths from the
/// block's edge, on the patch it falls in (the earlier one on a shared
/// edge); every variable there is what that patch's own dicing gives. A
/// block of 8 x 8 tiny patches is one grid instead of 64.
class BicubicBlock final : public Primitive {
public:
    BicubicBlock(std::shared_ptr<const scene::PrimitiveRecord> record, std::shared_ptr<const BicubicPatchArray> patches,
                 int i0, int j0, int i1, int j1);

    Bound3 bound() const override { return m_bound; }
    void split(bool splitU, std::vector<PrimitivePtr>& out) const override;
    Grid dice(int nu, int nv) const override;
    void dicePositions(int nu, int nv, std::vector<Vec3>& P) const override;

    int columns() const { return m_i1 - m_i0; }
    int rows() const { return m_j1 - m_j0; }

    /// Appends the pieces of patches [i0, i1) x [j0, j1): a BicubicBlock,
    /// or the BicubicPatch when it is one patch.
    static void appendPiece(const std::shared_ptr<const scene::PrimitiveRecord>& record,
                            const std::shared_ptr<const BicubicPatchArray>& patches, int i0, int j0, int i1, int j1,
                            std::vector<PrimitivePtr>& out);
    /// Tiles the whole array with blocks of at most maxSide x maxSide
    /// patches (as even as can be) and appends them.
    static void appendBlocks(const std::shared_ptr<const scene::PrimitiveRecord>& record,
                             const std::shared_ptr<const BicubicPatchArray>& patches, int maxSide,
                             std::vector<PrimitivePtr>& out);

private:
    /// The homogeneous values of one table of every patch's coefficients
    /// (BicubicCoeffs::pos, posDu or posDv) at the block's nu x nv lattice,
    /// 4 floats a vertex.
    void lattice(int nu, int nv, float (BicubicCoeffs::*table)[4][4][4], std::vector<float>& h) const;
    /// P at the lattice; `h` keeps their homogeneous values.
    void positions(int nu, int nv, Vec3* P, std::vector<float>& h) const;

    std::shared_ptr<const BicubicPatchArray> m_patches;
    int m_i0, m_j0, m_i1, m_j1;
    Bound3 m_bound;
};

/// The hull bound of `range` of a bicubic patch: its coefficients over the
/// range re-expressed as Bezier control points, padded for rounding.
Bound3 bicubicHullBound(const BicubicCoeffs& coeffs, const ParamRange& range);

/// Evaluates a power-basis bicubic with `comps` components ([k][l][comp]
/// layout) over the grid of parameters a (columns) x b (rows) into `out`
/// (row after row, `comps` floats per vertex).
void evalBicubicGrid(const float* c, int comps, const std::vector<float>& a, const std::vector<float>& b, float* out);
/// evalBicubicGrid() over na columns and nb rows whose rows start
/// `rowStride` floats apart in `out`.
void evalBicubicRect(const float* c, int comps, const float* a, int na, const float* b, int nb, float* out,
                     size_t rowStride);

}  // namespace umbra::geometry
