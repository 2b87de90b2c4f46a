#include "umbra/shadow/shadow_map.h"

#include "umbra/util/exr_header.h"

#include "map_header.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfMultiPartInputFile.h>
#include <ImfStdIO.h>
#include <ImfThreading.h>
#include <ImfTiledInputPart.h>
#include <nlohmann/json.hpp>

#include <bit>
#include <cmath>
#include <exception>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <future>
#include <mutex>
#include <numeric>

namespace umbra {

ShadowStats& ShadowStats::operator+=(const ShadowStats& o) {
    points += o.points;
    outside += o.outside;
    culledLit += o.culledLit;
    culledShadowed += o.culledShadowed;
    texelRangeLit += o.texelRangeLit;
    texelRangeShadowed += o.texelRangeShadowed;
    filtered += o.filtered;
    samples += o.samples;
    tileFetches += o.tileFetches;
    secondLit += o.secondLit;
    secondShadowed += o.secondShadowed;
    virtualPoints += o.virtualPoints;
    storedPlaneLit += o.storedPlaneLit;
    storedPlaneGridPoints += o.storedPlaneGridPoints;
    return *this;
}

namespace {

bool isPowerOfTwo(int v) { return v > 0 && (v & (v - 1)) == 0; }

// The tiling a map must have. Checked before OpenEXR opens the part: it
// allocates a tile's buffers, and its table of tile offsets, from the
// header (a damaged tile size asked for 1.7 GB, found by fuzz_maps). The
// table alone takes 8 bytes a tile of the file, which bounds the count.
bool tiledLikeAMap(const Imf::Header& header, uint64_t fileBytes, std::string& why) {
    if (!header.hasTileDescription()) {
        why = "expected a tiled image (use MakeShadow to convert scanline images)";
        return false;
    }
    const Imf::TileDescription& td = header.tileDescription();
    if (td.mode != Imf::ONE_LEVEL) {
        why = "expected a single-level (ONE_LEVEL) tiled image";
        return false;
    }
    if (!isPowerOfTwo(int(td.xSize)) || !isPowerOfTwo(int(td.ySize)) || td.xSize < 4 || td.xSize > 1024 ||
        td.ySize < 4 || td.ySize > 1024) {
        why = fmt::format("unsupported tile size {}x{} (expected powers of two from 4 to 1024)", td.xSize, td.ySize);
        return false;
    }
    const Imath::Box2i data = header.dataWindow();
    const uint64_t tiles = (uint64_t(int64_t(data.max.x) - data.min.x + 1) / td.xSize + 1) *
                           (uint64_t(int64_t(data.max.y) - data.min.y + 1) / td.ySize + 1);
    if (data.max.x < data.min.x || data.max.y < data.min.y || tiles > fileBytes / 8) {
        why = fmt::format("the data window [{} {}] x [{} {}] needs more tiles than the file's {} bytes can hold",
                          data.min.x, data.max.x, data.min.y, data.max.y, fileBytes);
        return false;
    }
    return true;
}

int log2i(int v) {
    int s = 0;
    while ((1 << s) < v) ++s;
    return s;
}

// OpenEXR accepts a file whose tile offset table is intact but whose tile
// data was cut off, and only throws when such a tile is read. A map must be
// checked at open instead: every chunk the table names has to lie inside
// the file. Single-part tiled layout: magic, version, header, then one
// uint64 offset per tile, each pointing at {int32 dx, dy, lx, ly, size;
// size bytes}. Returns an empty string when the file is whole.
std::string checkTileChunks(const std::string& path, uint64_t fileBytes, size_t nTiles) {
    Imf::StdIFStream is(path.c_str());
    char magicVersion[8];
    is.read(magicVersion, 8);
    int version;
    std::memcpy(&version, magicVersion + 4, 4);
    if (version & 0x1000) return "";  // multi-part: OpenEXR validates its own chunk table
    Imf::Header header;
    header.readFrom(is, version);
    const uint64_t tableAt = is.tellg();
    if (tableAt + nTiles * 8 > fileBytes) return "the file is truncated (tile offset table cut off)";
    std::ifstream in(path, std::ios::binary);
    in.seekg(std::streamoff(tableAt));
    std::vector<uint64_t> offsets(nTiles);
    in.read(reinterpret_cast<char*>(offsets.data()), std::streamsize(nTiles * 8));
    if (!in) return "the file is truncated (tile offset table cut off)";
    // A cut file loses its last chunk first: every offset must point inside
    // the file, and the chunk at the largest offset must be whole.
    uint64_t last = 0;
    for (uint64_t at : offsets) {
        if (at < tableAt + nTiles * 8 || at + 20 > fileBytes) return "the file is truncated (tiles are missing)";
        last = std::max(last, at);
    }
    int32_t chunk[5];
    in.seekg(std::streamoff(last));
    in.read(reinterpret_cast<char*>(chunk), sizeof chunk);
    if (!in || chunk[4] < 0 || last + 20 + uint64_t(chunk[4]) > fileBytes)
        return "the file is truncated (tile data cut off)";
    return "";
}

}  // namespace

/// The file behind a map's tiles, shared by a cube map's faces.
struct ShadowMap::File {
    int parts = 1;  // 1, or a cube map's 6
    /// Maps built from memory: the writer's result, set when the file is
    /// complete (or failed); invalid when the file was there at the start.
    std::shared_future<bool> written;
    /// OpenEXR files are not safe for concurrent reads: one lock per file.
    std::mutex mutex;
    // Guarded by `mutex`:
    std::shared_ptr<Imf::MultiPartInputFile> input;  // null until a part is opened
    bool openFailed = false;                         // the file cannot be opened: no retries
    bool readFailed = false;                         // a failure was reported: later ones stay quiet

