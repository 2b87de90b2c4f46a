#include "umbra/shadow/depth_image.h"
#include "umbra/util/exr_header.h"
#include "umbra/util/file.h"
#include "umbra/util/lanes.h"
#include "umbra/util/parallel.h"

#include "map_header.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <libdeflate.h>
#include <openexr.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <limits>
#include <map>
#include <stdexcept>

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
    // Reeves §3.3: only the bounding box of finite depths is stored. Most
    // rows of a sparse map are empty: each row is first checked for a
    // finite depth four at a time; a row with one is trimmed from both
    // ends and what is left scanned without branches (the map is built
    // while the frame waits for it).
    // Only the texels the pass wrote are read (DepthImage::writtenX0...).
    int x0 = w, y0 = h, x1 = -1, y1 = -1;
    int64_t finite = 0;
    float minZ = kInfinity, maxZ = -kInfinity;
    const int cx0 = image.columnBegin(), cx1 = image.columnEnd();
    for (int y = image.rowBegin(); y < image.rowEnd() && cx0 < cx1; ++y) {
        const float* row = image.z.data() + size_t(y) * size_t(w);
        I4 any{};
        int x = cx0;
        for (; x + 4 <= cx1; x += 4) any |= finite4(load4(row + x));
        bool hasDepth = (any[0] | any[1] | any[2] | any[3]) != 0;
        for (; x < cx1; ++x) hasDepth = hasDepth || isFiniteDepth(row[x]);
        if (!hasDepth) continue;
        int first = cx0, last = cx1 - 1;
        while (!isFiniteDepth(row[first])) ++first;
        while (!isFiniteDepth(row[last])) --last;
        x0 = std::min(x0, first);
        x1 = std::max(x1, last);
        y0 = std::min(y0, y);
        y1 = y;
        int rowFinite = 0;
        for (x = first; x <= last; ++x) {
            const float z = row[x];
            const bool f = isFiniteDepth(z);
            rowFinite += f;
            minZ = std::min(minZ, f ? z : kInfinity);
            maxZ = std::max(maxZ, f ? z : -kInfinity);
        }
        finite += rowFinite;
    }
    const bool none = finite == 0;
    if (none) x0 = y0 = x1 = y1 = 0;  // OpenEXR needs a non-empty data window (of +infinity)
    const int dw = x1 - x0 + 1, dh = y1 - y0 + 1;
    const int tilesX = (dw + kMapTileSize - 1) / kMapTileSize, tilesY = (dh + kMapTileSize - 1) / kMapTileSize;

    // The per-tile depth ranges: known before the file is opened, because
    // OpenEXR writes the header at open. Rows are taken a tile wide at a
    // time, the range kept in registers.
    out.image = &image;
    out.none = none;
    std::vector<float> tileMin(size_t(tilesX) * tilesY, kInfinity), tileMax(size_t(tilesX) * tilesY, -kInfinity);
    for (int y = 0; y < dh && !none; ++y) {
        const float* in = image.z.data() + size_t(y + y0) * size_t(w) + size_t(x0);
        float* rowMin = tileMin.data() + size_t(y / kMapTileSize) * size_t(tilesX);
        float* rowMax = tileMax.data() + size_t(y / kMapTileSize) * size_t(tilesX);
        for (int tx = 0; tx < tilesX; ++tx) {
            const int xa = tx * kMapTileSize, xb = std::min(dw, xa + kMapTileSize);
            float lo = rowMin[tx], hi = rowMax[tx];
            for (int x = xa; x < xb; ++x) {
                const float z = sanitize(in[x]);
                lo = std::min(lo, z);
                hi = std::max(hi, z);
            }
            rowMin[tx] = lo;
            rowMax[tx] = hi;
        }
    }

    Imath::Box2i display(Imath::V2i(0, 0), Imath::V2i(w - 1, h - 1));
    out.data = Imath::Box2i(Imath::V2i(x0, y0), Imath::V2i(x1, y1));
    Imf::Header header(display, out.data, 1.0f, Imath::V2f(0, 0), 1.0f, Imf::INCREASING_Y, Imf::ZIP_COMPRESSION);
    header.setTileDescription(Imf::TileDescription(kMapTileSize, kMapTileSize, Imf::ONE_LEVEL));
    header.channels().insert("Z", Imf::Channel(Imf::FLOAT));
    if (!image.z2.empty()) header.channels().insert("Z2", Imf::Channel(Imf::FLOAT));
    header.insert(kAttrWorldToCamera, Imf::M44fAttribute(toImath(image.lightFromWorld)));
    header.insert(kAttrWorldToNDC, Imf::M44fAttribute(toImath(image.ndcFromWorld)));
    header.insert(kAttrProjection, Imf::StringAttribute(projectionName(image.projection)));
    header.insert(kAttrDepthFilter, Imf::StringAttribute(depthFilterName(image.filter)));
    header.insert(kAttrDualOffset, Imf::FloatAttribute(image.dualOffset));
    if (image.timeTile > 0) header.insert(kAttrTimeTile, Imf::IntAttribute(image.timeTile));
    if (validTexelTimes(image.texelTimes, image.timeTile))
        header.insert(kAttrTexelTimes, Imf::FloatVectorAttribute(image.texelTimes));
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

