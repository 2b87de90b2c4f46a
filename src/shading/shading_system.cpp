// ShadingSystem: compile cache, instance binding, and shading one grid.

#include "umbra/shading/shading_system.h"
#include "umbra/util/search_path.h"

#include "builtins.h"
#include "vm.h"


#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

namespace umbra::shading {

const char* valueTypeName(ValueType t) {
    switch (t) {
    case ValueType::Float: return "float";
    case ValueType::Color: return "color";
    case ValueType::Point: return "point";
    case ValueType::Vector: return "vector";
    case ValueType::Normal: return "normal";
    case ValueType::Matrix: return "matrix";
    case ValueType::String: return "string";
    }
    return "?";
}

int valueTypeFloats(ValueType t) {
    switch (t) {
    case ValueType::Float: return 1;
    case ValueType::Matrix: return 16;
    case ValueType::String: return 0;
    default: return 3;
    }
}

const char* shaderKindName(ShaderKind k) {
    switch (k) {
    case ShaderKind::Surface: return "surface";
    case ShaderKind::Light: return "light";
    case ShaderKind::Displacement: return "displacement";
    case ShaderKind::Volume: return "volume";
    case ShaderKind::Imager: return "imager";
    }
    return "?";
}

bool RendererServices::rendererInfo(const std::string& name, ShadeValue* out) {
    if (name == "renderer") {
        out->type = ValueType::String;
        out->strings = {"umbra"};
        return true;
    }
    if (name == "version") {
        out->type = ValueType::Float;
        out->floats = {0, 1, 0, 0};
        return true;
    }
    if (name == "versionstring") {
        out->type = ValueType::String;
        out->strings = {"0.1.0"};
        return true;
    }
    return false;
}

void RendererServices::print(const std::string& text) {
    std::fwrite(text.data(), 1, text.size(), stdout);
    std::fflush(stdout);
}

Shader::Shader(std::shared_ptr<const CompiledShader> code) : m_code(std::move(code)) {}
const std::string& Shader::name() const { return m_code->name; }
ShaderKind Shader::kind() const { return m_code->kind; }
const std::vector<ShaderParamInfo>& Shader::params() const { return m_code->params; }
const ShaderParamInfo* Shader::param(const std::string& name) const {
    for (const ShaderParamInfo& p : m_code->params)
        if (p.name == name) return &p;
    return nullptr;
}
std::string Shader::listing() const { return m_code->listing(); }
bool Shader::variesByFrame() const {
    for (const Instr& in : m_code->code) {
        if (in.op != Op::Call) continue;
        const Bi id = Bi(in.sub);
        if (id == Bi::RandomF || id == Bi::RandomT || id == Bi::Shadow || id == Bi::Shadow4 || id == Bi::Option)
            return true;
    }
    return false;
}

bool Shader::readsSurfaceParameters() const {
    const CompiledShader& cs = *m_code;
    auto surfaceParameter = [&](int r) {
        if (r < 0) return false;
        for (GlobalId g : {gS, gT, gU, gV})
            if (r == cs.globalRegs[g]) return true;
        return false;
    };
    for (const Instr& in : cs.code) {
        if (surfaceParameter(in.dst) || surfaceParameter(in.a) || surfaceParameter(in.b) || surfaceParameter(in.c))
            return true;
        for (int k = 0; k < in.nargs; ++k)
            if (surfaceParameter(cs.args[size_t(in.argBase + k)])) return true;
    }
    return false;
}

// --- ShadingGrid ----------------------------------------------------------

void ShadingGrid::resize(int uVertices, int vVertices) {
    m_nu = std::max(1, uVertices);
    m_nv = std::max(1, vVertices);
    size_t n = size_t(m_nu) * size_t(m_nv);
    for (auto* v : {&P, &N, &Ng, &I, &dPdu, &dPdv, &Cs, &Os, &Ci, &Oi}) v->resize(n);
    for (auto* v : {&s, &t, &u, &v}) v->resize(n);
}

namespace {
const geometry::GridVar* findVar(const geometry::Grid& grid, const char* name) {
    for (const geometry::GridVar& v : grid.vars)
        if (v.name == name) return &v;
    return nullptr;
}
}  // namespace

void ShadingGrid::bind(const geometry::Grid& grid, const Color& color, const Color& opacity, bool perspective) {
    int nu = grid.nu + 1, nv = grid.nv + 1;
    resize(nu, nv);
    size_t n = size_t(nu) * size_t(nv);
    for (size_t i = 0; i < n; ++i) {
        P[i] = i < grid.P.size() ? grid.P[i] : Vec3(0.f);
        u[i] = i < grid.u.size() ? grid.u[i] : 0.f;
        v[i] = i < grid.v.size() ? grid.v[i] : 0.f;
    }
    du = grid.du;
    dv = grid.dv;
    auto scalarVar = [&](const char* name, std::vector<float>& out, const std::vector<float>& fallback) {
        const geometry::GridVar* gv = findVar(grid, name);
        for (size_t i = 0; i < n; ++i) out[i] = gv && gv->components == 1 ? gv->at(int(i))[0] : fallback[i];
    };
    scalarVar("s", s, u);
    scalarVar("t", t, v);
    auto colorVar = [&](const char* name, std::vector<Vec3>& out, const Color& fallback) {
        const geometry::GridVar* gv = findVar(grid, name);
        for (size_t i = 0; i < n; ++i) {
            if (gv && gv->components == 3) {
                const float* f = gv->at(int(i));
                out[i] = Vec3(f[0], f[1], f[2]);
            } else {
                out[i] = fallback;
            }
        }
    };
    colorVar("Cs", Cs, color);
    colorVar("Os", Os, opacity);
    // dPdu, dPdv by differences (central inside, one-sided at the edges).
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i < nu; ++i) {
            int k = j * nu + i;
            auto diff = [&](int a, int b, float step) { return step > 0 ? (P[size_t(a)] - P[size_t(b)]) / step : Vec3(0.f); };
            int i0 = std::max(0, i - 1), i1 = std::min(nu - 1, i + 1);
            // A point's disc is its own two columns (Grid::discs): its
            // neighbour in the grid is another particle.
            if (grid.discs) i0 = i & ~1, i1 = std::min(nu - 1, i0 + 1);
            int j0 = std::max(0, j - 1), j1 = std::min(nv - 1, j + 1);
            dPdu[size_t(k)] = nu > 1 ? diff(j * nu + i1, j * nu + i0, float(i1 - i0) * du) : Vec3(0.f);
            dPdv[size_t(k)] = nv > 1 ? diff(j1 * nu + i, j0 * nu + i, float(j1 - j0) * dv) : Vec3(0.f);
            Vec3 ng = cross(dPdu[size_t(k)], dPdv[size_t(k)]);
            const float uu = dot(dPdu[size_t(k)], dPdu[size_t(k)]) * du * du;
            const float vv = dot(dPdv[size_t(k)], dPdv[size_t(k)]) * dv * dv;
            if (uu <= 1e-8f * vv || vv <= 1e-8f * uu || dot(ng, ng) == 0) {
                // A degenerate row or column (a sphere's pole, a triangle's
                // collapsed edge): the cross of the cell's diagonals has the
                // same orientation, (a+b) x (b-a) = 2 a x b.
                Vec3 d1 = P[size_t(j1 * nu + i1)] - P[size_t(j0 * nu + i0)];
                Vec3 d2 = P[size_t(j1 * nu + i0)] - P[size_t(j0 * nu + i1)];
                ng = cross(d1, d2);
            }
            Ng[size_t(k)] = flipNormals ? -ng : ng;
        }
    for (size_t i = 0; i < n; ++i) {
        N[i] = i < grid.N.size() ? grid.N[i] : Ng[i];
        I[i] = perspective ? P[i] - E : Vec3(0, 0, P[i].z);
        // RI 3.2 section 12.1.1: a shader that sets neither leaves black
        // and opaque (a surface without Oi = ... must not vanish).
        Ci[i] = Vec3(0.f);
        Oi[i] = Vec3(1.f);
    }
    primvars = &grid.vars;
}

