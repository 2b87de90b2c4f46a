#pragma once
// The scene builder: keeps RenderMan's graphics state (options, the
// attribute and transform stacks, lights, named coordinate systems, object
// definitions) while the RIB parser calls it, and hands finished
// WorldRecords and MakeRecords to a SceneSink in request order.

#include "umbra/ri/target.h"
#include "umbra/scene/scene.h"
#include "umbra/util/error.h"

#include <map>
#include <memory>
#include <string>
#include <vector>

namespace umbra::scene {

/// Request values beyond which a render would hang or exhaust memory; the
/// builder clamps to them with a warning at the request (docs/rib.md,
/// "Limits").
constexpr float kMinShadingRate = 1.0f / 64;  // pixels of area: 8 x 8 micropolygons a pixel
constexpr float kMaxFilterWidth = 16;         // pixels, each axis
constexpr int kMaxPixelSamples = 32;          // samples along each axis of a pixel
/// Open blocks named one by one when a WorldEnd, FrameEnd or the end of
/// the input closes them; the rest are counted in one line.
constexpr int kMaxListedOpenBlocks = 10;

/// An ri::Target that turns requests into scene records (see docs/rib.md
/// for what each request does and which ones are reported unsupported).
///
/// Transforms: before WorldBegin the current transform maps the current
/// coordinate system to camera space; at WorldBegin it becomes
/// Options::cameraFromWorld and is reset to the identity, after which it is
/// worldFromObject. Concatenating requests (ConcatTransform, Translate,
/// Rotate, Scale, Skew, Perspective) post-multiply, `C = C * M`, so the new
/// transform applies to object coordinates first, as in RenderMan.
/// `Transform`, `Identity` and `CoordSysTransform` inside the world set the
/// transform relative to world space.
class Builder : public ri::Target {
public:
    Builder(SceneSink& sink, Diagnostics& diag);
    ~Builder() override;

    /// What '@' stands for in Option "searchpath" `kind` (e.g. "shader"),
    /// and what '&' stands for before the path is first set.
    void setDefaultSearchPath(const std::string& kind, const std::string& path);
    /// Sets search path `kind` as Option "searchpath" does ('&', '@' expanded).
    void setSearchPath(const std::string& kind, const std::string& spec);

    /// The frame number of worlds outside FrameBegin/FrameEnd (-1 by
    /// default: none). `umbra shot.####.rib --frames 1-3` gives each file's
    /// worlds the number it was named by.
    void setDefaultFrame(int frame) { m_defaultFrame = m_frame = frame; }

    /// Current state, for tests and tools.
    const Options& options() const { return m_options; }
    const Attributes& attributes() const { return *m_state.attrs; }
    const Mat4& currentTransform() const { return m_state.transform; }
    bool inWorld() const { return m_world != nullptr; }

    /// Makes this (fresh) builder take the requests of a procedural
    /// primitive's RIB (RI spec 3.2 §5.7): inside `world`, with its options,
    /// coordinate systems and light handles, and the graphics state of the
    /// `Procedural` request (its attributes and transform). World, frame
    /// and option requests are errors there, as are new lights.
    void beginProcedural(const WorldRecord& world, const PrimitiveRecord& procedural);
    /// The primitives made since beginProcedural, in request order.
    std::vector<PrimitiveRecord> takePrimitives();
    /// Orientation as a handedness: true when "outside" is left-handed.

    void unhandled(std::string_view request, const FileLoc& loc) override;
    std::vector<std::string> archiveSearchPath() const override;
    uint64_t decompressedByteBudget() const override { return m_options.decompressedBytes; }
    void endOfInput(const FileLoc& loc) override;
    bool conditionValue(const std::string& name, ri::ExprValue* out) const override;

    void version(float v, const FileLoc& loc) override;
    void declare(const ri::ParamDecl& decl, const FileLoc& loc) override;
    void errorHandler(const std::string& name, const FileLoc& loc) override;
    bool readArchive(const std::string& resolvedPath, const FileLoc& loc) override;
    bool archivesWanted() const override { return m_sink.frameWanted(m_frame); }

    void frameBegin(int frame, const FileLoc& loc) override;
    void frameEnd(const FileLoc& loc) override;
    void worldBegin(const FileLoc& loc) override;
    void worldEnd(const FileLoc& loc) override;
    void attributeBegin(const FileLoc& loc) override;
    void attributeEnd(const FileLoc& loc) override;
    void transformBegin(const FileLoc& loc) override;
    void transformEnd(const FileLoc& loc) override;
    void solidBegin(const std::string& operation, const FileLoc& loc) override;
    void solidEnd(const FileLoc& loc) override;
    void objectBegin(const std::string& handle, const FileLoc& loc) override;
    void objectEnd(const FileLoc& loc) override;
    void objectInstance(const std::string& handle, const FileLoc& loc) override;
    void motionBegin(const std::vector<float>& times, const FileLoc& loc) override;
    void motionEnd(const FileLoc& loc) override;

