#pragma once
// The `umbra slc` and `umbra info` commands.

#include "umbra/util/error.h"

#include <string>
#include <vector>

namespace umbra::apps {

/// Compiles each shader, printing errors (and the bytecode with `listing`).
int compileShaders(const std::vector<std::string>& files, const std::vector<std::string>& includePath, bool listing,
                   Diagnostics& diag);
/// Prints a depth map's resolution, bounds, tiles and storage (Reeves' Table 2).
int describeMap(const std::string& path, bool json, Diagnostics& diag);

}  // namespace umbra::apps