    /// True once the writer finished and succeeded (never waits).
    bool writtenNow() const {
        if (!written.valid() || written.wait_for(std::chrono::seconds(0)) != std::future_status::ready) return false;
        try {
            return written.get();
        } catch (const std::exception&) {
            return false;
        }
    }
};

std::shared_ptr<ShadowMap> ShadowMap::open(const std::string& path, Diagnostics& diag, const FileLoc& loc,
                                           std::shared_ptr<TileCache> cache) {
    auto fail = [&](const std::string& why) {
        diag.error(loc, "cannot open shadow map \"{}\": {}", path, why);
        return nullptr;
    };
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) return fail("no such file");
    const uint64_t fileBytes = std::filesystem::file_size(path, ec);
    if (std::string why; !exrHeadersFit(path, &why)) return fail(why);
    if (!cache) cache = TileCache::shared();
    std::shared_ptr<ShadowMap> map(new ShadowMap());
    try {
        auto file = std::make_shared<File>();
        // No chunk-table reconstruction: a damaged file must fail here, not
        // be half-repaired.
        file->input = std::make_shared<Imf::MultiPartInputFile>(path.c_str(), Imf::globalThreadCount(), false);
        const int parts = file->input->parts();
        if (parts != 1 && parts != 6)
            return fail(fmt::format("{} parts, expected 1 (a map) or 6 (a cube map's faces)", parts));
        file->parts = parts;
        std::vector<std::shared_ptr<ShadowMap>> faces;
        for (int p = 0; p < parts; ++p) {
            std::shared_ptr<ShadowMap> face = part(map, parts, p, path, diag, cache, file);
            face->m_fileBytes = fileBytes;
            if (std::string why; !tiledLikeAMap(file->input->header(p), fileBytes, why))
                return fail(parts == 1 ? why : fmt::format("face {}: {}", p, why));
            Imf::TiledInputPart input(*file->input, p);
            std::string why;
            if (!face->initHeader(input.header(), input.numXTiles(), input.numYTiles(), why) || !face->openPart(why))
                return fail(parts == 1 ? why : fmt::format("face {}: {}", p, why));
            face->setupVirtualSampling();
            face->m_mapId = TileCache::newMapId();
            faces.push_back(std::move(face));
        }
        if (parts == 6) map->setFaces(std::move(faces));
    } catch (const std::exception& e) {
        return fail(e.what());
    }
    return map;
}

