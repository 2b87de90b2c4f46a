#include "umbra/ri/parser.h"
#include "umbra/util/interrupt.h"

#include "umbra/ri/lexer.h"

#include <zlib.h>

#include <cerrno>
#include <cmath>
#include <climits>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <unistd.h>
#include <unordered_map>
#include <optional>

namespace umbra::ri {

namespace {

/// A value as written in the RIB, before it is matched to an argument or a
/// parameter.
struct Value {
    enum Kind { Number, String, NumArray, StrArray };
    Kind kind = Number;
    int line = 0, column = 0;
    double num = 0;
    std::string str;
    std::vector<double> nums;
    std::vector<std::string> strs;
};

/// A positional argument matched to a signature code.
struct Arg {
    enum Kind { Missing, Number, String, NumArray, StrArray };
    Kind kind = Missing;
    bool integer = false;  // matched an integer code (i or I)
    double num = 0;
    std::string str;
    std::vector<double> nums;
    std::vector<std::string> strs;
};

bool integral(double v) { return v == std::floor(v) && v >= double(INT_MIN) && v <= double(INT_MAX); }

std::string numberText(double v) {
    if (integral(v)) return fmt::format("{}", static_cast<long long>(v));
    return fmt::format("{}", v);
}

std::string describe(const Value& v) {
    switch (v.kind) {
    case Value::Number: return fmt::format("number {}", numberText(v.num));
    case Value::String: return fmt::format("string \"{}\"", v.str);
    case Value::NumArray: return fmt::format("an array of {} numbers", v.nums.size());
    case Value::StrArray: return fmt::format("an array of {} strings", v.strs.size());
    }
    return "a value";
}

/// Reads the matched arguments of one request in signature order.
class ArgReader {
public:
    explicit ArgReader(std::vector<Arg>& args) : m_args(args) {}
    bool present() const { return m_i < m_args.size() && m_args[m_i].kind != Arg::Missing; }
    float f() { return static_cast<float>(take().num); }
    int i() { return static_cast<int>(take().num); }
    std::string s() { return std::move(take().str); }
    std::string h() {
        Arg& a = take();
        return a.kind == Arg::String ? std::move(a.str) : numberText(a.num);
    }
    std::vector<float> F() {
        Arg& a = take();
        return std::vector<float>(a.nums.begin(), a.nums.end());
    }
    std::vector<std::string> S() { return std::move(take().strs); }
    Vec3 v3() {
        float x = f(), y = f(), z = f();
        return {x, y, z};
    }
    Mat4 matrix() {
        float v[16];
        for (float& x : v) x = f();
        return Mat4::fromRib(v);
    }
    BasisSpec basis() {
        Arg& a = take();
        BasisSpec b;
        if (a.kind == Arg::String)
            b.name = std::move(a.str);
        else
            for (size_t k = 0; k < 16 && k < a.nums.size(); ++k) b.matrix[k] = static_cast<float>(a.nums[k]);
        return b;
    }
    /// All remaining arguments as geometry arguments.
    RequestArgs rest() {
        RequestArgs r;
        for (; m_i < m_args.size(); ++m_i) {
            Arg& a = m_args[m_i];
            switch (a.kind) {
            case Arg::Missing: break;
            case Arg::Number:
                if (a.integer)
                    r.ints.push_back(static_cast<int>(a.num));
                else
                    r.floats.push_back(static_cast<float>(a.num));
                break;
            case Arg::String: r.strings.push_back(std::move(a.str)); break;
            case Arg::StrArray:
                for (auto& s : a.strs) r.strings.push_back(std::move(s));
                break;
            case Arg::NumArray:
                if (a.integer) {
                    std::vector<int> v(a.nums.size());
                    for (size_t k = 0; k < v.size(); ++k) v[k] = static_cast<int>(a.nums[k]);
                    r.ints.insert(r.ints.end(), v.begin(), v.end());
                    r.intArrays.push_back(std::move(v));
                } else {
                    for (double d : a.nums) r.floats.push_back(static_cast<float>(d));
                }
                break;
            }
        }
        return r;
    }

private:
    Arg& take() {
        static Arg missing;
        return m_i < m_args.size() ? m_args[m_i++] : missing;
    }
    std::vector<Arg>& m_args;
    size_t m_i = 0;
};

using Handler = void (*)(Target&, const std::string& request, ArgReader&, ParamList&&, const FileLoc&);

/// One RIB request: its positional signature, argument names (for
/// messages), whether a parameter list may follow, and its dispatch.
/// Signature codes: f float, i integer, s string, h handle (integer or
/// string), F/I/S float/integer/string array, M 16 floats, B basis (name or
/// 16-float array); after '|' the rest is optional (absent when the next
/// value is a string or there is none). Consecutive f/i codes accept their
/// numbers bare or grouped in [ ].
struct RequestSpec {
    const char* name;
    const char* sig;
    const char* argNames;
    bool params;
    Handler handler;  // null: handled by the parser itself
};

#define UMBRA_H(...) [](Target& t, const std::string& req, ArgReader& a, ParamList&& p, const FileLoc& l) { __VA_ARGS__; }

void geometry(Target& t, const std::string& req, ArgReader& a, ParamList&& p, const FileLoc& l) {
    t.primitive(req, a.rest(), std::move(p), l);
}

// clang-format off
const RequestSpec kRequests[] = {
    {"version", "f", "version", false, UMBRA_H(t.version(a.f(), l))},
    {"Declare", "ss", "name declaration", false, nullptr},
    {"ReadArchive", "s", "filename", true, nullptr},
    {"ArchiveBegin", "s", "name", true, nullptr},
    {"ArchiveEnd", "", "", false, nullptr},
    {"IfBegin", "s", "condition", false, nullptr},
    {"ElseIf", "s", "condition", false, nullptr},
    {"Else", "", "", false, nullptr},
    {"IfEnd", "", "", false, nullptr},
    {"System", "s", "command", false, UMBRA_H(t.system(a.s(), l))},
    {"Resource", "ss", "handle type", true, UMBRA_H(std::string h = a.s(); std::string ty = a.s(); t.resource(h, ty, std::move(p), l))},
    {"ResourceBegin", "", "", false, UMBRA_H(t.resourceBegin(l))},
    {"ResourceEnd", "", "", false, UMBRA_H(t.resourceEnd(l))},
    {"ErrorHandler", "s", "handler", false, UMBRA_H(t.errorHandler(a.s(), l))},
    {"FrameBegin", "i", "frame", false, UMBRA_H(t.frameBegin(a.i(), l))},
    {"FrameEnd", "", "", false, UMBRA_H(t.frameEnd(l))},
    {"WorldBegin", "", "", false, UMBRA_H(t.worldBegin(l))},
    {"WorldEnd", "", "", false, UMBRA_H(t.worldEnd(l))},
    {"AttributeBegin", "", "", false, UMBRA_H(t.attributeBegin(l))},
    {"AttributeEnd", "", "", false, UMBRA_H(t.attributeEnd(l))},
    {"TransformBegin", "", "", false, UMBRA_H(t.transformBegin(l))},
    {"TransformEnd", "", "", false, UMBRA_H(t.transformEnd(l))},
    {"SolidBegin", "s", "operation", false, UMBRA_H(t.solidBegin(a.s(), l))},
    {"SolidEnd", "", "", false, UMBRA_H(t.solidEnd(l))},
    {"ObjectBegin", "h", "handle", false, UMBRA_H(t.objectBegin(a.h(), l))},
    {"ObjectEnd", "", "", false, UMBRA_H(t.objectEnd(l))},
    {"ObjectInstance", "h", "handle", false, UMBRA_H(t.objectInstance(a.h(), l))},
    {"MotionBegin", "F", "times", false, UMBRA_H(t.motionBegin(a.F(), l))},
    {"MotionEnd", "", "", false, UMBRA_H(t.motionEnd(l))},

    {"Identity", "", "", false, UMBRA_H(t.identity(l))},
    {"Transform", "M", "matrix", false, UMBRA_H(t.transform(a.matrix(), l))},
    {"ConcatTransform", "M", "matrix", false, UMBRA_H(t.concatTransform(a.matrix(), l))},
    {"Translate", "fff", "dx dy dz", false, UMBRA_H(t.translate(a.v3(), l))},
    {"Rotate", "ffff", "angle dx dy dz", false, UMBRA_H(float ang = a.f(); t.rotate(ang, a.v3(), l))},
    {"Scale", "fff", "sx sy sz", false, UMBRA_H(t.scale(a.v3(), l))},
    {"Skew", "fffffff", "angle dx1 dy1 dz1 dx2 dy2 dz2", false,
     UMBRA_H(float ang = a.f(); Vec3 d1 = a.v3(); t.skew(ang, d1, a.v3(), l))},
    {"Perspective", "f", "fov", false, UMBRA_H(t.perspective(a.f(), l))},
    {"CoordinateSystem", "s", "name", false, UMBRA_H(t.coordinateSystem(a.s(), l))},
    // PRMan's: a CoordinateSystem whose name the end of its block forgets.
    {"ScopedCoordinateSystem", "s", "name", false, UMBRA_H(t.scopedCoordinateSystem(a.s(), l))},
    {"CoordSysTransform", "s", "name", false, UMBRA_H(t.coordSysTransform(a.s(), l))},
    {"Camera", "s", "name", true, UMBRA_H(t.camera(a.s(), std::move(p), l))},

    {"Option", "s", "name", true, UMBRA_H(t.option(a.s(), std::move(p), l))},
    {"Format", "iif", "xresolution yresolution pixelaspectratio", false,
     UMBRA_H(int x = a.i(); int y = a.i(); t.format(x, y, a.f(), l))},
    {"FrameAspectRatio", "f", "aspect", false, UMBRA_H(t.frameAspectRatio(a.f(), l))},
    {"ScreenWindow", "ffff", "left right bottom top", false,
     UMBRA_H(float x0 = a.f(); float x1 = a.f(); float y0 = a.f(); t.screenWindow(x0, x1, y0, a.f(), l))},
    {"CropWindow", "ffff", "xmin xmax ymin ymax", false,
     UMBRA_H(float x0 = a.f(); float x1 = a.f(); float y0 = a.f(); t.cropWindow(x0, x1, y0, a.f(), l))},
    {"Projection", "s", "name", true, UMBRA_H(t.projection(a.s(), std::move(p), l))},
    {"Clipping", "ff", "near far", false, UMBRA_H(float n = a.f(); t.clipping(n, a.f(), l))},
    {"ClippingPlane", "ffffff", "x y z nx ny nz", false, UMBRA_H(Vec3 pt = a.v3(); t.clippingPlane(pt, a.v3(), l))},
    {"DepthOfField", "|fff", "fstop focallength focaldistance", false,
     UMBRA_H(std::vector<float> v; while (a.present()) v.push_back(a.f()); t.depthOfField(v, l))},
    {"Shutter", "ff", "opentime closetime", false, UMBRA_H(float o = a.f(); t.shutter(o, a.f(), l))},
    {"PixelVariance", "f", "variation", false, UMBRA_H(t.pixelVariance(a.f(), l))},
    {"PixelSamples", "ff", "xsamples ysamples", false, UMBRA_H(float x = a.f(); t.pixelSamples(x, a.f(), l))},
    {"PixelFilter", "sff", "filter xwidth ywidth", false,
     UMBRA_H(std::string n = a.s(); float x = a.f(); t.pixelFilter(n, x, a.f(), l))},
    {"Exposure", "ff", "gain gamma", false, UMBRA_H(float g = a.f(); t.exposure(g, a.f(), l))},
    {"Imager", "s", "name", true, UMBRA_H(t.imager(a.s(), std::move(p), l))},
    {"Quantize", "sffff", "type one min max ditheramplitude", false,
     UMBRA_H(std::string ty = a.s(); float one = a.f(); float mn = a.f(); float mx = a.f();
             t.quantize(ty, one, mn, mx, a.f(), l))},
    {"Display", "sss", "name type mode", true,
     UMBRA_H(std::string n = a.s(); std::string ty = a.s(); std::string m = a.s();
             t.display(n, ty, m, std::move(p), l))},
    {"DisplayChannel", "s", "channel", true, UMBRA_H(t.displayChannel(a.s(), std::move(p), l))},
    {"Hider", "s", "type", true, UMBRA_H(t.hider(a.s(), std::move(p), l))},
    {"ColorSamples", "FF", "nRGB RGBn", false, UMBRA_H(std::vector<float> n = a.F(); t.colorSamples(n, a.F(), l))},
    {"RelativeDetail", "f", "relativedetail", false, UMBRA_H(t.relativeDetail(a.f(), l))},

    {"Attribute", "s", "name", true, UMBRA_H(t.attribute(a.s(), std::move(p), l))},
    {"Color", "fff", "red green blue", false, UMBRA_H(t.color(a.v3(), l))},
    {"Opacity", "fff", "red green blue", false, UMBRA_H(t.opacity(a.v3(), l))},
    {"TextureCoordinates", "ffffffff", "s1 t1 s2 t2 s3 t3 s4 t4", false,
     UMBRA_H(std::array<float, 8> v; for (float& x : v) x = a.f(); t.textureCoordinates(v, l))},
    {"Matte", "i", "onoff", false, UMBRA_H(t.matte(a.i() != 0, l))},
    {"ShadingRate", "f", "size", false, UMBRA_H(t.shadingRate(a.f(), l))},
    {"ShadingInterpolation", "s", "type", false, UMBRA_H(t.shadingInterpolation(a.s(), l))},
    {"Sides", "i", "sides", false, UMBRA_H(t.sides(a.i(), l))},
    {"Orientation", "s", "orientation", false, UMBRA_H(t.orientation(a.s(), l))},
    {"ReverseOrientation", "", "", false, UMBRA_H(t.reverseOrientation(l))},
    {"Basis", "BiBi", "ubasis ustep vbasis vstep", false,
     UMBRA_H(BasisSpec u = a.basis(); int us = a.i(); BasisSpec v = a.basis(); t.basis(u, us, v, a.i(), l))},
    {"Bound", "ffffff", "xmin xmax ymin ymax zmin zmax", false,
     UMBRA_H(std::array<float, 6> v; for (float& x : v) x = a.f(); t.bound(v, l))},
    {"Detail", "ffffff", "xmin xmax ymin ymax zmin zmax", false,
     UMBRA_H(std::array<float, 6> v; for (float& x : v) x = a.f(); t.detail(v, l))},
    {"DetailRange", "ffff", "minvisible lowertransition uppertransition maxvisible", false,
     UMBRA_H(std::array<float, 4> v; for (float& x : v) x = a.f(); t.detailRange(v, l))},
    {"GeometricRepresentation", "s", "type", false, UMBRA_H(t.geometricRepresentation(a.s(), l))},
    {"GeometricApproximation", "sf", "type value", false,
     UMBRA_H(std::string ty = a.s(); t.geometricApproximation(ty, a.f(), l))},
    {"Surface", "s", "name", true, UMBRA_H(t.surface(a.s(), std::move(p), l))},
    {"Displacement", "s", "name", true, UMBRA_H(t.displacement(a.s(), std::move(p), l))},
    {"Atmosphere", "s", "name", true, UMBRA_H(t.atmosphere(a.s(), std::move(p), l))},
    {"Interior", "s", "name", true, UMBRA_H(t.interior(a.s(), std::move(p), l))},
    {"Exterior", "s", "name", true, UMBRA_H(t.exterior(a.s(), std::move(p), l))},
    {"Deformation", "s", "name", true, UMBRA_H(t.deformation(a.s(), std::move(p), l))},
    {"LightSource", "sh", "name handle", true,
     UMBRA_H(std::string n = a.s(); std::string h = a.h(); t.lightSource(n, h, std::move(p), l))},
    {"AreaLightSource", "sh", "name handle", true,
     UMBRA_H(std::string n = a.s(); std::string h = a.h(); t.areaLightSource(n, h, std::move(p), l))},
    {"Illuminate", "hi", "handle onoff", false, UMBRA_H(std::string h = a.h(); t.illuminate(h, a.i() != 0, l))},
    {"TrimCurve", "IIFFFIFFF", "ncurves order knot min max n u v w", false, UMBRA_H(t.trimCurve(a.rest(), l))},

    {"Sphere", "ffff", "radius zmin zmax thetamax", true, geometry},
    {"Cylinder", "ffff", "radius zmin zmax thetamax", true, geometry},
    {"Cone", "fff", "height radius thetamax", true, geometry},
    {"Disk", "fff", "height radius thetamax", true, geometry},
    {"Paraboloid", "ffff", "rmax zmin zmax thetamax", true, geometry},
    {"Hyperboloid", "fffffff", "x1 y1 z1 x2 y2 z2 thetamax", true, geometry},
    {"Torus", "fffff", "rmajor rminor phimin phimax thetamax", true, geometry},
    {"Polygon", "", "", true, geometry},
    {"GeneralPolygon", "I", "nvertices", true, geometry},
    {"PointsPolygons", "II", "nvertices vertices", true, geometry},
    {"PointsGeneralPolygons", "III", "nloops nvertices vertices", true, geometry},
    {"Patch", "s", "type", true, geometry},
    {"PatchMesh", "sisis", "type nu uwrap nv vwrap", true, geometry},
    {"NuPatch", "iiFffiiFff", "nu uorder uknot umin umax nv vorder vknot vmin vmax", true, geometry},
    {"SubdivisionMesh", "sII|SIIF", "scheme nvertices vertices tags nargs intargs floatargs", true, geometry},
    {"HierarchicalSubdivisionMesh", "sII|SIIFS", "scheme nvertices vertices tags nargs intargs floatargs stringargs",
     true, geometry},
    {"Points", "", "", true, geometry},
    {"Curves", "sIs", "type nvertices wrap", true, geometry},
    {"Blobby", "iIFS", "nleaf code floats strings", true, geometry},
    {"Procedural", "sSF", "name args bound", true, geometry},
    {"Procedural2", "ss", "name boundfunction", true, geometry},
    {"Geometry", "s", "type", true, geometry},

    {"MakeTexture", "sssssff", "picturename texturename swrap twrap filter swidth twidth", true,
     UMBRA_H(std::string pic = a.s(); std::string tex = a.s(); std::string sw = a.s(); std::string tw = a.s();
             std::string fi = a.s(); float sx = a.f(); float tx = a.f();
             t.makeTexture(pic, tex, sw, tw, fi, sx, tx, std::move(p), l))},
    {"MakeBump", "sssssff", "picturename texturename swrap twrap filter swidth twidth", true,
     UMBRA_H(std::string pic = a.s(); std::string tex = a.s(); std::string sw = a.s(); std::string tw = a.s();
             std::string fi = a.s(); float sx = a.f(); float tx = a.f();
             t.makeBump(pic, tex, sw, tw, fi, sx, tx, std::move(p), l))},
    {"MakeLatLongEnvironment", "sssff", "picturename texturename filter swidth twidth", true,
     UMBRA_H(std::string pic = a.s(); std::string tex = a.s(); std::string fi = a.s(); float sx = a.f();
             float tx = a.f(); t.makeLatLongEnvironment(pic, tex, fi, sx, tx, std::move(p), l))},
    {"MakeCubeFaceEnvironment", "sssssssfsff", "px nx py ny pz nz texturename fov filter swidth twidth", true,
     UMBRA_H(std::array<std::string, 6> faces; for (auto& f : faces) f = a.s(); std::string tex = a.s();
             float fov = a.f(); std::string fi = a.s(); float sx = a.f(); float tx = a.f();
             t.makeCubeFaceEnvironment(faces, tex, fov, fi, sx, tx, std::move(p), l))},
    {"MakeShadow", "ss", "picturename texturename", true,
     UMBRA_H(std::string pic = a.s(); std::string tex = a.s(); t.makeShadow(pic, tex, std::move(p), l))},
};
// clang-format on
#undef UMBRA_H

const RequestSpec* findRequest(std::string_view name) {
    static const std::unordered_map<std::string_view, const RequestSpec*> table = [] {
        std::unordered_map<std::string_view, const RequestSpec*> m;
        for (const RequestSpec& r : kRequests) m.emplace(r.name, &r);
        return m;
    }();
    auto it = table.find(name);
    return it == table.end() ? nullptr : it->second;
}

/// Requests of later RenderMan versions that umbra does not have. A file
/// written for them is warned once per request and rendered without them,
/// as Aqsis renders what it can of such a file, rather than failed with an
/// error at every use; a misspelt request is still an error.
const char* foreignRequest(std::string_view name) {
    static const std::unordered_map<std::string_view, const char*> table = {
        {"Bxdf", "a RenderMan 19+ (RIS) material umbra does not have; the current Surface shades instead"},
        {"Pattern", "a RenderMan 19+ (RIS) pattern node umbra does not have; ignored"},
        {"Integrator", "a RenderMan 19+ (RIS) integrator umbra does not have; the REYES hider renders the frame"},
        {"Light", "a RenderMan 19+ (RIS) light umbra does not have; it gives no light (LightSource does)"},
        {"LightFilter", "a RenderMan 19+ (RIS) light filter umbra does not have; ignored"},
        {"DisplayFilter", "a RenderMan 19+ (RIS) display filter umbra does not have; ignored"},
        {"SampleFilter", "a RenderMan 19+ (RIS) sample filter umbra does not have; ignored"},
        {"Shader", "a PRMan 15+ co-shader umbra does not have; ignored"},
        {"Volume", "a PRMan 16+ volume primitive umbra does not have; ignored"},
        {"VPSurface", "a PRMan visible-point shader umbra does not have; ignored"},
        {"VPAtmosphere", "a PRMan visible-point shader umbra does not have; ignored"},
        {"VPInterior", "a PRMan visible-point shader umbra does not have; ignored"},
        {"MakeBrickMap", "a PRMan brick map umbra cannot make; ignored"},
        {"EditBegin", "a PRMan re-rendering edit umbra does not have; ignored"},
        {"EditEnd", "a PRMan re-rendering edit umbra does not have; ignored"},
        {"EditAttributeBegin", "a PRMan re-rendering edit umbra does not have; ignored"},
        {"EditAttributeEnd", "a PRMan re-rendering edit umbra does not have; ignored"},
        {"EditWorldBegin", "a PRMan re-rendering edit umbra does not have; ignored"},
        {"EditWorldEnd", "a PRMan re-rendering edit umbra does not have; ignored"},
    };
    auto it = table.find(name);
    return it == table.end() ? nullptr : it->second;
}

std::string directoryOf(const std::string& path) {
    size_t slash = path.find_last_of('/');
    return slash == std::string::npos ? std::string() : path.substr(0, slash);
}

std::string joinPath(const std::string& dir, const std::string& name) {
    if (dir.empty()) return name;
    if (dir.back() == '/') return dir + name;
    return dir + "/" + name;
}

bool isRegularFile(const std::string& path) {
    std::error_code ec;
    return std::filesystem::is_regular_file(path, ec);
}

/// A file read in chunks; its first two bytes can be looked at first (is
/// it gzip?) and are then read again.
class FileSource final : public ByteSource {
public:
    explicit FileSource(std::FILE* f) : m_file(f) {}
    ~FileSource() override { std::fclose(m_file); }
    FileSource(const FileSource&) = delete;
    FileSource& operator=(const FileSource&) = delete;

