#pragma once
// A check of an OpenEXR file's headers made before OpenEXR reads them.
//
// OpenEXR 3.1 allocates the size an attribute claims before reading its
// value: a damaged 2 KB depth map whose attribute claims 1.8 GB made
// ShadowMap::open (and OpenImageIO's texture lookups) allocate 1.8 GB
// (found by tests/fuzz/fuzz_maps). No attribute can be larger than what
// follows it in the file, so that is checked here. Header-only: the
// texture plugin uses it too, and links nothing of umbra.

#include <cstdint>
#include <fstream>
#include <string>

namespace umbra {

/// False, with the reason in `why`, when `path` starts with the OpenEXR
/// magic number and one of its headers is truncated, names an attribute or
/// type longer than the format allows, or gives an attribute a size
/// larger than the rest of the file. True for anything else (files that
/// are not OpenEXR are left to their readers).
inline bool exrHeadersFit(const std::string& path, std::string* why) {
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (!in) return true;
    const uint64_t fileBytes = uint64_t(in.tellg());
    in.seekg(0);
    unsigned char start[8];
    if (!in.read(reinterpret_cast<char*>(start), 8)) return true;
    if (start[0] != 0x76 || start[1] != 0x2f || start[2] != 0x31 || start[3] != 0x01) return true;
    const uint32_t version = uint32_t(start[4]) | uint32_t(start[5]) << 8 | uint32_t(start[6]) << 16 |
                             uint32_t(start[7]) << 24;
    const bool multipart = (version & 0x1000) != 0;
    const size_t maxName = (version & 0x400) != 0 ? 255 : 31;
    uint64_t pos = 8;
    // A name or type: up to maxName characters and a terminating zero.
    auto readName = [&](std::string& s) {
        s.clear();
        for (char c; in.get(c);) {
            ++pos;
            if (c == '\0') return true;
            if (s.size() == maxName) return false;
            s.push_back(c);
        }
        return false;
    };
    std::string name, type;
    for (;;) {
        bool anyAttribute = false;
        for (;;) {
            if (!readName(name)) {
                *why = "damaged OpenEXR header (an attribute name is cut or too long)";
                return false;
            }
            if (name.empty()) break;  // the end of this header
            anyAttribute = true;
            unsigned char size[4];
            if (!readName(type) || !in.read(reinterpret_cast<char*>(size), 4)) {
                *why = "damaged OpenEXR header (attribute \"" + name + "\" is cut)";
                return false;
            }
            pos += 4;
            const int32_t bytes = int32_t(uint32_t(size[0]) | uint32_t(size[1]) << 8 | uint32_t(size[2]) << 16 |
                                          uint32_t(size[3]) << 24);
            if (bytes < 0 || uint64_t(bytes) > fileBytes - pos) {
                *why = "damaged OpenEXR header (attribute \"" + name + "\" claims " + std::to_string(bytes) +
                       " bytes, the file has " + std::to_string(fileBytes - pos) + " after it)";
                return false;
            }
            in.seekg(bytes, std::ios::cur);
            pos += uint64_t(bytes);
        }
        // One header, or (multi-part) headers until an empty one.
        if (!multipart || !anyAttribute) return true;
    }
}

}  // namespace umbra