std::shared_ptr<ShadowMap> ShadowMap::fromImage(const DepthImage& image, const std::string& path,
                                                std::shared_future<bool> written, Diagnostics& diag,
                                                const FileLoc& loc, std::shared_ptr<TileCache> cache,
                                                bool* everyTileCached) {
    return fromImages(&image, 1, path, std::move(written), diag, loc, std::move(cache), everyTileCached);
}

std::shared_ptr<ShadowMap> ShadowMap::fromCubeImages(const std::array<DepthImage, 6>& faces, const std::string& path,
                                                     std::shared_future<bool> written, Diagnostics& diag,
                                                     const FileLoc& loc, std::shared_ptr<TileCache> cache,
                                                     bool* everyTileCached) {
    return fromImages(faces.data(), 6, path, std::move(written), diag, loc, std::move(cache), everyTileCached);
}

std::shared_ptr<ShadowMap> ShadowMap::fromImages(const DepthImage* images, int count, const std::string& path,
                                                 std::shared_future<bool> written, Diagnostics& diag,
                                                 const FileLoc& loc, std::shared_ptr<TileCache> cache,
                                                 bool* everyTileCached) {
    auto fail = [&](const std::string& why) {
        diag.error(loc, "cannot make shadow map \"{}\": {}", path, why);
        return nullptr;
    };
    if (!cache) cache = TileCache::shared();
    auto file = std::make_shared<File>();
    file->parts = count;
    file->written = std::move(written);
    std::shared_ptr<ShadowMap> map(new ShadowMap());
    std::vector<std::shared_ptr<ShadowMap>> faces;
    bool allCached = true;
    try {
        for (int p = 0; p < count; ++p) {
            std::shared_ptr<ShadowMap> face = part(map, count, p, path, diag, cache, file);
            PreparedMap prepared;
            std::string why;
            if (!prepareMap(images[p], prepared, why) ||
                !face->initHeader(prepared.header, prepared.tilesX, prepared.tilesY, why))
                return fail(count == 1 ? why : fmt::format("face {}: {}", kCubeFaceNames[p], why));
            face->setupVirtualSampling();
            face->m_mapId = TileCache::newMapId();
            const int added = face->preload(images[p]);
            allCached = allCached && (face->empty() || added == face->m_tilesX * face->m_tilesY);
            faces.push_back(std::move(face));
        }
    } catch (const std::exception& e) {  // OpenEXR header attributes allocate
        return fail(e.what());
    }
    if (count == 6) map->setFaces(std::move(faces));
    if (everyTileCached) *everyTileCached = allCached;
    return map;
}

std::shared_ptr<ShadowMap> ShadowMap::part(const std::shared_ptr<ShadowMap>& whole, int parts, int p,
                                           const std::string& path, Diagnostics& diag,
                                           const std::shared_ptr<TileCache>& cache, const std::shared_ptr<File>& file) {
    std::shared_ptr<ShadowMap> face = parts == 1 ? whole : std::shared_ptr<ShadowMap>(new ShadowMap());
    face->m_path = path;
    face->m_diag = &diag;
    face->m_cache = cache;
    face->m_file = file;
    face->m_partNumber = p;
    return face;
}

void ShadowMap::setFaces(std::vector<std::shared_ptr<ShadowMap>> faces) {
    const ShadowMap& f0 = *faces[0];
    m_path = f0.m_path;
    m_diag = f0.m_diag;
    m_cache = f0.m_cache;
    m_file = f0.m_file;
    m_fileBytes = f0.m_fileBytes;
    m_width = f0.m_width;
    m_height = f0.m_height;
    m_lightFromWorld = f0.m_lightFromWorld;
    m_ndcFromWorld = f0.m_ndcFromWorld;
    m_projection = f0.m_projection;
    m_filter = f0.m_filter;
    m_dualOffset = f0.m_dualOffset;
    m_timeTile = f0.m_timeTile;
    m_timePeriod = f0.m_timePeriod;
    m_texelTimes = f0.m_texelTimes;
    m_slotTexel = f0.m_slotTexel;
    m_slotTime = f0.m_slotTime;
    m_texelSlot = f0.m_texelSlot;
    m_finiteCount = 0;
    for (const auto& f : faces) m_finiteCount += f->m_finiteCount;
    m_faces = std::move(faces);
}