    void identity(const FileLoc& loc) override;
    void transform(const Mat4& m, const FileLoc& loc) override;
    void concatTransform(const Mat4& m, const FileLoc& loc) override;
    void translate(const Vec3& d, const FileLoc& loc) override;
    void rotate(float angleDeg, const Vec3& axis, const FileLoc& loc) override;
    void scale(const Vec3& s, const FileLoc& loc) override;
    void skew(float angleDeg, const Vec3& a, const Vec3& b, const FileLoc& loc) override;
    void perspective(float fovDeg, const FileLoc& loc) override;
    void coordinateSystem(const std::string& name, const FileLoc& loc) override;
    void scopedCoordinateSystem(const std::string& name, const FileLoc& loc) override;
    void coordSysTransform(const std::string& name, const FileLoc& loc) override;
    void camera(const std::string& name, ri::ParamList params, const FileLoc& loc) override;
    void resource(const std::string& handle, const std::string& type, ri::ParamList params,
                  const FileLoc& loc) override;
    void resourceBegin(const FileLoc& loc) override;
    void resourceEnd(const FileLoc& loc) override;
    void geometricRepresentation(const std::string& type, const FileLoc& loc) override;
    void system(const std::string& command, const FileLoc& loc) override;

    void option(const std::string& name, ri::ParamList params, const FileLoc& loc) override;
    void format(int xres, int yres, float pixelAspect, const FileLoc& loc) override;
    void frameAspectRatio(float aspect, const FileLoc& loc) override;
    /// Fits a frame's resolution to its FrameAspectRatio (RI Spec 3.2).
    static void fitFrameAspectRatio(Options& o);
    void screenWindow(float left, float right, float bottom, float top, const FileLoc& loc) override;
    void cropWindow(float xmin, float xmax, float ymin, float ymax, const FileLoc& loc) override;
    void projection(const std::string& name, ri::ParamList params, const FileLoc& loc) override;
    void clipping(float nearZ, float farZ, const FileLoc& loc) override;
    void clippingPlane(const Vec3& point, const Vec3& normal, const FileLoc& loc) override;
    void depthOfField(const std::vector<float>& args, const FileLoc& loc) override;
    void shutter(float open, float close, const FileLoc& loc) override;
    void pixelVariance(float v, const FileLoc& loc) override;
    void pixelSamples(float xs, float ys, const FileLoc& loc) override;
    void pixelFilter(const std::string& name, float xwidth, float ywidth, const FileLoc& loc) override;
    void exposure(float gain, float gamma, const FileLoc& loc) override;
    void imager(const std::string& name, ri::ParamList params, const FileLoc& loc) override;
    void quantize(const std::string& type, float one, float qmin, float qmax, float dither, const FileLoc& loc) override;
    void display(const std::string& name, const std::string& driver, const std::string& mode, ri::ParamList params,
                 const FileLoc& loc) override;
    void displayChannel(const std::string& channel, ri::ParamList params, const FileLoc& loc) override;
    void hider(const std::string& name, ri::ParamList params, const FileLoc& loc) override;
    void colorSamples(const std::vector<float>& nRGB, const std::vector<float>& RGBn, const FileLoc& loc) override;
    void relativeDetail(float v, const FileLoc& loc) override;

    void attribute(const std::string& name, ri::ParamList params, const FileLoc& loc) override;
    void color(const Color& c, const FileLoc& loc) override;
    void opacity(const Color& c, const FileLoc& loc) override;
    void textureCoordinates(const std::array<float, 8>& st, const FileLoc& loc) override;
    void matte(bool on, const FileLoc& loc) override;
    void shadingRate(float rate, const FileLoc& loc) override;
    void shadingInterpolation(const std::string& type, const FileLoc& loc) override;
    void sides(int n, const FileLoc& loc) override;
    void orientation(const std::string& o, const FileLoc& loc) override;
    void reverseOrientation(const FileLoc& loc) override;
    void basis(const ri::BasisSpec& u, int ustep, const ri::BasisSpec& v, int vstep, const FileLoc& loc) override;
    void bound(const std::array<float, 6>& b, const FileLoc& loc) override;
    void detail(const std::array<float, 6>& b, const FileLoc& loc) override;
    void detailRange(const std::array<float, 4>& r, const FileLoc& loc) override;
    void geometricApproximation(const std::string& type, float value, const FileLoc& loc) override;
    void surface(const std::string& name, ri::ParamList params, const FileLoc& loc) override;
    void displacement(const std::string& name, ri::ParamList params, const FileLoc& loc) override;
    void atmosphere(const std::string& name, ri::ParamList params, const FileLoc& loc) override;
    void interior(const std::string& name, ri::ParamList params, const FileLoc& loc) override;
    void exterior(const std::string& name, ri::ParamList params, const FileLoc& loc) override;
    void deformation(const std::string& name, ri::ParamList params, const FileLoc& loc) override;
    void lightSource(const std::string& name, const std::string& handle, ri::ParamList params,
                     const FileLoc& loc) override;
    void areaLightSource(const std::string& name, const std::string& handle, ri::ParamList params,
                         const FileLoc& loc) override;
    void illuminate(const std::string& handle, bool on, const FileLoc& loc) override;
    void trimCurve(const ri::RequestArgs& args, const FileLoc& loc) override;

