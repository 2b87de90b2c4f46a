// The texture backend on OpenImageIO 2.4: TextureSystem for lookups,
// ImageBufAlgo::make_texture for MakeTexture and friends.

#include "umbra/shading/texture_backend.h"

#include <Imath/ImathVec.h>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/texture.h>

#include <cstdio>
#include <mutex>
#include <sstream>

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
    return opt;
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
    }
    bool texture(const std::string& file, const TextureOptions& o, float s, float t, float dsdx, float dtdx,
                 float dsdy, float dtdy, int nchannels, float* result) override {
        OIIO::TextureOpt opt = toOiio(o);
        return m_ts->texture(OIIO::ustring(file), opt, s, t, dsdx, dtdx, dsdy, dtdy, nchannels, result);
    }
    bool environment(const std::string& file, const TextureOptions& o, const Vec3& R, const Vec3& dRdx,
                     const Vec3& dRdy, int nchannels, float* result) override {
        OIIO::TextureOpt opt = toOiio(o);
        return m_ts->environment(OIIO::ustring(file), opt, Imath::V3f(R.x, R.y, R.z), Imath::V3f(dRdx.x, dRdx.y, dRdx.z),
                                 Imath::V3f(dRdy.x, dRdy.y, dRdy.z), nchannels, result);
    }
    bool textureInfoString(const std::string& file, const std::string& what, std::string* out) override {
        OIIO::ustring s;
        if (!m_ts->get_texture_info(OIIO::ustring(file), 0, OIIO::ustring(what), OIIO::TypeDesc::STRING, &s)) return false;
        *out = s.string();
        return true;
    }
    bool textureInfoFloats(const std::string& file, const std::string& what, int count, float* out) override {
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
        OIIO::ImageSpec config;
        config.attribute("maketx:filtername", r.filter == "box" ? "box" : "gaussian");
        config.attribute("wrapmodes", r.swrap + "," + r.twrap);
        config.tile_width = config.tile_height = 64;
        OIIO::ImageBufAlgo::MakeTextureMode mode = OIIO::ImageBufAlgo::MakeTxTexture;
        if (r.kind == "latlong") mode = OIIO::ImageBufAlgo::MakeTxEnvLatl;
        OIIO::ImageBuf input(r.inputs[0]);
        // The temporary name keeps the extension: OIIO picks the format by it.
        std::string tmp = r.output;
        size_t dot = tmp.find_last_of('.');
        size_t slash = tmp.find_last_of('/');
        if (dot == std::string::npos || (slash != std::string::npos && dot < slash))
            tmp += ".umbra-tmp";
        else
            tmp.insert(dot, ".umbra-tmp");
        std::stringstream log;
        if (!OIIO::ImageBufAlgo::make_texture(mode, input, tmp, config, &log)) {
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
    std::mutex m_mutex;
    OIIO::TextureSystem* m_ts;
};

}  // namespace

extern "C" umbra::shading::TextureBackend* umbra_texture_backend() {
    static OiioTextureBackend backend;
    return &backend;
}
