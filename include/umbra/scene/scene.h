#pragma once
// Scene records: what the builder (scene/builder.h) makes of RIB requests.
//
// Records are plain data: names, parameter lists, transforms and source
// locations. Nothing here is a renderer object; the render module creates
// primitives, shader instances and displays from the records of one world
// (WorldBegin ... WorldEnd) when it renders it.

#include "umbra/ri/param_list.h"
#include "umbra/ri/target.h"
#include "umbra/util/error.h"
#include "umbra/util/math.h"
#include "umbra/util/motion.h"

#include <array>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace umbra::scene {

/// A shader as named by `Surface`, `Displacement`, `LightSource`,
/// `Atmosphere`, `Imager`: its name, its instance parameters, and the
/// "shader" coordinate system (the current transform when it was named).
struct ShaderRecord {
    std::string name;
    ri::ParamList params;
    Mat4 worldFromShader;
    FileLoc loc;
};

/// A cubic basis for `Patch "bicubic"` and `PatchMesh` (RI spec 3.2 §5.5),
/// applied to column vectors of control values: the 4x4 matrix of the
/// `Basis` request, and its step.
struct Basis {
    float m[4][4];
    int step = 3;
    static Basis bezier();
    static Basis bspline();
    static Basis catmullRom();
    static Basis hermite();
    static Basis power();
    /// By RIB name; false if unknown.
    static bool byName(const std::string& name, Basis* out);
};

/// The attribute state a primitive carries (immutable once a primitive
/// references it; the builder copies on write). A new field must also be
/// merged by instanceAttributes() (src/scene/attributes.cpp).
/// The loops of a TrimCurve request (RI spec 3.2 §5.4) as given: NURBS
/// curves in the (u, v) parameter space of the NuPatches that follow it
/// in the attribute block. Loop l is curves ncurves[0] + ... of the
/// flattened arrays; curve c has order[c], n[c] points (u, v, w: homogeneous,
/// u and v already multiplied by w) and n[c] + order[c] knots, drawn over
/// [min[c], max[c]].
struct TrimCurveRecord {
    std::vector<int> ncurves, order, n;
    std::vector<float> knot, min, max, u, v, w;
    FileLoc loc;
};

struct Attributes {
    Color color{1, 1, 1};
    Color opacity{1, 1, 1};
    bool matte = false;
    float shadingRate = 1.0f;        // micropolygon area in pixels
    int sides = 2;                   // 1: back faces are culled
    // Orientation (RI spec 3.2 §4.2): true when the current orientation
    // differs from the handedness of the current coordinate system, so the
    // primitive is "turned inside out". The spec's orientation flips with
    // every mirroring transform, so this relative flag is what stays fixed
    // under transforms: "outside" and the default give false, "inside" true,
    // ReverseOrientation toggles, "lh"/"rh" compare with the handedness of
    // the coordinate system they are given in (camera space is left-handed).
    // How a grid's normals follow from it: render::normalsFlip().
    bool insideOut = false;
    std::shared_ptr<const ShaderRecord> surface;       // null: the default surface
    std::shared_ptr<const ShaderRecord> displacement;  // null: none
    std::shared_ptr<const ShaderRecord> atmosphere;    // null: none
    std::vector<int> lights;         // indices into WorldRecord::lights that illuminate this
    float displacementBound = 0;     // "displacementbound" "sphere" in "object" space units
    std::string displacementBoundSpace = "object";
    Basis uBasis = Basis::bezier();
    Basis vBasis = Basis::bezier();
    std::string name;                // Attribute "identifier" "name"
    bool smoothShading = false;      // ShadingInterpolation "smooth" (false: "constant")
    // TextureCoordinates s1 t1 s2 t2 s3 t3 s4 t4: default s, t of patch corners.
    float textureCoordinates[8] = {0, 0, 1, 0, 0, 1, 1, 1};
    // SolidBegin operation of the innermost solid block ("primitive",
    // "union", ...); empty outside solids. "primitive" marks a closed solid
    // for the depth pass.
    std::string solid;
    // Visibility: RenderMan's Attribute "visibility" "camera" / "transmission"
    // ("shadow" in older RIBs). transmission 0 leaves the object out of
    // depth-map passes (Reeves' ground plane).
    bool visibleToCamera = true;
    bool castsShadows = true;
    /// Attribute "dice" "binary": grids diced into powers of two.
    bool binaryDice = false;
    /// Level of detail: the Detail box's corners in world space (set when
    /// hasDetail), and the DetailRange minvisible, lowertransition,
    /// uppertransition, maxvisible the primitives are drawn over
    /// (docs/rib.md, "Level of detail").
    bool hasDetail = false;
    std::array<Vec3, 8> detailCorners{};
    std::array<float, 4> detailRange{0, 0, std::numeric_limits<float>::infinity(),
                                     std::numeric_limits<float>::infinity()};
    /// The current TrimCurve (null: none); it applies to NuPatch only.
    std::shared_ptr<const TrimCurveRecord> trimCurves;
    /// Every other `Attribute "class" "name" value` by "class:name", for the
    /// attribute() shadeop and for modules' own attributes ("umbra:...").
    std::map<std::string, ri::Param> user;
    /// Names given by ScopedCoordinateSystem in the world (world from the
    /// named space): in force until the attribute block ends, before the
    /// world's names of the same spelling.
    std::map<std::string, Mat4> scopedSpaces;
    /// The named space `name` (world from it) as this state sees it: its
    /// scoped names, then the world's `named`. Null if neither has it.
    const Mat4* space(const std::string& name, const std::map<std::string, Mat4>& named) const {
        if (auto it = scopedSpaces.find(name); it != scopedSpaces.end()) return &it->second;
        if (auto it = named.find(name); it != named.end()) return &it->second;
        return nullptr;
    }
};

