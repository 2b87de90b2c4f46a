// The texture backend on OpenImageIO 2.4: TextureSystem for lookups,
// ImageBufAlgo::make_texture for MakeTexture and friends.

#include "umbra/shading/texture_backend.h"
#include "umbra/util/exr_header.h"

#include <Imath/ImathVec.h>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/texture.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <limits>
#include <mutex>
#include <cctype>
#include <sstream>
#include <unordered_map>

namespace {

using namespace umbra;
using namespace umbra::shading;

OIIO::TextureOpt toOiio(const TextureOptions& o) {
    OIIO::TextureOpt opt;
    opt.firstchannel = o.firstChannel;
    opt.sblur = o.sblur;
    opt.tblur = o.tblur;
    opt.swidth = o.swidth;
    opt.twidth = o.twidth;
    opt.fill = o.fill;
    // Bilinear between texels, as RenderMan's texture() reconstructs (a
    // lookup at a texel's centre reads that texel; Pixie agrees). OpenImageIO's
    // default, a B-spline bicubic when magnifying, read 0.56 at the centre
    // of a checker's white texel and smeared block edges over 1.5 texels.
    opt.interpmode = OIIO::TextureOpt::InterpBilinear;
    return opt;
}

/// Lookups across a blurred texture's box, per blurred direction.
constexpr int kBlurTaps = 4;

/// A footprint with an area: OpenImageIO's blur asserts (aborting the
/// render) that both axes of the filter's ellipse are longer than 0, and a
/// lookup along a line (texture(m, s, s)) or at one point (coordinates the
/// same on every point) has none. The short side becomes perpendicular to
/// the long one, a thousandth of it (or of 1e-6, for a point): the blur
/// widens it anyway.
void giveFootprintAnArea(float& dsdx, float& dtdx, float& dsdy, float& dtdy) {
    const float lx = std::hypot(dsdx, dtdx), ly = std::hypot(dsdy, dtdy);
    const float major = std::max({lx, ly, 1e-6f}), minor = 1e-3f * major;
    if (std::abs(dsdx * dtdy - dtdx * dsdy) >= minor * major) return;
    if (lx < 1e-6f && ly < 1e-6f) {
        dsdx = dtdy = 1e-6f;
        dtdx = dsdy = 0;
    } else if (lx >= ly) {
        dsdy = -dtdx / lx * minor;
        dtdy = dsdx / lx * minor;
    } else {
        dsdx = dtdy / ly * minor;
        dtdx = -dsdy / ly * minor;
    }
}

const char* kFaceNames[6] = {"px", "nx", "py", "ny", "pz", "nz"};

/// A cube face as the camera that rendered it saw the world: looking along
/// `forward`, with `right` and `up` the image's +x and +y. These are the
/// RenderMan views along each axis (left-handed: right = up x forward),
/// as Aqsis and PRMan read them.
struct FaceFrame {
    Vec3 forward, right, up;
};
const FaceFrame kFaceFrames[6] = {
    {{1, 0, 0}, {0, 0, -1}, {0, 1, 0}},   // px
    {{-1, 0, 0}, {0, 0, 1}, {0, 1, 0}},   // nx
    {{0, 1, 0}, {1, 0, 0}, {0, 0, -1}},   // py
    {{0, -1, 0}, {1, 0, 0}, {0, 0, 1}},   // ny
    {{0, 0, 1}, {1, 0, 0}, {0, 1, 0}},    // pz
    {{0, 0, -1}, {-1, 0, 0}, {0, 1, 0}},  // nz
};

/// `path` with `suffix` inserted before its extension ("a/b.tx" -> "a/b.umbra-tmp.tx").
std::string withSuffix(const std::string& path, const std::string& suffix) {
    std::string out = path;
    size_t dot = out.find_last_of('.');
    size_t slash = out.find_last_of('/');
    if (dot == std::string::npos || (slash != std::string::npos && dot < slash))
        out += suffix;
    else
        out.insert(dot, suffix);
    return out;
}

float dot3(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

/// A direction as environment() receives it, turned into OpenImageIO's
/// lat-long frame. RenderMan's maps (as Aqsis 1.8.4 and Pixie 2.2.6 read
/// them) put the poles on z: t = 1/2 - asin(z) / pi (+z is the top row)
/// and s = atan2(y, x) / 2 pi + 1/2 (+x at s = 1/2, +y at s = 3/4).
/// OpenImageIO 2.4 reads every lat-long map with +y up (whatever the
/// file's "oiio:updirection"): s = atan2(-x', z') / 2 pi + 1/2,
/// t = 1/2 - asin(y') / pi. The two agree for (x', y', z') = (-y, z, x);
/// the map is linear, so derivatives turn the same way.
Vec3 toOiioFrame(const Vec3& d) { return Vec3(-d.y, d.z, d.x); }
/// The inverse of toOiioFrame.
Vec3 fromOiioFrame(const Vec3& d) { return Vec3(d.z, -d.x, d.y); }

/// The faces of a MakeCubeFaceEnvironment request resampled into one
/// lat-long image (4n x 2n for n x n faces) laid out as environment()
/// reads MakeLatLongEnvironment's maps: +z at the top, s = atan2(y, x) /
/// 2pi + 1/2, t = 1/2 - asin(z) / pi (RenderMan's layout; toOiioFrame),
/// texel centres at (i + 1/2) / width.
bool cubeToLatLong(const MakeTextureRequest& r, OIIO::ImageBuf* out, std::string* error) {
    std::vector<std::vector<float>> faces(6);
    int res = 0, nch = 0;
    OIIO::ImageSpec first;
    for (int f = 0; f < 6; ++f) {
        OIIO::ImageBuf face(r.inputs[size_t(f)]);
        if (!face.read(0, 0, true, OIIO::TypeDesc::FLOAT)) {
            *error = "cannot read the " + std::string(kFaceNames[f]) + " face \"" + r.inputs[size_t(f)] +
                     "\": " + face.geterror();
            return false;
        }
        const OIIO::ImageSpec& spec = face.spec();
        auto describe = [&] {
            return "the " + std::string(kFaceNames[f]) + " face \"" + r.inputs[size_t(f)] + "\" is " +
                   std::to_string(spec.width) + "x" + std::to_string(spec.height) + " pixels with " +
                   std::to_string(spec.nchannels) + " channels";
        };
        if (spec.width != spec.height) {
            *error = describe() + "; expected a square image";
            return false;
        }
        if (f == 0) {
            res = spec.width;
            nch = spec.nchannels;
            first = spec;
        } else if (spec.width != res || spec.nchannels != nch) {
            *error = describe() + "; expected " + std::to_string(res) + "x" + std::to_string(res) + " pixels with " +
                     std::to_string(nch) + " channels, as the px face has";
            return false;
        }
        faces[size_t(f)].resize(size_t(res) * size_t(res) * size_t(nch));
        face.get_pixels(face.roi(), OIIO::TypeDesc::FLOAT, faces[size_t(f)].data());
    }
    const float tanHalf = std::tan(r.fov * float(M_PI) / 360.0f);
    const int width = 4 * res, height = 2 * res;
    std::vector<float> pixels(size_t(width) * size_t(height) * size_t(nch));
    for (int j = 0; j < height; ++j)
        for (int i = 0; i < width; ++i) {
            const float phi = ((float(i) + 0.5f) / float(width) - 0.5f) * 2.0f * float(M_PI);
            const float theta = (0.5f - (float(j) + 0.5f) / float(height)) * float(M_PI);
            const Vec3 d = fromOiioFrame(
                Vec3(-std::cos(theta) * std::sin(phi), std::sin(theta), std::cos(theta) * std::cos(phi)));
            int f = 0;
            for (int k = 1; k < 6; ++k)
                if (dot3(d, kFaceFrames[k].forward) > dot3(d, kFaceFrames[f].forward)) f = k;
            const FaceFrame& fr = kFaceFrames[f];
            const float depth = dot3(d, fr.forward);
            const float sx = dot3(d, fr.right) / depth / tanHalf, sy = dot3(d, fr.up) / depth / tanHalf;
            // Bilinear, clamped at the face's edges; pixel (x, y) is centred
            // at s = (x + 1/2) / res, t = (y + 1/2) / res, t = 0 at the top.
            const float x = (sx + 1.0f) * 0.5f * float(res) - 0.5f, y = (1.0f - sy) * 0.5f * float(res) - 0.5f;
            const int x0 = int(std::floor(x)), y0 = int(std::floor(y));
            const float fx = x - float(x0), fy = y - float(y0);
            auto at = [&](int px, int py, int c) {
                px = std::clamp(px, 0, res - 1);
                py = std::clamp(py, 0, res - 1);
                return faces[size_t(f)][(size_t(py) * size_t(res) + size_t(px)) * size_t(nch) + size_t(c)];
            };
            float* o = &pixels[(size_t(j) * size_t(width) + size_t(i)) * size_t(nch)];
            for (int c = 0; c < nch; ++c)
                o[c] = (1 - fy) * ((1 - fx) * at(x0, y0, c) + fx * at(x0 + 1, y0, c)) +
                       fy * ((1 - fx) * at(x0, y0 + 1, c) + fx * at(x0 + 1, y0 + 1, c));
        }
    OIIO::ImageSpec spec(width, height, nch, OIIO::TypeDesc::FLOAT);
    spec.channelnames = first.channelnames;
    spec.alpha_channel = first.alpha_channel;
    out->reset(spec);
    out->set_pixels(out->roi(), OIIO::TypeDesc::FLOAT, pixels.data());
    return true;
}

class OiioTextureBackend final : public TextureBackend {
public:
    // The shared TextureSystem is never destroyed: OpenImageIO owns it (and
    // destroying a private one trips a sized-delete mismatch inside 2.4
    // under AddressSanitizer).
    OiioTextureBackend() : m_ts(OIIO::TextureSystem::create(true)) {}

    void setSearchPath(const std::string& dirs) override {
        std::lock_guard<std::mutex> lock(m_mutex);
        m_ts->attribute("searchpath", dirs);
        m_searchPath = dirs;
        m_fits.clear();
    }
    bool texture(const std::string& file, const TextureOptions& o, float s, float t, float dsdx, float dtdx,
                 float dsdy, float dtdy, int nchannels, float* result) override {
        const FileFacts known = facts(file);
        if (!known.fits) return false;
        bool filled = false;
        if (pastLastChannel(known.channels, o, nchannels, result, &filled, [&](int present) {
                return texture(file, o, s, t, dsdx, dtdx, dsdy, dtdy, present, result);
            }))
            return filled;
        if (known.depthMap && !(s >= known.boxS0 && s <= known.boxS1 && t >= known.boxT0 && t <= known.boxT1)) {
            std::fill(result, result + nchannels, std::numeric_limits<float>::infinity());
            return true;
        }
        OIIO::TextureOpt opt = toOiio(o);
        const OIIO::ustring name(file);
        if (!(o.sblur > 0) && !(o.tblur > 0))
            return m_ts->texture(name, opt, s, t, dsdx, dtdx, dsdy, dtdy, nchannels, result);
        // RenderMan's "blur" lengthens the filtered region by its value (in
        // texture coordinates: 1 is the whole map), filtered with a box (RI
        // Spec 3.2, table 15.1): a step then ramps over the blur, 0.8 of it
        // from 10% to 90%. OpenImageIO's own blur widens the footprint and
        // reads it at a coarser MIP level with wider kernels, so its spread
        // depends on how the MIP levels were filtered: the same value ramped
        // a step over 2.6 blur (0.47 with box-filtered levels), where Pixie
        // gives 0.8-0.9 and Aqsis 1.1. So the box is taken here: taps evenly
        // across it, each filtering its own cell.
        const int ns = o.sblur > 0 ? kBlurTaps : 1, nt = o.tblur > 0 ? kBlurTaps : 1;
        opt.sblur = o.sblur > 0 ? o.sblur / float(ns) : 0.0f;
        opt.tblur = o.tblur > 0 ? o.tblur / float(nt) : 0.0f;
        giveFootprintAnArea(dsdx, dtdx, dsdy, dtdy);
        thread_local std::vector<float> tap;
        tap.assign(size_t(nchannels), 0.0f);
        std::fill(result, result + nchannels, 0.0f);
        bool ok = true;
        for (int j = 0; j < nt; ++j)
            for (int i = 0; i < ns; ++i) {
                const float ss = s + (ns > 1 ? o.sblur * ((float(i) + 0.5f) / float(ns) - 0.5f) : 0.0f);
                const float tt = t + (nt > 1 ? o.tblur * ((float(j) + 0.5f) / float(nt) - 0.5f) : 0.0f);
                ok = m_ts->texture(name, opt, ss, tt, dsdx, dtdx, dsdy, dtdy, nchannels, tap.data()) && ok;
                for (int c = 0; c < nchannels; ++c) result[c] += tap[size_t(c)];
            }
        const float weight = 1.0f / float(ns * nt);
        for (int c = 0; c < nchannels; ++c) result[c] *= weight;
        return ok;
    }
    bool environment(const std::string& file, const TextureOptions& o, const Vec3& Rin, const Vec3& dRdxIn,
                     const Vec3& dRdyIn, int nchannels, float* result) override {
        const FileFacts known = facts(file);
        if (!known.fits) return false;
        bool filled = false;
        if (pastLastChannel(known.channels, o, nchannels, result, &filled,
                            [&](int present) { return environment(file, o, Rin, dRdxIn, dRdyIn, present, result); }))
            return filled;
        // Everything below is in OpenImageIO's frame (+y the poles' axis).
        const Vec3 R = toOiioFrame(Rin), dRdx = toOiioFrame(dRdxIn), dRdy = toOiioFrame(dRdyIn);
        OIIO::TextureOpt opt = toOiio(o);
        const OIIO::ustring name(file);
        auto lookup = [&](const Vec3& d, float* out) {
            return m_ts->environment(name, opt, Imath::V3f(d.x, d.y, d.z), Imath::V3f(dRdx.x, dRdx.y, dRdx.z),
                                     Imath::V3f(dRdy.x, dRdy.y, dRdy.z), nchannels, out);
        };
        if (!(o.sblur > 0) && !(o.tblur > 0)) return lookup(R, result);
        // The same rule as texture()'s blur (RI Spec 3.2, a box added to the
        // filtered region), read in the lat-long map's s units at the
        // equator, as Aqsis reads it: a blur b is an angle of 2 pi b, in
        // longitude for "sblur" and in latitude for "tblur", at every
        // latitude (a full turn for 1). Taps rotate R across the box, each
        // filtering its own cell. OpenImageIO's own environment blur b ramps
        // a step over about 0.4 of 2 pi b (10% to 90%), so each tap asks for
        // three times its cell: with the cell alone the four taps left a
        // staircase.
        const float len = std::sqrt(dot3(R, R));
        if (!(len > 0)) return lookup(R, result);
        const Vec3 dir(R.x / len, R.y / len, R.z / len);
        // East (the way longitude grows) and north (the way latitude grows)
        // about OpenImageIO's lat-long axis, +y; at a pole any east will do.
        Vec3 east(dir.z, 0.0f, -dir.x);  // y x dir
        float el = std::sqrt(dot3(east, east));
        if (el < 1e-6f) {
            east = Vec3(1, 0, 0);
            el = 1;
        }
        east = Vec3(east.x / el, east.y / el, east.z / el);
        const Vec3 north(dir.y * east.z - dir.z * east.y, dir.z * east.x - dir.x * east.z,
                         dir.x * east.y - dir.y * east.x);
        const float kTurn = 6.28318531f;
        const int ns = o.sblur > 0 ? kBlurTaps : 1, nt = o.tblur > 0 ? kBlurTaps : 1;
        constexpr float kCellBlur = 3.0f;
        opt.sblur = o.sblur > 0 ? kCellBlur * o.sblur / float(ns) : 0.0f;
        opt.tblur = o.tblur > 0 ? kCellBlur * o.tblur / float(nt) : 0.0f;
        thread_local std::vector<float> tap;
        tap.assign(size_t(nchannels), 0.0f);
        std::fill(result, result + nchannels, 0.0f);
        bool ok = true;
        for (int j = 0; j < nt; ++j)
            for (int i = 0; i < ns; ++i) {
                const float a = ns > 1 ? kTurn * o.sblur * ((float(i) + 0.5f) / float(ns) - 0.5f) : 0.0f;
                const float b = nt > 1 ? kTurn * o.tblur * ((float(j) + 0.5f) / float(nt) - 0.5f) : 0.0f;
                // Turn by a towards east (on the great circle tangent to the
                // latitude circle), then by b towards north.
                const float ca = std::cos(a), sa = std::sin(a), cb = std::cos(b), sb = std::sin(b);
                const Vec3 d1(ca * dir.x + sa * east.x, ca * dir.y + sa * east.y, ca * dir.z + sa * east.z);
                const Vec3 d(cb * d1.x + sb * north.x, cb * d1.y + sb * north.y, cb * d1.z + sb * north.z);
                ok = lookup(Vec3(d.x * len, d.y * len, d.z * len), tap.data()) && ok;
                for (int c = 0; c < nchannels; ++c) result[c] += tap[size_t(c)];
            }
        const float weight = 1.0f / float(ns * nt);
        for (int c = 0; c < nchannels; ++c) result[c] *= weight;
        return ok;
    }
    void invalidate(const std::string& file) override {
        m_ts->invalidate(OIIO::ustring(file), true);
        std::lock_guard<std::mutex> lock(m_mutex);
        m_fits.erase(file);
    }
    bool textureInfoString(const std::string& file, const std::string& what, std::string* out) override {
        const FileFacts known = facts(file);
        if (!known.fits) return false;
        if (what == "type") {
            if (known.channels < 0) return false;
            *out = known.type;
            return true;
        }
        OIIO::ustring s;
        if (!m_ts->get_texture_info(OIIO::ustring(file), 0, OIIO::ustring(what), OIIO::TypeDesc::STRING, &s)) return false;
        *out = s.string();
        return true;
    }
    bool textureInfoFloats(const std::string& file, const std::string& what, int count, float* out) override {
        const FileFacts known = facts(file);
        if (!known.fits) return false;
        if (what == "resolution" && count == 2 && known.width > 0) {
            out[0] = float(known.width);
            out[1] = float(known.height);
            return true;
        }
        if (what == "viewingmatrix" || what == "projectionmatrix") {
            const std::vector<float>& m = what == "viewingmatrix" ? known.viewing : known.projection;
            if (count != 16 || m.empty()) return false;
            std::copy(m.begin(), m.end(), out);
            return true;
        }
        OIIO::TypeDesc tf(OIIO::TypeDesc::FLOAT, count > 1 ? count : 0);
        if (m_ts->get_texture_info(OIIO::ustring(file), 0, OIIO::ustring(what), tf, out)) return true;
        std::vector<int> iv(size_t(std::max(count, 1)));
        OIIO::TypeDesc ti(OIIO::TypeDesc::INT, count > 1 ? count : 0);
        if (!m_ts->get_texture_info(OIIO::ustring(file), 0, OIIO::ustring(what), ti, iv.data())) return false;
        for (int k = 0; k < count; ++k) out[k] = float(iv[size_t(k)]);
        return true;
    }
    bool makeTexture(const MakeTextureRequest& r, std::string* error) override {
        if (r.inputs.empty()) {
            *error = "no input image";
            return false;
        }
        const bool environment = r.kind == "latlong" || r.kind == "cubeface";
        OIIO::ImageSpec config;
        config.attribute("maketx:filtername", r.filter);
        // Environment maps wrap around in s and stop at the poles in t.
        config.attribute("wrapmodes", environment ? std::string("periodic,clamp") : r.swrap + "," + r.twrap);
        config.tile_width = config.tile_height = 64;
        OIIO::ImageBufAlgo::MakeTextureMode mode =
            environment ? OIIO::ImageBufAlgo::MakeTxEnvLatl : OIIO::ImageBufAlgo::MakeTxTexture;
        // Update mode stamps the texture with its source file's time, not
        // the clock's: the same inputs make the same bytes. (The output is
        // written under a new name, so update mode never skips the work.)
        config.attribute("maketx:updatemode", 1);
        // The temporary names keep the extension: OIIO picks the format by
        // it. RenderMan's own names (".tex", ".tx", ".env", ".tdl", ...) are
        // tiled TIFF, as txmake writes them; only ".exr" asks for OpenEXR.
        const std::string tmp = withSuffix(r.output, ".umbra-tmp");
        {
            std::string ext = OIIO::Filesystem::extension(r.output);
            for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
            if (ext != ".exr") config.attribute("maketx:fileformatname", "tiff");
        }
        std::string source = r.inputs[0];
        if (r.kind == "cubeface") {
            if (r.inputs.size() != 6) {
                *error = "expected six cube faces";
                return false;
            }
            // The faces become one lat-long image, in a file dated like the
            // newest face.
            OIIO::ImageBuf latlong;
            if (!cubeToLatLong(r, &latlong, error)) return false;
            source = r.output + ".umbra-tmp-faces.tif";
            std::time_t newest = 0;
            for (const std::string& face : r.inputs)
                newest = std::max(newest, OIIO::Filesystem::last_write_time(face));
            if (!latlong.write(source)) {
                *error = "cannot write the resampled faces \"" + source + "\": " + latlong.geterror();
                std::remove(source.c_str());
                return false;
            }
            OIIO::Filesystem::last_write_time(source, newest);
        }
        std::stringstream log;
        const bool made = OIIO::ImageBufAlgo::make_texture(mode, source, tmp, config, &log);
        if (r.kind == "cubeface") std::remove(source.c_str());
        if (!made) {
            *error = OIIO::geterror();
            if (error->empty()) *error = log.str();
            std::remove(tmp.c_str());
            return false;
        }
        if (std::rename(tmp.c_str(), r.output.c_str()) != 0) {
            *error = "cannot rename the finished texture into place";
            std::remove(tmp.c_str());
            return false;
        }
        return true;
    }

private:
    /// False when the file OpenImageIO would open for `file` (as named,
    /// else in the search path) is an OpenEXR file whose headers claim more
    /// than it holds (OpenEXR would allocate what they claim, see
    /// util/exr_header.h), or an untiled image of more than 2^24 channel
    /// values: OpenImageIO reads those whole, at up to 32 bytes a value (a
    /// 1.5 KB file of 393,232 x 16 RGBA pixels asked 805 MB, found by
    /// fuzz_maps); MakeTexture makes tiled textures. Checked once per name.
    struct FileFacts {
        bool fits = true;
        int channels = -1;  // unknown (not found)
        // What textureinfo() answers from the file's header, as RenderMan
        // names it: the full resolution (a depth map stores only the box of
        // its finite depths), "texture", "shadow" or "environment", and
        // the camera a map was rendered from (16 values in the shading
        // language's row-vector order; empty when the file has none).
        int width = 0, height = 0;
        std::string type = "texture";
        std::vector<float> viewing, projection;
        // umbra's depth maps store only the box of their finite depths:
        // outside it (in s, t of the whole map) nothing was rendered, and a
        // texture() lookup reads +infinity, as Aqsis gives (OpenImageIO
        // would read 0, a surface at the light).
        bool depthMap = false;
        float boxS0 = 0, boxS1 = 1, boxT0 = 0, boxT1 = 1;
    };
    FileFacts facts(const std::string& file) {
        std::lock_guard<std::mutex> lock(m_mutex);
        auto [it, fresh] = m_fits.try_emplace(file, FileFacts{});
        if (fresh) {
            std::vector<std::string> dirs;
            OIIO::Filesystem::searchpath_split(m_searchPath, dirs, true);
            const std::string found = OIIO::Filesystem::searchpath_find(file, dirs, true);
            std::string why;
            if (!found.empty() && !exrHeadersFit(found, &why)) {
                it->second.fits = false;
            } else if (auto in = found.empty() ? nullptr : OIIO::ImageInput::open(found)) {
                const OIIO::ImageSpec& spec = in->spec();
                const uint64_t values = uint64_t(std::max(spec.width, 0)) * uint64_t(std::max(spec.height, 0)) *
                                        uint64_t(std::max(spec.depth, 1)) * uint64_t(std::max(spec.nchannels, 0));
                it->second.fits = spec.tile_width > 0 || values <= (uint64_t(1) << 24);
                it->second.channels = spec.nchannels;
                describe(spec, it->second);
            }
        }
        return it->second;
    }
    bool fits(const std::string& file) { return facts(file).fits; }

    static void describe(const OIIO::ImageSpec& spec, FileFacts& f) {
        f.width = spec.full_width > 0 ? spec.full_width : spec.width;
        f.height = spec.full_height > 0 ? spec.full_height : spec.height;
        const std::string format = spec.get_string_attribute("textureformat");
        if (spec.extra_attribs.contains("umbra:projection") && f.width > 0 && f.height > 0) {
            f.depthMap = true;
            f.boxS0 = float(spec.x - spec.full_x) / float(f.width);
            f.boxS1 = float(spec.x - spec.full_x + spec.width) / float(f.width);
            f.boxT0 = float(spec.y - spec.full_y) / float(f.height);
            f.boxT1 = float(spec.y - spec.full_y + spec.height) / float(f.height);
        }
        if (spec.extra_attribs.contains("umbra:projection") || format == "Shadow") f.type = "shadow";
        else if (format.find("Environment") != std::string::npos) f.type = "environment";
        auto matrix = [&](const char* name, std::vector<float>* out) {
            const OIIO::ParamValue* p = spec.find_attribute(name, OIIO::TypeMatrix);
            if (!p) return false;
            const float* m = static_cast<const float*>(p->data());
            out->assign(m, m + 16);
            return true;
        };
        matrix("worldtocamera", &f.viewing);
        if (matrix("worldtoscreen", &f.projection)) return;
        // umbra's depth maps store world to NDC: screen space is NDC
        // scaled to the screen window, [-a, a] x [-b, b] with the longer
        // side's half-width the aspect ratio (y up), applied on the right
        // in row-vector order.
        std::vector<float> ndc;
        if (!matrix("worldtoNDC", &ndc) || f.width <= 0 || f.height <= 0) return;
        const float a = f.width >= f.height ? float(f.width) / float(f.height) : 1.0f;
        const float b = f.width >= f.height ? 1.0f : float(f.height) / float(f.width);
        f.projection.resize(16);
        for (int r = 0; r < 4; ++r) {
            const float* row = &ndc[size_t(4 * r)];
            float* out = &f.projection[size_t(4 * r)];
            out[0] = 2 * a * row[0] - a * row[3];
            out[1] = -2 * b * row[1] + b * row[3];
            out[2] = row[2];
            out[3] = row[3];
        }
    }

    /// Channels past the file's last (it has `channels`, -1: unknown) read
    /// as "fill" (RI Spec 3.2), which OpenImageIO does not do for a first
    /// channel past the end (it trips an assertion at coarse MIP levels):
    /// the result is filled and only the channels the file has are looked
    /// up, by `lookup(count)`. False: nothing to adjust.
    template <class Lookup>
    static bool pastLastChannel(int channels, const TextureOptions& o, int nchannels, float* result, bool* ok,
                                Lookup&& lookup) {
        if (channels < 0 || o.firstChannel + nchannels <= channels) return false;
        std::fill(result, result + nchannels, o.fill);
        const int present = std::max(0, channels - o.firstChannel);
        *ok = present == 0 || lookup(present);
        return true;
    }

    std::mutex m_mutex;  // guards the search path and m_fits
    OIIO::TextureSystem* m_ts;
    std::string m_searchPath;
    std::unordered_map<std::string, FileFacts> m_fits;
};

}  // namespace

extern "C" umbra::shading::TextureBackend* umbra_texture_backend() {
    static OiioTextureBackend backend;
    return &backend;
}
