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

/// Evaluates a power-basis bicubic with `comps` components ([k][l][comp]
/// layout) over the grid of parameters a (columns) x b (rows) into `out`
/// (row after row, `comps` floats per vertex).
void evalBicubicGrid(const float* c, int comps, const std::vector<float>& a, const std::vector<float>& b, float* out);

}  // namespace umbra::geometry
