#pragma once
// RenderMan search paths and where an installed umbra finds its files.
//
// A search path is a ':'-separated list of directories. In
// `Option "searchpath"` and in $UMBRA_SHADER_PATH / $UMBRA_TEXTURE_PATH,
// `&` stands for the previous value and `@` for the built-in default
// (the Aqsis and PRMan convention).

#include <string>
#include <vector>

namespace umbra {

/// `spec` with each `&` replaced by `previous` and each `@` by `builtin`,
/// also inside an entry (`../&` is `../` then `previous`); empty entries
/// are dropped. The result has no `&` or `@` left.
std::string expandSearchPath(const std::string& spec, const std::string& previous, const std::string& builtin);

/// The directories of a search path, in order, without empty entries.
std::vector<std::string> splitSearchPath(const std::string& path);

/// The directories joined with ':'.
std::string joinSearchPath(const std::vector<std::string>& dirs);

/// The directory of the running executable (read from /proc/self/exe, so
/// an installed tree may be moved); empty when it cannot be read.
std::string executableDirectory();

/// The standard shaders: `<exe dir>/../share/umbra/shaders` in an installed
/// tree; when that directory does not exist (the build tree), the source
/// tree's shaders_dsl/.
std::string builtinShaderDir();

/// The default shader path (what `@` stands for): $UMBRA_SHADER_PATH, in
/// which `&` and `@` are builtinShaderDir(), or builtinShaderDir() alone.
std::string defaultShaderPath();

/// The default texture path (what `@` stands for): $UMBRA_TEXTURE_PATH, in
/// which `&` and `@` are nothing (umbra ships no textures), or empty.
std::string defaultTexturePath();

}  // namespace umbra