bool ShadowMap::openPart(std::string& why) const {
    if (!m_file->input) {
        if (m_file->written.valid() && !m_file->written.get()) {
            why = "the file was not written";
            return false;
        }
        auto input = std::make_shared<Imf::MultiPartInputFile>(m_path.c_str(), Imf::globalThreadCount(), false);
        if (input->parts() != m_file->parts) {
            why = fmt::format("{} parts, expected {}", input->parts(), m_file->parts);
            return false;
        }
        m_file->input = std::move(input);
    }
    auto part = std::make_unique<Imf::TiledInputPart>(*m_file->input, m_partNumber);
    // Tiles are addressed by the layout initHeader() read: the file must
    // have it (it does unless it was replaced since).
    const Imath::Box2i data = part->header().dataWindow();
    const Imf::TileDescription& td = part->header().tileDescription();
    if (data.min.x != m_fileX0 || data.min.y != m_fileY0 || int(td.xSize) != m_tileW || int(td.ySize) != m_tileH ||
        part->numXTiles() != m_tilesX || part->numYTiles() != m_tilesY) {
        why = "the file's data window or tiles differ from the map's";
        return false;
    }
    if (!part->isComplete()) {
        why = "the file is truncated (tiles are missing)";
        return false;
    }
    if (m_file->parts == 1) {
        std::error_code ec;
        why = checkTileChunks(m_path, std::filesystem::file_size(m_path, ec),
                              size_t(m_tilesX) * size_t(m_tilesY));
        if (!why.empty()) return false;
    }
    m_part = std::move(part);
    return true;
}

void ShadowMap::setupTimeSlots(const std::vector<float>& texelTimes) {
    m_timePeriod = 0;
    m_texelTimes.clear(), m_slotTexel.clear(), m_slotTime.clear(), m_texelSlot.clear();
    // A time tile's texels must fit the slot index (uint8_t) and the
    // lookup's table of slots (256); its search takes powers of two.
    if (!validTexelTimes(texelTimes, m_timeTile) || m_timeTile > 16) return;
    const int n = int(std::lround(std::sqrt(double(texelTimes.size())))), T = m_timeTile, slots = T * T;
    if (!std::has_single_bit(unsigned(n)) || !std::has_single_bit(unsigned(T))) return;
    const int tilesPerSide = n / T;
    m_timePeriod = n;
    m_texelTimes = texelTimes;
    m_slotTexel.resize(size_t(tilesPerSide) * size_t(tilesPerSide) * size_t(slots));
    m_slotTime.assign(size_t(slots), 0.0f);
    m_texelSlot.resize(size_t(n) * size_t(n));
    std::vector<int> order(static_cast<size_t>(slots));
    for (int ty = 0; ty < tilesPerSide; ++ty)
        for (int tx = 0; tx < tilesPerSide; ++tx) {
            auto timeOf = [&](int k) { return texelTimes[size_t(ty * T + k / T) * size_t(n) + size_t(tx * T + k % T)]; };
            std::iota(order.begin(), order.end(), 0);
            std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return timeOf(a) < timeOf(b); });
            const size_t tile = size_t(ty * tilesPerSide + tx) * size_t(slots);
            for (int k = 0; k < slots; ++k) {
                m_slotTexel[tile + size_t(k)] = uint8_t(order[size_t(k)]);
                const int texel = order[size_t(k)];
                m_texelSlot[size_t(ty * T + texel / T) * size_t(n) + size_t(tx * T + texel % T)] = uint8_t(k);
                m_slotTime[size_t(k)] += timeOf(order[size_t(k)]) / float(tilesPerSide * tilesPerSide);
            }
        }
    // Umbra's maps time every tile's k-th texel alike: the slot's time is
    // then exactly its texels' (a mean of equal floats need not be).
    for (int k = 0; k < slots; ++k) {
        const int texel = m_slotTexel[size_t(k)];
        const float first = texelTimes[size_t(texel / T) * size_t(n) + size_t(texel % T)];
        bool shared = true;
        for (int tile = 0; tile < tilesPerSide * tilesPerSide && shared; ++tile) {
            const int tx = tile % tilesPerSide, ty = tile / tilesPerSide;
            const int t = m_slotTexel[size_t(tile) * size_t(slots) + size_t(k)];
            shared = texelTimes[size_t(ty * T + t / T) * size_t(n) + size_t(tx * T + t % T)] == first;
        }
        if (shared) m_slotTime[size_t(k)] = first;
    }
}

