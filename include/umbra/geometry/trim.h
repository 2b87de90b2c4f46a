#pragma once
// Trim curves (RI spec 3.2 §5.4, TrimCurve): closed loops of NURBS curves in
// the (u, v) parameter space of a NuPatch that cut parts of it away.
//
// Each curve is tessellated into kTrimSegmentsPerSpan straight segments per
// knot span; a parameter point is inside the trim loops when a ray from it
// crosses their segments an odd number of times (the even-odd rule, which
// does not depend on the loops' directions). Attribute "trimcurve" "sense"
// "inside" (the default, as in Aqsis) removes what is inside; "outside"
// keeps only that. The hider applies the test at every sample, to the
// (u, v) interpolated across the micropolygon, so the cut edge follows the
// tessellated curve, not the micropolygon lattice.

#include "umbra/scene/scene.h"
#include "umbra/util/error.h"

#include <memory>
#include <vector>

namespace umbra::geometry {

/// Segments per knot span of a trim curve: a circle of 4 rational
/// quadratic spans then deviates from its polygon by 1 - cos(pi/256), about
/// 8e-5 of its radius.
constexpr int kTrimSegmentsPerSpan = 64;

/// The tessellated trim loops of one TrimCurve, shared by every NuPatch
/// that uses them.
class TrimRegion {
public:
    /// Tessellates `rec`; `removeInside` is the "sense" (true: "outside",
    /// keeping what is outside the loops; false: "inside", the default).
    static std::shared_ptr<const TrimRegion> make(const scene::TrimCurveRecord& rec, bool removeInside);

    /// Whether the surface at parameter (u, v) is kept.
    bool keeps(float u, float v) const { return insideLoops(u, v) != m_removeInside; }
    /// Whether (u, v) is inside the loops (even-odd).
    bool insideLoops(float u, float v) const;

    enum class Cover { Kept, Removed, Mixed };
    /// What the trim does to the parameter rectangle [u0,u1] x [v0,v1]:
    /// Kept or Removed when no segment comes near it.
    Cover classify(float u0, float u1, float v0, float v1) const;

    /// The tessellated segments, for tests: (u0, v0, u1, v1) each.
    const std::vector<float>& segments() const { return m_seg; }

private:
    void buildBands();

    std::vector<float> m_seg;  // u0 v0 u1 v1 per segment
    bool m_removeInside = true;
    float m_vLo = 0, m_vHi = 0, m_bandScale = 0;
    std::vector<std::vector<int>> m_bands;  // segments overlapping each band of v
};

/// The trim region of a record's attributes (TrimCurve and "trimcurve"
/// "sense"), or null without TrimCurve.
std::shared_ptr<const TrimRegion> trimRegionOf(const scene::Attributes& attrs);

}  // namespace umbra::geometry