    /// True when the file starts with the gzip magic number.
    bool startsWithGzip() {
        char magic[2];
        m_peeked.assign(magic, std::fread(magic, 1, 2, m_file));
        return isGzip(m_peeked);
    }
    size_t read(char* dst, size_t capacity, std::string* error) override {
        size_t got = std::min(m_peeked.size(), capacity);
        std::memcpy(dst, m_peeked.data(), got);
        m_peeked.erase(0, got);
        got += std::fread(dst + got, 1, capacity - got, m_file);
        if (got == 0 && std::ferror(m_file)) *error = "cannot read the file: read error";
        return got;
    }

private:
    std::FILE* m_file;
    std::string m_peeked;
};

/// Bytes already in memory (gzip data handed to Parser::parseString).
class MemorySource final : public ByteSource {
public:
    explicit MemorySource(std::string_view bytes) : m_bytes(bytes) {}
    size_t read(char* dst, size_t capacity, std::string*) override {
        const size_t got = std::min(capacity, m_bytes.size());
        std::memcpy(dst, m_bytes.data(), got);
        m_bytes.remove_prefix(got);
        return got;
    }

private:
    std::string_view m_bytes;
};

/// Inflates gzip data (one or more members) as it is read, within the
/// target's budget of decompressed bytes: a few MB of gzip can expand to
/// terabytes, and only the parse state, never the whole text, is kept.
class GzipSource final : public ByteSource {
public:
    GzipSource(ByteSource& compressed, const Target& target) : m_in(compressed), m_target(target) {
        // 15 + 32: a zlib or gzip header, detected automatically.
        m_ok = inflateInit2(&m_zs, 15 + 32) == Z_OK;
        m_buffer.resize(Lexer::kChunkBytes);
    }
    ~GzipSource() override {
        if (m_ok) inflateEnd(&m_zs);
    }
    GzipSource(const GzipSource&) = delete;
    GzipSource& operator=(const GzipSource&) = delete;

