#pragma once
// Curves and Points (RI spec 3.2 §5.6) as grids.
//
// A curve segment dices into a grid whose v runs along the segment and u
// across its width (RI Spec 3.2): built along the curve (the decision's
// nu), then transposed. Each row is the centreline point C(t) offset by
// -side * width * (u - 1/2), where side is the unit
//  - cross(toward the eye, tangent) for camera-facing ribbons (negated for
//    an inside-out primitive), so dPdu x dPdv, the outward side, faces
//    the pass's eye whatever the transforms (docs/rib.md "Orientation");
//  - cross(N, tangent) when "N" is given (N-oriented ribbons): the outward
//    side is then N, as for any surface with user normals.
// The eye comes from Primitive::diceInView, so a depth pass turns ribbons
// towards its light. dicePositionsInView() gives the ribbon as seen: the
// dicing decision dices along the curve by its screen length and across
// by its screen width (at least one micropolygon, however thin: the hider
// samples it, so a ribbon 0.2 pixel wide covers about a fifth of the
// samples it crosses; a wide one gets several, so a shader that bends the
// normal across it, as a tube, has points to bend).
//
// A point is a square of side "width" facing the eye, drawn by the hider
// as its inscribed disc (Grid::discs).

#include "umbra/geometry/primitive.h"
#include "umbra/geometry/primvars.h"

namespace umbra::geometry {

/// What every segment of one Curves record shares.
struct CurveSet {
    struct Curve {
        int vertexStart = 0, vertexCount = 0;  // into the vertex-class arrays
        int varyingStart = 0, segments = 0;    // varying values: segments (+1 when nonperiodic)
    };
    std::shared_ptr<const SurfaceData> data;
    std::vector<Curve> curves;
    bool cubic = false, periodic = false;
    int vstep = 1;
    float basis[4][4] = {};  // ascending powers: coefficient of t^k from control value i is basis[k][i]
    int widthVar = -1;       // index of "width" in data->vars, or -1
    float constantWidth = 1; // "constantwidth", else 1
    int normalVar = -1;      // index of "N" in data->vars, or -1 (camera-facing)

    /// Index of control value i (0..3 cubic, 0..1 linear) of segment s of
    /// curve c in the vertex-class arrays.
    int control(int c, int s, int i) const;
    /// Index of the varying value at the start (end = 0) or end (1) of segment s.
    int varyingEnd(int c, int s, int end) const;
    /// Interpolates `comps` floats of a vertex-class array (`at(k)` gives
    /// element k) at segment parameter t through the basis; `deriv` also
    /// gets d/dt when not null.
    template <class At>
    void evalVertex(int c, int s, float t, int comps, At at, float* out, float* deriv) const;
};

/// One segment of one curve of a Curves record, or a split piece of it
/// (the range [t0, t1] of the segment's parameter).
class CurveSegment final : public Primitive {
public:
    CurveSegment(std::shared_ptr<const scene::PrimitiveRecord> record, std::shared_ptr<const CurveSet> set, int curve,
                 int segment, float t0 = 0, float t1 = 1);

    /// The hull of the range's Bezier control points, grown by half the
    /// widest width in the range.
    Bound3 bound() const override;
    void split(bool splitU, std::vector<PrimitivePtr>& out) const override;
    int splitsLeft(bool) const override { return ParamRange::spanHalvings(m_t0, m_t1); }
    Grid dice(int nu, int nv) const override { return diceInView(nu, nv, ViewContext{}); }
    Grid diceInView(int nu, int nv, const ViewContext& view) const override;
    void dicePositions(int nu, int nv, std::vector<Vec3>& P) const override;
    /// The ribbon as diceInView() builds it (rows along the curve): the
    /// decision sees its width on screen and dices across it too.
    void dicePositionsInView(int nu, int nv, const ViewContext& view, std::vector<Vec3>& P) const override;

    /// Centreline point and tangent at segment parameter t.
    Vec3 centre(float t, Vec3* tangent = nullptr) const;
    float width(float t) const;

private:
    /// The segment parameter of lattice column i of n (exactly m_t1 at n).
    float paramAt(int i, int n) const { return i == n ? m_t1 : m_t0 + (m_t1 - m_t0) * float(i) / float(n); }

    std::shared_ptr<const CurveSet> m_set;
    int m_curve, m_segment;
    float m_t0, m_t1;
};

/// What every piece of one Points record shares.
struct PointSet {
    std::shared_ptr<const SurfaceData> data;
    int widthVar = -1;
    float constantWidth = 1;
    float width(int k) const;
};

/// The points [first, first + count) of a Points record.
class PointGroup final : public Primitive {
public:
    PointGroup(std::shared_ptr<const scene::PrimitiveRecord> record, std::shared_ptr<const PointSet> set, int first,
               int count);

    Bound3 bound() const override;
    /// Halves the points (whatever the direction).
    void split(bool splitU, std::vector<PrimitivePtr>& out) const override;
    int splitsLeft(bool) const override { return m_count > 1 ? int(std::ceil(std::log2(double(m_count)))) : 0; }
    bool fixedCounts(int* nu, int* nv) const override;
    Grid dice(int nu, int nv) const override { return diceInView(nu, nv, ViewContext{}); }
    /// One square per point (nu, nv are always fixedCounts()).
    Grid diceInView(int nu, int nv, const ViewContext& view) const override;
    void dicePositions(int nu, int nv, std::vector<Vec3>& P) const override;
    /// Each disc's square, its sides the camera's axes: at its centre's depth.
    Bound3 cameraBound(const Mat4& cameraFromObject, bool orthographic) const override;

private:
    std::shared_ptr<const PointSet> m_set;
    int m_first, m_count;
};

/// Curves "linear"|"cubic" [nvertices] "nonperiodic"|"periodic" ...: one
/// CurveSegment per segment. Cubic curves use the v basis and vstep.
void makeCurves(const std::shared_ptr<const scene::PrimitiveRecord>& record, Diagnostics& diag,
                std::vector<PrimitivePtr>& out);
/// Points "P" [...]: one PointGroup for all.
void makePoints(const std::shared_ptr<const scene::PrimitiveRecord>& record, Diagnostics& diag,
                std::vector<PrimitivePtr>& out);

}  // namespace umbra::geometry
