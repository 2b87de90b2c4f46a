#include "umbra/shadow/depth_image.h"
#include "umbra/util/file.h"

#include "map_header.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>

namespace umbra {

namespace {

constexpr uint32_t kZFileMagic = 0x2f0867abU;
constexpr uint32_t kExrMagic = 0x01312f76U;  // bytes 76 2f 31 01, read little-endian
constexpr size_t kZFileHeaderBytes = 4 + 2 + 2 + 16 * 4 + 16 * 4;
/// A motion-blurred depth frame's zfile carries, after its depths, when
/// each texel holds its casters (DepthImage::texelTimes), so MakeShadow's
/// map can compare moving receivers time by time: this tag, the time tile
/// and the table's side n (int32 each), and n * n float times, in the
/// file's byte order. Readers that read the w * h depths after the header
/// (PRMan's, Pixie's, Aqsis's) stop before it.
constexpr char kTimesTag[8] = {'u', 'm', 'b', 'r', 'a', 'T', 'I', 'M'};
constexpr size_t kTimesHeaderBytes = sizeof kTimesTag + 4 + 4;

// RenderMan's default screen window for an image of aspect w/h.
void defaultScreenWindow(int w, int h, float* l, float* r, float* b, float* t) {
    float a = float(w) / float(h);
    if (a >= 1) { *l = -a; *r = a; *b = -1; *t = 1; }
    else { *l = -1; *r = 1; *b = -1 / a; *t = 1 / a; }
}

// Screen (x right, y up, screen window [l,r]x[b,t]) from NDC (x right, y
// down, [0,1]^2); z passes through.
Mat4 screenFromNdc(int w, int h) {
    float l, r, b, t;
    defaultScreenWindow(w, h, &l, &r, &b, &t);
    Mat4 m;
    m.m[0][0] = r - l; m.m[0][3] = l;
    m.m[1][1] = -(t - b); m.m[1][3] = t;
    return m;
}

Mat4 ndcFromScreen(int w, int h) {
    float l, r, b, t;
    defaultScreenWindow(w, h, &l, &r, &b, &t);
    Mat4 m;
    m.m[0][0] = 1 / (r - l); m.m[0][3] = -l / (r - l);
    m.m[1][1] = -1 / (t - b); m.m[1][3] = t / (t - b);
    return m;
}

template <typename T> T byteSwap(T v) {
    unsigned char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    for (size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
    std::memcpy(&v, b, sizeof(T));
    return v;
}

bool writeZFileImpl(const std::string& named, const DepthImage& image, std::string& why) {
    if (image.width <= 0 || image.height <= 0 || image.width > 32767 || image.height > 32767 ||
        image.z.size() != size_t(image.width) * image.height) {
        why = "expected an image of 1..32767 x 1..32767 depths";
        return false;
    }
    std::string path;
    if (!resolveOutputPath(named, &path, &why)) return false;
    const std::string tmp = path + ".tmp";
    {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        if (!out) {
            why = "cannot open the file for writing";
            return false;
        }
        uint32_t magic = kZFileMagic;
        int16_t w = int16_t(image.width), h = int16_t(image.height);
        float np[16], nl[16];
        (screenFromNdc(image.width, image.height) * image.ndcFromWorld).toRib(np);
        image.lightFromWorld.toRib(nl);
        out.write(reinterpret_cast<const char*>(&magic), 4);
        out.write(reinterpret_cast<const char*>(&w), 2);
        out.write(reinterpret_cast<const char*>(&h), 2);
        out.write(reinterpret_cast<const char*>(np), sizeof np);
        out.write(reinterpret_cast<const char*>(nl), sizeof nl);
        if (image.whole()) {
            out.write(reinterpret_cast<const char*>(image.z.data()), std::streamsize(image.z.size() * sizeof(float)));
        } else {
            // Row by row, +infinity outside the texels the pass wrote.
            std::vector<float> row(size_t(image.width), kInfinity);
            const int x0 = image.columnBegin(), x1 = std::max(x0, image.columnEnd());
            for (int y = 0; y < image.height; ++y) {
                const bool written = y >= image.rowBegin() && y < image.rowEnd();
                if (written) std::copy_n(&image.z[size_t(y) * size_t(image.width) + size_t(x0)], x1 - x0, &row[size_t(x0)]);
                else std::fill(row.begin() + x0, row.begin() + x1, kInfinity);
                out.write(reinterpret_cast<const char*>(row.data()), std::streamsize(row.size() * sizeof(float)));
            }
        }
        if (validTexelTimes(image.texelTimes, image.timeTile)) {
            const int32_t tile = image.timeTile, side = int32_t(std::lround(std::sqrt(double(image.texelTimes.size()))));
            out.write(kTimesTag, sizeof kTimesTag);
            out.write(reinterpret_cast<const char*>(&tile), 4);
            out.write(reinterpret_cast<const char*>(&side), 4);
            out.write(reinterpret_cast<const char*>(image.texelTimes.data()),
                      std::streamsize(image.texelTimes.size() * sizeof(float)));
        }
        out.flush();
        if (!out) {
            out.close();
            std::remove(tmp.c_str());
            why = "write failed";
            return false;
        }
    }
    if (!moveIntoPlace(tmp, path)) {
        std::remove(tmp.c_str());
        why = "renaming the temporary file failed";
        return false;
    }
    return true;
}

}  // namespace

bool writeZFile(const std::string& path, const DepthImage& image) {
    std::string why;
    return writeZFileImpl(path, image, why);
}

bool writeZFile(const std::string& path, const DepthImage& image, Diagnostics& diag, const FileLoc& loc) {
    std::string why;
    if (writeZFileImpl(path, image, why)) return true;
    diag.error(loc, "cannot write zfile \"{}\": {}", path, why);
    return false;
}

bool readZFile(const std::string& path, DepthImage& out, Diagnostics& diag, const FileLoc& loc) {
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (!in) {
        diag.error(loc, "cannot open zfile \"{}\"", path);
        return false;
    }
    uint64_t size = uint64_t(in.tellg());
    int timeTile = 0;
    std::vector<float> texelTimes;
    in.seekg(0);
    unsigned char header[kZFileHeaderBytes];
    if (size < kZFileHeaderBytes || !in.read(reinterpret_cast<char*>(header), kZFileHeaderBytes)) {
        diag.error(loc, "cannot read zfile \"{}\": the file is shorter than the {}-byte header", path,
                   kZFileHeaderBytes);
        return false;
    }
    uint32_t magic;
    int16_t w, h;
    float np[16], nl[16];
    std::memcpy(&magic, header, 4);
    std::memcpy(&w, header + 4, 2);
    std::memcpy(&h, header + 6, 2);
    std::memcpy(np, header + 8, sizeof np);
    std::memcpy(nl, header + 8 + sizeof np, sizeof nl);
    bool swap = false;
    if (magic == byteSwap(kZFileMagic)) swap = true;
    else if (magic != kZFileMagic) {
        diag.error(loc, "cannot read zfile \"{}\": bad magic number {:#010x} (expected {:#010x})", path, magic,
                   kZFileMagic);
        return false;
    }
    if (swap) {
        w = byteSwap(w);
        h = byteSwap(h);
        for (float& v : np) v = byteSwap(v);
        for (float& v : nl) v = byteSwap(v);
    }
    if (w <= 0 || h <= 0) {
        diag.error(loc, "cannot read zfile \"{}\": bad resolution {}x{}", path, w, h);
        return false;
    }
    const uint64_t expected = kZFileHeaderBytes + uint64_t(w) * uint64_t(h) * 4;
    // umbra's record of the texels' times may follow the depths.
    if (size > expected + kTimesHeaderBytes) {
        in.seekg(std::streamoff(expected));
        char tag[sizeof kTimesTag];
        int32_t tile = 0, side = 0;
        in.read(tag, sizeof tag);
        in.read(reinterpret_cast<char*>(&tile), 4);
        in.read(reinterpret_cast<char*>(&side), 4);
        if (swap) tile = byteSwap(tile), side = byteSwap(side);
        const bool tagged = in && std::memcmp(tag, kTimesTag, sizeof tag) == 0;
        if (tagged && side > 0 && side <= 64 &&
            size == expected + kTimesHeaderBytes + uint64_t(side) * uint64_t(side) * 4) {
            std::vector<float> times(size_t(side) * size_t(side));
            in.read(reinterpret_cast<char*>(times.data()), std::streamsize(times.size() * sizeof(float)));
            if (swap)
                for (float& t : times) t = byteSwap(t);
            // A table that is not one (another writer's bytes) is dropped:
            // the depths are still a map, of unknown times.
            if (in && validTexelTimes(times, tile)) {
                timeTile = tile;
                texelTimes = std::move(times);
            }
            size = expected;
        }
        in.clear();
        in.seekg(std::streamoff(kZFileHeaderBytes));
    }
    if (size != expected) {
        diag.error(loc, "cannot read zfile \"{}\": {} bytes, expected {} for {}x{} depths{}", path, size, expected, w,
                   h, size < expected ? " (truncated)" : "");
        return false;
    }
    // The depths are read straight into an untouched plane (not one filled
    // with +infinity first: on these hosts a page's first write costs
    // 11-12 us, and a 2048^2 plane has 4,096 of them).
    DepthImage img;
    img.width = w;
    img.height = h;
    img.z = FloatPlane(size_t(w) * size_t(h));
    if (!in.read(reinterpret_cast<char*>(img.z.data()), std::streamsize(img.z.size() * sizeof(float)))) {
        diag.error(loc, "cannot read zfile \"{}\": read failed", path);
        return false;
    }
    if (swap)
        for (float& z : img.z) z = byteSwap(z);
    // No depth (past 1e30, infinite or not a number) is +infinity; written
    // as a select, which the compiler vectorises.
    for (float& z : img.z) z = (z < 1e30f && z > -kInfinity) ? z : kInfinity;
    img.lightFromWorld = Mat4::fromRib(nl);
    img.ndcFromWorld = ndcFromScreen(w, h) * Mat4::fromRib(np);
    const auto& n = img.ndcFromWorld.m;
    img.projection = (n[3][0] == 0 && n[3][1] == 0 && n[3][2] == 0) ? Projection::Orthographic
                                                                    : Projection::Perspective;
    img.timeTile = timeTile;
    img.texelTimes = std::move(texelTimes);
    out = std::move(img);
    return true;
}

Mat4 defaultNdcFromScreen(int w, int h) { return ndcFromScreen(w, h); }

// tiff_depth.cpp
bool readTiffDepth(const std::string& path, DepthImage& out, Diagnostics& diag, const FileLoc& loc,
                   const char* what);

namespace {

// readDepthFile, its messages starting with `what` ("MakeShadow: ").
bool readDepthFileAs(const char* what, const std::string& in, DepthImage& image, Diagnostics& diag,
                     const FileLoc& loc) {
    uint32_t magic = 0;
    {
        std::ifstream f(in, std::ios::binary);
        if (!f) {
            diag.error(loc, "{}cannot open \"{}\"", what, in);
            return false;
        }
        f.read(reinterpret_cast<char*>(&magic), 4);
        if (!f) {
            diag.error(loc, "{}\"{}\" is too short to be a zfile or an OpenEXR image", what, in);
            return false;
        }
    }
    if (magic == kZFileMagic || magic == byteSwap(kZFileMagic)) return readZFile(in, image, diag, loc);
    if (magic == kExrMagic) return readDepthImage(in, image, diag, loc);
    if (magic == 0x002A4949u || magic == 0x2A004D4Du) return readTiffDepth(in, image, diag, loc, what);  // II*. MM.*
    diag.error(loc, "{}\"{}\" is neither a zfile nor an OpenEXR or TIFF depth image (magic {:#010x})", what, in,
               magic);
    return false;
}

}  // namespace

bool readDepthFile(const std::string& path, DepthImage& out, Diagnostics& diag, const FileLoc& loc) {
    return readDepthFileAs("", path, out, diag, loc);
}

bool makeShadow(const std::string& in, const std::string& out, Diagnostics& diag, const FileLoc& loc) {
    DepthImage image;
    if (!readDepthFileAs("MakeShadow: ", in, image, diag, loc)) return false;
    return writeDepthMap(out, image, diag, loc);
}

}  // namespace umbra