    size_t read(char* dst, size_t capacity, std::string* error) override {
        if (m_done) return 0;
        if (!m_ok) return fail(error, "cannot decompress: cannot initialise zlib");
        if (m_overBudget)
            return fail(error, fmt::format("the decompressed RIB is larger than {} MiB (Option \"limits\" "
                                           "\"decompressedmb\"); the rest of it is not read",
                                           m_target.decompressedByteBudget() >> 20));
        // One byte past the budget tells "exactly the budget" from "more".
        const uint64_t budget = m_target.decompressedByteBudget();
        const uint64_t room = budget >= m_produced ? budget - m_produced + 1 : 1;
        const uInt want = static_cast<uInt>(std::min<uint64_t>({capacity, room, UINT_MAX}));
        m_zs.next_out = reinterpret_cast<Bytef*>(dst);
        m_zs.avail_out = want;
        while (m_zs.avail_out == want) {
            if (m_zs.avail_in == 0 && !moreInput(1, error)) {
                if (!error->empty()) return fail(error, *error);
                if (m_midMember) return fail(error, "cannot decompress: gzip data is truncated");
                m_done = true;
                break;
            }
            m_midMember = true;
            const int rc = inflate(&m_zs, Z_NO_FLUSH);
            if (rc == Z_STREAM_END) {
                m_midMember = false;
                // Concatenated gzip members decompress to the concatenated
                // data; anything else after a member is ignored.
                moreInput(2, error);
                if (!error->empty()) return fail(error, *error);
                if (m_zs.avail_in >= 2 &&
                    isGzip(std::string_view(reinterpret_cast<const char*>(m_zs.next_in), m_zs.avail_in))) {
                    inflateReset(&m_zs);
                    continue;
                }
                m_done = true;
                break;
            }
            if (rc == Z_OK || (rc == Z_BUF_ERROR && m_zs.avail_in == 0)) continue;
            return fail(error, fmt::format("cannot decompress: gzip data is corrupt ({})",
                                           m_zs.msg ? m_zs.msg : "inflate failed"));
        }
        size_t got = want - m_zs.avail_out;
        m_produced += got;
        if (m_produced > budget) {
            // The bytes within the budget are read; the next read fails, so
            // the error stands exactly where the budget ran out.
            got -= m_produced - budget;
            m_produced = budget;
            m_overBudget = true;
            if (got == 0) return read(dst, capacity, error);
        }
        return got;
    }

private:
    size_t fail(std::string* error, std::string message) {
        *error = std::move(message);
        m_done = true;
        return 0;
    }
    /// Tops the compressed input up to `need` bytes where the file has them.
    /// False at the end of the compressed data (or a read failure).
    bool moreInput(size_t need, std::string* error) {
        while (m_zs.avail_in < need && !m_inEnd) {
            std::memmove(m_buffer.data(), m_zs.next_in ? m_zs.next_in : reinterpret_cast<Bytef*>(m_buffer.data()),
                         m_zs.avail_in);
            const size_t got = m_in.read(m_buffer.data() + m_zs.avail_in, m_buffer.size() - m_zs.avail_in, error);
            m_inEnd = got == 0;
            m_zs.next_in = reinterpret_cast<Bytef*>(m_buffer.data());
            m_zs.avail_in += static_cast<uInt>(got);
        }
        return m_zs.avail_in >= need;
    }

