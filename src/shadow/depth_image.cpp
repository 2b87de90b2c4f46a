#include "umbra/shadow/depth_image.h"
#include "umbra/util/file.h"

#include "map_header.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfMultiPartOutputFile.h>
#include <ImfPartType.h>
#include <ImfTiledOutputFile.h>
#include <ImfTiledOutputPart.h>

#include <cmath>
#include <cstdio>
#include <exception>
#include <limits>

namespace umbra {

const char* projectionName(Projection p) { return p == Projection::Orthographic ? "orthographic" : "perspective"; }

const char* depthFilterName(DepthFilter f) {
    switch (f) {
    case DepthFilter::Min: return "min";
    case DepthFilter::Max: return "max";
    case DepthFilter::Average: return "average";
    case DepthFilter::Midpoint: return "midpoint";
    case DepthFilter::Second: return "second";
    case DepthFilter::Dual: return "dual";
    }
    return "min";
}

bool parseProjection(const std::string& s, Projection* out) {
    if (s == "perspective") *out = Projection::Perspective;
    else if (s == "orthographic") *out = Projection::Orthographic;
    else return false;
    return true;
}

bool parseDepthFilter(const std::string& s, DepthFilter* out) {
    static const DepthFilter kAll[] = {DepthFilter::Min,      DepthFilter::Max,    DepthFilter::Average,
                                       DepthFilter::Midpoint, DepthFilter::Second, DepthFilter::Dual};
    for (DepthFilter f : kAll)
        if (s == depthFilterName(f)) {
            *out = f;
            return true;
        }
    return false;
}

namespace {

Imath::M44f toImath(const Mat4& m) {
    float v[16];
    m.toRib(v);
    return Imath::M44f(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8], v[9], v[10], v[11], v[12], v[13],
                       v[14], v[15]);
}

// Depths that are not finite numbers (NaN from a degenerate projection, -inf)
// must not reach the map: they would poison min/max and comparisons. (The
// comparison is false for NaN, and vectorises where std::isfinite may not.)
inline bool isFiniteDepth(float z) { return std::abs(z) <= std::numeric_limits<float>::max(); }
inline float sanitize(float z) { return isFiniteDepth(z) ? z : kInfinity; }

}  // namespace

Mat4 fromImath(const Imath::M44f& m) {
    float v[16];
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) v[i * 4 + j] = m[i][j];
    return Mat4::fromRib(v);
}