/// OpenEXR's ZIP coding of one chunk (the OpenEXR file layout): the bytes
/// split into even and odd halves, each byte replaced by its difference from
/// the one before (+128), as a zlib stream; stored raw when that is no
/// smaller.
///
/// Maps are written through OpenEXR's core API with chunks coded here,
/// because deflating the tiles was most of a map's writing time: zlib, as
/// Imf::TiledOutputFile calls it, took 46-51 us per 4 KiB tile of depths
/// (and set up a new stream for each); libdeflate at level 1 takes 18-20
/// us, for files 0.5-1.5% larger. Empty tiles (all +infinity)
/// are coded once per size.
class ZipChunks {
public:
    ZipChunks() : m_compressor(libdeflate_alloc_compressor(1)) {
        if (!m_compressor) throw std::runtime_error("libdeflate could not start");
    }
    ~ZipChunks() { libdeflate_free_compressor(m_compressor); }
    ZipChunks(const ZipChunks&) = delete;
    ZipChunks& operator=(const ZipChunks&) = delete;

    /// The chunk for `n` bytes at `raw`; valid until the next call.
    std::pair<const void*, size_t> encode(const uint8_t* raw, size_t n, bool empty) {
        if (empty) {
            auto it = m_empty.find(n);
            if (it == m_empty.end()) {
                auto coded = code(raw, n);
                const uint8_t* b = static_cast<const uint8_t*>(coded.first);
                it = m_empty.emplace(n, std::vector<uint8_t>(b, b + coded.second)).first;
            }
            return {it->second.data(), it->second.size()};
        }
        return code(raw, n);
    }

private:
    std::pair<const void*, size_t> code(const uint8_t* raw, size_t n) {
        // Written as plain forward loops over separate buffers, which the
        // compiler vectorises (one loop in place, backwards, it did not).
        m_split.resize(n);
        m_tmp.resize(n);
        const size_t half = (n + 1) / 2;
        for (size_t j = 0; j < half; ++j) m_split[j] = raw[2 * j];
        for (size_t j = 0; half + j < n; ++j) m_split[half + j] = raw[2 * j + 1];
        if (n > 0) m_tmp[0] = m_split[0];
        for (size_t i = 1; i < n; ++i) m_tmp[i] = uint8_t(m_split[i] - m_split[i - 1] + 128);
        // Output must be smaller than the input to be worth storing.
        m_out.resize(n);
        const size_t coded = libdeflate_zlib_compress(m_compressor, m_tmp.data(), n, m_out.data(), n - 1);
        if (coded == 0) return {raw, n};
        return {m_out.data(), coded};
    }

    libdeflate_compressor* m_compressor;
    std::vector<uint8_t> m_split, m_tmp, m_out;  // bytes split into halves; their differences; the zlib stream
    std::map<size_t, std::vector<uint8_t>> m_empty;  // by size: edge tiles are smaller
};

void check(exr_result_t r, const char* what) {
    if (r != EXR_ERR_SUCCESS) throw std::runtime_error(fmt::format("{}: {}", what, exr_get_default_error_message(r)));
}