    ByteSource& m_in;
    const Target& m_target;
    z_stream m_zs{};
    std::string m_buffer;  // compressed bytes not yet inflated
    uint64_t m_produced = 0;
    bool m_ok = false, m_inEnd = false, m_done = false;
    bool m_midMember = false;  // inside a member: its end is still due
    bool m_overBudget = false;
};

}  // namespace

/// Parses one stream (a file, a string or an archive) into the parser's
/// target.
class StreamParser {
public:
    StreamParser(Parser& parser, Lexer& lexer, std::shared_ptr<const std::string> file, std::string directory,
                 int depth)
        : m_parser(parser), m_lex(lexer), m_file(std::move(file)),
          m_directory(std::move(directory)), m_depth(depth) {}

    bool run() {
        Diagnostics& diag = m_parser.m_diag;
        int errorsAtStart = diag.errorCount();
        advance();
        while (m_tok.kind != TokenKind::End) {
            if (diag.aborted() || interrupted()) return false;
            if (diag.errorCount() - errorsAtStart >= Parser::kMaxErrorsPerStream) {
                diag.error(loc(m_tok.line, m_tok.column), "RIB: too many errors; skipping the rest of {}", *m_file);
                return false;
            }
            if (m_tok.kind != TokenKind::Name) {
                reportStray();
                continue;
            }
            const int line = m_tok.line, column = m_tok.column;
            try {
                request();
            } catch (const OutOfMemory&) {
                throw;
            } catch (const std::bad_alloc&) {
                throw OutOfMemory(loc(line, column), fmt::format("the values of a {} request", m_request), valueBytes());
            }
        }
        if (m_recordDepth > 0)
            diag.error(m_recordLoc, "ArchiveBegin: no matching ArchiveEnd before the end of {} (archive \"{}\" "
                       "is not recorded)", *m_file, m_recordName);
        for (size_t k = m_ifs.size(); k-- > 0;)
            diag.error(m_ifs[k].loc, "IfBegin: no matching IfEnd before the end of {}", *m_file);
        if (m_depth == 0) m_parser.m_target.endOfInput(loc(m_tok.line, m_tok.column));
        return diag.errorCount() == errorsAtStart;
    }

private:
    void advance() { m_tok = m_lex.next(); }
    FileLoc loc(int line, int column) const { return FileLoc(m_file, line, column); }

    template <typename... Args>
    void error(int line, int column, std::string_view request, fmt::format_string<Args...> f, Args&&... args) {
        if (m_quiet) return;
        m_parser.m_diag.error(loc(line, column), "{}: {}", request, fmt::format(f, std::forward<Args>(args)...));
    }

    // A malformed token inside `request`. Input that cannot be read on is
    // the file's fault, not the request's, and is reported even while an
    // inline archive is being recorded.
    void tokenError(std::string_view request) {
        if (m_tok.inputFailed)
            m_parser.m_diag.error(loc(m_tok.line, m_tok.column), "RIB: {}", m_tok.text);
        else
            error(m_tok.line, m_tok.column, request, "{}", m_tok.text);
    }

    // Values outside any request: report once, then skip to the next name.
    void reportStray() {
        if (m_tok.kind == TokenKind::Error)
            tokenError("RIB");
        else
            error(m_tok.line, m_tok.column, "RIB", "expected a request name, got {}", tokenText());
        advance();
        while (m_tok.kind != TokenKind::Name && m_tok.kind != TokenKind::End) {
            if (m_tok.kind == TokenKind::Error) tokenError("RIB");
            advance();
        }
    }

    std::string tokenText() const {
        switch (m_tok.kind) {
        case TokenKind::Number: return fmt::format("number {}", m_tok.text);
        case TokenKind::String: return fmt::format("string \"{}\"", m_tok.text);
        case TokenKind::ArrayBegin: return "'['";
        case TokenKind::ArrayEnd: return "']'";
        case TokenKind::Name: return fmt::format("\"{}\"", m_tok.text);
        default: return "end of input";
        }
    }

