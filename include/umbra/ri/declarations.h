#pragma once
// Parameter declarations: the `Declare` table, pre-filled with the standard
// declarations of RI spec 3.2 (geometric variables, the standard shaders'
// parameters, and the parameters of the options and attributes umbra
// understands), plus parsing of declaration strings.

#include "umbra/ri/param_list.h"

#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

namespace umbra::ri {

/// The declarations in force while parsing one RIB stream. `Declare` adds
/// or replaces entries; inline declarations ("varying color Cs2") are used
/// for one parameter only and never enter the table.
class Declarations {
public:
    /// A table holding the standard declarations.
    Declarations();

    /// Parses "[class] type[[n]]" (with `withName`, a trailing name too:
    /// "[class] type[[n]] name"). On failure returns false and sets
    /// `*error` to what was wrong.
    static bool parse(std::string_view text, bool withName, ParamDecl* out, std::string* error);

    /// The declaration for `name`, or nullptr.
    const ParamDecl* find(std::string_view name) const;
    void declare(const ParamDecl& decl);

    /// Resolves a parameter-list name token: an inline declaration when it
    /// contains a space, otherwise a table lookup. False with `*error` set
    /// when the inline declaration is malformed or the name is undeclared.
    bool resolve(std::string_view token, ParamDecl* out, std::string* error) const;

    /// The declarations RenderMan renderers (PRMan, Aqsis, Pixie) give the
    /// parameter `name` of `Option`/`Attribute` class `cls`, or of a
    /// `Hider` of type `cls`, e.g. Attribute "dice" "binary": uniform
    /// integer. A name may have several ("visibility" "transmission" is an
    /// integer, or a string in older RIBs); empty when umbra knows none.
    /// `request` is "Option", "Attribute" or "Hider".
    static std::vector<ParamDecl> forClass(std::string_view request, std::string_view cls, std::string_view name);

private:
    std::unordered_map<std::string, ParamDecl> m_table;
};

}  // namespace umbra::ri