bool ShadingGrid::output(const std::string& name, std::vector<float>* values, int* floatsPerValue) const {
    auto it = m_outputs.find(name);
    if (it == m_outputs.end()) return false;
    *floatsPerValue = it->second.first;
    *values = it->second.second;
    return true;
}

// --- ShadingSystem ------------------------------------------------------

namespace {

const char* kDefaultSurface = R"(
surface defaultsurface(float Kd = .8, Ka = .2) {
    float d = normalize(I) . normalize(N);
    Ci = Os * Cs * (Ka + Kd * d * d);
    Oi = Os;
}
)";

/// "float[2]", "color", ... for a RIB parameter's declared type and size.
std::string describeParam(const ri::Param& p) {
    using ri::ParamType;
    const char* t = "float";
    switch (p.decl.type) {
    case ParamType::Float: t = "float"; break;
    case ParamType::Integer: t = "integer"; break;
    case ParamType::String: t = "string"; break;
    case ParamType::Point: t = "point"; break;
    case ParamType::Vector: t = "vector"; break;
    case ParamType::Normal: t = "normal"; break;
    case ParamType::Color: t = "color"; break;
    case ParamType::HPoint: t = "hpoint"; break;
    case ParamType::Matrix: t = "matrix"; break;
    case ParamType::Bool: t = "bool"; break;
    }
    size_t values = p.decl.type == ParamType::String ? p.strings.size()
                    : (p.decl.type == ParamType::Integer || p.decl.type == ParamType::Bool) ? p.ints.size()
                                                                                            : p.floats.size();
    int per = p.decl.type == ParamType::Matrix ? 16 : (p.decl.type == ParamType::HPoint ? 4 : (p.decl.type == ParamType::Point || p.decl.type == ParamType::Vector || p.decl.type == ParamType::Normal || p.decl.type == ParamType::Color) ? 3 : 1);
    size_t count = values / size_t(per);
    return count == 1 ? std::string(t) : fmt::format("{}[{}]", t, count);
}