    /// Bytes the values read so far take (for an out-of-memory message).
    uint64_t valueBytes() const {
        uint64_t bytes = 0;
        for (const Value& v : m_values) {
            bytes += sizeof(Value) + v.str.size() + v.nums.size() * sizeof(double);
            for (const std::string& s : v.strs) bytes += sizeof(std::string) + s.size();
        }
        return bytes;
    }

    // request: Name value* ; value: number | string | '[' number* ']' | '[' string* ']'
    void request() {
        std::string name(m_tok.text);
        m_request = name;
        int line = m_tok.line, column = m_tok.column;
        const size_t offset = m_tok.offset;
        advance();
        if (m_recordDepth > 0) {
            // Inside ArchiveBegin/ArchiveEnd: kept as text, checked when read.
            m_quiet = true;
            collectValues(name);
            m_quiet = false;
            if (name == "ArchiveBegin")
                ++m_recordDepth;
            else if (name == "ArchiveEnd" && --m_recordDepth == 0)
                finishRecording(offset);
            return;
        }
        const bool ifRequest = name == "IfBegin" || name == "ElseIf" || name == "Else" || name == "IfEnd";
        if (skipping() && !ifRequest) {
            // A branch not taken: its requests are read past, not run.
            collectValues(name);
            return;
        }
        const RequestSpec* spec = findRequest(name);
        bool ok = collectValues(name);
        if (!spec) {
            if (const char* what = foreignRequest(name))
                m_parser.m_diag.warningOnce("foreign:" + name, loc(line, column), "{}: {} (its arguments are skipped)",
                                            name, what);
            else
                error(line, column, name, "unknown request (its arguments are skipped)");
            return;
        }
        if (!ok) return;
        std::vector<Arg> args;
        size_t used = 0;
        if (!matchArgs(*spec, line, column, args, &used)) return;
        if (!spec->params && used < m_values.size()) {
            const Value& v = m_values[used];
            error(v.line, v.column, name, "too many arguments: got {} after the expected ones (usage: {}{}{})", describe(v),
                  spec->name, *spec->argNames ? " " : "", spec->argNames);
            return;
        }
        ParamList params;
        if (spec->params) {
            std::string_view rn = spec->name;
            const bool classed = rn == "Option" || rn == "Attribute" || rn == "Hider";
            // LightSource "pointlight" "intensity" [20]: the handle was left
            // out and the first parameter's name taken for it.
            const bool light = rn == "LightSource" || rn == "AreaLightSource";
            const std::string handle = light && args.size() == 2 && used >= 2 && m_values[used - 1].kind == Value::String
                                           ? args[1].str : std::string();
            buildParams(name, classed && !args.empty() ? args[0].str : std::string(), used, params, handle);
        }
        FileLoc where = loc(line, column);
        if (!spec->handler) {
            special(*spec, args, std::move(params), where);
            return;
        }
        ArgReader reader(args);
        spec->handler(m_parser.m_target, name, reader, std::move(params), where);
    }

    // Reads the values up to the next request name. False when any of them
    // was malformed (already reported); the request is then skipped.
    bool collectValues(std::string_view request) {
        m_values.clear();
        bool ok = true;
        while (m_tok.kind != TokenKind::Name && m_tok.kind != TokenKind::End) {
            switch (m_tok.kind) {
            case TokenKind::Number: {
                Value& v = push();
                v.kind = Value::Number;
                v.num = m_tok.number;
                advance();
                break;
            }
            case TokenKind::String: {
                Value& v = push();
                v.kind = Value::String;
                v.str.assign(m_tok.text);
                advance();
                break;
            }
            case TokenKind::ArrayBegin: ok = collectArray(request) && ok; break;
            case TokenKind::ArrayEnd:
                // A ']' closing nothing is skipped and the request kept, as
                // Pixie and Aqsis do: an exporter that writes one after every
                // coloured polygon (Jan Walter's for Blender) lost them all.
                if (!m_quiet)
                    m_parser.m_diag.warningOnce("stray]", loc(m_tok.line, m_tok.column),
                                                "{}: skipped a ']' that closes no '['", request);
                advance();
                break;
            case TokenKind::Error:
                if (m_tok.junk) {
                    tokenError("RIB");  // a stray, not the request's
                } else {
                    tokenError(request);
                    ok = false;
                }
                advance();
                break;
            default: advance(); break;
            }
        }
        return ok;
    }

    bool collectArray(std::string_view request) {
        Value& v = push();
        v.kind = Value::NumArray;
        int line = m_tok.line, column = m_tok.column;
        bool sawNumber = false, sawString = false, ok = true;
        advance();
        for (;;) {
            switch (m_tok.kind) {
            case TokenKind::Number:
                sawNumber = true;
                v.nums.push_back(m_tok.number);
                advance();
                break;
            case TokenKind::String:
                sawString = true;
                v.strs.emplace_back(m_tok.text);
                advance();
                break;
            case TokenKind::ArrayEnd:
                advance();
                if (sawNumber && sawString) {
                    error(line, column, request, "array mixes numbers and strings");
                    return false;
                }
                if (sawString) v.kind = Value::StrArray;
                return ok;
            case TokenKind::ArrayBegin:
                error(m_tok.line, m_tok.column, request, "nested '[' (arrays cannot contain arrays)");
                ok = false;
                advance();
                break;
            case TokenKind::Error:
                tokenError(request);
                ok = false;
                advance();
                break;
            default:  // a name or the end: the ']' is missing
                error(line, column, request, "missing ']' to close this array");
                return false;
            }
        }
    }

    Value& push() {
        m_values.emplace_back();
        Value& v = m_values.back();
        v.line = m_tok.line;
        v.column = m_tok.column;
        return v;
    }

