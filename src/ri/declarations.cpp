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
    "uniform integer depthlayers",
    // Option "searchpath", "limits", "statistics".
    "uniform string shader", "uniform string texture", "uniform string archive",
    "uniform string procedural", "uniform string resource", "uniform string display",
    "uniform integer[2] bucketsize", "uniform integer gridsize", "uniform integer eyesplits",
    "uniform integer archivereads",
    "uniform integer texturememory", "uniform integer endofframe", "uniform string filename",
    "uniform color zthreshold", "uniform color othreshold",
    // Attribute "displacementbound", "identifier", "visibility", "trimcurve".
    "uniform float sphere", "uniform string coordinatesystem", "uniform string name",
    "uniform integer camera", "uniform integer transmission", "uniform integer shadow",
    "uniform integer diffuse", "uniform integer specular", "uniform integer photon",
    "uniform integer trace", "uniform string sense",
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

}  // namespace umbra::ri
