#include "umbra/shading/texture_backend.h"
#include "umbra/util/search_path.h"

#include <dlfcn.h>

#include <cstdlib>
#include <filesystem>
#include <mutex>

namespace umbra::shading {

namespace {

std::vector<std::string> pluginCandidates() {
    std::vector<std::string> out;
    if (const char* env = std::getenv("UMBRA_PLUGIN_PATH")) out.push_back(std::string(env) + "/umbra_oiio.so");
    // Beside the executable (the build tree), or in <prefix>/lib/umbra for
    // <prefix>/bin/umbra (an installed tree, wherever it was moved).
    const std::filesystem::path exeDir = executableDirectory();
    if (!exeDir.empty()) {
        out.push_back((exeDir / "umbra_oiio.so").string());
        out.push_back((exeDir.parent_path() / "lib" / "umbra" / "umbra_oiio.so").string());
    }
#ifdef UMBRA_PLUGIN_DIR
    out.push_back(std::string(UMBRA_PLUGIN_DIR) + "/umbra_oiio.so");
#endif
    return out;
}

}  // namespace

TextureBackend* textureBackend(std::string* error) {
    static std::once_flag once;
    static TextureBackend* backend = nullptr;
    static std::string failure;
    std::call_once(once, [] {
        std::string tried;
        for (const std::string& path : pluginCandidates()) {
            void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
            if (!handle) {
                tried += (tried.empty() ? "" : "; ") + std::string(dlerror());
                continue;
            }
            auto entry = reinterpret_cast<TextureBackend* (*)()>(dlsym(handle, "umbra_texture_backend"));
            if (entry) {
                backend = entry();
                return;
            }
            tried += (tried.empty() ? "" : "; ") + path + ": no entry point";
        }
        failure = "cannot load the OpenImageIO texture plugin umbra_oiio.so (" + tried + ")";
    });
    if (!backend && error) *error = failure;
    return backend;
}

}  // namespace umbra::shading