    // Matches the values against the request's signature.
    bool matchArgs(const RequestSpec& spec, int line, int column, std::vector<Arg>& args, size_t* used) {
        std::vector<std::string_view> names;
        {
            std::string_view s = spec.argNames;
            while (!s.empty()) {
                size_t sp = s.find(' ');
                names.push_back(s.substr(0, sp));
                if (sp == std::string_view::npos) break;
                s.remove_prefix(sp + 1);
            }
        }
        auto usage = [&] { return fmt::format("{}{}{}", spec.name, *spec.argNames ? " " : "", spec.argNames); };
        size_t vi = 0;        // next value
        size_t inArray = 0;   // position inside a [ ] grouping scalar numbers, when > 0
        size_t nameIndex = 0;
        // Where the scalar numbers came from: RIB gives them all loose or
        // all in one [ ]; other mixes are read in order with a warning
        // (Pixie and Aqsis refuse them). A one-number [x] counts as loose.
        int looseNumbers = 0, numberArrays = 0;
        for (const char* c = spec.sig; *c; ++c) {
            if (*c == '|') {
                if (inArray == 0 && (vi >= m_values.size() || m_values[vi].kind == Value::String)) break;
                continue;
            }
            std::string_view argName = nameIndex < names.size() ? names[nameIndex] : "argument";
            int repeat = *c == 'M' ? 16 : 1;
            char code = *c == 'M' ? 'f' : *c;
            ++nameIndex;
            for (int r = 0; r < repeat; ++r) {
                Arg a;
                if (code == 'f' || code == 'i') {
                    double num;
                    int vl, vc;
                    if (inArray > 0) {
                        const Value& v = m_values[vi];
                        num = v.nums[inArray];
                        vl = v.line;
                        vc = v.column;
                        if (++inArray == v.nums.size()) {
                            inArray = 0;
                            ++vi;
                        }
                    } else if (vi < m_values.size() && m_values[vi].kind == Value::Number) {
                        ++looseNumbers;
                        num = m_values[vi].num;
                        vl = m_values[vi].line;
                        vc = m_values[vi].column;
                        ++vi;
                    } else if (vi < m_values.size() && m_values[vi].kind == Value::NumArray && !m_values[vi].nums.empty()) {
                        ++(m_values[vi].nums.size() > 1 ? numberArrays : looseNumbers);  // [x] is one number
                        const Value& v = m_values[vi];
                        num = v.nums[0];
                        vl = v.line;
                        vc = v.column;
                        if (v.nums.size() == 1)
                            ++vi;
                        else
                            inArray = 1;
                    } else {
                        if (vi >= m_values.size() || (m_values[vi].kind == Value::String && spec.params))
                            error(line, column, spec.name, "missing argument {} (usage: {})", argName, usage());
                        else
                            error(m_values[vi].line, m_values[vi].column, spec.name,
                                  "argument {} must be a number, got {} (usage: {})", argName, describe(m_values[vi]),
                                  usage());
                        return false;
                    }
                    if (code == 'i' && !integral(num)) {
                        error(vl, vc, spec.name, "argument {} must be an integer, got {}", argName, numberText(num));
                        return false;
                    }
                    a.kind = Arg::Number;
                    a.num = num;
                    a.integer = code == 'i';
                    args.push_back(std::move(a));
                    continue;
                }
                if (inArray > 0) {
                    const Value& v = m_values[vi];
                    error(v.line, v.column, spec.name, "too many numbers in [ ] before argument {} (usage: {})",
                          argName, usage());
                    return false;
                }
                if (vi >= m_values.size()) {
                    error(line, column, spec.name, "missing argument {} (usage: {})", argName, usage());
                    return false;
                }
                Value& v = m_values[vi];
                switch (code) {
                case 's':
                    if (v.kind != Value::String) {
                        error(v.line, v.column, spec.name, "argument {} must be a string, got {} (usage: {})",
                              argName, describe(v), usage());
                        return false;
                    }
                    a.kind = Arg::String;
                    a.str = std::move(v.str);
                    break;
                case 'h':
                    if (v.kind == Value::String) {
                        a.kind = Arg::String;
                        a.str = std::move(v.str);
                    } else if (v.kind == Value::Number && integral(v.num)) {
                        a.kind = Arg::Number;
                        a.num = v.num;
                    } else {
                        error(v.line, v.column, spec.name,
                              "argument {} must be an integer or a string, got {} (usage: {})", argName, describe(v),
                              usage());
                        return false;
                    }
                    break;
                case 'B':
                    if (v.kind == Value::String) {
                        a.kind = Arg::String;
                        a.str = std::move(v.str);
                    } else if (v.kind == Value::NumArray && v.nums.size() == 16) {
                        a.kind = Arg::NumArray;
                        a.nums = std::move(v.nums);
                    } else {
                        error(v.line, v.column, spec.name,
                              "argument {} must be a basis name or an array of 16 numbers, got {} (usage: {})",
                              argName, describe(v), usage());
                        return false;
                    }
                    break;
                case 'F':
                case 'I': {
                    if (v.kind == Value::Number) {
                        v.nums.assign(1, v.num);
                    } else if (v.kind == Value::StrArray && v.strs.empty()) {
                        v.nums.clear();
                    } else if (v.kind != Value::NumArray && !(v.kind == Value::StrArray && v.strs.empty())) {
                        error(v.line, v.column, spec.name, "argument {} must be an array of {}, got {} (usage: {})",
                              argName, code == 'I' ? "integers" : "numbers", describe(v), usage());
                        return false;
                    }
                    if (code == 'I') {
                        for (double d : v.nums)
                            if (!integral(d)) {
                                error(v.line, v.column, spec.name,
                                      "argument {} must be an array of integers, got {} in it", argName,
                                      numberText(d));
                                return false;
                            }
                    }
                    a.kind = Arg::NumArray;
                    a.nums = std::move(v.nums);
                    a.integer = code == 'I';
                    break;
                }
                case 'S':
                    if (v.kind == Value::String) {
                        v.strs.assign(1, std::move(v.str));
                    } else if (v.kind == Value::NumArray && v.nums.empty()) {
                        v.strs.clear();
                    } else if (v.kind != Value::StrArray) {
                        error(v.line, v.column, spec.name, "argument {} must be an array of strings, got {} (usage: {})",
                              argName, describe(v), usage());
                        return false;
                    }
                    a.kind = Arg::StrArray;
                    a.strs = std::move(v.strs);
                    break;
                default: break;
                }
                ++vi;
                args.push_back(std::move(a));
            }
        }
        if (inArray > 0) {
            const Value& v = m_values[vi];
            error(v.line, v.column, spec.name, "too many numbers in [ ]: {} given (usage: {})", v.nums.size(), usage());
            return false;
        }
        if (numberArrays > 1 || (numberArrays > 0 && looseNumbers > 0))
            m_parser.m_diag.warningOnce(fmt::format("mixed-args:{}", spec.name), loc(line, column),
                                        "{}: numbers given partly in [ ] and partly loose, or in several [ ]; read in "
                                        "order (RIB gives them all loose or all in one [ ]; usage: {})",
                                        spec.name, usage());
        *used = vi;
        return true;
    }

    /// Requests whose parameters are a shader's (or a display driver's):
    /// undeclared names there are the shader's own parameters, typed by its
    /// declarations when bound; a driver reads what it knows ("exposure"
    /// [gain gamma]) and ignores the rest.
    static bool isShaderRequest(std::string_view request) {
        return request == "Surface" || request == "Displacement" || request == "Atmosphere" ||
               request == "Interior" || request == "Exterior" || request == "LightSource" ||
               request == "AreaLightSource" || request == "Imager" || request == "Display";
    }

    /// A declaration from the values alone: strings are `uniform string`,
    /// numbers `uniform float` (one element per number).
    static bool inferDeclaration(const std::string& name, const Value& v, ParamDecl* out) {
        if (name.empty() || name.find_first_of(" \t") != std::string::npos) return false;
        out->name = name;
        out->storage = StorageClass::Uniform;
        out->arraySize = 1;
        out->inferred = true;
        if (v.kind == Value::String || v.kind == Value::StrArray)
            out->type = ParamType::String;
        else if (v.kind == Value::Number || v.kind == Value::NumArray)
            out->type = ParamType::Float;
        else
            return false;
        return true;
    }

    /// Requests whose parameters other renderers give meanings umbra may
    /// not know (renderer-specific options, attributes, hider and display
    /// settings): an undeclared name, or a value that does not fit its
    /// declaration, is read as its values say with one warning per name,
    /// never an error (docs/rib.md, "Lenient parameters").
    static bool isLenientRequest(std::string_view request) {
        return request == "Option" || request == "Attribute" || request == "Hider" || request == "Display" ||
               request == "DisplayChannel" || request == "Camera" || request == "Resource" ||
               request == "ArchiveBegin";
    }

    /// "uniform float" for "uniform float name": a declaration without its name.
    static std::string typeText(const ParamDecl& d) {
        std::string s = d.str();
        return s.size() > d.name.size() ? s.substr(0, s.size() - d.name.size() - 1) : s;
    }

