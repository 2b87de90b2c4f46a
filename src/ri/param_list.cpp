#include "umbra/ri/param_list.h"

namespace umbra::ri {

const char* storageClassName(StorageClass c) {
    switch (c) {
    case StorageClass::Constant: return "constant";
    case StorageClass::Uniform: return "uniform";
    case StorageClass::Varying: return "varying";
    case StorageClass::Vertex: return "vertex";
    case StorageClass::FaceVarying: return "facevarying";
    case StorageClass::FaceVertex: return "facevertex";
    }
    return "uniform";
}

const char* paramTypeName(ParamType t) {
    switch (t) {
    case ParamType::Float: return "float";
    case ParamType::Integer: return "integer";
    case ParamType::String: return "string";
    case ParamType::Point: return "point";
    case ParamType::Vector: return "vector";
    case ParamType::Normal: return "normal";
    case ParamType::Color: return "color";
    case ParamType::HPoint: return "hpoint";
    case ParamType::Matrix: return "matrix";
    case ParamType::Bool: return "bool";
    }
    return "float";
}

int componentsOf(ParamType t) {
    switch (t) {
    case ParamType::Point:
    case ParamType::Vector:
    case ParamType::Normal:
    case ParamType::Color: return 3;
    case ParamType::HPoint: return 4;
    case ParamType::Matrix: return 16;
    default: return 1;
    }
}

bool isFloatType(ParamType t) {
    return t != ParamType::Integer && t != ParamType::String && t != ParamType::Bool;
}

std::string ParamDecl::str() const {
    std::string s = storageClassName(storage);
    s += ' ';
    s += paramTypeName(type);
    if (arraySize != 1) s += fmt::format("[{}]", arraySize);
    s += ' ';
    s += name;
    return s;
}

size_t Param::count() const {
    size_t per = static_cast<size_t>(decl.elementSize() > 0 ? decl.elementSize() : 1);
    if (decl.type == ParamType::String) return strings.size() / per;
    if (isFloatType(decl.type)) return floats.size() / per;
    return ints.size() / per;
}

const std::string& Param::stringAt(size_t i) const {
    static const std::string kEmpty;
    return i < strings.size() ? strings[i] : kEmpty;
}

void ParamList::add(Param p) {
    // A later parameter of the same name replaces the earlier one, as in
    // RenderMan where the last value given wins.
    for (size_t i = 0; i < m_params.size(); ++i) {
        if (m_params[i].decl.name == p.decl.name) {
            m_params[i] = std::move(p);
            m_used[i] = false;
            return;
        }
    }
    m_params.push_back(std::move(p));
    m_used.push_back(false);
}

const Param* ParamList::find(std::string_view name) const {
    for (size_t i = 0; i < m_params.size(); ++i) {
        if (m_params[i].decl.name == name) {
            m_used[i] = true;
            return &m_params[i];
        }
    }
    return nullptr;
}

Param* ParamList::findMutable(std::string_view name) {
    for (Param& p : m_params)
        if (p.decl.name == name) return &p;
    return nullptr;
}

float ParamList::getFloat(std::string_view name, float def) const {
    const Param* p = find(name);
    if (!p) return def;
    if (isFloatType(p->decl.type)) return p->floatAt(0, def);
    if (p->decl.type != ParamType::String && !p->ints.empty()) return static_cast<float>(p->ints[0]);
    return def;
}

int ParamList::getInt(std::string_view name, int def) const {
    const Param* p = find(name);
    if (!p) return def;
    if (p->decl.type == ParamType::Integer || p->decl.type == ParamType::Bool) return p->intAt(0, def);
    if (isFloatType(p->decl.type) && !p->floats.empty()) return static_cast<int>(p->floats[0]);
    return def;
}

std::string ParamList::getString(std::string_view name, const std::string& def) const {
    const Param* p = find(name);
    if (!p || p->decl.type != ParamType::String || p->strings.empty()) return def;
    return p->strings[0];
}

void ParamList::reportUnused(Diagnostics& diag, std::string_view context) const {
    for (size_t i = 0; i < m_params.size(); ++i)
        if (!m_used[i])
            diag.warning(m_params[i].loc, "{}: parameter \"{}\" is not used", context, m_params[i].decl.name);
}

}  // namespace umbra::ri