bool ShadowMap::initHeader(const Imf::Header& header, int tilesX, int tilesY, std::string& why) {
    const Imf::TileDescription& td = header.tileDescription();
    const Imf::Channel* z = header.channels().findChannel("Z");
    if (!z || z->type != Imf::FLOAT || z->xSampling != 1 || z->ySampling != 1) {
        why = "expected a full-resolution FLOAT channel \"Z\"";
        return false;
    }
    MapMatrices mm;
    if (!readMapMatrices(header, mm, why)) return false;
    m_lightFromWorld = mm.lightFromWorld;
    m_ndcFromWorld = mm.ndcFromWorld;
    m_projection = mm.projection;
    m_filter = mm.filter;
    m_dualOffset = mm.dualOffset;
    m_timeTile = mm.timeTile;
    setupTimeSlots(mm.texelTimes);

    const Imath::Box2i display = header.displayWindow(), data = header.dataWindow();
    if (display.min.x != 0 || display.min.y != 0) {
        why = "expected the display window to start at (0,0) (use MakeShadow to convert the image)";
        return false;
    }
    m_width = display.max.x + 1;
    m_height = display.max.y + 1;
    m_fileX0 = data.min.x;
    m_fileY0 = data.min.y;
    m_dx0 = std::max(data.min.x, 0);
    m_dy0 = std::max(data.min.y, 0);
    m_dx1 = std::min(data.max.x, display.max.x);
    m_dy1 = std::min(data.max.y, display.max.y);
    m_tileW = int(td.xSize);
    m_tileH = int(td.ySize);
    m_tileShiftX = log2i(m_tileW);
    m_tileShiftY = log2i(m_tileH);
    if (m_tileW >= ShadowTile::kBlocks && m_tileH >= ShadowTile::kBlocks) {
        m_blockShiftX = m_tileShiftX - log2i(ShadowTile::kBlocks);
        m_blockShiftY = m_tileShiftY - log2i(ShadowTile::kBlocks);
    }
    m_tilesX = tilesX;
    m_tilesY = tilesY;
    const size_t nTiles = size_t(m_tilesX) * size_t(m_tilesY);

    // Per-tile depth ranges; without them (a foreign map) nothing is culled:
    // [-inf, +inf] never passes either cull test.
    auto* tmin = header.findTypedAttribute<Imf::FloatVectorAttribute>(kAttrTileMinZ);
    auto* tmax = header.findTypedAttribute<Imf::FloatVectorAttribute>(kAttrTileMaxZ);
    if (tmin && tmax) {
        if (tmin->value().size() != nTiles || tmax->value().size() != nTiles) {
            why = fmt::format("umbra:tileMinZ/umbra:tileMaxZ hold {}/{} values, expected {} ({}x{} tiles)",
                              tmin->value().size(), tmax->value().size(), nTiles, m_tilesX, m_tilesY);
            return false;
        }
        m_tileMin = tmin->value();
        m_tileMax = tmax->value();
        for (size_t i = 0; i < nTiles; ++i)
            if (std::isnan(m_tileMin[i]) || std::isnan(m_tileMax[i])) {
                why = "umbra:tileMinZ/umbra:tileMaxZ contain NaN";
                return false;
            }
    } else {
        m_tileMin.assign(nTiles, -kInfinity);
        m_tileMax.assign(nTiles, kInfinity);
    }
    if (auto* a = header.findTypedAttribute<Imf::FloatAttribute>(kAttrMinZ)) m_minZ = a->value();
    if (auto* a = header.findTypedAttribute<Imf::FloatAttribute>(kAttrMaxZ)) m_maxZ = a->value();
    if (auto* a = header.findTypedAttribute<Imf::DoubleAttribute>(kAttrFiniteCount)) {
        const double texels = std::max(0.0, double(m_dx1 - m_dx0 + 1) * double(m_dy1 - m_dy0 + 1));
        if (!(a->value() >= 0 && a->value() <= texels)) {
            why = fmt::format("{} is {}, not a count of the data window's {} texels", kAttrFiniteCount, a->value(),
                              texels);
            return false;
        }
        m_finiteCount = int64_t(a->value());
    } else
        m_finiteCount = int64_t(m_dx1 - m_dx0 + 1) * (m_dy1 - m_dy0 + 1);
    if (m_dx1 < m_dx0 || m_dy1 < m_dy0) m_finiteCount = 0;
    return true;
}