bool prepareMap(const DepthImage& image, PreparedMap& out, std::string& why) {
    const int w = image.width, h = image.height;
    if (w <= 0 || h <= 0 || image.z.size() != size_t(w) * size_t(h) ||
        (!image.z2.empty() && image.z2.size() != image.z.size())) {
        why = fmt::format("expected a {}x{} image with {} depths", w, h,
                          size_t(std::max(w, 0)) * size_t(std::max(h, 0)));
        return false;
    }
    // Reeves §3.3: only the bounding box of finite depths is stored. Each
    // row is trimmed from both ends; what is left is scanned without
    // branches (the map is built while the frame waits for it).
    int x0 = w, y0 = h, x1 = -1, y1 = -1;
    int64_t finite = 0;
    float minZ = kInfinity, maxZ = -kInfinity;
    for (int y = 0; y < h; ++y) {
        const float* row = image.z.data() + size_t(y) * size_t(w);
        int first = 0, last = w - 1;
        while (first < w && !isFiniteDepth(row[first])) ++first;
        if (first == w) continue;
        while (!isFiniteDepth(row[last])) --last;
        x0 = std::min(x0, first);
        x1 = std::max(x1, last);
        y0 = std::min(y0, y);
        y1 = y;
        int rowFinite = 0;
        for (int x = first; x <= last; ++x) {
            const float z = row[x];
            const bool f = isFiniteDepth(z);
            rowFinite += f;
            minZ = std::min(minZ, f ? z : kInfinity);
            maxZ = std::max(maxZ, f ? z : -kInfinity);
        }
        finite += rowFinite;
    }
    if (finite == 0) x0 = y0 = x1 = y1 = 0;  // OpenEXR needs a non-empty data window
    const int dw = x1 - x0 + 1, dh = y1 - y0 + 1;
    const int tilesX = (dw + kMapTileSize - 1) / kMapTileSize, tilesY = (dh + kMapTileSize - 1) / kMapTileSize;

    // The cropped layers and the per-tile depth ranges: all known before the
    // file is opened, because OpenEXR writes the header at open. Rows are
    // taken a tile wide at a time, the range kept in registers.
    out.crop.resize(size_t(dw) * dh);
    out.crop2.clear();
    if (!image.z2.empty()) out.crop2.resize(out.crop.size());
    std::vector<float> tileMin(size_t(tilesX) * tilesY, kInfinity), tileMax(size_t(tilesX) * tilesY, -kInfinity);
    for (int y = 0; y < dh; ++y) {
        const size_t src = size_t(y + y0) * size_t(w) + size_t(x0), dst = size_t(y) * size_t(dw);
        const float* in = image.z.data() + src;
        float* crop = out.crop.data() + dst;
        float* rowMin = tileMin.data() + size_t(y / kMapTileSize) * size_t(tilesX);
        float* rowMax = tileMax.data() + size_t(y / kMapTileSize) * size_t(tilesX);
        for (int tx = 0; tx < tilesX; ++tx) {
            const int xa = tx * kMapTileSize, xb = std::min(dw, xa + kMapTileSize);
            float lo = rowMin[tx], hi = rowMax[tx];
            for (int x = xa; x < xb; ++x) {
                const float z = sanitize(in[x]);
                crop[x] = z;
                lo = std::min(lo, z);
                hi = std::max(hi, z);
            }
            rowMin[tx] = lo;
            rowMax[tx] = hi;
        }
        if (!out.crop2.empty())
            for (int x = 0; x < dw; ++x) out.crop2[dst + size_t(x)] = sanitize(image.z2[src + size_t(x)]);
    }

    Imath::Box2i display(Imath::V2i(0, 0), Imath::V2i(w - 1, h - 1));
    out.data = Imath::Box2i(Imath::V2i(x0, y0), Imath::V2i(x1, y1));
    Imf::Header header(display, out.data, 1.0f, Imath::V2f(0, 0), 1.0f, Imf::INCREASING_Y, Imf::ZIP_COMPRESSION);
    header.setTileDescription(Imf::TileDescription(kMapTileSize, kMapTileSize, Imf::ONE_LEVEL));
    // zlib level 4 instead of 6: a 1024^2 map writes about twice as fast
    // for a few per cent more bytes (maps are written every shadowed frame).
    header.zipCompressionLevel() = 4;
    header.channels().insert("Z", Imf::Channel(Imf::FLOAT));
    if (!out.crop2.empty()) header.channels().insert("Z2", Imf::Channel(Imf::FLOAT));
    header.insert(kAttrWorldToCamera, Imf::M44fAttribute(toImath(image.lightFromWorld)));
    header.insert(kAttrWorldToNDC, Imf::M44fAttribute(toImath(image.ndcFromWorld)));
    header.insert(kAttrProjection, Imf::StringAttribute(projectionName(image.projection)));
    header.insert(kAttrDepthFilter, Imf::StringAttribute(depthFilterName(image.filter)));
    header.insert(kAttrDualOffset, Imf::FloatAttribute(image.dualOffset));
    header.insert(kAttrTilesX, Imf::IntAttribute(tilesX));
    header.insert(kAttrTilesY, Imf::IntAttribute(tilesY));
    header.insert(kAttrTileMinZ, Imf::FloatVectorAttribute(tileMin));
    header.insert(kAttrTileMaxZ, Imf::FloatVectorAttribute(tileMax));
    header.insert(kAttrMinZ, Imf::FloatAttribute(minZ));
    header.insert(kAttrMaxZ, Imf::FloatAttribute(maxZ));
    // A double holds counts beyond 2^31 exactly (a 65536^2 map).
    header.insert(kAttrFiniteCount, Imf::DoubleAttribute(double(finite)));
    out.header = header;
    out.tilesX = tilesX;
    out.tilesY = tilesY;
    return true;
}

