#pragma once
// The `umbra slc`, `umbra info` and `umbra txmake` commands.

#include "umbra/util/error.h"

#include <string>
#include <vector>

namespace umbra::apps {

/// Compiles each shader, printing errors (and the bytecode with `listing`).
int compileShaders(const std::vector<std::string>& files, const std::vector<std::string>& includePath, bool listing,
                   Diagnostics& diag);
/// What `umbra txmake` was asked to make.
struct TxmakeArgs {
    std::vector<std::string> files;  // inputs, then the output
    bool shadow = false, envLatl = false, envCube = false;
    std::string wrap, swrap, twrap;  // empty: --wrap, or "black"
    std::string filter = "gaussian";
    float width = 0, swidth = 0, twidth = 0;  // 0: --width, or 2
    float fov = 90;
};
/// Makes a texture, environment or shadow map file with the code of the
/// MakeTexture, MakeLatLongEnvironment, MakeCubeFaceEnvironment and
/// MakeShadow requests.
int txmake(const TxmakeArgs& args, Diagnostics& diag);
/// Prints a depth map's resolution, bounds, tiles and storage (Reeves' Table 2).
int describeMap(const std::string& path, bool json, Diagnostics& diag);

}  // namespace umbra::apps