bool readFile(const std::string& path, std::string* text) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return false;
    std::stringstream ss;
    ss << in.rdbuf();
    *text = ss.str();
    return true;
}

std::vector<std::string> includePathFor(const std::string& path, const std::vector<std::string>& searchPath) {
    (void)path;
    return searchPath;
}

}  // namespace

ShadingSystem::ShadingSystem(Diagnostics& diag, std::vector<std::string> searchPath)
    : m_diag(diag), m_searchPath(std::move(searchPath)) {
    auto code = compileShaderSource(kDefaultSurface, "<defaultsurface>", {}, m_diag);
    UMBRA_CHECK(code, "the built-in default surface must compile");
    m_default = std::make_shared<Shader>(code);
}

ShadingSystem::~ShadingSystem() = default;

TextureBackend* ShadingSystem::textures() const {
    std::call_once(m_texturesOnce, [this] {
        std::string error;
        TextureBackend* backend = textureBackend(&error);
        if (!backend) {
            m_diag.error(FileLoc(), "texture(): {}", error);
            return;
        }
        std::lock_guard<std::mutex> lock(m_mutex);
        m_textures = backend;
        if (!m_textureSearchPath.empty()) backend->setSearchPath(m_textureSearchPath);
    });
    return m_textures;
}

void ShadingSystem::setTextureSearchPath(const std::vector<std::string>& dirs) {
    std::string joined;
    for (const std::string& d : dirs) joined += (joined.empty() ? "" : ":") + d;
    std::lock_guard<std::mutex> lock(m_mutex);
    m_textureSearchPath = joined;
    if (m_textures) m_textures->setSearchPath(joined);
}

void ShadingSystem::setSearchPath(std::vector<std::string> dirs) {
    std::lock_guard<std::mutex> lock(m_mutex);
    m_searchPath = std::move(dirs);
    m_byName.clear();
}

std::shared_ptr<const Shader> ShadingSystem::compileSource(const std::string& source, const std::string& fileName) {
    auto code = compileShaderSource(source, fileName, includePathFor(fileName, m_searchPath), m_diag);
    if (!code) return nullptr;
    return std::make_shared<Shader>(code);
}

std::shared_ptr<const Shader> ShadingSystem::compile(const std::string& path) {
    std::lock_guard<std::mutex> lock(m_mutex);
    auto it = m_byPath.find(path);
    if (it != m_byPath.end()) return it->second;
    std::string text;
    std::shared_ptr<const Shader> shader;
    if (!readFile(path, &text)) {
        m_diag.error(FileLoc::inFile(path), "cannot read shader file");
    } else {
        auto code = compileShaderSource(text, path, includePathFor(path, m_searchPath), m_diag);
        if (code) shader = std::make_shared<Shader>(code);
    }
    m_byPath[path] = shader;  // failures are cached too: report once
    return shader;
}