/// The attributes of a piece of an object instance: the instance's, except
/// for those the object's definition set (RI spec 3.2 §4.4 as PRMan reads
/// it): where `defined` (the piece's state inside ObjectBegin/ObjectEnd)
/// differs from `atBegin` (the state at ObjectBegin), the definition wins.
Attributes instanceAttributes(const Attributes& instance, const Attributes& atBegin, const Attributes& defined);

/// A geometric primitive request: type name ("Sphere", "PointsPolygons",
/// "PatchMesh", ...), its positional arguments, its parameter list, and the
/// transform and attributes current when it was given.
struct PrimitiveRecord {
    std::string type;
    std::vector<float> floatArgs;          // e.g. Sphere radius zmin zmax thetamax
    std::vector<int> intArgs;              // e.g. PointsPolygons nverts then verts
    std::vector<std::string> stringArgs;   // e.g. Patch "bicubic", PatchMesh "periodic"
    /// Array arguments in the order they appeared, for requests with more
    /// than one (PointsGeneralPolygons: nloops, nverts, verts). A "Polygon"
    /// record with one array is a run of consecutive Polygon requests
    /// (only "P", the same attributes and transform) the builder merged:
    /// the array holds each polygon's vertex count, "P" their points one
    /// polygon after another, `loc` is the first's. It renders exactly as
    /// the separate records would.
    std::vector<std::vector<int>> intArrays;
    ri::ParamList params;
    /// The transform at the shutter's opening (all of it unless moving).
    Mat4 worldFromObject;
    /// Transform motion blur (MotionBegin around transforms): the
    /// transform over the shutter; null when it does not move.
    std::shared_ptr<const MotionTransform> worldFromObjectMotion;
    /// Deformation blur (MotionBegin around the primitive itself): the
    /// times of its shapes, ascending, and shapes 1.. as records of the same
    /// type and topology (shape 0 is this record). Empty: one shape.
    std::vector<float> shapeTimes;
    std::vector<PrimitiveRecord> shapes;
    std::shared_ptr<const Attributes> attributes;
    FileLoc loc;
    /// CSG: the "primitive" solid (index into WorldRecord::solids) whose
    /// closed boundary this surface is part of; -1 outside CSG trees.
    int solid = -1;

    bool moving() const { return (worldFromObjectMotion && worldFromObjectMotion->moving()) || !shapes.empty(); }

    /// A record of another type that a family makes of this one (the
    /// teapot's patches, a sphere point's sphere): where and how this one
    /// is -- transform, motion, attributes, location and CSG solid -- with
    /// no arguments or parameters of its own yet.
    PrimitiveRecord derived(std::string derivedType) const {
        PrimitiveRecord r;
        r.type = std::move(derivedType);
        r.worldFromObject = worldFromObject;
        r.worldFromObjectMotion = worldFromObjectMotion;
        r.attributes = attributes;
        r.loc = loc;
        r.solid = solid;
        return r;
    }
};

