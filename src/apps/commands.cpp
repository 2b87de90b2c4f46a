#include "apps/commands.h"

#include "umbra/render/make_files.h"
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

int txmake(const TxmakeArgs& a, Diagnostics& diag) {
    const FileLoc loc = FileLoc::inFile("umbra txmake");
    const int modes = int(a.shadow) + int(a.envLatl) + int(a.envCube);
    if (modes > 1) {
        diag.error(loc, "--shadow, --envlatl and --envcube exclude each other");
        return 1;
    }
    const size_t want = a.envCube ? 7 : 2;
    if (a.files.size() != want) {
        diag.error(loc, "expected {}, got {} file name{}",
                   a.envCube ? "six cube faces (px nx py ny pz nz) and an output file"
                             : "an input file and an output file",
                   a.files.size(), a.files.size() == 1 ? "" : "s");
        return 1;
    }
    scene::MakeRecord make;
    make.request = a.shadow ? "MakeShadow" : a.envLatl ? "MakeLatLongEnvironment"
                                       : a.envCube ? "MakeCubeFaceEnvironment" : "MakeTexture";
    make.inputs.assign(a.files.begin(), a.files.end() - 1);
    make.output = a.files.back();
    make.loc = loc;
    const std::string wrap = a.wrap.empty() ? "black" : a.wrap;
    const float width = a.width > 0 ? a.width : 2.0f;
    const float sw = a.swidth > 0 ? a.swidth : width, tw = a.twidth > 0 ? a.twidth : width;
    if (make.request == "MakeTexture") {
        make.stringArgs = {a.swrap.empty() ? wrap : a.swrap, a.twrap.empty() ? wrap : a.twrap, a.filter};
        make.floatArgs = {sw, tw};
    } else if (!a.shadow) {
        make.stringArgs = {a.filter};
        make.floatArgs = {sw, tw};
        if (a.envCube) make.floatArgs.insert(make.floatArgs.begin(), a.fov);
    }
    return render::makeFile(make, diag) ? 0 : 1;
}

}  // namespace umbra::apps
