#pragma once
// The request interface: the RIB parser calls one method of a Target per
// request, with arguments already validated (count and types) and the
// request's source location. Like pbrt-v4's ParserTarget, the parser never
// builds scene or renderer objects; scene::Builder is the main Target.

#include "umbra/ri/expression.h"
#include "umbra/ri/param_list.h"
#include "umbra/util/error.h"
#include "umbra/util/math.h"

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace umbra::ri {

/// Positional arguments of a geometry request, in the order given:
/// every float value (scalars and float arrays flattened), every integer
/// value (scalars and integer arrays flattened), every string (scalars and
/// string arrays flattened), and each integer array on its own.
/// E.g. PointsPolygons [3 3] [0 1 2 0 2 3]: ints = 3 3 0 1 2 0 2 3,
/// intArrays = {{3 3}, {0 1 2 0 2 3}}; NuPatch: ints = nu uorder nv vorder,
/// floats = uknot... umin umax vknot... vmin vmax.
struct RequestArgs {
    std::vector<float> floats;
    std::vector<int> ints;
    std::vector<std::string> strings;
    std::vector<std::vector<int>> intArrays;
};

/// A `Basis` argument: a standard basis by name, or an explicit matrix
/// (16 floats, row by row exactly as written in the RIB).
struct BasisSpec {
    std::string name;  // empty: use `matrix`
    std::array<float, 16> matrix{};
};

/// ReadArchive requests one frame may make unless Option "limits"
/// "archivereads" says otherwise: archives that each read the next twice,
/// 30 deep, stay within the nesting limit but would read 2^30 files.
constexpr int kDefaultArchiveReads = 10000;

/// Decompressed bytes one gzip RIB stream may expand to unless Option
/// "limits" "decompressedmb" says otherwise: a few MB of gzip can hold
/// terabytes of whitespace.
constexpr uint64_t kDefaultDecompressedBytes = uint64_t(4) << 30;

/// Receives parsed requests. Every method has a default that calls
/// unhandled(), so a partial target (a test, a tool) overrides only what it
/// needs; scene::Builder overrides all of them.
class Target {
public:
    virtual ~Target() = default;

    /// Called for a request this target does not override.
    virtual void unhandled(std::string_view request, const FileLoc& loc) {}
    /// Directories `ReadArchive` searches after the including file's own
    /// directory (Option "searchpath" "archive").
    virtual std::vector<std::string> archiveSearchPath() const { return {}; }
    /// Decompressed bytes a gzip stream may expand to; read as the stream
    /// is inflated, so an Option early in a file applies to its rest.
    virtual uint64_t decompressedByteBudget() const { return kDefaultDecompressedBytes; }
    /// After the last request of the top-level input (not of archives).
    virtual void endOfInput(const FileLoc& loc) {}
    /// The value an `IfBegin`/`ElseIf` reference names ("user:pass",
    /// "Option:user:pass", "Attribute:identifier:name", "Frame"); false
    /// when it names nothing.
    virtual bool conditionValue(const std::string& name, ExprValue* out) const { return false; }

    virtual void version(float v, const FileLoc& loc) { unhandled("version", loc); }
    virtual void declare(const ParamDecl& decl, const FileLoc& loc) { unhandled("Declare", loc); }
    virtual void errorHandler(const std::string& name, const FileLoc& loc) { unhandled("ErrorHandler", loc); }
    /// Called for each archive found, before the parser reads it. False
    /// refuses the read (the target has reported why): scene::Builder
    /// keeps each frame within its archive-read budget.
    virtual bool readArchive(const std::string& resolvedPath, const FileLoc& loc) {
        unhandled("ReadArchive", loc);
        return true;
    }
    /// False while the requests read go to nothing rendered (a frame left
    /// out by `--frames`): the parser then skips ReadArchive requests
    /// without looking for the file.
    virtual bool archivesWanted() const { return true; }

    // Blocks.
    virtual void frameBegin(int frame, const FileLoc& loc) { unhandled("FrameBegin", loc); }
    virtual void frameEnd(const FileLoc& loc) { unhandled("FrameEnd", loc); }
    virtual void worldBegin(const FileLoc& loc) { unhandled("WorldBegin", loc); }
    virtual void worldEnd(const FileLoc& loc) { unhandled("WorldEnd", loc); }
    virtual void attributeBegin(const FileLoc& loc) { unhandled("AttributeBegin", loc); }
    virtual void attributeEnd(const FileLoc& loc) { unhandled("AttributeEnd", loc); }
    virtual void transformBegin(const FileLoc& loc) { unhandled("TransformBegin", loc); }
    virtual void transformEnd(const FileLoc& loc) { unhandled("TransformEnd", loc); }
    virtual void solidBegin(const std::string& operation, const FileLoc& loc) { unhandled("SolidBegin", loc); }
    virtual void solidEnd(const FileLoc& loc) { unhandled("SolidEnd", loc); }
    virtual void objectBegin(const std::string& handle, const FileLoc& loc) { unhandled("ObjectBegin", loc); }
    virtual void objectEnd(const FileLoc& loc) { unhandled("ObjectEnd", loc); }
    virtual void objectInstance(const std::string& handle, const FileLoc& loc) { unhandled("ObjectInstance", loc); }
    virtual void motionBegin(const std::vector<float>& times, const FileLoc& loc) { unhandled("MotionBegin", loc); }
    virtual void motionEnd(const FileLoc& loc) { unhandled("MotionEnd", loc); }

    // Transforms. Matrices are already in umbra's column-vector convention
    // (Mat4::fromRib applied).
    virtual void identity(const FileLoc& loc) { unhandled("Identity", loc); }
    virtual void transform(const Mat4& m, const FileLoc& loc) { unhandled("Transform", loc); }
    virtual void concatTransform(const Mat4& m, const FileLoc& loc) { unhandled("ConcatTransform", loc); }
    virtual void translate(const Vec3& d, const FileLoc& loc) { unhandled("Translate", loc); }
    virtual void rotate(float angleDeg, const Vec3& axis, const FileLoc& loc) { unhandled("Rotate", loc); }
    virtual void scale(const Vec3& s, const FileLoc& loc) { unhandled("Scale", loc); }
    virtual void skew(float angleDeg, const Vec3& a, const Vec3& b, const FileLoc& loc) { unhandled("Skew", loc); }
    virtual void perspective(float fovDeg, const FileLoc& loc) { unhandled("Perspective", loc); }
    virtual void coordinateSystem(const std::string& name, const FileLoc& loc) { unhandled("CoordinateSystem", loc); }
    virtual void scopedCoordinateSystem(const std::string& name, const FileLoc& loc) { unhandled("ScopedCoordinateSystem", loc); }
    virtual void coordSysTransform(const std::string& name, const FileLoc& loc) { unhandled("CoordSysTransform", loc); }
    /// RenderMan 14's `Camera "name"`: the current camera transform, named.
    virtual void camera(const std::string& name, ParamList params, const FileLoc& loc) { unhandled("Camera", loc); }

    // RenderMan 13's named attribute states: `Resource "handle" "attributes"
    // "string operation" "save"|"restore"`, scoped by ResourceBegin/End.
    virtual void resource(const std::string& handle, const std::string& type, ParamList params, const FileLoc& loc) { unhandled("Resource", loc); }
    virtual void resourceBegin(const FileLoc& loc) { unhandled("ResourceBegin", loc); }
    virtual void resourceEnd(const FileLoc& loc) { unhandled("ResourceEnd", loc); }
    virtual void geometricRepresentation(const std::string& type, const FileLoc& loc) { unhandled("GeometricRepresentation", loc); }
    /// `System "command"`: never run.
    virtual void system(const std::string& command, const FileLoc& loc) { unhandled("System", loc); }

    // Options.
    virtual void option(const std::string& name, ParamList params, const FileLoc& loc) { unhandled("Option", loc); }
    virtual void format(int xres, int yres, float pixelAspect, const FileLoc& loc) { unhandled("Format", loc); }
    virtual void frameAspectRatio(float aspect, const FileLoc& loc) { unhandled("FrameAspectRatio", loc); }
    virtual void screenWindow(float left, float right, float bottom, float top, const FileLoc& loc) { unhandled("ScreenWindow", loc); }
    virtual void cropWindow(float xmin, float xmax, float ymin, float ymax, const FileLoc& loc) { unhandled("CropWindow", loc); }
    virtual void projection(const std::string& name, ParamList params, const FileLoc& loc) { unhandled("Projection", loc); }
    virtual void clipping(float nearZ, float farZ, const FileLoc& loc) { unhandled("Clipping", loc); }
    virtual void clippingPlane(const Vec3& point, const Vec3& normal, const FileLoc& loc) { unhandled("ClippingPlane", loc); }
    virtual void depthOfField(const std::vector<float>& fstopFocalLengthDistance, const FileLoc& loc) { unhandled("DepthOfField", loc); }
    virtual void shutter(float open, float close, const FileLoc& loc) { unhandled("Shutter", loc); }
    virtual void pixelVariance(float v, const FileLoc& loc) { unhandled("PixelVariance", loc); }
    virtual void pixelSamples(float xs, float ys, const FileLoc& loc) { unhandled("PixelSamples", loc); }
    virtual void pixelFilter(const std::string& name, float xwidth, float ywidth, const FileLoc& loc) { unhandled("PixelFilter", loc); }
    virtual void exposure(float gain, float gamma, const FileLoc& loc) { unhandled("Exposure", loc); }
    virtual void imager(const std::string& name, ParamList params, const FileLoc& loc) { unhandled("Imager", loc); }
    virtual void quantize(const std::string& type, float one, float qmin, float qmax, float dither, const FileLoc& loc) { unhandled("Quantize", loc); }
    virtual void display(const std::string& name, const std::string& driver, const std::string& mode, ParamList params, const FileLoc& loc) { unhandled("Display", loc); }
    virtual void displayChannel(const std::string& channel, ParamList params, const FileLoc& loc) { unhandled("DisplayChannel", loc); }
    virtual void hider(const std::string& name, ParamList params, const FileLoc& loc) { unhandled("Hider", loc); }
    virtual void colorSamples(const std::vector<float>& nRGB, const std::vector<float>& RGBn, const FileLoc& loc) { unhandled("ColorSamples", loc); }
    virtual void relativeDetail(float v, const FileLoc& loc) { unhandled("RelativeDetail", loc); }

    // Attributes.
    virtual void attribute(const std::string& name, ParamList params, const FileLoc& loc) { unhandled("Attribute", loc); }
    virtual void color(const Color& c, const FileLoc& loc) { unhandled("Color", loc); }
    virtual void opacity(const Color& c, const FileLoc& loc) { unhandled("Opacity", loc); }
    virtual void textureCoordinates(const std::array<float, 8>& st, const FileLoc& loc) { unhandled("TextureCoordinates", loc); }
    virtual void matte(bool on, const FileLoc& loc) { unhandled("Matte", loc); }
    virtual void shadingRate(float rate, const FileLoc& loc) { unhandled("ShadingRate", loc); }
    virtual void shadingInterpolation(const std::string& type, const FileLoc& loc) { unhandled("ShadingInterpolation", loc); }
    virtual void sides(int n, const FileLoc& loc) { unhandled("Sides", loc); }
    virtual void orientation(const std::string& o, const FileLoc& loc) { unhandled("Orientation", loc); }
    virtual void reverseOrientation(const FileLoc& loc) { unhandled("ReverseOrientation", loc); }
    virtual void basis(const BasisSpec& u, int ustep, const BasisSpec& v, int vstep, const FileLoc& loc) { unhandled("Basis", loc); }
    virtual void bound(const std::array<float, 6>& b, const FileLoc& loc) { unhandled("Bound", loc); }
    virtual void detail(const std::array<float, 6>& b, const FileLoc& loc) { unhandled("Detail", loc); }
    virtual void detailRange(const std::array<float, 4>& r, const FileLoc& loc) { unhandled("DetailRange", loc); }
    virtual void geometricApproximation(const std::string& type, float value, const FileLoc& loc) { unhandled("GeometricApproximation", loc); }
    virtual void surface(const std::string& name, ParamList params, const FileLoc& loc) { unhandled("Surface", loc); }
    virtual void displacement(const std::string& name, ParamList params, const FileLoc& loc) { unhandled("Displacement", loc); }
    virtual void atmosphere(const std::string& name, ParamList params, const FileLoc& loc) { unhandled("Atmosphere", loc); }
    virtual void interior(const std::string& name, ParamList params, const FileLoc& loc) { unhandled("Interior", loc); }
    virtual void exterior(const std::string& name, ParamList params, const FileLoc& loc) { unhandled("Exterior", loc); }
    virtual void deformation(const std::string& name, ParamList params, const FileLoc& loc) { unhandled("Deformation", loc); }
    /// `handle` is the RIB sequence number or string handle, as text.
    virtual void lightSource(const std::string& name, const std::string& handle, ParamList params, const FileLoc& loc) { unhandled("LightSource", loc); }
    virtual void areaLightSource(const std::string& name, const std::string& handle, ParamList params, const FileLoc& loc) { unhandled("AreaLightSource", loc); }
    virtual void illuminate(const std::string& handle, bool on, const FileLoc& loc) { unhandled("Illuminate", loc); }
    virtual void trimCurve(const RequestArgs& args, const FileLoc& loc) { unhandled("TrimCurve", loc); }

    /// Every geometry request (Sphere ... Geometry, see docs/rib.md): the
    /// request name, its validated positional arguments and parameters.
    virtual void primitive(const std::string& type, RequestArgs args, ParamList params, const FileLoc& loc) { unhandled(type, loc); }

    // File conversions.
    virtual void makeTexture(const std::string& picture, const std::string& texture, const std::string& swrap,
                             const std::string& twrap, const std::string& filter, float swidth, float twidth,
                             ParamList params, const FileLoc& loc) { unhandled("MakeTexture", loc); }
    virtual void makeBump(const std::string& picture, const std::string& texture, const std::string& swrap,
                          const std::string& twrap, const std::string& filter, float swidth, float twidth,
                          ParamList params, const FileLoc& loc) { unhandled("MakeBump", loc); }
    virtual void makeLatLongEnvironment(const std::string& picture, const std::string& texture, const std::string& filter,
                                        float swidth, float twidth, ParamList params, const FileLoc& loc) { unhandled("MakeLatLongEnvironment", loc); }
    /// `faces`: px nx py ny pz nz.
    virtual void makeCubeFaceEnvironment(const std::array<std::string, 6>& faces, const std::string& texture, float fov,
                                         const std::string& filter, float swidth, float twidth, ParamList params,
                                         const FileLoc& loc) { unhandled("MakeCubeFaceEnvironment", loc); }
    virtual void makeShadow(const std::string& picture, const std::string& texture, ParamList params, const FileLoc& loc) { unhandled("MakeShadow", loc); }
};

}  // namespace umbra::ri