namespace {

Imf::FrameBuffer frameBufferFor(PreparedMap& m) {
    Imf::FrameBuffer fb;
    fb.insert("Z", Imf::Slice::Make(Imf::FLOAT, m.crop.data(), m.data));
    if (!m.crop2.empty()) fb.insert("Z2", Imf::Slice::Make(Imf::FLOAT, m.crop2.data(), m.data));
    return fb;
}

/// Runs `write` on `path + ".tmp"` and renames the result into place; no
/// partial file survives a failure.
template <typename Write>
bool writeAtomically(const std::string& path, const char* what, Diagnostics& diag, const FileLoc& loc, Write write) {
    const std::string tmp = path + ".tmp";
    try {
        write(tmp);
    } catch (const std::exception& e) {
        std::remove(tmp.c_str());
        diag.error(loc, "cannot write {} \"{}\": {}", what, path, e.what());
        return false;
    }
    if (!moveIntoPlace(tmp, path)) {
        std::remove(tmp.c_str());
        diag.error(loc, "cannot write {} \"{}\": renaming the temporary file failed", what, path);
        return false;
    }
    return true;
}

}  // namespace

bool writeDepthMap(const std::string& path, const DepthImage& image, Diagnostics& diag, const FileLoc& loc) {
    PreparedMap m;
    std::string why;
    if (!prepareMap(image, m, why)) {
        diag.error(loc, "cannot write depth map \"{}\": {}", path, why);
        return false;
    }
    return writeAtomically(path, "depth map", diag, loc, [&](const std::string& tmp) {
        Imf::TiledOutputFile out(tmp.c_str(), m.header);
        out.setFrameBuffer(frameBufferFor(m));
        // Every tile of the data window: OpenEXR silently drops a file's
        // unwritten tiles and readers then throw.
        out.writeTiles(0, out.numXTiles() - 1, 0, out.numYTiles() - 1);
    });
}

const char* const kCubeFaceNames[6] = {"+x", "-x", "+y", "-y", "+z", "-z"};

bool writeCubeDepthMap(const std::string& path, const std::array<DepthImage, 6>& faces, Diagnostics& diag,
                       const FileLoc& loc) {
    std::vector<PreparedMap> maps(6);
    std::vector<Imf::Header> headers;
    for (int f = 0; f < 6; ++f) {
        std::string why;
        if (!prepareMap(faces[size_t(f)], maps[size_t(f)], why)) {
            diag.error(loc, "cannot write cube depth map \"{}\": face {}: {}", path, kCubeFaceNames[f], why);
            return false;
        }
        maps[size_t(f)].header.setName(kCubeFaceNames[f]);
        maps[size_t(f)].header.setType(Imf::TILEDIMAGE);
        headers.push_back(maps[size_t(f)].header);
    }
    return writeAtomically(path, "cube depth map", diag, loc, [&](const std::string& tmp) {
        Imf::MultiPartOutputFile out(tmp.c_str(), headers.data(), 6);
        for (int f = 0; f < 6; ++f) {
            Imf::TiledOutputPart part(out, f);
            part.setFrameBuffer(frameBufferFor(maps[size_t(f)]));
            part.writeTiles(0, part.numXTiles() - 1, 0, part.numYTiles() - 1);
        }
    });
}

