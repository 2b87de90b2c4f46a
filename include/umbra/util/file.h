#pragma once
// Finished output files are written under a temporary name and moved into
// place, so no reader (and no crash) ever sees half a file.

#include <string>

namespace umbra {

/// Moves the finished file `tmp` to `target`, replacing what is there;
/// false (with `tmp` left in place) when the rename fails.
///
/// The old `target` is unlinked first: ext4 (auto_da_alloc) flushes a file
/// renamed over an existing one, which made the rename itself take 2-3 ms
/// for a 150 KB image, on every frame's critical path. A crash between the
/// two steps leaves no `target` and a complete `tmp`, never a partial file.
bool moveIntoPlace(const std::string& tmp, const std::string& target);

}  // namespace umbra