void ShadowMap::setupVirtualSampling() {
    bool ok = false;
    const Mat4 lightToWorld = m_lightFromWorld.inverse(&ok);
    if (!ok) return;
    const Mat4 rasterFromLight =
        Mat4::scale(Vec3(float(m_width), float(m_height), 1.0f)) * m_ndcFromWorld * lightToWorld;
    const auto& r = rasterFromLight.m;
    // The homogeneous w row must be k*z (a pinhole light) or k (orthographic);
    // anything else has no simple depth coordinate.
    auto tiny = [&](float v, float k) { return std::abs(v) <= 1e-5f * std::abs(k); };
    Mat4 screen = rasterFromLight;
    if (r[3][2] != 0 && tiny(r[3][0], r[3][2]) && tiny(r[3][1], r[3][2]) && tiny(r[3][3], r[3][2])) {
        m_virtualMode = 1;
        m_wScale = r[3][2];
        screen.m[2][0] = screen.m[2][1] = screen.m[2][2] = 0;  // depth coordinate 1/w = 1/(k z)
        screen.m[2][3] = 1;
    } else if (r[3][3] != 0 && tiny(r[3][0], r[3][3]) && tiny(r[3][1], r[3][3]) && tiny(r[3][2], r[3][3])) {
        m_virtualMode = 2;
        m_wScale = r[3][3];
        screen.m[2][0] = screen.m[2][1] = screen.m[2][3] = 0;  // depth coordinate z (times 1/k after the divide)
        screen.m[2][2] = 1;
    } else {
        return;
    }
    const Mat4 lightFromScreen = screen.inverse(&ok);
    if (!ok) {
        m_virtualMode = 0;
        return;
    }
    m_planeFromLight = lightFromScreen.transposed();
}

ShadowMap::~ShadowMap() {
    if (m_cache && m_mapId) m_cache->erase(m_mapId);
}

ShadowTilePtr ShadowMap::readTile(int tx, int ty) const {
    auto tile = std::make_shared<ShadowTile>();
    tile->width = m_tileW;
    tile->height = m_tileH;
    tile->z.assign(size_t(m_tileW) * m_tileH, kInfinity);
    std::lock_guard<std::mutex> lock(m_file->mutex);
    std::string why;
    try {
        if (!m_part && !m_file->openFailed && !openPart(why)) m_file->openFailed = true;
        if (m_part) {
            Imath::Box2i box = m_part->dataWindowForTile(tx, ty);
            Imf::FrameBuffer fb;
            fb.insert("Z", Imf::Slice::Make(Imf::FLOAT, tile->z.data(), box.min, m_tileW, m_tileH, sizeof(float),
                                            sizeof(float) * size_t(m_tileW), 1, 1, double(kInfinity)));
            m_part->setFrameBuffer(fb);
            m_part->readTile(tx, ty);
            for (float& z : tile->z)
                if (std::isnan(z)) z = kInfinity;
        }
    } catch (const std::exception& e) {
        why = e.what();
        if (!m_part) m_file->openFailed = true;
        std::fill(tile->z.begin(), tile->z.end(), kInfinity);
    }
    if (!why.empty() && !m_file->readFailed) {
        m_file->readFailed = true;
        m_diag->error(FileLoc::inFile(m_path), "shadow map \"{}\": cannot read tile ({}, {}): {}; "
                                               "its texels are treated as empty",
                      m_path, tx, ty, why);
    }
    tile->computeBlocks(blockPlanes());
    return tile;
}