/// One node of a CSG tree (RI spec 3.2 §5.8): a SolidBegin block inside a
/// union, intersection or difference, or such an operation itself. A
/// primitive given directly inside an operation is a "primitive" node of
/// its own; a top-level SolidBegin "primitive" is no tree (ordinary geometry).
struct SolidRecord {
    std::string operation;  // "primitive", "union", "intersection" or "difference"
    int parent = -1;        // index into WorldRecord::solids, before this one; -1 for a tree's root
    FileLoc loc;
};

/// A light source or area light, with its transform.
struct LightRecord {
    ShaderRecord shader;
    std::string handle;      // the RIB handle (integer or string) as text
    bool area = false;       // given by AreaLightSource (lit from its shader space, as an ordinary light)
    std::shared_ptr<const Attributes> attributes;
};

/// One `Display` request. The first has no '+'; more add outputs.
struct DisplayRecord {
    std::string name;        // file name, without a leading '+'
    /// The name as given when it held a frame pattern ("out.####.tif"; the
    /// builder put the frame's number in `name`); empty otherwise.
    std::string pattern;
    std::string driver;      // "file", "tiff", "openexr", "png", "zfile", "shadow", "framebuffer", ...
    std::string mode;        // "rgb", "rgba", "z", "rgbaz", or AOV: "color myaov"
    ri::ParamList params;
    FileLoc loc;
    /// Not asked for: the frame had no Display, and this is the default
    /// ("ri.pic", as PRMan and Aqsis write).
    bool implicitDefault = false;
};

enum class Projection { Orthographic, Perspective };

/// The options of one frame (everything set before WorldBegin).
struct Options {
    int xResolution = 640, yResolution = 480;
    float pixelAspectRatio = 1.0f;
    float frameAspectRatio = -1.0f;           // -1: xres*pixelAspect/yres
    bool screenWindowSet = false;
    float screenWindow[4] = {-1, 1, -1, 1};  // left right bottom top; derived when not set
    float cropWindow[4] = {0, 1, 0, 1};      // xmin xmax ymin ymax in NDC
    Projection projection = Projection::Orthographic;
    float fov = 90.0f;                        // degrees, perspective only
    /// The screen transformation (RI Spec 3.2, Projection): transforms given
    /// before `Projection` apply after it, in screen space. umbra keeps the
    /// part a screen transform can mean for a picture, the 2D affine map
    /// x' = a x + b y + tx, y' = c x + d y + ty with screenLinear = {a, b,
    /// c, d} (rotation, shear, scale; a negative determinant mirrors);
    /// Builder::takeScreenTransform warns about and drops the rest (depth,
    /// projective parts).
    float screenLinear[4] = {1, 0, 0, 1};
    float screenOffset[2] = {0, 0};
    float nearClip = 1e-10f, farClip = 1e30f; // RenderMan's RI_EPSILON / RI_INFINITY
    int pixelSamples[2] = {2, 2};
    std::string pixelFilter = "gaussian";
    float filterWidth[2] = {2, 2};
    float exposureGain = 1.0f, exposureGamma = 1.0f;
    float relativeDetail = 1.0f;             // RelativeDetail: scales every level-of-detail measure
    // Quantize "rgba" one min max dither; (0,0,0,0) means floating point.
    float quantizeOne = 255, quantizeMin = 0, quantizeMax = 255, quantizeDither = 0.5f;
    float zQuantizeOne = 0, zQuantizeMin = 0, zQuantizeMax = 0, zQuantizeDither = 0;
    /// `Quantize "name" one min max dither` for any other name (RenderMan
    /// 13+): one min max dither of the display whose mode is that AOV.
    std::map<std::string, std::array<float, 4>> namedQuantize;
    std::vector<DisplayRecord> displays;
    /// DisplayChannel declarations (name: "varying color myaov"; no driver).
    std::vector<DisplayRecord> displayChannels;
    std::shared_ptr<const ShaderRecord> imager;  // Imager shader; null: none
    std::string hider = "hidden";
    ri::ParamList hiderParams;                // "jitter", "depthfilter", ...
    bool jitter = true;
    std::string depthFilter = "min";
    int bucketSize[2] = {16, 16};
    /// Option "limits" "bucketsize" was given: the renderer then keeps
    /// bucketSize for every pass but automatic maps' (otherwise it picks
    /// 32 pixels for camera passes and 64 for depth passes:
    /// docs/performance.md).
    bool bucketSizeSet = false;
    int gridSize = 256;                       // max micropolygons per grid
    int eyeSplits = 10;
    /// ReadArchive requests allowed in one frame (Option "limits"
    /// "archivereads"); bounds the work of archives that read each other.
    int archiveReads = ri::kDefaultArchiveReads;
    /// Bytes a gzip RIB may decompress to (Option "limits" "decompressedmb").
    uint64_t decompressedBytes = ri::kDefaultDecompressedBytes;
    std::map<std::string, std::string> searchPaths;  // "shader", "texture", "archive", "resource"
    /// Option "statistics" "endofframe": 0 nothing, 1 a summary of each
    /// frame on stderr, 2 also every pass, map and the shadow lookups'
    /// counters, 3 also the frame's whole --stats record (docs/statistics.md).
    int statisticsEndOfFrame = 0;
    /// Shutter open close; Option "shutter" "offset" is added to both
    /// (PRMan's: motion times stay those of the scene, the shutter moves).
    float shutter[2] = {0, 0};
    float shutterOffset = 0;
    /// How the shutter opens and closes (Option "shutter" "opening" [a b],
    /// PRMan's "shutteropening"): fully open from a to b (fractions of the
    /// interval), ramping linearly before and after; [0 1]: a box.
    float shutterOpening[2] = {0, 1};
    /// DepthOfField fstop focallength focaldistance; an infinite fstop is
    /// the pinhole camera (the default, and DepthOfField with no
    /// arguments). The lens radius is focallength / (2 fstop), in camera
    /// units, as focaldistance is.
    float fstop = kInfinity, focalLength = 0, focalDistance = 0;
    /// Every other `Option "class" "name" value` by "class:name".
    std::map<std::string, ri::Param> user;

