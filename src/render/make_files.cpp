#include "umbra/render/make_files.h"

#include "umbra/shading/texture_backend.h"
#include "umbra/shadow/depth_image.h"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>

namespace umbra::render {

namespace {

/// RenderMan filter names and the OpenImageIO filters that build the MIP
/// levels with them.
struct NamedFilter {
    const char* renderman;
    const char* oiio;
};
constexpr NamedFilter kFilters[] = {
    {"box", "box"},
    {"triangle", "triangle"},
    {"gaussian", "gaussian"},
    {"catmull-rom", "catmull-rom"},
    {"separable-catmull-rom", "catmull-rom"},
    {"sinc", "sinc"},
    {"lanczos", "lanczos3"},
    {"mitchell", "mitchell"},
    {"blackman-harris", "blackman-harris"},
    {"disk", "disk"},
};

const char* oiioFilter(const std::string& name) {
    for (const NamedFilter& f : kFilters)
        if (name == f.renderman) return f.oiio;
    return nullptr;
}

bool knownWrap(const std::string& w) { return w == "black" || w == "periodic" || w == "clamp"; }

/// "" if `path` can be opened for reading, else why not.
std::string unreadable(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    if (f) return {};
    return std::strerror(errno);
}

const char* kFaceNames[6] = {"px", "nx", "py", "ny", "pz", "nz"};

}  // namespace

const char* makeFilterNames() {
    return "box, triangle, gaussian, catmull-rom, separable-catmull-rom, sinc, lanczos, mitchell, "
           "blackman-harris, disk";
}

bool makeFile(const scene::MakeRecord& make, Diagnostics& diag) {
    const std::string& req = make.request;
    const bool cube = req == "MakeCubeFaceEnvironment";
    if (req != "MakeTexture" && req != "MakeLatLongEnvironment" && !cube && req != "MakeShadow") {
        diag.error(make.loc, "{}: not a texture-making request", req);
        return false;
    }
    const size_t inputCount = cube ? 6 : 1;
    if (make.inputs.size() != inputCount || make.output.empty()) {
        diag.error(make.loc, "{}: expected {} input file{} and an output file name", req, inputCount,
                   inputCount == 1 ? "" : "s");
        return false;
    }
    for (size_t i = 0; i < make.inputs.size(); ++i) {
        std::string why = unreadable(make.inputs[i]);
        if (!why.empty()) {
            diag.error(make.loc, "{}: cannot open {}\"{}\": {}", req,
                       cube ? fmt::format("the {} face ", kFaceNames[i]) : std::string(), make.inputs[i], why);
            return false;
        }
    }
    if (req == "MakeShadow") return makeShadow(make.inputs[0], make.output, diag, make.loc);

    shading::MakeTextureRequest request;
    request.kind = req == "MakeTexture" ? "texture" : cube ? "cubeface" : "latlong";
    request.inputs = make.inputs;
    request.output = make.output;
    std::string filter = "gaussian";
    if (req == "MakeTexture") {
        if (make.stringArgs.size() != 3 || make.floatArgs.size() != 2) {
            diag.error(make.loc, "MakeTexture: expected swrap, twrap, filter, swidth and twidth");
            return false;
        }
        std::string wrap[2];
        for (int k = 0; k < 2; ++k) {
            wrap[k] = make.stringArgs[size_t(k)];
            if (!knownWrap(wrap[k])) {
                // Pixie and Aqsis make the texture and wrap as black.
                diag.warning(make.loc, "MakeTexture: unknown {} \"{}\" (expected \"periodic\", \"black\" or "
                             "\"clamp\"); \"black\" is used", k == 0 ? "swrap" : "twrap", wrap[k]);
                wrap[k] = "black";
            }
        }
        request.swrap = wrap[0];
        request.twrap = wrap[1];
        filter = make.stringArgs[2];
    } else {
        const size_t floats = cube ? 3 : 2;
        if (make.stringArgs.size() != 1 || make.floatArgs.size() != floats) {
            diag.error(make.loc, "{}: expected {}filter, swidth and twidth", req, cube ? "fov, " : "");
            return false;
        }
        filter = make.stringArgs[0];
    }
    const float* widths = make.floatArgs.data() + (cube ? 1 : 0);
    for (int k = 0; k < 2; ++k)
        if (!(widths[k] > 0) || !std::isfinite(widths[k])) {
            diag.error(make.loc, "{}: {} must be a positive number, got {}", req, k == 0 ? "swidth" : "twidth",
                       widths[k]);
            return false;
        }
    request.swidth = widths[0];
    request.twidth = widths[1];
    if (cube) {
        const float fov = make.floatArgs[0];
        if (!(fov >= 90 && fov < 180)) {
            diag.error(make.loc, "MakeCubeFaceEnvironment: fov must be at least 90 and less than 180 degrees, got {}",
                       fov);
            return false;
        }
        request.fov = fov;
    }
    const char* oiio = oiioFilter(filter);
    if (!oiio) {
        diag.error(make.loc, "{}: unknown filter \"{}\" (expected one of {})", req, filter, makeFilterNames());
        return false;
    }
    request.filter = oiio;

    std::string error;
    shading::TextureBackend* backend = shading::textureBackend(&error);
    if (!backend || !backend->makeTexture(request, &error)) {
        diag.error(make.loc, "{}: cannot make \"{}\" from \"{}\"{}: {}", req, make.output, make.inputs[0],
                   cube ? " and the other faces" : "", error);
        return false;
    }
    return true;
}

}  // namespace umbra::render