namespace {

/// The names of the shaders a source declares, found by pattern; a name
/// that is a macro of the file (`surface NAME(...)`) is not one.
std::vector<std::string> declaredShaderNames(const std::string& text) {
    static const std::regex declaration(
        "(^|[^A-Za-z0-9_])(surface|displacement|light|volume|imager)[ \t\r\n]+([A-Za-z_][A-Za-z0-9_]*)[ \t\r\n]*\\(");
    static const std::regex definition("#[ \t]*define[ \t]+([A-Za-z_][A-Za-z0-9_]*)");
    std::set<std::string> macros;
    for (std::sregex_iterator it(text.begin(), text.end(), definition), end; it != end; ++it) macros.insert((*it)[1].str());
    std::vector<std::string> names;
    for (std::sregex_iterator it(text.begin(), text.end(), declaration), end; it != end; ++it)
        if (!macros.count((*it)[3].str())) names.push_back((*it)[3].str());
    return names;
}

}  // namespace

std::optional<std::string> ShadingSystem::findFile(const std::string& name, std::string* declaresOther) const {
    namespace fs = std::filesystem;
    std::error_code ec;
    bool hasExt = name.size() > 3 && name.compare(name.size() - 3, 3, ".sl") == 0;
    if (fs::path(name).has_parent_path() && fs::is_regular_file(name, ec)) return name;
    const bool identifier = !name.empty() && !std::isdigit(static_cast<unsigned char>(name[0])) &&
                            std::all_of(name.begin(), name.end(), [](char c) {
                                return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
                            });
    constexpr uintmax_t kLargestSource = 1 << 20;
    // Compilers name their output after the shader, not the file: red.sl
    // declaring `surface green` gives green.slo, and "red" is not found
    // (Pixie and Aqsis say so and draw the default surface; umbra ran
    // green). A file of the name declaring only another shader is passed
    // over; one whose declaration is not seen (made by a macro) is taken.
    auto otherShaderIn = [&](const fs::path& p) -> std::string {
        std::string text;
        if (!identifier || fs::file_size(p, ec) > kLargestSource || !readFile(p.string(), &text)) return "";
        const std::vector<std::string> names = declaredShaderNames(text);
        if (names.empty() || std::find(names.begin(), names.end(), name) != names.end()) return "";
        return names.front();
    };
    for (const std::string& d : m_searchPath) {
        fs::path p = fs::path(d) / (hasExt ? name : name + ".sl");
        if (!fs::is_regular_file(p, ec)) continue;
        if (hasExt) return p.string();
        const std::string other = otherShaderIn(p);
        if (other.empty()) return p.string();
        if (declaresOther && declaresOther->empty())
            *declaresOther = fmt::format("{} declares '{}'", p.filename().string(), other);
    }
    if (hasExt || !identifier) return std::nullopt;
    // Scenes name shaders whose source file is called otherwise
    // (stripes-v2.sl declaring `surface stripes`): a source on the path
    // that declares it will do.
    for (const std::string& d : m_searchPath) {
        for (fs::directory_iterator it(d, ec), end; !ec && it != end; it.increment(ec)) {
            const fs::path& p = it->path();
            if (p.extension() != ".sl" || !it->is_regular_file(ec) || it->file_size(ec) > kLargestSource) continue;
            std::string text;
            if (!readFile(p.string(), &text)) continue;
            const std::vector<std::string> names = declaredShaderNames(text);
            if (std::find(names.begin(), names.end(), name) != names.end()) return p.string();
        }
    }
    return std::nullopt;
}

std::shared_ptr<const Shader> ShadingSystem::find(const std::string& name, const FileLoc& loc) {
    {
        std::lock_guard<std::mutex> lock(m_mutex);
        auto it = m_byName.find(name);
        if (it != m_byName.end()) return it->second;
    }
    std::string declaresOther;
    const std::string found = findFile(name, &declaresOther).value_or("");
    std::shared_ptr<const Shader> shader;
    if (found.empty()) {
        std::string where;
        for (const std::string& d : m_searchPath) where += (where.empty() ? "" : ":") + d;
        m_diag.error(loc, "cannot find shader '{}' ({}searched {})", name,
                     declaresOther.empty() ? "" : declaresOther + "; ", where.empty() ? "nothing" : where);
    } else {
        shader = compile(found);
    }
    std::lock_guard<std::mutex> lock(m_mutex);
    m_byName[name] = shader;
    return shader;
}