    void primitive(const std::string& type, ri::RequestArgs args, ri::ParamList params, const FileLoc& loc) override;

    void makeTexture(const std::string& picture, const std::string& texture, const std::string& swrap,
                     const std::string& twrap, const std::string& filter, float swidth, float twidth,
                     ri::ParamList params, const FileLoc& loc) override;
    void makeBump(const std::string& picture, const std::string& texture, const std::string& swrap,
                  const std::string& twrap, const std::string& filter, float swidth, float twidth,
                  ri::ParamList params, const FileLoc& loc) override;
    void makeLatLongEnvironment(const std::string& picture, const std::string& texture, const std::string& filter,
                                float swidth, float twidth, ri::ParamList params, const FileLoc& loc) override;
    void makeCubeFaceEnvironment(const std::array<std::string, 6>& faces, const std::string& texture, float fov,
                                 const std::string& filter, float swidth, float twidth, ri::ParamList params,
                                 const FileLoc& loc) override;
    void makeShadow(const std::string& picture, const std::string& texture, ri::ParamList params,
                    const FileLoc& loc) override;

private:
    /// Option "shutter" "opening" and Camera "shutteropening": the fractions
    /// of the shutter interval where it is fully open (a ramp on each side).
    void setShutterOpening(const char* request, const ri::Param& p);
    enum class Block { Frame, World, Attribute, Transform, Solid, Object, Motion, Resource };
    /// The part of the graphics state AttributeBegin saves.
    struct State {
        std::shared_ptr<Attributes> attrs;
        Mat4 transform;  // at the shutter's opening
        /// The current transform over the shutter when a motion block moved
        /// it; null: `transform` is all of it.
        std::shared_ptr<const MotionTransform> motion;
        int solid = -1;  // the innermost open CSG node (WorldRecord::solids); -1: none
    };
    /// What an open MotionBegin block has collected: one transform or one
    /// primitive per time.
    struct MotionBlock {
        std::vector<float> times;
        FileLoc loc;
        std::vector<TransformRequest> transforms;  // each request, with its own matrix
        bool absolute = false;          // Transform/Identity requests: they replace the current transform
        std::vector<PrimitiveRecord> shapes;
        int requests = 0;               // every request seen in the block
        bool warnedUnblurred = false;   // skipMotionSample() said so
    };
    struct OpenBlock {
        Block kind;
        FileLoc loc;
        State saved;
        std::shared_ptr<Options> savedOptions;                  // Frame only
        std::shared_ptr<std::map<std::string, Mat4>> savedSpaces;  // Frame only
        std::shared_ptr<std::map<std::string, State>> savedResources;  // Resource only
    };
    /// A primitive inside ObjectBegin/ObjectEnd, relative to the object's
    /// coordinate system (the transform at ObjectBegin).
    struct ObjectPrim {
        PrimitiveRecord record;   // its attributes: the state inside the definition
        Mat4 objectFromPrim;
        /// A transform moving inside the definition (a motion block there),
        /// relative to the object's space; null when it does not move.
        std::shared_ptr<const MotionTransform> objectFromPrimMotion;
        std::shared_ptr<const Attributes> atBegin;  // the state at ObjectBegin
    };
    struct ObjectDefinition {
        std::vector<ObjectPrim> pieces;
        size_t bytes = 0;  // about what the pieces hold (recordBytes)
    };

