#include "umbra/ri/declarations.h"

#include <fmt/format.h>

#include <charconv>
#include <vector>

namespace umbra::ri {

namespace {

// RI spec 3.2 table 5.1 (geometric variables), the parameters of the
// standard shaders (appendix A), and the options/attributes umbra reads.
// Shader parameters are uniform; geometric variables carry their class.
constexpr const char* kStandard[] = {
    // Geometry.
    "vertex point P", "vertex float Pz", "vertex hpoint Pw", "varying normal N", "uniform normal Np",
    "varying color Cs", "varying color Os", "varying float s", "varying float t", "varying float[2] st",
    "varying float width", "constant float constantwidth", "uniform normal Nu", "varying point Pref",
    // Standard shader parameters.
    "uniform float Ka", "uniform float Kd", "uniform float Ks", "uniform float Kr", "uniform float Km",
    "uniform float roughness", "uniform color specularcolor", "uniform string texturename",
    "uniform float intensity", "uniform color lightcolor", "uniform point from", "uniform point to",
    "uniform float coneangle", "uniform float conedeltaangle", "uniform float beamdistribution",
    "uniform float mindistance", "uniform float maxdistance", "uniform color background",
    "uniform float distance", "uniform float amplitude", "uniform string shadowname",
    "uniform string mapname", "uniform float samples", "uniform float blur", "uniform float bias",
    "uniform float bias0", "uniform float bias1", "uniform float sblur", "uniform float tblur",
    "uniform float swidth", "uniform float twidth", "uniform float minsamples", "uniform float minsize",
    "uniform string filter",
    // Projection, Display, Hider.
    "uniform float fov", "uniform integer[2] origin", "uniform float[4] quantize", "uniform float dither",
    "uniform string compression", "uniform float gain", "uniform float gamma", "uniform integer jitter",
    "uniform string depthfilter", "uniform float offset",
    // umbra's own options (docs/shadows.md).
    "uniform integer shadowmapsize", "uniform float dualoffset", "uniform integer tilecachemb",
    "uniform string depthcull", "uniform float depthshadingrate",
    "uniform integer depthlayers", "uniform integer reusemaps", "uniform integer patchblock",
    // Option "searchpath", "limits", "statistics".
    "uniform string shader", "uniform string texture", "uniform string archive",
    "uniform string procedural", "uniform string resource", "uniform string display",
    "uniform integer[2] bucketsize", "uniform integer gridsize", "uniform integer eyesplits",
    "uniform integer archivereads", "uniform integer decompressedmb",
    "uniform integer texturememory", "uniform integer endofframe", "uniform string filename",
    "uniform color zthreshold", "uniform color othreshold",
    // Attribute "displacementbound", "identifier", "visibility", "trimcurve".
    "uniform float sphere", "uniform string coordinatesystem", "uniform string name",
    "uniform integer camera", "uniform integer transmission", "uniform integer shadow",
    "uniform integer diffuse", "uniform integer specular", "uniform integer photon",
    "uniform integer trace", "uniform string sense",
};

/// Option, Attribute and Hider parameters by class: "Request class decl".
/// Each is honoured by umbra (docs/rib.md says how), or accepted and
/// ignored without a warning because it only matters to features umbra has
/// not got (ray tracing, baking, PRMan's caches). The class "*" of Hider
/// is any hider type.
constexpr const char* kByClass[] = {
    // Options.
    "Option render uniform float minshadowbias", "Option render uniform string bucketorder",
    "Option shutter uniform float[2] opening", "Option shutter uniform float[2] shutteropening",
    "Option shadow uniform float bias", "Option limits uniform integer brickmemory",
    "Option limits uniform integer geocachememory", "Option limits uniform integer proceduralmemory",
    "Option limits uniform float proceduraltime",  // honoured: RunProgram's answer time
    "Option limits uniform integer deepshadowtiles", "Option limits uniform integer deepshadowmemory",
    "Option statistics uniform string xmlfilename", "Option trace uniform integer maxdepth",
    "Option trace uniform float specularthreshold",
    // Attribute "visibility": PRMan's ray types and Pixie's "trace" (no
    // ray tracing: accepted, ignored); transmission as a string in BMRT
    // and Pixie RIBs ("opaque", "transparent", "shader").
    "Attribute visibility uniform string transmission", "Attribute visibility uniform integer indirect",
    "Attribute visibility uniform integer midpoint",
    "Attribute dice uniform integer binary", "Attribute dice uniform integer rasterorient",
    "Attribute dice uniform integer hair", "Attribute dice uniform string strategy",
    "Attribute dice uniform string referencecamera", "Attribute dice uniform integer preservecv",
    "Attribute cull uniform integer hidden", "Attribute cull uniform integer backfacing",
    "Attribute sides uniform float backfacetolerance", "Attribute sides uniform integer doubleshaded",
    "Attribute identifier uniform integer id",
    "Attribute trace uniform float bias", "Attribute trace uniform integer maxdiffusedepth",
    "Attribute trace uniform integer maxspeculardepth", "Attribute trace uniform integer displacements",
    "Attribute trace uniform integer samplemotion", "Attribute trace uniform float importancethreshold",
    "Attribute trace uniform integer decimationrate",
    "Attribute shade uniform string strategy", "Attribute shade uniform string transmissionhitmode",
    "Attribute shade uniform string diffusehitmode", "Attribute shade uniform string specularhitmode",
    "Attribute shade uniform string camerahitmode", "Attribute shade uniform float relativeshadingrate",
    "Attribute shade uniform string frequency", "Attribute shade uniform integer resetst",
    "Attribute irradiance uniform float maxerror", "Attribute irradiance uniform float maxpixeldist",
    "Attribute irradiance uniform string handle", "Attribute irradiance uniform string filemode",
    "Attribute photon uniform string shadingmodel", "Attribute photon uniform integer estimator",
    "Attribute photon uniform string causticmap", "Attribute photon uniform string globalmap",
    "Attribute render uniform string casts_shadows", "Attribute render uniform integer truedisplacement",
    "Attribute stochastic uniform integer sigma", "Attribute stochastic uniform integer pointfalloff",
    // Display: PRMan's and Pixie's per-display pixel filter widths (two,
    // or one for both); "filter" is the standard "uniform string filter".
    "Display * uniform float[2] filterwidth", "Display * uniform float filterwidth",
    "DisplayChannel * uniform float[2] filterwidth", "DisplayChannel * uniform float filterwidth",
    // Hider parameters of PRMan's hidden and raytrace hiders.
    "Hider * uniform integer mpcache", "Hider * uniform integer mpmemory", "Hider * uniform string mpcachedir",
    "Hider * uniform integer samplemotion", "Hider * uniform integer subpixel",
    "Hider * uniform integer extrememotiondof", "Hider * uniform integer sigma", "Hider * uniform float sigmablur",
    "Hider * uniform float[4] aperture", "Hider * uniform float dofaspect", "Hider * uniform string pixelfiltermode",
    "Hider * uniform float occlusionbound", "Hider * uniform integer maxvpdepth", "Hider * uniform integer emit",
    "Hider * uniform integer incremental", "Hider * uniform integer maxsamples",
    "Hider * uniform string integrationmode", "Hider * uniform string samplemode",
    "Hider * uniform integer progressive",
};

bool storageByName(std::string_view w, StorageClass* out) {
    static const std::pair<const char*, StorageClass> k[] = {
        {"constant", StorageClass::Constant}, {"uniform", StorageClass::Uniform},
        {"varying", StorageClass::Varying},   {"vertex", StorageClass::Vertex},
        {"facevarying", StorageClass::FaceVarying}, {"facevertex", StorageClass::FaceVertex},
    };
    for (auto& [name, c] : k)
        if (w == name) {
            *out = c;
            return true;
        }
    return false;
}

bool typeByName(std::string_view w, ParamType* out) {
    static const std::pair<const char*, ParamType> k[] = {
        {"float", ParamType::Float},   {"integer", ParamType::Integer}, {"int", ParamType::Integer},
        {"string", ParamType::String}, {"point", ParamType::Point},     {"vector", ParamType::Vector},
        {"normal", ParamType::Normal}, {"color", ParamType::Color},     {"hpoint", ParamType::HPoint},
        {"matrix", ParamType::Matrix}, {"bool", ParamType::Bool},
    };
    for (auto& [name, t] : k)
        if (w == name) {
            *out = t;
            return true;
        }
    return false;
}

}  // namespace

Declarations::Declarations() {
    for (const char* d : kStandard) {
        ParamDecl decl;
        std::string err;
        bool ok = parse(d, true, &decl, &err);
        (void)ok;
        m_table[decl.name] = decl;
    }
}

bool Declarations::parse(std::string_view text, bool withName, ParamDecl* out, std::string* error) {
    // Split on blanks, keeping "[n]" attached to the word before it so that
    // both "float[4]" and "float [4]" work.
    std::vector<std::string> words;
    size_t i = 0;
    while (i < text.size()) {
        while (i < text.size() && (text[i] == ' ' || text[i] == '\t')) ++i;
        if (i >= text.size()) break;
        size_t j = i;
        while (j < text.size() && text[j] != ' ' && text[j] != '\t') ++j;
        std::string_view w = text.substr(i, j - i);
        if (!words.empty() && w.front() == '[')
            words.back() += w;
        else
            words.emplace_back(w);
        i = j;
    }
    ParamDecl d;
    size_t k = 0;
    if (k < words.size() && storageByName(words[k], &d.storage)) ++k;
    if (k >= words.size()) {
        *error = "missing type";
        return false;
    }
    std::string typeWord = words[k++];
    size_t bracket = typeWord.find('[');
    if (bracket != std::string::npos) {
        std::string_view inside = std::string_view(typeWord).substr(bracket + 1);
        if (inside.empty() || inside.back() != ']') {
            *error = fmt::format("bad array size in \"{}\"", typeWord);
            return false;
        }
        inside.remove_suffix(1);
        int n = 0;
        auto res = std::from_chars(inside.data(), inside.data() + inside.size(), n);
        if (res.ec != std::errc() || res.ptr != inside.data() + inside.size() || n < 1 || n > 1 << 20) {
            *error = fmt::format("bad array size in \"{}\"", typeWord);
            return false;
        }
        d.arraySize = n;
        typeWord.resize(bracket);
    }
    if (!typeByName(typeWord, &d.type)) {
        *error = fmt::format("unknown type \"{}\"", typeWord);
        return false;
    }
    if (withName) {
        if (k >= words.size()) {
            *error = "missing parameter name";
            return false;
        }
        d.name = words[k++];
    }
    if (k != words.size()) {
        *error = fmt::format("unexpected \"{}\"", words[k]);
        return false;
    }
    *out = std::move(d);
    return true;
}

const ParamDecl* Declarations::find(std::string_view name) const {
    auto it = m_table.find(std::string(name));
    return it == m_table.end() ? nullptr : &it->second;
}

void Declarations::declare(const ParamDecl& decl) { m_table[decl.name] = decl; }

bool Declarations::resolve(std::string_view token, ParamDecl* out, std::string* error) const {
    if (token.find_first_of(" \t") != std::string_view::npos) {
        std::string why;
        if (parse(token, true, out, &why)) return true;
        *error = fmt::format("bad inline declaration \"{}\": {} (expected \"[class] type[[n]] name\", "
                             "e.g. \"varying color Cs\")", token, why);
        return false;
    }
    if (const ParamDecl* d = find(token)) {
        *out = *d;
        return true;
    }
    *error = fmt::format("parameter \"{}\" is not declared (use Declare or an inline declaration "
                         "such as \"uniform float {}\")", token, token);
    return false;
}

std::vector<ParamDecl> Declarations::forClass(std::string_view request, std::string_view cls, std::string_view name) {
    std::vector<ParamDecl> out;
    for (std::string_view entry : kByClass) {
        size_t a = entry.find(' '), b = entry.find(' ', a + 1);
        std::string_view req = entry.substr(0, a), c = entry.substr(a + 1, b - a - 1);
        if (req != request || (c != cls && c != "*")) continue;
        ParamDecl d;
        std::string why;
        if (parse(entry.substr(b + 1), true, &d, &why) && d.name == name) out.push_back(std::move(d));
    }
    return out;
}

}  // namespace umbra::ri
