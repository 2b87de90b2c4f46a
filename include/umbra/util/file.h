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
/// A file that exists and is not a regular file (or a link to one) is
/// never replaced: false, with errno EISDIR or EEXIST.
bool moveIntoPlace(const std::string& tmp, const std::string& target);

/// Where an output named `path` is written: `path` itself, or the file its
/// symbolic links lead to (written through, not replaced). False, with the
/// reason in `why`, when it names a directory, a device, a FIFO or a socket:
/// outputs are written whole under a temporary name and renamed, which
/// cannot be done to those (and must never replace them).
bool resolveOutputPath(const std::string& path, std::string* resolved, std::string* why);

}  // namespace umbra
