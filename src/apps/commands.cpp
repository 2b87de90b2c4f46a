#include "apps/commands.h"

#include "umbra/shading/shading_system.h"
#include "umbra/shadow/shadow_map.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

namespace umbra::apps {

int compileShaders(const std::vector<std::string>& files, const std::vector<std::string>& includePath, bool listing,
                   Diagnostics& diag) {
    bool ok = true;
    for (const auto& file : files) {
        std::string text;
        if (!shading::compileFile(file, includePath, diag, listing ? &text : nullptr)) {
            ok = false;
            continue;
        }
        if (listing) fmt::print("{}", text);
    }
    return ok ? 0 : 1;
}

int describeMap(const std::string& path, bool json, Diagnostics& diag) {
    auto map = ShadowMap::open(path, diag, FileLoc::inFile(path));
    if (!map) return 1;
    MapInfo info = map->info();
    if (json)
        fmt::print("{}\n", mapInfoJson(info).dump(2));
    else
        fmt::print("{}", mapInfoText(info));
    return 0;
}

}  // namespace umbra::apps
