#pragma once
// RenderMan parameter lists: the `"name" [values]` pairs that follow most
// RIB requests, each typed by a declaration (`Declare` or inline, e.g.
// "uniform float Ka" or "varying color[2] Cs2").

#include "umbra/util/error.h"

#include <string>
#include <string_view>
#include <vector>

namespace umbra::ri {

/// How a primitive variable is interpolated over a primitive (RI spec 3.2,
/// section 5.6): one value per primitive, per face, per corner (bilinear),
/// per control vertex (with the basis), or per face corner.
enum class StorageClass { Constant, Uniform, Varying, Vertex, FaceVarying, FaceVertex };

enum class ParamType { Float, Integer, String, Point, Vector, Normal, Color, HPoint, Matrix, Bool };

const char* storageClassName(StorageClass c);
const char* paramTypeName(ParamType t);

/// Floats per element: 1, 3 for point/vector/normal/color, 4 for hpoint,
/// 16 for matrix; 1 for integer/string/bool (stored in their own arrays).
int componentsOf(ParamType t);
/// True for types whose values live in Param::floats.
bool isFloatType(ParamType t);

/// A parameter's declaration. Undeclared parameters fall back to the
/// standard ones (P, N, Cs, Os, s, t, st, Pw, Pz, ...) or are errors.
struct ParamDecl {
    std::string name;
    StorageClass storage = StorageClass::Uniform;
    ParamType type = ParamType::Float;
    int arraySize = 1;  // `float[4]` has 4; plain has 1
    /// True for a shader parameter the RIB never declared: its type was
    /// inferred from its values (strings, or floats) and the shader's own
    /// declaration decides how it binds (RenderMan reads the shader's
    /// declarations for shader requests).
    bool inferred = false;

    /// Floats (or ints/strings) per element, array size included.
    int elementSize() const { return componentsOf(type) * arraySize; }
    /// "varying color[2] Cs2" form.
    std::string str() const;
};

/// One parameter: its declaration and its values, kept in the array that
/// fits its type.
struct Param {
    ParamDecl decl;
    std::vector<float> floats;         // float, point, vector, normal, color, hpoint, matrix
    std::vector<int> ints;             // integer, bool
    std::vector<std::string> strings;  // string
    FileLoc loc;                       // where the name token was

    /// Number of elements (values / elementSize), e.g. vertices for "P".
    size_t count() const;
    float floatAt(size_t i, float def = 0) const { return i < floats.size() ? floats[i] : def; }
    int intAt(size_t i, int def = 0) const { return i < ints.size() ? ints[i] : def; }
    const std::string& stringAt(size_t i) const;
};

/// An ordered parameter list. Lookups mark parameters as used, so the
/// consumer can warn about misspelled or unused ones (pbrt's
/// ParameterDictionary::ReportUnused).
class ParamList {
public:
    void add(Param p);
    const std::vector<Param>& params() const { return m_params; }
    bool empty() const { return m_params.empty(); }
    size_t size() const { return m_params.size(); }

    /// The parameter called `name`, or nullptr; marks it used.
    const Param* find(std::string_view name) const;
    /// The parameter called `name` for changing its values, or nullptr;
    /// does not mark it used.
    Param* findMutable(std::string_view name);
    /// Typed single-value lookups with a default; mark the parameter used.
    float getFloat(std::string_view name, float def) const;
    int getInt(std::string_view name, int def) const;
    std::string getString(std::string_view name, const std::string& def) const;

    /// Warns once per parameter that no lookup asked for, naming `context`.
    void reportUnused(Diagnostics& diag, std::string_view context) const;

private:
    std::vector<Param> m_params;
    mutable std::vector<bool> m_used;
};

}  // namespace umbra::ri