    // params: ( "name" value )*
    // `cls` is the Option/Attribute class or the Hider type (else empty).
    void buildParams(std::string_view request, const std::string& cls, size_t first, ParamList& params,
                     const std::string& stringHandle = {}) {
        const Declarations& decls = m_parser.m_decls;
        const bool lenient = isLenientRequest(request);
        // "Attribute \"dice\"" in lenient messages; the request alone otherwise.
        const std::string where = cls.empty() ? std::string(request) : fmt::format("{} \"{}\"", request, cls);
        for (size_t i = first; i < m_values.size();) {
            Value& nameValue = m_values[i];
            if (nameValue.kind != Value::String) {
                if (i == first && !stringHandle.empty())
                    error(nameValue.line, nameValue.column, request,
                          "expected a parameter name string, got {}: \"{}\" was read as the light's handle (a "
                          "number or string handle must follow the shader name)",
                          describe(nameValue), stringHandle);
                else
                    error(nameValue.line, nameValue.column, request, "expected a parameter name string, got {}",
                          describe(nameValue));
                ++i;
                continue;
            }
            if (i + 1 >= m_values.size()) {
                error(nameValue.line, nameValue.column, request, "parameter \"{}\" has no value", nameValue.str);
                return;
            }
            Value& v = m_values[i + 1];
            i += 2;
            const std::string& token = nameValue.str;
            const bool inlineDecl = token.find_first_of(" \t") != std::string::npos;
            // The declaration in force (Declare, inline or standard), then
            // the ones other renderers give the name in this class.
            std::vector<ParamDecl> candidates;
            std::string why;
            ParamDecl declared;
            const bool resolved = decls.resolve(token, &declared, &why);
            if (resolved) candidates.push_back(declared);
            if (lenient && !inlineDecl)
                for (ParamDecl& d : Declarations::forClass(request, cls, token)) candidates.push_back(std::move(d));
            bool undeclared = false;
            if (candidates.empty()) {
                ParamDecl d;
                if (lenient && !inlineDecl && inferDeclaration(token, v, &d)) {
                    d.inferred = false;
                    candidates.push_back(std::move(d));
                    undeclared = true;
                } else if (!isShaderRequest(request) || !inferDeclaration(token, v, &d)) {
                    error(nameValue.line, nameValue.column, request, "{}", why);
                    continue;
                } else {
                    candidates.push_back(std::move(d));
                }
            }
            const FileLoc at = loc(nameValue.line, nameValue.column);
            const std::string onceKey = fmt::format("param:{}:{}:{}", request, cls, candidates[0].name);
            if (undeclared && cls != "user")
                m_parser.m_diag.warningOnce(onceKey, at, "{}: parameter \"{}\" is not declared; read as \"{}\" (umbra "
                                            "does not use it)", where, candidates[0].name, typeText(candidates[0]));
            if (!lenient) {
                Param p;
                p.decl = candidates[0];
                p.loc = at;
                if (convert(request, nameValue, v, p, &why)) {
                    if (!why.empty()) m_parser.m_diag.warning(at, "{}: {}", request, why);
                    params.add(std::move(p));
                } else {
                    error(nameValue.line, nameValue.column, request, "{}", why);
                }
                continue;
            }
            // Lenient: the first declaration the values fit; else what the
            // values say, with one warning for the name.
            // One that holds every value before one that drops some.
            bool done = false;
            std::string firstWhy, truncatedWhy;
            std::optional<Param> truncated;
            for (const ParamDecl& d : candidates) {
                Value copy = v;
                Param p;
                p.decl = d;
                p.loc = at;
                if (convert(request, nameValue, copy, p, &why)) {
                    if (why.empty()) {
                        params.add(std::move(p));
                        done = true;
                        break;
                    }
                    if (!truncated) truncated = std::move(p), truncatedWhy = why;
                    continue;
                }
                if (firstWhy.empty()) firstWhy = why;
            }
            if (!done && truncated) {
                m_parser.m_diag.warning(at, "{}: {}", request, truncatedWhy);
                params.add(std::move(*truncated));
                done = true;
            }
            if (done) continue;
            Param p;
            p.loc = at;
            const bool inferred = inferDeclaration(candidates[0].name, v, &p.decl);
            p.decl.inferred = false;
            if (!inferred || !convert(request, nameValue, v, p, &why)) {
                error(nameValue.line, nameValue.column, request, "{}", firstWhy);
                continue;
            }
            m_parser.m_diag.warningOnce(onceKey, at, "{}: {}; read as \"{}\"", where, firstWhy, typeText(p.decl));
            if (!why.empty()) m_parser.m_diag.warning(at, "{}: {}", request, why);
            params.add(std::move(p));
        }
    }

    /// Fills `p` (whose declaration is set) from the value `v`; false with
    /// `*why` saying what did not fit.
    bool convert(std::string_view request, const Value& nameValue, Value& v, Param& p, std::string* why) {
        const ParamDecl& d = p.decl;
        size_t count = 0;
        auto fail = [&](std::string_view what, std::string got = {}) {
            *why = fmt::format("parameter \"{}\" ({} {}{}) expects {}, got {}", d.name, storageClassName(d.storage),
                               paramTypeName(d.type), d.arraySize != 1 ? fmt::format("[{}]", d.arraySize) : std::string(),
                               what, got.empty() ? describe(v) : got);
            return false;
        };
        if (d.type == ParamType::String) {
            if (v.kind == Value::String)
                p.strings.push_back(std::move(v.str));
            else if (v.kind == Value::StrArray)
                p.strings = std::move(v.strs);
            else if (!(v.kind == Value::NumArray && v.nums.empty()))
                return fail("strings");
            count = p.strings.size();
        } else {
            if (v.kind == Value::Number)
                v.nums.assign(1, v.num);
            else if (v.kind == Value::StrArray && v.strs.empty())
                v.nums.clear();
            else if (v.kind != Value::NumArray)
                return fail("numbers");
            count = v.nums.size();
            if (isFloatType(d.type)) {
                p.floats.resize(count);
                for (size_t k = 0; k < count; ++k) p.floats[k] = static_cast<float>(v.nums[k]);
            } else {
                p.ints.resize(count);
                for (size_t k = 0; k < count; ++k) {
                    if (!integral(v.nums[k])) return fail("integers", numberText(v.nums[k]));
                    p.ints[k] = static_cast<int>(v.nums[k]);
                }
            }
        }
        size_t per = static_cast<size_t>(d.elementSize());
        std::string type = fmt::format("{} {}{}", storageClassName(d.storage), paramTypeName(d.type),
                                       d.arraySize != 1 ? fmt::format("[{}]", d.arraySize) : std::string());
        if (count == 0) {
            *why = fmt::format("parameter \"{}\" ({}) has no values", d.name, type);
            return false;
        }
        why->clear();
        // A shader parameter given more values than fit: the leading ones,
        // with a note the caller warns of (Pixie takes them silently, Aqsis
        // warns). Geometry's counts are its topology's, not to be guessed.
        const bool shader = isShaderRequest(request);
        const size_t keep = !shader                                               ? count
                            : d.storage == StorageClass::Constant && count > per ? per
                            : count > per && count % per != 0                     ? count - count % per
                                                                                  : count;
        if (keep != count) {
            *why = fmt::format("parameter \"{}\" ({}) expects {} value{}, got {}; {} used", d.name, type,
                               d.storage == StorageClass::Constant ? std::to_string(per)
                                                                   : fmt::format("a multiple of {}", per),
                               per == 1 && d.storage == StorageClass::Constant ? "" : "s", count,
                               keep == 1 ? std::string("the first is") : fmt::format("the first {} are", keep));
            if (d.type == ParamType::String) p.strings.resize(keep);
            else if (isFloatType(d.type)) p.floats.resize(keep);
            else p.ints.resize(keep);
            return true;
        }
        if (d.storage == StorageClass::Constant && count != per) {
            *why = fmt::format("parameter \"{}\" ({}) expects {} value{}, got {}", d.name, type, per,
                               per == 1 ? "" : "s", count);
            return false;
        }
        if (count % per != 0) {
            *why = fmt::format("parameter \"{}\" ({}) expects a multiple of {} values, got {}", d.name, type, per,
                               count);
            return false;
        }
        return true;
    }