ShadowTilePtr ShadowMap::fetchTile(int tx, int ty) const {
    const uint32_t index = uint32_t(ty) * uint32_t(m_tilesX) + uint32_t(tx);
    if (ShadowTilePtr t = m_cache->find(m_mapId, index)) return t;
    return m_cache->insert(m_mapId, index, readTile(tx, ty));
}

int ShadowMap::preload(const DepthImage& image) const {
    if (isCube() || image.width != m_width || image.height != m_height || empty()) return 0;
    int added = 0;
    for (int ty = 0; ty < m_tilesY; ++ty)
        for (int tx = 0; tx < m_tilesX; ++tx) {
            auto tile = std::make_shared<ShadowTile>();
            tile->width = m_tileW;
            tile->height = m_tileH;
            tile->z.assign(size_t(m_tileW) * m_tileH, kInfinity);
            // What readTile() would give: the data window's texels, with the
            // non-finite depths writeDepthMap stores as +infinity.
            const int tileX0 = m_fileX0 + tx * m_tileW, tileY0 = m_fileY0 + ty * m_tileH;
            const int xa = std::max(tileX0, m_dx0), xb = std::min(tileX0 + m_tileW - 1, m_dx1);
            const int ya = std::max(tileY0, m_dy0), yb = std::min(tileY0 + m_tileH - 1, m_dy1);
            for (int y = ya; y <= yb; ++y) {
                const float* in = &image.z[size_t(y) * size_t(m_width)];
                float* out = tile->z.data() + size_t(y - tileY0) * size_t(m_tileW);
                for (int x = xa; x <= xb; ++x) out[x - tileX0] = std::isfinite(in[x]) ? in[x] : kInfinity;
            }
            tile->computeBlocks(blockPlanes());
            const uint32_t index = uint32_t(ty) * uint32_t(m_tilesX) + uint32_t(tx);
            if (!m_cache->preload(m_mapId, index, std::move(tile))) return added;
            ++added;
        }
    return added;
}

float ShadowMap::texel(int x, int y) const {
    if (isCube()) return m_faces[0]->texel(x, y);
    if (x < m_dx0 || x > m_dx1 || y < m_dy0 || y > m_dy1) return kInfinity;
    const int fx = x - m_fileX0, fy = y - m_fileY0;
    ShadowTilePtr t = fetchTile(fx >> m_tileShiftX, fy >> m_tileShiftY);
    return t->z[size_t(fy & (m_tileH - 1)) * m_tileW + size_t(fx & (m_tileW - 1))];
}

MapInfo ShadowMap::info() const {
    if (isCube()) {
        MapInfo in = m_faces[0]->info();
        in.faces = 6;
        for (size_t f = 1; f < 6; ++f) {
            MapInfo fi = m_faces[f]->info();
            in.empty = in.empty && fi.empty;
            in.tileCount += fi.tileCount;
            in.emptyTiles += fi.emptyTiles;
            in.minZ = std::min(in.minZ, fi.minZ);
            in.maxZ = std::max(in.maxZ, fi.maxZ);
            in.rawBytes += fi.rawBytes;
            in.bboxBytes += fi.bboxBytes;
            in.tileBytes += fi.tileBytes;
        }
        return in;
    }
    MapInfo in;
    in.path = m_path;
    in.width = m_width;
    in.height = m_height;
    in.empty = empty();
    if (!in.empty) {
        in.bboxMinX = m_dx0;
        in.bboxMinY = m_dy0;
        in.bboxMaxX = m_dx1;
        in.bboxMaxY = m_dy1;
    }
    in.tileWidth = m_tileW;
    in.tileHeight = m_tileH;
    in.tilesX = m_tilesX;
    in.tilesY = m_tilesY;
    int nonEmpty = 0;
    for (float z : m_tileMin)
        if (z != kInfinity) ++nonEmpty;
    in.tileCount = m_tilesX * m_tilesY;
    in.emptyTiles = in.tileCount - nonEmpty;
    in.minZ = m_minZ;
    in.maxZ = m_maxZ;
    in.projection = projectionName(m_projection);
    in.depthFilter = depthFilterName(m_filter);
    in.rawBytes = uint64_t(m_width) * uint64_t(m_height) * 4;
    in.bboxBytes = in.empty ? 0 : uint64_t(m_dx1 - m_dx0 + 1) * uint64_t(m_dy1 - m_dy0 + 1) * 4;
    in.tileBytes = uint64_t(nonEmpty) * uint64_t(m_tileW) * uint64_t(m_tileH) * 4;
    // A map built from memory has a size on disk once its file is written.
    in.fileBytes = m_fileBytes;
    if (m_file->writtenNow()) {
        std::error_code ec;
        in.fileBytes = std::filesystem::file_size(m_path, ec);
        if (ec) in.fileBytes = 0;
    }
    return in;
}