    Mat4 cameraFromWorld;                     // the transform at WorldBegin (at the shutter's opening)
    /// A moving camera (MotionBegin around camera transforms): cameraFromWorld
    /// over the shutter; null when it does not move.
    std::shared_ptr<const MotionTransform> cameraMotion;
    FileLoc loc;                              // where the frame's options began
};

/// Everything needed to render one world block.
struct WorldRecord {
    int frameNumber = -1;                     // FrameBegin number, -1 outside frames
    Options options;
    std::vector<LightRecord> lights;
    std::vector<PrimitiveRecord> primitives;
    std::vector<SolidRecord> solids;          // CSG trees, parents first
    /// CoordinateSystem names -> worldFromNamed, including "world".
    std::map<std::string, Mat4> coordinateSystems;
    FileLoc loc;                              // the WorldBegin
};

/// MakeTexture, MakeShadow, MakeLatLongEnvironment, MakeCubeFaceEnvironment:
/// file conversions run in request order between worlds.
struct MakeRecord {
    std::string request;                 // "MakeShadow", "MakeTexture", ...
    std::vector<std::string> inputs;     // one, or six for cube faces
    std::string output;
    std::vector<std::string> stringArgs; // swrap twrap filter
    std::vector<float> floatArgs;        // swidth twidth (fov for cube faces)
    ri::ParamList params;
    FileLoc loc;
};

/// What the scene builder hands on, in request order.
class SceneSink {
public:
    virtual ~SceneSink() = default;
    /// Called at WorldEnd; the record is complete.
    virtual void renderWorld(const WorldRecord& world) = 0;
    virtual void make(const MakeRecord& make) = 0;
    /// FrameBegin/FrameEnd bracket worlds; no-ops by default.
    virtual void frameBegin(int frameNumber, const FileLoc& loc) {}
    virtual void frameEnd(const FileLoc& loc) {}
    /// Whether the worlds of frame `frameNumber` (-1: outside any frame)
    /// will be rendered. A builder reads no archive inside a frame that
    /// will not (`--frames`): what it holds reaches no picture.
    virtual bool frameWanted(int frameNumber) const { return true; }
};

}  // namespace umbra::scene