std::shared_ptr<const ShaderInstance> ShadingSystem::instantiate(const scene::ShaderRecord& record, ShaderKind expected) {
    // "null" is the conventional name of no shader (depth passes write
    // Surface "null"): no surface shader, so the default surface as Pixie
    // and Aqsis draw it, and no displacement, atmosphere or light. Unless a
    // null.sl is on the search path.
    if (record.name == "null" && !findFile(record.name)) return nullptr;
    auto shader = find(record.name, record.loc);
    if (!shader) return nullptr;
    if (shader->kind() != expected) {
        m_diag.error(record.loc, "shader '{}' is a {} shader, but a {} shader is needed here", record.name,
                     shaderKindName(shader->kind()), shaderKindName(expected));
        return nullptr;
    }
    return instantiate(shader, record);
}

std::shared_ptr<const ShaderInstance> ShadingSystem::instantiate(std::shared_ptr<const Shader> shader,
                                                                 const scene::ShaderRecord& record) {
    if (!shader) return nullptr;
    auto inst = std::make_shared<ShaderInstance>();
    inst->m_shader = shader;
    inst->m_worldFromShader = record.worldFromShader;
    const auto& params = shader->params();
    for (const ri::Param& rp : record.params.params()) {
        // RenderMan for Maya gives the background imager its colour as
        // "color color", a name no shading-language parameter can have
        // (it is a type keyword): it is the colour the imager calls bgcolor.
        const bool backgroundColour =
            shader->kind() == ShaderKind::Imager && shader->name() == "background" && rp.decl.name == "color";
        const std::string& name = backgroundColour ? std::string("bgcolor") : rp.decl.name;
        int index = -1;
        for (size_t k = 0; k < params.size(); ++k)
            if (params[k].name == name) index = int(k);
        if (index < 0) {
            m_diag.warningOnce(fmt::format("shading:unknownparam:{}:{}", shader->name(), name), record.loc,
                               "shader '{}' has no parameter '{}' (ignored)", shader->name(), name);
            continue;
        }
        const ShaderParamInfo& info = params[size_t(index)];
        ShaderInstance::Binding b;
        b.param = index;
        int count = std::max(1, info.arraySize);
        int per = valueTypeFloats(info.type);
        bool ok = false;
        using ri::ParamType;
        ParamType t = rp.decl.type;
        if (info.type == ValueType::String) {
            if (t == ParamType::String && int(rp.strings.size()) == count) {
                b.strings = rp.strings;
                ok = true;
            }
        } else if (t == ParamType::Float || t == ParamType::Integer) {
            std::vector<float> f = rp.floats;
            if (t == ParamType::Integer) {
                f.clear();
                for (int v : rp.ints) f.push_back(float(v));
            }
            if (int(f.size()) == count * per) {
                b.floats = f;
                ok = true;
            } else if (int(f.size()) == count && per == 3) {  // float promotes to every component
                for (float v : f) b.floats.insert(b.floats.end(), {v, v, v});
                ok = true;
            } else if (int(f.size()) == count && per == 16) {
                for (float v : f)
                    for (int k = 0; k < 16; ++k) b.floats.push_back(k % 5 == 0 ? v : 0.f);
                ok = true;
            }
        } else if (t == ParamType::Color) {
            ok = info.type == ValueType::Color && int(rp.floats.size()) == count * 3;
            b.floats = rp.floats;
        } else if (t == ParamType::Point || t == ParamType::Vector || t == ParamType::Normal) {
            ok = (info.type == ValueType::Point || info.type == ValueType::Vector || info.type == ValueType::Normal) &&
                 int(rp.floats.size()) == count * 3;
            b.floats = rp.floats;
        } else if (t == ParamType::Matrix) {
            ok = info.type == ValueType::Matrix && int(rp.floats.size()) == count * 16;
            b.floats = rp.floats;
        }
        if (!ok) {
            m_diag.warningOnce(fmt::format("shading:badparam:{}:{}:{}", shader->name(), name, record.loc.str()), rp.loc.line ? rp.loc : record.loc,
                               "parameter '{}' of shader '{}' is {}{}, but was given {} (ignored)", name, shader->name(),
                               valueTypeName(info.type), info.arraySize ? fmt::format("[{}]", info.arraySize) : "",
                               describeParam(rp));
            continue;
        }
        if (name == "__category" && !b.strings.empty()) inst->m_category = b.strings[0];
        inst->m_bindings.push_back(std::move(b));
    }
    if (inst->m_category.empty())
        if (const ShaderParamInfo* c = shader->param("__category"); c && c->constantDefault && !c->defaultStrings.empty())
            inst->m_category = c->defaultStrings[0];
    return inst;
}