    void special(const RequestSpec& spec, std::vector<Arg>& args, ParamList params, const FileLoc& where) {
        std::string_view name = spec.name;
        if (name == "Declare") {
            ParamDecl d;
            std::string why;
            if (!Declarations::parse(args[1].str, false, &d, &why)) {
                m_parser.m_diag.error(where, "Declare: bad declaration \"{}\" for \"{}\": {} (expected \"[class] "
                                      "type[[n]]\", e.g. \"varying color\")", args[1].str, args[0].str, why);
                return;
            }
            // Blanks around the name are dropped. A name with blanks inside
            // (a parser test of Aqsis's writes one) could never be told from
            // an inline declaration when used: Aqsis and Pixie take it
            // without a word, umbra warns and leaves it undeclared.
            const std::string& given = args[0].str;
            const size_t first = given.find_first_not_of(" \t\r\n");
            const size_t last = given.find_last_not_of(" \t\r\n");
            d.name = first == std::string::npos ? std::string() : given.substr(first, last - first + 1);
            if (d.name.empty() || d.name.find_first_of(" \t\r\n") != std::string::npos) {
                m_parser.m_diag.warning(where, "Declare: parameter name \"{}\" is not one word; the declaration is "
                                               "ignored (no parameter list could name it)", given);
                return;
            }
            m_parser.m_decls.declare(d);
            m_parser.m_target.declare(d, where);
        } else if (name == "ReadArchive") {
            m_parser.readArchive(args[0].str, where, m_directory, m_depth);
        } else if (name == "ArchiveBegin") {
            if (args[0].str.empty()) {
                m_parser.m_diag.error(where, "ArchiveBegin: expected a non-empty archive name");
                m_recordName.clear();
            } else {
                m_recordName = args[0].str;
            }
            // The body starts at the next token (or the end).
            m_recordDepth = 1;
            m_recordLoc = where;
            m_recordLine = m_tok.line;
            m_recordColumn = m_tok.column;
            m_lex.beginCapture(m_tok.offset);
        } else if (name == "ArchiveEnd") {
            m_parser.m_diag.error(where, "ArchiveEnd: no matching ArchiveBegin (ignored)");
        } else if (name == "IfBegin") {
            IfState s;
            s.loc = where;
            s.parentActive = !skipping();
            if (s.parentActive) s.active = s.taken = condition("IfBegin", args[0].str, where);
            m_ifs.push_back(s);
        } else if (name == "ElseIf" || name == "Else" || name == "IfEnd") {
            if (m_ifs.empty()) {
                m_parser.m_diag.error(where, "{}: no matching IfBegin (ignored)", name);
                return;
            }
            IfState& s = m_ifs.back();
            if (name == "IfEnd") {
                m_ifs.pop_back();
                return;
            }
            if (s.elseLoc.file) {
                m_parser.m_diag.error(where, "{}: after the Else at {} of the IfBegin at {} (ignored)", name,
                                      s.elseLoc.str(), s.loc.str());
                return;
            }
            if (name == "Else") {
                s.elseLoc = where;
                s.active = s.parentActive && !s.taken;
                s.taken = true;
            } else {
                s.active = s.parentActive && !s.taken && condition("ElseIf", args[0].str, where);
                s.taken = s.taken || s.active;
            }
        }
    }

    /// One open IfBegin: whether the block it is in runs, whether one of
    /// its branches has run, whether the current branch runs.
    struct IfState {
        FileLoc loc, elseLoc;
        bool parentActive = true, taken = false, active = false;
    };
    bool skipping() const { return !m_ifs.empty() && !m_ifs.back().active; }

    /// Evaluates an IfBegin/ElseIf condition against the target's values;
    /// a malformed one is reported and false.
    bool condition(std::string_view request, const std::string& expr, const FileLoc& where) {
        Target& target = m_parser.m_target;
        ExprLookup lookup = [&](const std::string& n, ExprValue* v) { return target.conditionValue(n, v); };
        bool result = false;
        std::string why;
        std::vector<std::string> undefined;
        if (!evaluateCondition(expr, lookup, &result, &why, &undefined)) {
            m_parser.m_diag.error(where, "{}: bad condition \"{}\": {} (taken as false)", request, expr, why);
            return false;
        }
        for (const std::string& u : undefined)
            m_parser.m_diag.warningOnce("if-undefined:" + u, where, "{}: \"${}\" is not defined (taken as the "
                                        "empty string)", request, u);
        return result;
    }

    /// ArchiveEnd at byte `endOffset` closes the recorded archive.
    void finishRecording(size_t endOffset) {
        std::string body = m_lex.endCapture(endOffset);
        if (m_recordName.empty()) return;
        Parser::InlineArchive a;
        // Columns before the body's first token blanked, so messages on
        // replay give the body's own lines and columns.
        a.text.assign(size_t(std::max(m_recordColumn - 1, 0)), ' ');  // 0: a column past INT_MAX
        a.text.append(body);
        a.file = m_file;
        a.firstLine = m_recordLine;
        a.directory = m_directory;
        m_parser.m_inlineArchives[m_recordName] = std::move(a);
    }

    Parser& m_parser;
    Lexer& m_lex;
    std::string m_request;  // the request being read
    Token m_tok;
    std::shared_ptr<const std::string> m_file;
    std::string m_directory;
    int m_depth;
    std::vector<Value> m_values;
    std::vector<IfState> m_ifs;
    bool m_quiet = false;  // while recording an inline archive
    int m_recordDepth = 0;  // > 0 while recording: ArchiveBegin nesting
    std::string m_recordName;
    FileLoc m_recordLoc;
    int m_recordLine = 1, m_recordColumn = 1;
};

Parser::Parser(Target& target, Diagnostics& diag) : m_target(target), m_diag(diag) {}

bool Parser::parseFile(const std::string& path) {
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (!f) {
        m_diag.error(FileLoc::inFile(path), "RIB: cannot read file: {}", std::strerror(errno));
        return false;
    }
    FileSource source(f);
    return parseStream(source, source.startsWithGzip(), path, directoryOf(path), 0);
}

bool Parser::parseString(std::string_view text, const std::string& name, const std::string& directory) {
    const std::string dir = directory.empty() ? directoryOf(name) : directory;
    if (isGzip(text)) {
        MemorySource source(text);
        return parseStream(source, true, name, dir, 0);
    }
    Lexer lexer(text);
    StreamParser p(*this, lexer, std::make_shared<const std::string>(name), dir, 0);
    return p.run();
}

bool Parser::parseStream(ByteSource& source, bool gzip, const std::string& name, const std::string& directory,
                         int depth) {
    auto file = std::make_shared<const std::string>(name);
    if (!gzip) {
        Lexer lexer(source);
        StreamParser p(*this, lexer, std::move(file), directory, depth);
        return p.run();
    }
    GzipSource inflated(source, m_target);
    Lexer lexer(inflated);
    StreamParser p(*this, lexer, std::move(file), directory, depth);
    return p.run();
}

bool Parser::readArchive(const std::string& name, const FileLoc& loc, const std::string& directory, int depth) {
    // Inside a frame `--frames` leaves out: neither found nor read (a
    // sequence's unselected frames cost no archive reading, and their
    // missing archives are no error).
    if (!m_target.archivesWanted()) return true;
    if (depth + 1 > kMaxArchiveDepth) {
        m_diag.error(loc, "ReadArchive: archives nested more than {} deep (does \"{}\" read itself?)",
                     kMaxArchiveDepth, name);
        return false;
    }
    // An ArchiveBegin/ArchiveEnd archive of that name comes before files.
    if (auto it = m_inlineArchives.find(name); it != m_inlineArchives.end()) {
        if (!m_target.readArchive(name, loc)) return false;
        const InlineArchive a = it->second;  // a copy: the body may redefine it
        Lexer lexer(a.text, a.firstLine);
        StreamParser p(*this, lexer, a.file, a.directory, depth + 1);
        return p.run();
    }
    // Candidates: an absolute name as is; otherwise beside the including
    // file, then on the archive search path, then in the current directory
    // (as Pixie, Aqsis and DelayedReadArchive look: exporters name archives
    // from the project directory the render runs in, even inside archives
    // read from elsewhere). The display name keeps the including file's
    // spelling so messages stay short and stable.
    std::string found, display;
    if (!name.empty() && name[0] == '/') {
        if (isRegularFile(name)) found = display = name;
    } else {
        std::string beside = joinPath(directory, name);
        if (isRegularFile(beside)) {
            found = beside;
            display = joinPath(directoryOf(loc.fileName()), name);
        } else {
            for (const std::string& dir : m_target.archiveSearchPath()) {
                std::string candidate = joinPath(dir, name);
                if (isRegularFile(candidate)) {
                    found = display = candidate;
                    break;
                }
            }
            if (found.empty() && isRegularFile(name)) found = display = name;
        }
    }
    if (found.empty()) {
        m_diag.error(loc, "ReadArchive: cannot find archive \"{}\" (looked beside the including file, on "
                     "Option \"searchpath\" \"archive\" and in the current directory)", name);
        return false;
    }
    if (!m_target.readArchive(found, loc)) return false;
    std::FILE* f = std::fopen(found.c_str(), "rb");
    if (!f) {
        m_diag.error(loc, "ReadArchive: cannot read archive \"{}\": {}", name, std::strerror(errno));
        return false;
    }
    FileSource source(f);
    return parseStream(source, source.startsWithGzip(), display, directoryOf(found), depth + 1);
}

bool parseFile(const std::string& path, Target& target, Diagnostics& diag) {
    Parser p(target, diag);
    return p.parseFile(path);
}

bool parseString(std::string_view text, const std::string& name, Target& target, Diagnostics& diag) {
    Parser p(target, diag);
    return p.parseString(text, name);
}

}  // namespace umbra::ri
