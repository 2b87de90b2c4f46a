#pragma once
// The renderer's side of the REYES loop for one pass: bound a piece of
// geometry in raster space, decide whether to split or dice it, and dice,
// displace, shade and project a grid.

#include "render/frame.h"
#include "render/services.h"

#include "umbra/dice/reyes.h"
#include "umbra/film/film.h"
#include "umbra/hider/bucket_scheduler.h"

#include <tbb/enumerable_thread_specific.h>

namespace umbra::render {

/// Level of detail (RI spec 3.2 Detail, DetailRange, RelativeDetail): the
/// detail of a Detail box is the area, in raster pixels, of the rectangle
/// bounding its corners' projection, times RelativeDetail; +infinity when a
/// corner is at or behind the eye (docs/rib.md, "Level of detail").
float rasterDetail(const std::array<Vec3, 8>& worldCorners, const hider::Camera& camera, float relativeDetail);
/// The dissolve window [from, below) of a representation whose DetailRange
/// is `range` at that detail: none outside [minvisible, maxvisible), all of
/// [0, 1) between the transitions, and in a transition the share of the
/// samples given by the linear ramp, [1 - w, 1) fading in, [0, w) fading out.
std::pair<float, float> dissolveWindow(float detail, const std::array<float, 4>& range);

/// The one orientation rule: whether dPdu x dPdv, measured in the space of
/// `cameraFromObject`, must be negated to give the primitive's outward
/// normal (Ng, calculatenormal(), facing culls).
bool normalsFlip(const scene::Attributes& attrs, const Mat4& cameraFromObject);

class SurfacePipeline : public hider::GeometryPipeline {
public:
    SurfacePipeline(FrameState& frame, const Pass& pass, Services& services, Diagnostics& diag,
                    const film::Film& film);

    Bound3 rasterBound(const geometry::Primitive& prim) override;
    Plan plan(const geometry::Primitive& prim, int eyeSplits, double splitBudget, double need) override;
    double rasterNeed(const geometry::Primitive& prim, const Bound3& rasterBound) override;
    bool shade(const geometry::Primitive& prim, int nu, int nv, uint64_t id, hider::ShadedGrid& out) override;

private:
    /// Whether this pass draws primitives of these attributes: a depth
    /// pass its shadow casters, the camera what the camera sees.
    bool takesPart(const scene::Attributes& attrs) const;
    /// cameraFromObject of a primitive in this pass, at the shutter's opening.
    Mat4 cameraFromObject(const geometry::Primitive& prim) const;
    /// ... and at scene time t.
    Mat4 cameraFromObjectAt(const scene::PrimitiveRecord& rec, float t) const;
    /// The scene times at which the hider places a piece (motion blur): the
    /// shutter's opening and closing and every key in between, with more
    /// keys where one interval turns far (its path is then followed by
    /// chords of at most kMaxChordTurn). Only the opening when the piece
    /// does not move in this pass.
    void placementTimes(const geometry::Primitive& prim, std::vector<float>& times) const;
    /// dice::rasterNeed, of a moving piece the mean over its placement
    /// times; negative when it cannot be measured.
    double measuredNeed(const geometry::Primitive& prim, dice::DiceParams p) const;
    /// The piece's camera-space bound over the placement times (padded by
    /// the displacement bound as dice::cameraBound pads).
    Bound3 sweptBound(const geometry::Primitive& prim, const dice::DiceParams& p,
                      const std::vector<float>& times) const;
    /// Raster pixels the thin lens spreads a point at camera depth z over,
    /// as a radius (0 for a pinhole).
    float confusionRadius(float z) const;
    /// Attribute "displacementbound" "sphere" in camera units, read in its
    /// "coordinatesystem" (object, world, camera, shader or a named space).
    float displacementAllowance(const scene::Attributes& attrs, const Mat4& cameraFromObject) const;
    /// The dicing parameters of a primitive in this pass.
    dice::DiceParams diceParams(const geometry::Primitive& prim) const;
    void fillAovs(const shading::ShadingGrid& sg, hider::ShadedGrid& out) const;
    /// Marks the micropolygons the pass culls by facing (see Pass::Cull);
    /// false when none is left.
    bool cullFacing(const std::vector<Vec3>& keyed, size_t keys, bool flip, hider::ShadedGrid& out) const;
    /// CSG leaves: marks the micropolygons (of the camera-space grid P)
    /// whose outward normal faces away from the eye (hider::MicroGrid::leaving).
    void markLeaving(const std::vector<Vec3>& P, bool flip, hider::ShadedGrid& out) const;
    /// Adds a blurred grid's bound growth to the frame's statistics.
    void noteBlur(const hider::ShadedGrid& out) const;
    /// Warns (once per Displacement request) when a displacement shader
    /// moved the grid's camera-space points `before` to `after` further
    /// than the primitive's displacement bound allows.
    void warnPastDisplacementBound(const scene::PrimitiveRecord& rec, const Mat4& cameraFromObject,
                                   const std::vector<Vec3>& before, const std::vector<Vec3>& after, int n) const;

    FrameState& m_frame;
    const Pass& m_pass;
    Services& m_services;
    Diagnostics& m_diag;
    Mat4 m_rasterFromCamera;
    float m_rasterWindow[4];
    float m_eyeZ = 1e-6f;  // camera depth below which projection is unusable
    tbb::enumerable_thread_specific<shading::ShadingGrid> m_grids;
};

}  // namespace umbra::render