void ShadingSystem::shade(ShadingGrid& grid, const ShadeRequest& request, RendererServices& services) const {
    size_t mark = execMark();
    ShadeContext ctx;
    ctx.system = this;
    ctx.grid = &grid;
    ctx.services = &services;
    grid.m_outputs.clear();
    for (const ShaderInstance* l : request.lights)
        if (l && l->shader().kind() == ShaderKind::Light) {
            LightRun lr;
            lr.instance = l;
            lr.ambient = l->shader().code().isAmbientLight;
            ctx.lights.push_back(std::move(lr));
        }
    // Each shader is in its slot of the context while it runs: the lights
    // its illuminance loops run may ask it for its parameters (surface()
    // in a light shader, as RIBMosaic's lights ask for ShadowAlpha).
    auto runOne = [&](const CompiledShader& code, const ShaderInstance* inst, uint32_t stream, Exec** slot) {
        Exec* e = acquireExec();
        e->setup(code, inst, ctx, stream);
        *slot = e;
        e->run();
    };
    if (request.displacement)
        runOne(request.displacement->shader().code(), request.displacement, kDisplacementStream, &ctx.displacement);
    if (request.surface) runOne(request.surface->shader().code(), request.surface, kSurfaceStream, &ctx.surface);
    else if (!request.displacementOnly) runOne(m_default->code(), nullptr, kSurfaceStream, &ctx.surface);
    for (const std::string& name : request.outputs) {
        for (Exec* e : {ctx.surface, ctx.displacement}) {
            if (!e) continue;
            const CompiledShader& cs = *e->cs;
            bool done = false;
            for (size_t p = 0; p < cs.params.size(); ++p) {
                if (cs.params[p].name != name || cs.params[p].type == ValueType::String) continue;
                int r = cs.paramRegs[p];
                const RegInfo& ri = cs.regs[size_t(r)];
                const int per = ri.floatsPerValue(), comps = tyFloats(ri.ty), elems = std::max(1, ri.arrayLen);
                const int vary = e->vary[size_t(r)];
                auto& out = grid.m_outputs[name];
                out.first = per;
                out.second.resize(size_t(grid.size()) * size_t(per));
                // Point-major out of the register's layout (a varying
                // array's elements each hold n values).
                for (int i = 0; i < grid.size(); ++i)
                    for (int el = 0; el < elems; ++el)
                        std::memcpy(out.second.data() + size_t(i) * size_t(per) + size_t(el) * size_t(comps),
                                    e->ptr[size_t(r)] + size_t(el) * size_t(comps) * size_t(vary ? grid.size() : 1) +
                                        size_t(i * vary * comps),
                                    sizeof(float) * size_t(comps));
                done = true;
                break;
            }
            if (done) break;
        }
    }
    if (request.atmosphere) runOne(request.atmosphere->shader().code(), request.atmosphere, kAtmosphereStream, &ctx.atmosphere);
    releaseExecs(mark);
}

void ShadingSystem::shadeImager(ShadingGrid& grid, const ShaderInstance& imager, RendererServices& services) const {
    UMBRA_CHECK(imager.shader().kind() == ShaderKind::Imager, "shadeImager() runs imager shaders only");
    UMBRA_CHECK(grid.alpha.size() == size_t(grid.size()), "an imager grid holds one alpha per pixel");
    size_t mark = execMark();
    ShadeContext ctx;
    ctx.system = this;
    ctx.grid = &grid;
    ctx.services = &services;
    grid.m_outputs.clear();
    Exec* e = acquireExec();
    e->setup(imager.shader().code(), &imager, ctx, kImagerStream);
    e->run();
    releaseExecs(mark);
}

bool compileFile(const std::string& path, const std::vector<std::string>& includePath, Diagnostics& diag,
                 std::string* listing) {
    std::string text;
    if (!readFile(path, &text)) {
        diag.error(FileLoc::inFile(path), "cannot read shader file");
        return false;
    }
    // -I directories, then the default shader path (the standard headers).
    std::vector<std::string> inc = includePath;
    for (const std::string& d : splitSearchPath(defaultShaderPath())) inc.push_back(d);
    auto code = compileShaderSource(text, path, includePathFor(path, inc), diag);
    if (!code) return false;
    if (listing) *listing = code->listing();
    return true;
}

}  // namespace umbra::shading
