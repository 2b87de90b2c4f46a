#pragma once
// A check of an OpenEXR file's headers made before OpenEXR reads them.
//
// OpenEXR 3.1 allocates the size an attribute claims before reading its
// value: a damaged 2 KB depth map whose attribute claims 1.8 GB made
// ShadowMap::open (and OpenImageIO's texture lookups) allocate 1.8 GB
// (found by tests/fuzz/fuzz_maps). No attribute can be larger than what
// follows it in the file, and OpenEXR must read each value exactly as
// long as its size says (else it reads the rest out of step, and
// allocates what garbage claims); nor may a chunk's buffers, or the table
// of chunk offsets, outgrow what a file can mean (chunksFit). Header-only:
// the texture plugin uses it too, and links nothing of umbra.

#include <algorithm>
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
    if (type == "floatvector") return n % 4 == 0;  // read as n / 4 floats
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

// A window of at most 2^24 pixels a side: OpenImageIO's texture() maps s
// and t across the display window, and aborted (an assertion in its blur
// adjustment) on a 522,125,313 x 1 one (fuzz_maps).
inline bool windowFits(const int32_t window[4], std::string* why) {
    const int64_t w = int64_t(window[2]) - window[0] + 1, h = int64_t(window[3]) - window[1] + 1;
    if (w <= int64_t(1) << 24 && h <= int64_t(1) << 24) return true;
    *why = "an OpenEXR window of " + std::to_string(w) + " x " + std::to_string(h) +
           " pixels (at most 2^24 a side are read)";
    return false;
}

// Bytes a pixel takes: the sum over a channel list's channels (HALF 2,
// UINT and FLOAT 4). The list is consistent (valueConsistent).
inline uint64_t pixelBytes(const std::string& chlist) {
    uint64_t bytes = 0;
    for (size_t pos = 0; pos < chlist.size() && chlist[pos] != '\0';) {
        pos = chlist.find('\0', pos) + 1;
        bytes += le32(reinterpret_cast<const unsigned char*>(chlist.data()) + pos) == 1 ? 2 : 4;
        pos += 16;
    }
    return bytes;
}

// Scan lines a chunk of each compression holds (NONE RLE ZIPS ZIP PIZ
// PXR24 B44 B44A DWAA DWAB).
inline uint64_t linesPerChunk(int compression) {
    static const uint64_t kLines[] = {1, 1, 1, 16, 32, 16, 32, 32, 32, 256};
    return compression >= 0 && compression < 10 ? kLines[compression] : 256;
}

// OpenEXR allocates a chunk's buffers (a tile, or a compression's scan
// lines) and a table of 8-byte chunk offsets from the header when it
// opens a part (a damaged tile size asked for 1.7 GB). The table is in
// the file, which bounds the chunks; no map or texture needs chunks of
// more than 256 MB.
inline bool chunksFit(const int32_t window[4], const uint32_t tile[2], uint64_t pixel, int compression,
                      uint64_t fileBytes, std::string* why) {
    constexpr uint64_t kMaxChunkBytes = uint64_t(1) << 28;
    const bool tiled = tile[0] != 0 || tile[1] != 0;
    // Without a data window OpenEXR takes its default, 64 x 64.
    const int64_t w = int64_t(window[2]) - window[0] + 1, h = int64_t(window[3]) - window[1] + 1;
    const uint64_t chunkPixels = tiled ? uint64_t(tile[0]) * tile[1]
                                       : uint64_t(w > 0 ? w : 64) * linesPerChunk(compression);
    if ((tiled && (tile[0] == 0 || tile[1] == 0)) || chunkPixels * std::max<uint64_t>(pixel, 1) > kMaxChunkBytes) {
        *why = "OpenEXR chunks of " + std::to_string(chunkPixels) + " pixels of " + std::to_string(pixel) +
               " bytes (at most 256 MB a chunk are read)";
        return false;
    }
    if (w <= 0 || h <= 0) return true;
    const uint64_t chunks = tiled ? (uint64_t(w) / tile[0] + 1) * (uint64_t(h) / tile[1] + 1)
                                  : uint64_t(h) / linesPerChunk(compression);
    if (chunks > fileBytes / 8) {
        *why = "an OpenEXR data window of " + std::to_string(w) + " x " + std::to_string(h) +
               " pixels needs more chunks than the file's " + std::to_string(fileBytes) + " bytes can hold";
        return false;
    }
    return true;
}

}  // namespace exr_detail

/// False, with the reason in `why`, when `path` starts with the OpenEXR
/// magic number and one of its headers is truncated, names an attribute or
/// type longer than the format allows, gives an attribute a size larger
/// than the rest of the file, or a value OpenEXR would read differently
/// from its size (a fixed-size type with another size, a channel list,
/// preview, string or float vector that does not fill it exactly). True for
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
        int32_t window[4] = {0, 0, -1, -1};  // dataWindow: xmin ymin xmax ymax
        uint32_t tile[2] = {0, 0};           // tiles' size; 0: scan lines
        int32_t display[4] = {0, 0, -1, -1};
        uint64_t pixel = 0;                  // bytes a pixel of all channels
        int compression = 0;
        for (;;) {
            if (!readName(name)) {
                *why = "damaged OpenEXR header (an attribute name is cut or too long)";
                return false;
            }
            if (name.empty()) {  // the end of this header
                if (!exr_detail::windowFits(window, why) || !exr_detail::windowFits(display, why) ||
                    !exr_detail::chunksFit(window, tile, pixel, compression, fileBytes, why))
                    return false;
                break;
            }
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
            const auto* v = reinterpret_cast<const unsigned char*>(value.data());
            if (name == "dataWindow" && type == "box2i")
                for (int k = 0; k < 4; ++k) window[k] = int32_t(exr_detail::le32(v + 4 * k));
            if (name == "displayWindow" && type == "box2i")
                for (int k = 0; k < 4; ++k) display[k] = int32_t(exr_detail::le32(v + 4 * k));
            if (name == "channels" && type == "chlist") pixel = exr_detail::pixelBytes(value);
            if (name == "compression" && type == "compression") compression = v[0];
            if (name == "tiles" && type == "tiledesc") {
                tile[0] = exr_detail::le32(v);
                tile[1] = exr_detail::le32(v + 4);
            }
        }
        // One header, or (multi-part) headers until an empty one.
        if (!multipart || !anyAttribute) return true;
    }
}

}  // namespace umbra