/// Declares the part in OpenEXR's core API from the map's Imf header.
void definePart(exr_context_t ctxt, const PreparedMap& m, const char* name) {
    int part = -1;
    check(exr_add_part(ctxt, name, EXR_STORAGE_TILED, &part), "adding a part");
    const Imf::Header& h = m.header;
    const Imath::Box2i& dw = h.dataWindow();
    const Imath::Box2i& dsp = h.displayWindow();
    exr_attr_box2i_t data = {{dw.min.x, dw.min.y}, {dw.max.x, dw.max.y}};
    exr_attr_box2i_t display = {{dsp.min.x, dsp.min.y}, {dsp.max.x, dsp.max.y}};
    exr_attr_v2f_t centre = {h.screenWindowCenter().x, h.screenWindowCenter().y};
    check(exr_initialize_required_attr(ctxt, part, &display, &data, h.pixelAspectRatio(), &centre,
                                       h.screenWindowWidth(), EXR_LINEORDER_INCREASING_Y, EXR_COMPRESSION_ZIP),
          "the required attributes");
    check(exr_set_tile_descriptor(ctxt, part, kMapTileSize, kMapTileSize, EXR_TILE_ONE_LEVEL, EXR_TILE_ROUND_DOWN),
          "the tile description");
    for (auto c = h.channels().begin(); c != h.channels().end(); ++c)
        if (exr_add_channel(ctxt, part, c.name(), EXR_PIXEL_FLOAT, EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1) != EXR_ERR_SUCCESS)
            throw std::runtime_error(fmt::format("adding channel {}", c.name()));
    // The map's own attributes, by type (those prepareMap writes).
    static const char* const kRequired[] = {"channels",   "compression",        "dataWindow",        "displayWindow",
                                            "lineOrder",  "pixelAspectRatio",   "screenWindowCenter", "screenWindowWidth",
                                            "tiles",      "name",               "type"};
    for (auto a = h.begin(); a != h.end(); ++a) {
        const std::string key = a.name();
        if (std::find(std::begin(kRequired), std::end(kRequired), key) != std::end(kRequired)) continue;
        const std::string type = a.attribute().typeName();
        if (type == "m44f") {
            const Imath::M44f& v = static_cast<const Imf::M44fAttribute&>(a.attribute()).value();
            exr_attr_m44f_t mat;
            for (int i = 0; i < 16; ++i) mat.m[i] = v[i / 4][i % 4];
            check(exr_attr_set_m44f(ctxt, part, key.c_str(), &mat), key.c_str());
        } else if (type == "string") {
            check(exr_attr_set_string(ctxt, part, key.c_str(),
                                      static_cast<const Imf::StringAttribute&>(a.attribute()).value().c_str()),
                  key.c_str());
        } else if (type == "float") {
            check(exr_attr_set_float(ctxt, part, key.c_str(), static_cast<const Imf::FloatAttribute&>(a.attribute()).value()),
                  key.c_str());
        } else if (type == "double") {
            check(exr_attr_set_double(ctxt, part, key.c_str(),
                                      static_cast<const Imf::DoubleAttribute&>(a.attribute()).value()),
                  key.c_str());
        } else if (type == "int") {
            check(exr_attr_set_int(ctxt, part, key.c_str(), static_cast<const Imf::IntAttribute&>(a.attribute()).value()),
                  key.c_str());
        } else if (type == "floatvector") {
            const auto& v = static_cast<const Imf::FloatVectorAttribute&>(a.attribute()).value();
            check(exr_attr_set_float_vector(ctxt, part, key.c_str(), int32_t(v.size()), v.data()), key.c_str());
        } else {
            throw std::runtime_error(fmt::format("attribute {} of type {} has no writer", key, type));
        }
    }
}

/// Writes every tile of the part's data window: rows of the tile, each
/// holding its channels one after another (Z, then Z2), little-endian.
/// Tiles are gathered and compressed in parallel, a batch at a time (a
/// MakeShadow has the machine to itself: one thread compressing three
/// 2048^2 maps was a third of their 0.5 s), and written in order, so the
/// file's bytes do not depend on the threads.
void writeTiles(exr_context_t ctxt, int part, const PreparedMap& m) {
    const int dw = m.data.max.x - m.data.min.x + 1, dh = m.data.max.y - m.data.min.y + 1;
    const DepthImage& image = *m.image;
    const FloatPlane* layers[2] = {&image.z, image.z2.empty() ? nullptr : &image.z2};
    const int count = m.tilesX * m.tilesY;
    // A batch's chunks, each at most a tile's raw bytes (ZipChunks stores a
    // tile raw when coding does not shrink it), in one block of a whole
    // batch even for fewer tiles: 512 tiles of one layer are a 2 MiB huge
    // page (allocateZeroed), where a vector a chunk took a fresh 4 KiB page
    // for each (a page fault of 11 us apiece on these hosts).
    constexpr int kBatch = 512;
    const size_t stride = size_t(kMapTileSize) * kMapTileSize * sizeof(float) * (layers[1] ? 2 : 1);
    std::vector<uint8_t, ZeroedAllocator<uint8_t>> coded(size_t(kBatch) * stride);
    std::vector<size_t> codedBytes(static_cast<size_t>(kBatch));
    for (int first = 0; first < count; first += kBatch) {
        const int last = std::min(count, first + kBatch);
        parallelFor(first, last, [&](int t) {
            thread_local ZipChunks zip;
            thread_local std::vector<float> tile;
            const int x0 = (t % m.tilesX) * kMapTileSize, y0 = (t / m.tilesX) * kMapTileSize;
            const int w = std::min(kMapTileSize, dw - x0), h = std::min(kMapTileSize, dh - y0);
            tile.clear();
            bool empty = true;
            for (int y = y0; y < y0 + h; ++y)
                for (const FloatPlane* layer : layers) {
                    if (!layer) continue;
                    // The data window's row, read in place and sanitised as
                    // the tile ranges were.
                    const float* row = layer->data() + size_t(m.data.min.y + y) * size_t(image.width) +
                                       size_t(m.data.min.x + x0);
                    for (int x = 0; x < w; ++x) {
                        const float z = m.none ? kInfinity : sanitize(row[x]);
                        empty = empty && z == kInfinity;
                        tile.push_back(z);
                    }
                }
            const auto chunk =
                zip.encode(reinterpret_cast<const uint8_t*>(tile.data()), tile.size() * sizeof(float), empty);
            const size_t k = size_t(t - first);
            std::memcpy(coded.data() + k * stride, chunk.first, chunk.second);
            codedBytes[k] = chunk.second;
        });
        for (int t = first; t < last; ++t) {
            const size_t k = size_t(t - first);
            check(exr_write_tile_chunk(ctxt, part, t % m.tilesX, t / m.tilesX, 0, 0, coded.data() + k * stride,
                                       codedBytes[k]),
                  "writing a tile");
        }
    }
}

