#pragma once
// Internal to the render module: the state of one world being rendered,
// prepared once before any bucket runs so that the per-grid path takes no
// locks and makes no lookups by name.

#include "umbra/geometry/primitive.h"
#include "umbra/hider/bucket_scheduler.h"
#include "umbra/hider/camera.h"
#include "umbra/scene/scene.h"
#include "umbra/shading/shading_system.h"
#include "umbra/trace/occlusion_scene.h"

#include <atomic>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace umbra::render {

/// Shaders and flags of one Attributes object, resolved once per world.
struct PreparedAttributes {
    const scene::Attributes* attributes = nullptr;
    std::shared_ptr<const shading::ShaderInstance> surface, displacement, atmosphere;
    std::vector<const shading::ShaderInstance*> lights;
    /// Level of detail: the samples that draw these primitives in every
    /// pass (hider::MicroGrid::dissolveFrom/Below); below <= from: none.
    float dissolveFrom = 0, dissolveBelow = 1;
};

/// One render pass: the camera pass, or a light's depth pass.
struct Pass {
    std::string name;               // "camera" or "depth:<light handle>"
    hider::Camera camera;
    bool depthOnly = false;         // no surface/light shading; displacement still runs
    /// Which micropolygons of one-sided (Sides 1) surfaces are dropped. The
    /// camera pass drops back faces, as RenderMan does; a depth pass drops
    /// none, the light-facing ones (Wang & Molnar's solids) or the back
    /// ones, by Option "umbra" "depthcull" (docs/shadows.md). Two-sided
    /// surfaces are never culled.
    enum class Cull { None, Front, Back };
    Cull cull = Cull::Back;
    /// Automatic depth maps dice no finer than this many map pixels per
    /// micropolygon (Option "umbra" "depthshadingrate"; default 4 for
    /// nearest-depth maps, none for two-layer ones): depth is interpolated
    /// linearly across a micropolygon, so coarser dicing costs a biased map
    /// no accuracy on flat surfaces and little on curved ones.
    float minShadingRate = 0;
    /// Automatic maps with a minShadingRate: how far, in map pixels, a micropolygon
    /// may stand off its surface (dice::DiceParams::flatness): smooth
    /// surfaces dice coarser than minShadingRate where that keeps them
    /// within it. 0: the rate alone decides.
    float flatness = 0;
    /// A spotlight's automatic map keeps only the disc inscribed in it (the
    /// cone plus its margin): the light never illuminates, so never looks
    /// up, the corners, and storing them would only cost tiles.
    bool discOnly = false;
    /// A second-depth map's pass: two-sided (open) surfaces are their own
    /// second layer, as Wang & Molnar §3.3 treat them, so they cast shadows
    /// (docs/shadows.md).
    bool openSurfacesAreOwnSecondLayer = false;
    /// The camera pass of a moving camera: cameraFromWorld over the
    /// shutter (camera.cameraFromWorld is its value at the opening).
    std::shared_ptr<const MotionTransform> cameraMotion;
    /// The camera pass's thin lens (DepthOfField): radius in camera units
    /// and focal distance; radius 0 is a pinhole.
    float lensRadius = 0, focalDistance = 1;
    /// A depth pass of a blurred frame whose casters move: its map's texels
    /// are time-interleaved over tiles this wide (DepthImage::timeTile).
    int timeTile = 0;
};

/// Everything the per-grid code needs about the current world.
struct FrameState {
    const scene::WorldRecord* world = nullptr;
    uint32_t frameSeed = 0;
    shading::ShadingSystem* shading = nullptr;
    std::map<const scene::Attributes*, PreparedAttributes> attributes;
    /// The prepared shaders of `attrs`: those of the world's primitives
    /// (`attributes`, made before any bucket runs and never changed while
    /// passes run), else those of an attribute set a procedural made while
    /// a pass ran, prepared on first use under a lock (`prepareLate`).
    const PreparedAttributes& prepared(const scene::Attributes& attrs) const;
    /// Instantiates a late attribute set's shaders.
    std::function<void(PreparedAttributes&)> prepareLate;
    /// The world's light instances, once made (after the depth passes):
    /// late attribute sets get theirs on their first use after that.
    const std::vector<std::shared_ptr<const shading::ShaderInstance>>* lights = nullptr;
    struct LateAttributes {
        PreparedAttributes prepared;
        bool shaded = false, lit = false;
    };
    mutable std::mutex lateMutex;
    mutable std::map<const scene::Attributes*, std::unique_ptr<LateAttributes>> late;
    std::vector<std::string> aovNames;  // film AOV channels in order
    std::vector<int> aovComponents;
    bool noShadows = false;
    std::atomic<uint64_t> shadingNanoseconds{0};
    /// The shutter in scene time (Shutter plus Option "shutter" "offset");
    /// motion blur when it stays open (close > open).
    float shutterOpen = 0, shutterClose = 0;
    bool motionBlur() const { return shutterClose > shutterOpen; }
    /// Some shadow caster moves (transform or deformation blur) in a
    /// blurred frame: depth maps are then time-interleaved.
    bool castersMove = false;
    /// Blur statistics: raster bound areas of the moving or defocused grids,
    /// at the shutter's opening without the lens (still) and over the
    /// shutter with the circle of confusion (blurred), in pixels, summed.
    std::atomic<uint64_t> blurredGrids{0};
    std::atomic<uint64_t> stillBoundPixels{0}, blurredBoundPixels{0};
    /// Every primitive of the world, for the exact ray-traced shadows of
    /// shadow("raytrace", ...), built on first use.
    const std::vector<geometry::PrimitivePtr>* primitives = nullptr;
    mutable std::once_flag occlusionOnce;
    mutable std::unique_ptr<trace::OcclusionScene> occlusion;
    /// The world's CSG trees (WorldRecord::solids), which the hider resolves.
    hider::CsgForest csg;
};

/// The renderState a ShadingGrid carries to RendererServices.
struct GridState {
    const FrameState* frame = nullptr;
    const Pass* pass = nullptr;
    const scene::PrimitiveRecord* record = nullptr;  // null for an imager's grid of pixels
    Mat4 cameraFromObject;
};

}  // namespace umbra::render
