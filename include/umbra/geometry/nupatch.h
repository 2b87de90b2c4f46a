#pragma once
// Non-uniform rational B-spline patches: NuPatch (RI spec 3.2 §5.4), of
// any order in u and v, with "P" or homogeneous "Pw" control points and a
// partial parameter range umin umax vmin vmax.
//
// A NuPatch is cut at its knots into *spans*, the rectangles of the knot
// grid where the surface is one polynomial (rational) patch. Each span is
// converted once, by blossoming, to a rational Bezier patch of degree
// (uorder-1, vorder-1): its control points bound the span (and, re-expressed
// over a sub-range, any piece of it) whenever the weights are positive.
//
// Parameters: the grid's u, v are knot values (so trim curves, given in
// the same space, apply directly). Primitive variables: vertex class uses
// the B-spline basis (non-rational, as BicubicPatch does); varying,
// facevarying (one per segment corner, (nu-uorder+2)*(nv-vorder+2)) and
// uniform (one per segment) are bilinear / constant over each segment, a
// segment being the span between two consecutive knots (zero-length ones
// included in the counts, as the spec counts them).
//
// Orientation: control point (i, j) is entry j * nu + i, u fastest, as in
// Patch; dPdu x dPdv is the outward side, so an order-4 NuPatch with knots
// 0 0 0 0 1 1 1 1 is the `Patch "bicubic"` of the same points.

#include "umbra/geometry/primitive.h"
#include "umbra/geometry/primvars.h"
#include "umbra/geometry/trim.h"

namespace umbra::geometry {

/// One span of a NuPatch as a rational Bezier patch over the span's own
/// corner domain [0,1]^2. Shared by every split piece of the span.
struct BezierSpan {
    int degU = 3, degV = 3;
    int posDim = 3;
    /// (degV+1) rows of (degU+1) homogeneous points (4 floats), u fastest.
    std::vector<float> pos;
    struct Var {
        int index;             // into SurfaceData::vars
        std::vector<float> c;  // (degV+1)(degU+1) values of `components` floats, u fastest
    };
    std::vector<Var> vertexVars;
};

/// A NuPatch span, or a split piece of one.
class NuPatch final : public Primitive {
public:
    NuPatch(std::shared_ptr<const scene::PrimitiveRecord> record, std::shared_ptr<const SurfaceData> data,
            std::shared_ptr<const BezierSpan> span, const CornerRefs& refs, const ParamRange& range,
            const ParamMap& map, std::shared_ptr<const TrimRegion> trim = nullptr);

    /// The hull of the Bezier control points of this piece's sub-range.
    Bound3 bound() const override;
    void split(bool splitU, std::vector<PrimitivePtr>& out) const override;
    int splitsLeft(bool splitU) const override { return m_range.halvingsLeft(splitU); }
    Grid dice(int nu, int nv) const override;
    void dicePositions(int nu, int nv, std::vector<Vec3>& P) const override;
    /// The trim curves, unless they miss this piece.
    std::shared_ptr<const TrimRegion> trimRegion() const override {
        return m_cover == TrimRegion::Cover::Mixed ? m_trim : nullptr;
    }
    bool trimmedAway() const override { return m_cover == TrimRegion::Cover::Removed; }

    /// Object-space point at corner-domain (a, b) of the span.
    Vec3 evaluate(float a, float b) const;
    const ParamRange& range() const { return m_range; }
    const ParamMap& map() const { return m_map; }

private:
    std::shared_ptr<const SurfaceData> m_data;
    std::shared_ptr<const BezierSpan> m_span;
    CornerRefs m_refs;
    ParamRange m_range;
    ParamMap m_map;
    std::shared_ptr<const TrimRegion> m_trim;
    TrimRegion::Cover m_cover = TrimRegion::Cover::Kept;
};

/// Validates a NuPatch record and appends one NuPatch per span that meets
/// [umin, umax] x [vmin, vmax].
void makeNuPatches(std::shared_ptr<const scene::PrimitiveRecord> record, Diagnostics& diag,
                   std::vector<PrimitivePtr>& out);

}  // namespace umbra::geometry