/// Writes the maps as the parts of one tiled OpenEXR file (one part: a
/// single-part file), every tile of each data window present.
void writeMapFile(const std::string& path, const std::vector<const PreparedMap*>& maps,
                  const char* const* partNames) {
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    exr_context_t ctxt = nullptr;
    check(exr_start_write(&ctxt, path.c_str(), EXR_WRITE_FILE_DIRECTLY, &init), "opening the file");
    struct Finish {
        exr_context_t* c;
        ~Finish() {
            if (*c) exr_finish(c);
        }
    } finish{&ctxt};
    for (size_t p = 0; p < maps.size(); ++p) definePart(ctxt, *maps[p], partNames ? partNames[p] : nullptr);
    check(exr_write_header(ctxt), "writing the header");
    for (size_t p = 0; p < maps.size(); ++p) writeTiles(ctxt, int(p), *maps[p]);
    exr_context_t done = ctxt;
    ctxt = nullptr;
    check(exr_finish(&done), "finishing the file");
}

/// Runs `write` on `path + ".tmp"` and renames the result into place; no
/// partial file survives a failure.
template <typename Write>
bool writeAtomically(const std::string& named, const char* what, Diagnostics& diag, const FileLoc& loc, Write write) {
    std::string path, why;
    if (!resolveOutputPath(named, &path, &why)) {
        diag.error(loc, "cannot write {} \"{}\": {}", what, named, why);
        return false;
    }
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
    return writeAtomically(path, "depth map", diag, loc,
                           [&](const std::string& tmp) { writeMapFile(tmp, {&m}, nullptr); });
}

const char* const kCubeFaceNames[6] = {"+x", "-x", "+y", "-y", "+z", "-z"};

bool writeCubeDepthMap(const std::string& path, const std::array<DepthImage, 6>& faces, Diagnostics& diag,
                       const FileLoc& loc) {
    std::vector<PreparedMap> maps(6);
    for (int f = 0; f < 6; ++f) {
        std::string why;
        if (!prepareMap(faces[size_t(f)], maps[size_t(f)], why)) {
            diag.error(loc, "cannot write cube depth map \"{}\": face {}: {}", path, kCubeFaceNames[f], why);
            return false;
        }
    }
    std::vector<const PreparedMap*> parts;
    for (const PreparedMap& m : maps) parts.push_back(&m);
    return writeAtomically(path, "cube depth map", diag, loc,
                           [&](const std::string& tmp) { writeMapFile(tmp, parts, kCubeFaceNames); });
}

bool readDepthImage(const std::string& path, DepthImage& out, Diagnostics& diag, const FileLoc& loc) {
    if (std::string why; !exrHeadersFit(path, &why)) {
        diag.error(loc, "cannot read depth image \"{}\": {}", path, why);
        return false;
    }
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
        img.timeTile = m.timeTile;
        img.texelTimes = m.texelTimes;
        out = std::move(img);
        return true;
    } catch (const std::exception& e) {
        diag.error(loc, "cannot read depth image \"{}\": {}", path, e.what());
        return false;
    }
}

}  // namespace umbra
