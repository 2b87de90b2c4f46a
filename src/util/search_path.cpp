#include "umbra/util/search_path.h"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <filesystem>

namespace umbra {

std::vector<std::string> splitSearchPath(const std::string& path) {
    std::vector<std::string> out;
    size_t start = 0;
    while (start <= path.size()) {
        size_t end = path.find(':', start);
        if (end == std::string::npos) end = path.size();
        if (end > start) out.push_back(path.substr(start, end - start));
        start = end + 1;
    }
    return out;
}

std::string joinSearchPath(const std::vector<std::string>& dirs) {
    std::string out;
    for (const std::string& d : dirs) {
        if (d.empty()) continue;
        if (!out.empty()) out += ':';
        out += d;
    }
    return out;
}

namespace {

/// $NAME and ${NAME} replaced by the environment's values, as PRMan and
/// Pixie read search paths ("${RMANTREE}/lib/shaders", RenderMan for Maya's
/// "${RMSPROJ}"); an unset variable is left as written (a directory that
/// does not exist, harmless and visible in messages).
std::string withEnvironment(const std::string& spec) {
    std::string out;
    for (size_t i = 0; i < spec.size();) {
        if (spec[i] != '$') {
            out += spec[i++];
            continue;
        }
        const bool braced = i + 1 < spec.size() && spec[i + 1] == '{';
        size_t start = i + (braced ? 2 : 1), end = start;
        while (end < spec.size() && (std::isalnum(static_cast<unsigned char>(spec[end])) || spec[end] == '_')) ++end;
        const bool closed = !braced || (end < spec.size() && spec[end] == '}');
        const char* value = end > start && closed ? std::getenv(spec.substr(start, end - start).c_str()) : nullptr;
        const size_t next = braced && closed ? end + 1 : end;
        if (value) out += value;
        else out.append(spec, i, std::max(next, i + 1) - i);
        i = std::max(next, i + 1);
    }
    return out;
}

}  // namespace

std::string expandSearchPath(const std::string& given, const std::string& previous, const std::string& builtin) {
    const std::string spec = withEnvironment(given);
    // A marker inside an entry ("../&", "shaders@") is still a marker: the
    // text on either side becomes an entry of its own and the marker's list
    // goes between, as Pixie and Aqsis read it (exported scenes write
    // ".:../&" for ".:..:&").
    std::vector<std::string> out;
    for (const std::string& part : splitSearchPath(spec)) {
        size_t start = 0;
        for (size_t i = 0; i <= part.size(); ++i) {
            if (i < part.size() && part[i] != '&' && part[i] != '@') continue;
            if (i > start) out.push_back(part.substr(start, i - start));
            if (i < part.size())
                for (auto& d : splitSearchPath(part[i] == '&' ? previous : builtin)) out.push_back(d);
            start = i + 1;
        }
    }
    // A directory named twice (".:@" where '@' holds ".") is searched once,
    // where it first comes.
    std::vector<std::string> once;
    for (std::string& d : out)
        if (std::find(once.begin(), once.end(), d) == once.end()) once.push_back(std::move(d));
    return joinSearchPath(once);
}

std::string executableDirectory() {
    std::error_code ec;
    std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
    if (ec) return {};
    return exe.parent_path().string();
}

std::string builtinShaderDir() {
    namespace fs = std::filesystem;
    std::string exeDir = executableDirectory();
    if (!exeDir.empty()) {
        fs::path installed = fs::path(exeDir).parent_path() / "share" / "umbra" / "shaders";
        std::error_code ec;
        if (fs::is_directory(installed, ec)) return installed.lexically_normal().string();
    }
    return UMBRA_SOURCE_SHADER_DIR;
}

std::string defaultShaderPath() {
    const std::string builtin = builtinShaderDir();
    const char* env = std::getenv("UMBRA_SHADER_PATH");
    if (!env || !*env) return builtin;
    return expandSearchPath(env, builtin, builtin);
}

std::string defaultTexturePath() {
    const char* env = std::getenv("UMBRA_TEXTURE_PATH");
    if (!env || !*env) return {};
    return expandSearchPath(env, {}, {});
}

}  // namespace umbra
