#pragma once
// The primitive contract every geometric family meets, so the REYES loop
// (dice/reyes.h) can treat them alike: bound, split, dice.

#include "umbra/geometry/grid.h"
#include "umbra/scene/scene.h"
#include "umbra/util/error.h"
#include "umbra/util/math.h"

#include <functional>
#include <memory>
#include <vector>

namespace umbra::geometry {

class Primitive;
class TrimRegion;
using PrimitivePtr = std::unique_ptr<Primitive>;

/// Where the pass's eye is, in a primitive's object space: what the
/// camera-facing families (curves' ribbons, points' discs) turn towards.
/// The renderer makes one per grid from cameraFromObject, so a depth pass
/// turns them towards its light, as its camera.
struct ViewContext {
    bool orthographic = true;
    Vec3 eye{0, 0, 0};         // perspective: the eye point
    Vec3 towardEye{0, 0, -1};  // orthographic: unit direction towards the eye
    /// The camera's unit x and y axes in object space (not unit there under
    /// a scale), and the camera-space length of an object-space unit as the
    /// cube root of the transform's volume scale: what Points discs, round
    /// in the image under any transform, are laid out with.
    Vec3 imageX{1, 0, 0}, imageY{0, 1, 0};
    float cameraPerObject = 1;
    /// From a point of the surface towards the eye (not normalized).
    Vec3 toward(const Vec3& p) const { return orthographic ? towardEye : eye - p; }
    /// The camera's eye seen from a primitive's object space.
    static ViewContext ofCamera(const Mat4& objectFromCamera, bool orthographic) {
        ViewContext v;
        v.orthographic = orthographic;
        v.eye = objectFromCamera.point({0, 0, 0});
        v.towardEye = normalize(objectFromCamera.vector({0, 0, -1}));
        v.imageX = objectFromCamera.vector({1, 0, 0});
        v.imageY = objectFromCamera.vector({0, 1, 0});
        const float volume = std::abs(objectFromCamera.det3());
        v.cameraPerObject = volume > 0 ? 1.0f / std::cbrt(volume) : 1.0f;
        return v;
    }
};

/// A surface that can be bounded, split into smaller surfaces of the same
/// kind, and diced into a grid. Everything is in the primitive's object
/// space; the record says where that is (worldFromObject) and what
/// attributes apply.
class Primitive {
public:
    explicit Primitive(std::shared_ptr<const scene::PrimitiveRecord> record) : m_record(std::move(record)) {}
    virtual ~Primitive() = default;

