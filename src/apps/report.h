#pragma once
// The `umbra report` command: a profiling report of `--stats` files that a
// person reads in a browser (report.html) or as text (report.md).

#include "umbra/util/error.h"

#include <string>
#include <vector>

namespace umbra::apps {

/// Reads each statistics file (a `.json` document with "frames", or JSON
/// lines, one frame per line) and writes DIR/report.md and DIR/report.html.
/// Both are written to temporary names and renamed only once both are
/// complete, so bad input never leaves a half-written report.
int writeReport(const std::vector<std::string>& statsFiles, const std::string& outDir, Diagnostics& diag);

}  // namespace umbra::apps