bool readDepthImage(const std::string& path, DepthImage& out, Diagnostics& diag, const FileLoc& loc) {
    try {
        Imf::InputFile in(path.c_str());
        const Imf::Header& header = in.header();
        if (!in.isComplete()) {
            diag.error(loc, "cannot read depth image \"{}\": the file is truncated (missing pixels)", path);
            return false;
        }
        const Imf::ChannelList& channels = header.channels();
        const char* name = nullptr;
        if (channels.findChannel("Z")) name = "Z";
        else if (channels.findChannel("R")) name = "R";
        else {
            int n = 0;
            for (auto it = channels.begin(); it != channels.end(); ++it) {
                ++n;
                name = it.name();
            }
            if (n != 1) name = nullptr;
        }
        if (!name) {
            diag.error(loc, "cannot read depth image \"{}\": expected a depth channel \"Z\" (or \"R\", or a single channel)",
                       path);
            return false;
        }
        const Imf::Channel* ch = channels.findChannel(name);
        if (ch->type == Imf::UINT || ch->xSampling != 1 || ch->ySampling != 1) {
            diag.error(loc, "cannot read depth image \"{}\": channel \"{}\" must be a full-resolution FLOAT or HALF channel",
                       path, name);
            return false;
        }
        MapMatrices m;
        std::string why;
        if (!readMapMatrices(header, m, why)) {
            diag.error(loc, "cannot read depth image \"{}\": {}", path, why);
            return false;
        }
        const Imath::Box2i display = header.displayWindow(), data = header.dataWindow();
        const int w = display.max.x - display.min.x + 1, h = display.max.y - display.min.y + 1;
        const int dw = data.max.x - data.min.x + 1, dh = data.max.y - data.min.y + 1;
        if (w <= 0 || h <= 0 || dw <= 0 || dh <= 0 || int64_t(w) * h > (int64_t(1) << 32) ||
            int64_t(dw) * dh > (int64_t(1) << 32)) {
            diag.error(loc, "cannot read depth image \"{}\": unusable display or data window", path);
            return false;
        }
        std::vector<float> buf(size_t(dw) * dh, kInfinity), buf2;
        Imf::FrameBuffer fb;
        fb.insert(name, Imf::Slice::Make(Imf::FLOAT, buf.data(), data, 0, 0, 1, 1, double(kInfinity)));
        const Imf::Channel* z2 = channels.findChannel("Z2");
        const bool hasZ2 = z2 && z2->type != Imf::UINT && z2->xSampling == 1 && z2->ySampling == 1;
        if (hasZ2) {
            buf2.assign(buf.size(), kInfinity);
            fb.insert("Z2", Imf::Slice::Make(Imf::FLOAT, buf2.data(), data, 0, 0, 1, 1, double(kInfinity)));
        }
        in.setFrameBuffer(fb);
        in.readPixels(data.min.y, data.max.y);

        DepthImage img(w, h);
        if (hasZ2) img.z2.assign(img.z.size(), kInfinity);
        auto clean = [](float z) { return std::isfinite(z) && z < 1e30f ? z : kInfinity; };
        for (int y = 0; y < dh; ++y)
            for (int x = 0; x < dw; ++x) {
                int X = x + data.min.x - display.min.x, Y = y + data.min.y - display.min.y;
                if (X < 0 || Y < 0 || X >= w || Y >= h) continue;
                img.at(X, Y) = clean(buf[size_t(y) * dw + x]);
                if (hasZ2) img.z2[size_t(Y) * w + size_t(X)] = clean(buf2[size_t(y) * dw + x]);
            }
        img.lightFromWorld = m.lightFromWorld;
        img.ndcFromWorld = m.ndcFromWorld;
        img.projection = m.projection;
        img.filter = m.filter;
        img.dualOffset = m.dualOffset;
        out = std::move(img);
        return true;
    } catch (const std::exception& e) {
        diag.error(loc, "cannot read depth image \"{}\": {}", path, e.what());
        return false;
    }
}

}  // namespace umbra