    /// Object-space bound of the surface (without displacement; the
    /// renderer pads it by the displacement bound).
    virtual Bound3 bound() const = 0;
    /// Splits into pieces that together cover this surface exactly.
    /// `splitU` asks for a cut across u (halving the u range) rather than
    /// v; primitives that cannot honour the direction may ignore it.
    virtual void split(bool splitU, std::vector<PrimitivePtr>& out) const = 0;
    /// How many more times split(splitU) can halve this piece into pieces
    /// smaller than it: 0 once the parameter range being cut is at float
    /// resolution (its halves would be this piece again) or a group holds a
    /// single item. Huge coordinates can need more halvings than float can
    /// make, and a piece that cannot shrink would otherwise split forever;
    /// the REYES loop cuts the other way, or dices such a piece coarsely
    /// with a warning (dice::decide). Families whose every split shrinks
    /// (meshes, blocks, procedurals) keep the default, kManySplits.
    static constexpr int kManySplits = 64;
    virtual int splitsLeft(bool splitU) const { return kManySplits; }
    /// False when the primitive must be split before it can be diced
    /// (e.g. a polygon mesh that has not yet been broken into faces).
    virtual bool diceable() const { return true; }
    /// Dices into an nu x nv grid of micropolygons (nu, nv >= 1) in object
    /// space, with every primitive variable interpolated onto it and s, t
    /// always present (defaulting to u, v as RenderMan does).
    virtual Grid dice(int nu, int nv) const = 0;
    /// dice() for a pass whose eye is at `view`: what the renderer calls.
    /// Families whose shape depends on the eye (camera-facing ribbons and
    /// discs) override it; their dice() uses a default view looking down
    /// +z. bound() must hold for every view.
    virtual Grid diceInView(int nu, int nv, const ViewContext& view) const { return dice(nu, nv); }
    /// The camera-space bound of what diceInView() makes for an eye at the
    /// origin of camera space (ViewContext::ofCamera(cameraFromObject's
    /// inverse)): bound() carried there, or tighter for a family that turns
    /// to face the eye. A point's disc lies across the view, at its centre's
    /// depth: bounded for every view, it crossed the eye plane of a light
    /// standing a disc's width from it, and its shadow was culled.
    virtual Bound3 cameraBound(const Mat4& cameraFromObject, bool orthographic) const {
        (void)orthographic;
        return transformBound(cameraFromObject, bound());
    }
    /// True when the family fixes its own grid counts (points: one
    /// micropolygon per point): the REYES loop dices at (*nu, *nv) when
    /// they fit a grid, and splits otherwise.
    virtual bool fixedCounts(int* nu, int* nv) const { return false; }
    /// Only the positions of dice(nu, nv), in the same order: what the
    /// dicing decision needs to measure a primitive's size on screen.
    /// Families override it to skip primitive variables.
    virtual void dicePositions(int nu, int nv, std::vector<Vec3>& P) const { P = dice(nu, nv).P; }
    /// The same seen from `view`, for a family whose shape depends on where
    /// the eye is (a curve's ribbon turns to face it): the dicing decision
    /// measures this one.
    virtual void dicePositionsInView(int nu, int nv, const ViewContext& view, std::vector<Vec3>& P) const {
        (void)view;
        dicePositions(nu, nv, P);
    }
    /// True when the surface is one flat, convex quadrilateral (or
    /// triangle) with straight edges: a single micropolygon of it then has
    /// the same outline and, under perspective too, the same depths as any
    /// finer grid, so a depth pass need not dice it finely.
    virtual bool flatQuad() const { return false; }
    /// What the hider removes of this surface sample by sample, tested at
    /// the grid's (u, v) interpolated across each micropolygon (a NuPatch's
    /// trim curves, geometry/trim.h); null: nothing.
    virtual std::shared_ptr<const TrimRegion> trimRegion() const { return nullptr; }
    /// True when trimming removes all of this piece, so it can be culled.
    virtual bool trimmedAway() const { return false; }
    /// Deformation blur: how many shapes the surface takes over the shutter
    /// (a MotionBegin block around the primitive; its record's shapeTimes).
    /// 1 for a primitive that does not deform.
    virtual int shapeCount() const { return 1; }
    /// The positions of shape k (0 .. shapeCount()-1) diced as
    /// diceInView(nu, nv, view), vertex for vertex; shape 0's are
    /// diceInView's own. bound() covers every shape.
    virtual void diceShape(int shape, int nu, int nv, const ViewContext& view, std::vector<Vec3>& P) const {
        P = diceInView(nu, nv, view).P;
    }

    const scene::PrimitiveRecord& record() const { return *m_record; }
    const std::shared_ptr<const scene::PrimitiveRecord>& recordPtr() const { return m_record; }
    const scene::Attributes& attributes() const { return *m_record->attributes; }

private:
    std::shared_ptr<const scene::PrimitiveRecord> m_record;
};

/// Creates the primitive(s) a record describes, reporting malformed records
/// (wrong argument counts, missing P, bad indices) with their location and
/// returning nothing for them.
std::vector<PrimitivePtr> makePrimitives(std::shared_ptr<const scene::PrimitiveRecord> record, Diagnostics& diag);

/// Asked by makePrimitives about a record's attributes: true when the
/// shaders that will run on it may tell how its surface is cut into grids
/// (a displacement shader, or a surface shader reading u, v, s or t).
/// Subdivision meshes dice their regular regions as bicubic blocks
/// (geometry/subdivision.h) only when it answers false; without it, never.
using ParameterReaders = std::function<bool(const scene::Attributes&)>;

class ProceduralContext;
/// makePrimitives() that also makes `Procedural` records into procedural
/// primitives (geometry/procedural.h) expanding in `procedurals`' world;
/// without a context they are skipped with a warning.
std::vector<PrimitivePtr> makePrimitives(std::shared_ptr<const scene::PrimitiveRecord> record, Diagnostics& diag,
                                         const std::shared_ptr<ProceduralContext>& procedurals,
                                         const ParameterReaders& readers = {});

}  // namespace umbra::geometry
