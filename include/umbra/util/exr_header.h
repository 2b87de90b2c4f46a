#pragma once
// A check of an OpenEXR file's headers made before OpenEXR reads them.
//
// OpenEXR 3.1 allocates the size an attribute claims before reading its
// value: a damaged 2 KB depth map whose attribute claims 1.8 GB made
// ShadowMap::open (and OpenImageIO's texture lookups) allocate 1.8 GB
// (found by tests/fuzz/fuzz_maps). No attribute can be larger than what
// follows it in the file, and OpenEXR must read each value exactly as
// long as its size says (else it reads the rest out of step, and
// allocates what garbage claims): both are checked here. Header-only: the
// texture plugin uses it too, and links nothing of umbra.

#include <cstdint>
#include <fstream>
#include <map>
#include <string>

namespace umbra {

namespace exr_detail {

inline uint32_t le32(const unsigned char* p) {
    return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}

// The bytes OpenEXR 3.1 reads for a value of a known fixed-size type
// (whatever size the attribute gives), 0 for a variable size, -1 for a
// type it does not know (read as `size` opaque bytes).
inline int fixedSize(const std::string& type) {
    static const std::map<std::string, int> kSizes = {
        {"box2i", 16},    {"box2f", 16}, {"chromaticities", 32}, {"compression", 1}, {"deepImageState", 1},
        {"double", 8},    {"envmap", 1}, {"float", 4},           {"int", 4},         {"keycode", 28},
        {"lineOrder", 1}, {"m33f", 36},  {"m33d", 72},           {"m44f", 64},       {"m44d", 128},
        {"rational", 8},  {"tiledesc", 9}, {"timecode", 8},      {"v2i", 8},         {"v2f", 8},
        {"v2d", 16},      {"v3i", 12},   {"v3f", 12},            {"v3d", 24},        {"chlist", 0},
        {"preview", 0},   {"string", 0}, {"stringvector", 0},    {"floatvector", 0}, {"idmanifest", 0},
    };
    auto it = kSizes.find(type);
    return it == kSizes.end() ? -1 : it->second;
}

// True when OpenEXR reads exactly `value` for an attribute of `type`: its
// readers of fixed-size types and of channel lists ignore the size given,
// so a damaged size would leave it reading the rest of the header out of
// step (and then allocate what garbage claims).
inline bool valueConsistent(const std::string& type, const std::string& value, size_t maxName) {
    const int fixed = fixedSize(type);
    if (fixed > 0) return value.size() == size_t(fixed);
    const auto* v = reinterpret_cast<const unsigned char*>(value.data());
    const size_t n = value.size();
    if (type == "chlist") {  // records (name, 16 bytes) up to an empty name
        size_t pos = 0;
        for (;;) {
            const size_t end = value.find('\0', pos);
            if (end == std::string::npos || end - pos > maxName) return false;
            if (end == pos) return end + 1 == n;
            pos = end + 1 + 16;
            if (pos > n) return false;
        }
    }
    if (type == "preview") return n >= 8 && uint64_t(n) == 8 + 4 * uint64_t(le32(v)) * uint64_t(le32(v + 4));
    if (type == "stringvector") {  // length-prefixed strings filling the value
        for (size_t pos = 0; pos < n;) {
            if (n - pos < 4) return false;
            const uint32_t length = le32(v + pos);
            pos += 4;
            if (length > n - pos) return false;
            pos += length;
        }
    }
    return true;
}

}  // namespace exr_detail

/// False, with the reason in `why`, when `path` starts with the OpenEXR
/// magic number and one of its headers is truncated, names an attribute or
/// type longer than the format allows, gives an attribute a size larger
/// than the rest of the file, or a value OpenEXR would read differently
/// from its size (a fixed-size type with another size, a channel list,
/// preview or string vector that does not fill it exactly). True for
/// anything else (files that are not OpenEXR are left to their readers).
inline bool exrHeadersFit(const std::string& path, std::string* why) {
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (!in) return true;
    const uint64_t fileBytes = uint64_t(in.tellg());
    in.seekg(0);
    unsigned char start[8];
    if (!in.read(reinterpret_cast<char*>(start), 8)) return true;
    if (start[0] != 0x76 || start[1] != 0x2f || start[2] != 0x31 || start[3] != 0x01) return true;
    const uint32_t version = exr_detail::le32(start + 4);
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
    std::string name, type, value;
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
            const int32_t bytes = int32_t(exr_detail::le32(size));
            if (bytes < 0 || uint64_t(bytes) > fileBytes - pos) {
                *why = "damaged OpenEXR header (attribute \"" + name + "\" claims " + std::to_string(bytes) +
                       " bytes, the file has " + std::to_string(fileBytes - pos) + " after it)";
                return false;
            }
            value.resize(size_t(bytes));
            if (!in.read(value.data(), bytes) || !exr_detail::valueConsistent(type, value, maxName)) {
                *why = "damaged OpenEXR header (attribute \"" + name + "\" of type \"" + type +
                       "\" does not fit its size, " + std::to_string(bytes) + ")";
                return false;
            }
            pos += uint64_t(bytes);
        }
        // One header, or (multi-part) headers until an empty one.
        if (!multipart || !anyAttribute) return true;
    }
}

}  // namespace umbra