std::string mapInfoText(const MapInfo& in) {
    std::string s;
    s += fmt::format("{}\n", in.path);
    s += fmt::format("  resolution      {} x {}\n", in.width, in.height);
    s += fmt::format("  projection      {}\n", in.projection);
    s += fmt::format("  depth filter    {}\n", in.depthFilter);
    if (in.empty)
        s += "  bounding box    empty (no finite depth)\n";
    else
        s += fmt::format("  bounding box    [{}, {}] - [{}, {}]  ({} x {})\n", in.bboxMinX, in.bboxMinY, in.bboxMaxX,
                         in.bboxMaxY, in.bboxMaxX - in.bboxMinX + 1, in.bboxMaxY - in.bboxMinY + 1);
    if (in.faces > 1)
        s += fmt::format("  cube faces      {} (figures below sum over faces; bounding box of face 0)\n", in.faces);
    s += fmt::format("  tiles           {} of {}x{} texels, {} empty\n", in.tileCount, in.tileWidth, in.tileHeight,
                     in.emptyTiles);
    if (!in.empty) s += fmt::format("  depth range     {} .. {}\n", in.minZ, in.maxZ);
    auto mb = [](uint64_t b) { return double(b) / (1024.0 * 1024.0); };
    s += "  storage (Reeves 1987, Table 2)\n";
    s += fmt::format("    raw           {:>12} bytes  {:8.3f} MB\n", in.rawBytes, mb(in.rawBytes));
    s += fmt::format("    bounding box  {:>12} bytes  {:8.3f} MB\n", in.bboxBytes, mb(in.bboxBytes));
    s += fmt::format("    tiles         {:>12} bytes  {:8.3f} MB\n", in.tileBytes, mb(in.tileBytes));
    s += fmt::format("    on disk       {:>12} bytes  {:8.3f} MB\n", in.fileBytes, mb(in.fileBytes));
    return s;
}

nlohmann::json mapInfoJson(const MapInfo& in) {
    nlohmann::json j;
    j["path"] = in.path;
    j["width"] = in.width;
    j["height"] = in.height;
    j["projection"] = in.projection;
    j["depthFilter"] = in.depthFilter;
    j["empty"] = in.empty;
    if (in.empty)
        j["bbox"] = nullptr;
    else
        j["bbox"] = {in.bboxMinX, in.bboxMinY, in.bboxMaxX, in.bboxMaxY};
    j["tileSize"] = {in.tileWidth, in.tileHeight};
    j["tiles"] = in.tileCount;
    j["faces"] = in.faces;
    j["emptyTiles"] = in.emptyTiles;
    if (in.empty) {
        j["minZ"] = nullptr;
        j["maxZ"] = nullptr;
    } else {
        j["minZ"] = in.minZ;
        j["maxZ"] = in.maxZ;
    }
    j["storage"] = {{"rawBytes", in.rawBytes},
                    {"bboxBytes", in.bboxBytes},
                    {"tileBytes", in.tileBytes},
                    {"fileBytes", in.fileBytes}};
    return j;
}

}  // namespace umbra