    Attributes& mutableAttributes();
    std::shared_ptr<ShaderRecord> makeShader(const std::string& name, ri::ParamList params, const FileLoc& loc) const;
    bool optionsAllowed(const char* request, const FileLoc& loc);
    bool requireWorld(const std::string& request, const FileLoc& loc);
    /// Whether a light request may add its light now; one before WorldBegin
    /// is kept for the world.
    bool lightAllowed(const char* request, const std::string& name, const std::string& handle,
                      const ri::ParamList& params, const FileLoc& loc);
    /// LightSource and AreaLightSource: the light joins the current light
    /// list (on until the attribute block ends, or Illuminate).
    void addLight(const char* request, const std::string& name, const std::string& handle, ri::ParamList params,
                  const FileLoc& loc, bool area);
    /// Inside a motion block, true for every request after the block's
    /// first (for requests that are not blurred: only the first counts),
    /// warned once a block.
    bool skipMotionSample(const char* request, const FileLoc& loc);
    /// The current transform becomes `m`, not moving.
    void setTransform(const Mat4& m);
    /// At `Projection`: the current transform is the screen transformation
    /// (RI Spec 3.2). Its 2D affine x/y part (scale, rotation, shear,
    /// mirror, offset) goes to the options; a depth part or a projective
    /// part is warned about at `loc` and dropped.
    void takeScreenTransform(const FileLoc& loc);
    /// Composes a transform request; inside a motion block, collects it.
    void concat(const Mat4& m, bool absolute = false) { concat(TransformRequest::of(m), absolute); }
    void concat(const TransformRequest& request, bool absolute = false);
    /// The record of a primitive request, with the current transform and
    /// attributes (and its motion).
    void placeRecord(PrimitiveRecord& r) const;
    /// Checks a Procedural request's name, strings and bound.
    bool proceduralValid(ri::RequestArgs& args, const FileLoc& loc);
    bool boundValid(ri::RequestArgs& args, const FileLoc& loc);
    /// Adds a finished primitive record to the world or the object being defined.
    void emitPrimitive(PrimitiveRecord r);
    /// Appends a plain Polygon to the world's last record when that is a
    /// Polygon (or a run of them) with the same attributes and transform;
    /// false (nothing changed) otherwise. See PrimitiveRecord.
    bool appendToPolygonRun(PrimitiveRecord& r);
    bool currentIsLeft(const Mat4& transform) const;
    void push(Block kind, const FileLoc& loc);
    /// Pops the innermost block of `kind`; reports and returns false when it
    /// is not the innermost (Attribute-like blocks) or not open at all.
    /// World and Frame ends close any blocks left open inside them.
    bool pop(Block kind, const char* request, const FileLoc& loc, OpenBlock* out);
    /// Reports the blocks m_blocks[first..] (innermost first) as left open,
    /// at most kMaxListedOpenBlocks of them, then one line for the rest.
    void reportOpenBlocks(size_t first, const char* request, const FileLoc& loc);
    void unsupported(const std::string& key, const FileLoc& loc, const std::string& what);
    /// The CSG leaf a primitive given now belongs to (a new "primitive"
    /// node when the innermost solid is an operation); -1 outside CSG.
    int solidLeaf(const FileLoc& loc);
    std::string expandSearchPath(const std::string& kind, const std::string& value) const;

    SceneSink& m_sink;
    Diagnostics& m_diag;
    Options m_options;
    State m_state;
    std::vector<OpenBlock> m_blocks;
    std::unique_ptr<WorldRecord> m_world;
    int m_frame = -1;
    int m_defaultFrame = -1;
    std::map<std::string, Mat4> m_cameraSpaces;  // named before WorldBegin: cameraFromNamed
    /// `Camera "name"`: the current transform when it was given, that
    /// camera's cameraFromWorld; at WorldBegin the named space is its camera
    /// space.
    std::map<std::string, Mat4> m_namedCameras;
    /// `Resource "name" "attributes"` saved states, scoped by ResourceBegin/End.
    std::map<std::string, State> m_resources;
    std::map<std::string, int> m_lightHandles;   // handle -> index into m_world->lights
    /// Lights given before WorldBegin (as the RenderMan Companion writes
    /// them), in camera-relative shader space; each world of the frame
    /// starts with them on.
    struct PreWorldLight {
        std::string name, handle;
        ri::ParamList params;
        Mat4 cameraFromShader;
        bool area = false;
        FileLoc loc;
        bool on = true;  // Illuminate before WorldBegin may turn it off
    };
    std::vector<PreWorldLight> m_preWorldLights;
    std::map<std::string, ri::ParamDecl> m_declarations;  // by Declare, by name
    std::map<std::string, ObjectDefinition> m_objects;
    size_t m_objectBytes = 0;                    // of every definition together
    std::string m_objectHandle;                  // non-empty while defining an object
    std::shared_ptr<const Attributes> m_objectAttributesAtBegin;
    Mat4 m_objectFromCurrentAtBegin;
    std::unique_ptr<MotionBlock> m_motion;  // the open motion block, if any
    int m_archiveReads = 0;              // ReadArchive requests of the current frame (or before the first)
    bool m_archiveBudgetReported = false;
    bool m_procedural = false;           // beginProcedural: the contents of a procedural primitive
    std::map<std::string, std::string> m_defaultSearchPaths;
};

}  // namespace umbra::scene
