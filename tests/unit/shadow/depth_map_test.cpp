// Map files: the tiled EXR writer, readers, zfiles, MakeShadow, MapInfo.

#include "shadow_test_util.h"

#include <ImfFloatVectorAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIntAttribute.h>
#include <ImfMatrixAttribute.h>
#include <ImfStringAttribute.h>
#include <ImfTiledInputFile.h>
#include <OpenImageIO/imageio.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <fstream>
#include <future>
#include <thread>

namespace umbra {
namespace {

using test::scratchFile;

// A 100x70 image whose finite depths fill [13, 81] x [7, 66]: a sloped
// surface with holes, so tiles differ in min, max and emptiness.
DepthImage sampleImage() {
    DepthImage img(100, 70);
    for (int y = 7; y <= 66; ++y)
        for (int x = 13; x <= 81; ++x)
            if ((x * 7 + y * 3) % 11 != 0) img.at(x, y) = 5.0f + 0.25f * float(x) + 0.125f * float(y);
    // A fully empty 32x32 tile region inside the box (tile (1,1) of the data
    // window is x 45..76, y 39..70).
    for (int y = 39; y <= 66; ++y)
        for (int x = 45; x <= 76; ++x) img.at(x, y) = kInfinity;
    img.lightFromWorld = Mat4::rotate(30, Vec3(1, 2, 3)) * Mat4::translate(Vec3(1, -2, 5));
    img.ndcFromWorld = Mat4::scale(Vec3(0.5f, -0.25f, 1)) * img.lightFromWorld;
    img.ndcFromWorld.m[3][2] = 1;  // a projective row, so it is "perspective"
    img.ndcFromWorld.m[3][3] = 0;
    img.filter = DepthFilter::Midpoint;
    img.dualOffset = 0.75f;
    return img;
}

Imath::M44f ribMatrix(const Mat4& m) {
    float v[16];
    m.toRib(v);
    return Imath::M44f(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8], v[9], v[10], v[11], v[12], v[13], v[14],
                       v[15]);
}

TEST(DepthMap, HeaderHoldsMatricesBoundingBoxAndTileRanges) {
    DepthImage img = sampleImage();
    Diagnostics diag;
    const std::string path = scratchFile("header.exr");
    ASSERT_TRUE(writeDepthMap(path, img, diag));
    EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));

    Imf::TiledInputFile in(path.c_str());
    const Imf::Header& h = in.header();
    EXPECT_EQ(h.displayWindow(), Imath::Box2i(Imath::V2i(0, 0), Imath::V2i(99, 69)));
    EXPECT_EQ(h.dataWindow(), Imath::Box2i(Imath::V2i(13, 7), Imath::V2i(81, 66)));
    EXPECT_EQ(h.tileDescription().xSize, 32u);
    EXPECT_EQ(h.tileDescription().ySize, 32u);
    EXPECT_EQ(h.compression(), Imf::ZIP_COMPRESSION);
    EXPECT_EQ(h.typedAttribute<Imf::M44fAttribute>("worldToCamera").value(), ribMatrix(img.lightFromWorld));
    EXPECT_EQ(h.typedAttribute<Imf::M44fAttribute>("worldToNDC").value(), ribMatrix(img.ndcFromWorld));
    EXPECT_EQ(h.typedAttribute<Imf::StringAttribute>("umbra:projection").value(), "perspective");
    EXPECT_EQ(h.typedAttribute<Imf::StringAttribute>("umbra:depthfilter").value(), "midpoint");
    EXPECT_EQ(h.typedAttribute<Imf::IntAttribute>("umbra:tilesX").value(), 3);  // 69 columns
    EXPECT_EQ(h.typedAttribute<Imf::IntAttribute>("umbra:tilesY").value(), 2);  // 60 rows
    EXPECT_EQ(in.numXTiles(), 3);
    EXPECT_EQ(in.numYTiles(), 2);

    // Independent per-tile ranges, tiles counted from the data window corner.
    const auto& tmin = h.typedAttribute<Imf::FloatVectorAttribute>("umbra:tileMinZ").value();
    const auto& tmax = h.typedAttribute<Imf::FloatVectorAttribute>("umbra:tileMaxZ").value();
    ASSERT_EQ(tmin.size(), 6u);
    ASSERT_EQ(tmax.size(), 6u);
    for (int ty = 0; ty < 2; ++ty)
        for (int tx = 0; tx < 3; ++tx) {
            float lo = kInfinity, hi = -kInfinity;
            for (int y = 7 + ty * 32; y < std::min(67, 7 + ty * 32 + 32); ++y)
                for (int x = 13 + tx * 32; x < std::min(82, 13 + tx * 32 + 32); ++x) {
                    lo = std::min(lo, img.at(x, y));
                    hi = std::max(hi, img.at(x, y));
                }
            EXPECT_EQ(tmin[ty * 3 + tx], lo) << tx << "," << ty;
            EXPECT_EQ(tmax[ty * 3 + tx], hi) << tx << "," << ty;
        }
    EXPECT_EQ(tmin[1 * 3 + 1], kInfinity);  // the emptied tile
}

TEST(DepthMap, EveryTileIsPresentAndRoundTripsThroughOpenEXR) {
    DepthImage img = sampleImage();
    Diagnostics diag;
    const std::string path = scratchFile("tiles.exr");
    ASSERT_TRUE(writeDepthMap(path, img, diag));
    Imf::TiledInputFile in(path.c_str());
    ASSERT_TRUE(in.isComplete());
    const Imath::Box2i dw = in.header().dataWindow();
    std::vector<float> buf(size_t(dw.max.x - dw.min.x + 1) * (dw.max.y - dw.min.y + 1), -1.0f);
    Imf::FrameBuffer fb;
    fb.insert("Z", Imf::Slice::Make(Imf::FLOAT, buf.data(), dw));
    in.setFrameBuffer(fb);
    in.readTiles(0, in.numXTiles() - 1, 0, in.numYTiles() - 1);  // throws on a missing tile
    const int w = dw.max.x - dw.min.x + 1;
    for (int y = dw.min.y; y <= dw.max.y; ++y)
        for (int x = dw.min.x; x <= dw.max.x; ++x)
            ASSERT_EQ(buf[size_t(y - dw.min.y) * w + (x - dw.min.x)], img.at(x, y)) << x << "," << y;
}

TEST(DepthMap, OpenImageIOReadsTheMap) {
    DepthImage img = sampleImage();
    Diagnostics diag;
    const std::string path = scratchFile("oiio.exr");
    ASSERT_TRUE(writeDepthMap(path, img, diag));
    auto in = OIIO::ImageInput::open(path);
    ASSERT_TRUE(in) << OIIO::geterror();
    const OIIO::ImageSpec& spec = in->spec();
    EXPECT_EQ(spec.full_width, 100);
    EXPECT_EQ(spec.full_height, 70);
    EXPECT_EQ(spec.x, 13);
    EXPECT_EQ(spec.y, 7);
    EXPECT_EQ(spec.tile_width, 32);
    EXPECT_EQ(spec.nchannels, 1);
    EXPECT_EQ(spec.channelnames[0], "Z");
    std::vector<float> buf(size_t(spec.width) * spec.height);
    ASSERT_TRUE(in->read_image(0, 0, 0, 1, OIIO::TypeDesc::FLOAT, buf.data())) << in->geterror();
    for (int y = 0; y < spec.height; ++y)
        for (int x = 0; x < spec.width; ++x)
            ASSERT_EQ(buf[size_t(y) * spec.width + x], img.at(x + 13, y + 7));
    const OIIO::ParamValue* m = spec.find_attribute("worldtocamera");
    ASSERT_TRUE(m);
    float v[16];
    img.lightFromWorld.toRib(v);
    const float* got = static_cast<const float*>(m->data());
    for (int i = 0; i < 16; ++i) EXPECT_EQ(got[i], v[i]);
}

TEST(DepthMap, ReadDepthImageRoundTripsEverything) {
    DepthImage img = sampleImage();
    img.z2 = img.z;
    for (float& z : img.z2) z += 1;
    Diagnostics diag;
    const std::string path = scratchFile("roundtrip.exr");
    ASSERT_TRUE(writeDepthMap(path, img, diag));
    DepthImage back;
    ASSERT_TRUE(readDepthImage(path, back, diag));
    EXPECT_EQ(back.width, 100);
    EXPECT_EQ(back.height, 70);
    EXPECT_EQ(back.z, img.z);
    EXPECT_EQ(back.z2, img.z2);
    EXPECT_TRUE(back.lightFromWorld == img.lightFromWorld);
    EXPECT_TRUE(back.ndcFromWorld == img.ndcFromWorld);
    EXPECT_EQ(back.projection, Projection::Perspective);
    EXPECT_EQ(back.filter, DepthFilter::Midpoint);
    EXPECT_EQ(back.dualOffset, 0.75f);
    EXPECT_EQ(diag.errorCount(), 0);
}

TEST(DepthMap, ShadowMapReadsTexelsAndInfo) {
    DepthImage img = sampleImage();
    auto map = test::writeAndOpen(img, "open.exr");
    ASSERT_TRUE(map);
    EXPECT_EQ(map->width(), 100);
    EXPECT_EQ(map->height(), 70);
    EXPECT_TRUE(map->lightFromWorld() == img.lightFromWorld);
    EXPECT_EQ(map->depthFilter(), DepthFilter::Midpoint);
    for (int y = 0; y < 70; ++y)
        for (int x = 0; x < 100; ++x) ASSERT_EQ(map->texel(x, y), img.at(x, y)) << x << "," << y;

    MapInfo info = map->info();
    float lo = kInfinity, hi = -kInfinity;
    for (float z : img.z)
        if (z != kInfinity) lo = std::min(lo, z), hi = std::max(hi, z);
    EXPECT_FALSE(info.empty);
    EXPECT_EQ(info.bboxMinX, 13);
    EXPECT_EQ(info.bboxMaxY, 66);
    EXPECT_EQ(info.tilesX * info.tilesY, 6);
    EXPECT_EQ(info.tileCount, 6);
    EXPECT_EQ(info.emptyTiles, 1);
    EXPECT_EQ(info.minZ, lo);
    EXPECT_EQ(info.maxZ, hi);
    EXPECT_EQ(info.rawBytes, 100u * 70u * 4u);
    EXPECT_EQ(info.bboxBytes, 69u * 60u * 4u);
    EXPECT_EQ(info.tileBytes, 5u * 4096u);
    EXPECT_EQ(info.fileBytes, std::filesystem::file_size(map->path()));
    nlohmann::json j = mapInfoJson(info);
    EXPECT_EQ(j["storage"]["tileBytes"].get<uint64_t>(), 5u * 4096u);
    EXPECT_EQ(j["bbox"], nlohmann::json({13, 7, 81, 66}));
    EXPECT_EQ(j["depthFilter"], "midpoint");
    std::string text = mapInfoText(info);
    EXPECT_NE(text.find("resolution      100 x 70"), std::string::npos) << text;
    EXPECT_NE(text.find("bounding box    [13, 7] - [81, 66]  (69 x 60)"), std::string::npos) << text;
}

TEST(DepthMap, PreloadedTilesEqualTheFileAndNeedNoReads) {
    DepthImage img = sampleImage();
    img.at(20, 20) = std::nanf("");  // stored as +infinity, in memory as on disk
    auto cache = std::make_shared<TileCache>();
    auto map = test::writeAndOpen(img, "preload.exr", cache);
    ASSERT_TRUE(map);
    EXPECT_EQ(map->preload(img), 6);  // 3 x 2 tiles cover the data window
    EXPECT_EQ(cache->stats().preloaded, 6u);
    auto fromFile = test::writeAndOpen(img, "preload-ref.exr", std::make_shared<TileCache>());
    for (int y = 0; y < 70; ++y)
        for (int x = 0; x < 100; ++x) ASSERT_EQ(map->texel(x, y), fromFile->texel(x, y)) << x << "," << y;
    EXPECT_EQ(map->texel(20, 20), kInfinity);
    EXPECT_EQ(cache->stats().tilesRead, 0u);
    EXPECT_EQ(cache->stats().evictions, 0u);

    // A cache with room for no tile takes none (never evicts for a preload);
    // lookups then read the file. An image of another size is refused.
    auto tiny = std::make_shared<TileCache>(1024);
    auto map2 = test::writeAndOpen(img, "preload-tiny.exr", tiny);
    EXPECT_EQ(map2->preload(img), 0);
    EXPECT_EQ(map2->texel(30, 30), img.at(30, 30));
    EXPECT_EQ(tiny->stats().tilesRead, 1u);
    EXPECT_EQ(map->preload(DepthImage(50, 70)), 0);
}

// Points over the whole raster of a sampleImage() map whose raster is world
// x, y and whose depth is world z (setRasterIsWorld): a little nearer and
// farther than the stored surface, so lookups are lit, shadowed and mixed.
struct SamplePoints {
    std::vector<Vec3> P, du, dv;
    SamplePoints() {
        const float offsets[] = {-1.0f, -0.05f, 0.05f, 1.0f};
        int k = 0;
        for (float y = 0.25f; y < 70; y += 1.5f)
            for (float x = 0.4f; x < 100; x += 1.25f, ++k) {
                P.push_back(Vec3(x, y, 5.0f + 0.25f * x + 0.125f * y + offsets[k % 4]));
                du.push_back(Vec3(1.3f, 0, 0));
                dv.push_back(Vec3(0, 0.9f, 0));
            }
    }
};

TEST(MapFromMemory, EqualsTheMapWrittenAndOpened) {
    DepthImage img = sampleImage();
    test::setRasterIsWorld(img);
    img.at(20, 20) = std::nanf("");
    Diagnostics diag;
    const std::string path = scratchFile("memory.exr");
    ASSERT_TRUE(writeDepthMap(path, img, diag));
    std::promise<bool> written;
    written.set_value(true);
    auto cache = std::make_shared<TileCache>();
    bool everyTileCached = false;
    auto memory = ShadowMap::fromImage(img, path, written.get_future().share(), diag, {}, cache, &everyTileCached);
    ASSERT_TRUE(memory);
    EXPECT_TRUE(everyTileCached);
    EXPECT_EQ(cache->stats().preloaded, 6u);  // the 3 x 2 tiles of the data window
    auto file = ShadowMap::open(path, diag, {}, std::make_shared<TileCache>());
    ASSERT_TRUE(file);
    test::expectSameMap(*memory, *file);
    test::expectSameInfo(memory->info(), file->info());
    EXPECT_EQ(memory->texel(20, 20), kInfinity);
    const SamplePoints pts;
    for (float bias : {0.0f, 0.3f}) {
        ShadowParams params;
        params.bias = bias;
        test::Lookups a = test::lookUp(*memory, pts.P, pts.du, pts.dv, params);
        test::Lookups b = test::lookUp(*file, pts.P, pts.du, pts.dv, params);
        test::expectSameLookups(a, b);
        EXPECT_GT(a.stats.filtered, 100u);
        EXPECT_GT(std::count(a.filtered.begin(), a.filtered.end(), 0.0f), 100);
        EXPECT_GT(std::count(a.filtered.begin(), a.filtered.end(), 1.0f), 100);
    }
    // Every texel came from memory.
    EXPECT_EQ(cache->stats().tilesRead, 0u);
    EXPECT_EQ(diag.errorCount(), 0);

    // An empty image: a valid empty map, no tile to cache.
    DepthImage none(40, 30);
    test::setRasterIsWorld(none);
    everyTileCached = false;
    auto empty = ShadowMap::fromImage(none, scratchFile("none.exr"), {}, diag, {}, cache, &everyTileCached);
    ASSERT_TRUE(empty);
    EXPECT_TRUE(everyTileCached);
    EXPECT_TRUE(empty->empty());
    EXPECT_EQ(empty->info().tileCount, 1);
}

TEST(MapFromMemory, ReadsWaitForTheFileWhenTheCacheIsTooSmall) {
    DepthImage img = sampleImage();
    test::setRasterIsWorld(img);
    Diagnostics diag;
    const std::string path = scratchFile("memory-late.exr");
    std::promise<bool> written;
    auto tiny = std::make_shared<TileCache>(1024);  // room for no tile
    bool everyTileCached = true;
    auto memory = ShadowMap::fromImage(img, path, written.get_future().share(), diag, {}, tiny, &everyTileCached);
    ASSERT_TRUE(memory);
    EXPECT_FALSE(everyTileCached);
    EXPECT_FALSE(std::filesystem::exists(path));
    // The file appears a little later, written on another thread as a frame
    // does; the lookups wait for it.
    std::thread writer([&] {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        written.set_value(writeDepthMap(path, img, diag));
    });
    const SamplePoints pts;
    ShadowParams params;
    params.bias = 0.3f;
    test::Lookups a = test::lookUp(*memory, pts.P, pts.du, pts.dv, params);
    writer.join();
    auto file = ShadowMap::open(path, diag, {}, std::make_shared<TileCache>());
    ASSERT_TRUE(file);
    test::expectSameLookups(a, test::lookUp(*file, pts.P, pts.du, pts.dv, params));
    test::expectSameMap(*memory, *file);
    test::expectSameInfo(memory->info(), file->info());
    EXPECT_GT(tiny->stats().tilesRead, 0u);
    EXPECT_EQ(tiny->stats().preloaded, 0u);
    EXPECT_EQ(diag.errorCount(), 0);
}

TEST(MapFromMemory, AFailedWriteLeavesUncachedTilesEmptyWithOneError) {
    DepthImage img = sampleImage();
    test::setRasterIsWorld(img);
    const std::string path = scratchFile("never-written.exr");
    std::promise<bool> written;
    written.set_value(false);
    const std::shared_future<bool> failed = written.get_future().share();
    Diagnostics diag;
    diag.setRecord(true);
    diag.setPolicy(Diagnostics::Policy::Ignore);

    // Tiles in the cache do not need the file.
    auto cached = ShadowMap::fromImage(img, path, failed, diag, {}, std::make_shared<TileCache>());
    ASSERT_TRUE(cached);
    for (int y = 0; y < 70; ++y)
        for (int x = 0; x < 100; ++x) ASSERT_EQ(cached->texel(x, y), img.at(x, y)) << x << "," << y;
    EXPECT_EQ(diag.errorCount(), 0);

    auto uncached = ShadowMap::fromImage(img, path, failed, diag, {}, std::make_shared<TileCache>(1024));
    ASSERT_TRUE(uncached);
    for (int y = 0; y < 70; ++y)
        for (int x = 0; x < 100; ++x) ASSERT_EQ(uncached->texel(x, y), kInfinity) << x << "," << y;
    const SamplePoints pts;
    test::Lookups lit = test::lookUp(*uncached, pts.P, pts.du, pts.dv, ShadowParams{});
    for (float v : lit.filtered) ASSERT_EQ(v, 0.0f);
    for (float v : lit.point) ASSERT_EQ(v, 0.0f);
    auto rec = diag.recorded();
    ASSERT_EQ(rec.size(), 1u);
    EXPECT_EQ(rec[0].loc.str(), path);
    EXPECT_EQ(rec[0].message, "shadow map \"" + path +
                                  "\": cannot read tile (0, 0): the file was not written; its texels are treated "
                                  "as empty");
}

TEST(DepthMap, EmptyImageGivesAValidEmptyMap) {
    DepthImage img(64, 48);
    test::setRasterIsWorld(img);
    auto map = test::writeAndOpen(img, "empty.exr");
    ASSERT_TRUE(map);
    EXPECT_TRUE(map->empty());
    MapInfo info = map->info();
    EXPECT_TRUE(info.empty);
    EXPECT_EQ(info.bboxBytes, 0u);
    EXPECT_EQ(info.tileBytes, 0u);
    EXPECT_EQ(info.emptyTiles, 1);
    EXPECT_EQ(map->texel(0, 0), kInfinity);
    // Everything is lit, whatever the depth.
    Vec3 P[2] = {Vec3(10, 10, 1e6f), Vec3(0.5f, 0.5f, 3)};
    ShadowBatch b;
    b.count = 2;
    b.P = P;
    float out[2] = {-1, -1};
    ShadowStats st;
    map->lookup(b, ShadowParams{}, out, st);
    EXPECT_EQ(out[0], 0.0f);
    EXPECT_EQ(out[1], 0.0f);
    auto in = OIIO::ImageInput::open(map->path());
    EXPECT_TRUE(in) << OIIO::geterror();
}

TEST(DepthMap, NonFiniteDepthsAreStoredAsInfinity) {
    DepthImage img(8, 8);
    test::setRasterIsWorld(img);
    img.at(2, 3) = 4;
    img.at(3, 3) = std::nanf("");
    img.at(4, 3) = -kInfinity;
    auto map = test::writeAndOpen(img, "nan.exr");
    ASSERT_TRUE(map);
    EXPECT_EQ(map->texel(2, 3), 4.0f);
    EXPECT_EQ(map->texel(3, 3), kInfinity);
    EXPECT_EQ(map->texel(4, 3), kInfinity);
    EXPECT_EQ(map->dataMinX(), 2);
    EXPECT_EQ(map->dataMaxX(), 2);
}

void writeBytes(const std::string& path, const std::string& bytes) {
    std::ofstream(path, std::ios::binary) << bytes;
}
std::string readBytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

TEST(DepthMap, TruncatedOrCorruptMapsGiveACleanError) {
    DepthImage img = sampleImage();
    Diagnostics ok;
    const std::string good = scratchFile("good.exr");
    ASSERT_TRUE(writeDepthMap(good, img, ok));
    const std::string bytes = readBytes(good);

    struct Case {
        std::string name, content;
    };
    std::vector<Case> cases = {
        {"zero.exr", ""},
        {"garbage.exr", std::string(300, 'x')},
        {"header_only.exr", bytes.substr(0, 200)},
        {"half.exr", bytes.substr(0, bytes.size() / 2)},
        {"last_byte.exr", bytes.substr(0, bytes.size() - 1)},
    };
    for (const Case& c : cases) {
        const std::string path = scratchFile(c.name);
        writeBytes(path, c.content);
        Diagnostics diag;
        diag.setRecord(true);
        diag.setPolicy(Diagnostics::Policy::Ignore);
        auto map = ShadowMap::open(path, diag, FileLoc::inFile("scene.rib", 12, 3));
        if (c.name == "last_byte.exr" && map) {
            // OpenEXR may accept a file missing only part of its last tile;
            // reading that tile must then fail cleanly: lit, one error.
            Vec3 P(80.5f, 65.5f, 0);
            ShadowBatch b;
            b.count = 1;
            b.P = &P;
            float out = -1;
            ShadowStats st;
            (void)map->texel(81, 66);
            map->lookupPoint(b, ShadowParams{}, &out, st);
            EXPECT_GE(out, 0.0f);
            continue;
        }
        EXPECT_FALSE(map) << c.name;
        auto rec = diag.recorded();
        ASSERT_EQ(rec.size(), 1u) << c.name;
        EXPECT_EQ(rec[0].loc.str(), "scene.rib:12:3");
        EXPECT_EQ(rec[0].message.rfind("cannot open shadow map \"" + path + "\": ", 0), 0u) << rec[0].message;
    }
    Diagnostics diag;
    diag.setRecord(true);
    diag.setPolicy(Diagnostics::Policy::Ignore);
    EXPECT_FALSE(ShadowMap::open(scratchFile("missing.exr"), diag));
    EXPECT_EQ(diag.recorded().at(0).message,
              "cannot open shadow map \"" + scratchFile("missing.exr") + "\": no such file");
}

TEST(DepthMap, AnAttributeClaimingMoreThanTheFileIsRejectedBeforeOpenEXRAllocatesIt) {
    DepthImage img = sampleImage();
    Diagnostics ok;
    const std::string good = scratchFile("claims.exr");
    ASSERT_TRUE(writeDepthMap(good, img, ok));
    std::string bytes = readBytes(good);
    // The first attribute: its name and type after the 8-byte magic and
    // version, then its size (little-endian), here 2^31 - 1.
    const size_t name = 8, type = bytes.find('\0', name) + 1, size = bytes.find('\0', type) + 1;
    bytes.replace(size, 4, std::string("\xff\xff\xff\x7f", 4));
    const std::string bad = scratchFile("claims_too_much.exr");
    writeBytes(bad, bytes);
    Diagnostics diag;
    diag.setRecord(true);
    diag.setPolicy(Diagnostics::Policy::Ignore);
    EXPECT_FALSE(ShadowMap::open(bad, diag));
    const std::string attribute = bytes.substr(name, type - name - 1);
    ASSERT_EQ(diag.recorded().size(), 1u);
    EXPECT_EQ(diag.recorded()[0].message,
              "cannot open shadow map \"" + bad + "\": damaged OpenEXR header (attribute \"" + attribute +
                  "\" claims 2147483647 bytes, the file has " + std::to_string(bytes.size() - size - 4) +
                  " after it)");
    DepthImage read;
    EXPECT_FALSE(readDepthImage(bad, read, diag));
    EXPECT_TRUE(ShadowMap::open(good, ok));
}

TEST(DepthMap, HugeTilesAreRejectedBeforeOpenEXRAllocatesThem) {
    // Tiles of 65536^2 pixels: OpenEXR would allocate a 16 GB buffer.
    DepthImage img = sampleImage();
    Diagnostics ok;
    const std::string good = scratchFile("tiles.exr");
    ASSERT_TRUE(writeDepthMap(good, img, ok));
    std::string bytes = readBytes(good);
    const std::string attribute = std::string("tiles") + '\0' + "tiledesc" + '\0';
    const size_t at = bytes.find(attribute);
    ASSERT_NE(at, std::string::npos);
    bytes.replace(at + attribute.size() + 4, 8, std::string("\0\0\1\0\0\0\1\0", 8));
    const std::string bad = scratchFile("tiles_too_large.exr");
    writeBytes(bad, bytes);
    Diagnostics diag;
    diag.setRecord(true);
    diag.setPolicy(Diagnostics::Policy::Ignore);
    EXPECT_FALSE(ShadowMap::open(bad, diag));
    ASSERT_EQ(diag.recorded().size(), 1u);
    EXPECT_EQ(diag.recorded()[0].message, "cannot open shadow map \"" + bad +
                                              "\": OpenEXR chunks of 4294967296 pixels of 4 bytes (at most 256 MB "
                                              "a chunk are read)");
}

TEST(DepthMap, AValueOpenEXRWouldReadPastItsSizeIsRejected) {
    // umbra:tileMinZ one byte shorter than its floats: OpenEXR reads whole
    // floats and takes the rest of the header out of step (fuzz_maps).
    DepthImage img = sampleImage();
    Diagnostics ok;
    const std::string good = scratchFile("vector.exr");
    ASSERT_TRUE(writeDepthMap(good, img, ok));
    std::string bytes = readBytes(good);
    const std::string attribute = std::string("umbra:tileMinZ") + '\0' + "floatvector" + '\0';
    const size_t at = bytes.find(attribute) + attribute.size();
    ASSERT_NE(at, std::string::npos + attribute.size());
    const uint32_t size = uint8_t(bytes[at]) | uint32_t(uint8_t(bytes[at + 1])) << 8;
    ASSERT_EQ(size % 4, 0u);
    ASSERT_TRUE(size >= 4 && size < 256);  // 6 tiles: the size is its low byte
    bytes[at] = char(size - 1);
    const std::string bad = scratchFile("vector_short.exr");
    writeBytes(bad, bytes);
    Diagnostics diag;
    diag.setRecord(true);
    diag.setPolicy(Diagnostics::Policy::Ignore);
    EXPECT_FALSE(ShadowMap::open(bad, diag));
    ASSERT_EQ(diag.recorded().size(), 1u);
    EXPECT_EQ(diag.recorded()[0].message, "cannot open shadow map \"" + bad +
                                              "\": damaged OpenEXR header (attribute \"umbra:tileMinZ\" of type "
                                              "\"floatvector\" does not fit its size, " +
                                              std::to_string(size - 1) + ")");
}

TEST(DepthMap, AFiniteCountNoWindowHoldsIsRejected) {
    // A damaged count (1e300 does not fit an integer) found by fuzz_maps.
    DepthImage img = sampleImage();
    Diagnostics ok;
    const std::string good = scratchFile("count.exr");
    ASSERT_TRUE(writeDepthMap(good, img, ok));
    std::string bytes = readBytes(good);
    const std::string attribute = std::string("umbra:finiteCount") + '\0' + "double" + '\0';
    const size_t at = bytes.find(attribute);
    ASSERT_NE(at, std::string::npos);
    const double huge = 1e300;
    bytes.replace(at + attribute.size() + 4, 8, std::string(reinterpret_cast<const char*>(&huge), 8));
    const std::string bad = scratchFile("count_too_large.exr");
    writeBytes(bad, bytes);
    Diagnostics diag;
    diag.setRecord(true);
    diag.setPolicy(Diagnostics::Policy::Ignore);
    EXPECT_FALSE(ShadowMap::open(bad, diag));
    ASSERT_EQ(diag.recorded().size(), 1u);
    EXPECT_NE(diag.recorded()[0].message.find("umbra:finiteCount is 1e+300, not a count of the data window's"),
              std::string::npos)
        << diag.recorded()[0].message;
}

TEST(DepthMap, MapWithoutMatricesIsRejected) {
    // A plain tiled EXR written by OIIO carries no worldToCamera.
    const std::string path = scratchFile("nomatrix.exr");
    OIIO::ImageSpec spec(40, 40, 1, OIIO::TypeDesc::FLOAT);
    spec.channelnames = {"Z"};
    spec.tile_width = spec.tile_height = 32;
    std::vector<float> px(40 * 40, 3.0f);
    auto out = OIIO::ImageOutput::create(path);
    ASSERT_TRUE(out);
    ASSERT_TRUE(out->open(path, spec));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, px.data()));
    out->close();
    Diagnostics diag;
    diag.setRecord(true);
    diag.setPolicy(Diagnostics::Policy::Ignore);
    EXPECT_FALSE(ShadowMap::open(path, diag));
    EXPECT_EQ(diag.recorded().at(0).message,
              "cannot open shadow map \"" + path +
                  "\": expected the header matrices worldToCamera and worldToNDC (m44f)");
}

TEST(ZFile, RoundTripsDepthsAndMatrices) {
    DepthImage img(37, 23);
    for (int y = 0; y < 23; ++y)
        for (int x = 0; x < 37; ++x)
            if ((x + y) % 5) img.at(x, y) = float(x * 100 + y) * 0.01f + 1.0f;
    // A perspective light: NDC from camera with a 90 degree field of view.
    img.lightFromWorld = Mat4::translate(Vec3(0, 0, 3)) * Mat4::rotate(20, Vec3(0, 1, 0));
    Mat4 persp;
    persp.m[3][2] = 1;
    persp.m[3][3] = 0;
    // screen [-a,a]x[-1,1] -> NDC, applied after the divide.
    float a = 37.0f / 23.0f;
    Mat4 ndcFromScreen;
    ndcFromScreen.m[0][0] = 1 / (2 * a);
    ndcFromScreen.m[0][3] = 0.5f;
    ndcFromScreen.m[1][1] = -0.5f;
    ndcFromScreen.m[1][3] = 0.5f;
    img.ndcFromWorld = ndcFromScreen * persp * img.lightFromWorld;

    const std::string path = scratchFile("depth.z");
    ASSERT_TRUE(writeZFile(path, img));
    EXPECT_EQ(std::filesystem::file_size(path), 136u + 37u * 23u * 4u);
    // The header as documented: magic, width, height, then Np (world to
    // screen) and Nl (world to camera) in row-vector order.
    std::string bytes = readBytes(path);
    uint32_t magic;
    int16_t w, h;
    float np[16], nl[16];
    std::memcpy(&magic, bytes.data(), 4);
    std::memcpy(&w, bytes.data() + 4, 2);
    std::memcpy(&h, bytes.data() + 6, 2);
    std::memcpy(np, bytes.data() + 8, 64);
    std::memcpy(nl, bytes.data() + 72, 64);
    EXPECT_EQ(magic, 0x2f0867abU);
    EXPECT_EQ(w, 37);
    EXPECT_EQ(h, 23);
    float expectNl[16], expectNp[16];
    img.lightFromWorld.toRib(expectNl);
    (persp * img.lightFromWorld).toRib(expectNp);
    for (int i = 0; i < 16; ++i) {
        EXPECT_EQ(nl[i], expectNl[i]);
        EXPECT_NEAR(np[i], expectNp[i], 1e-5f) << i;
    }

    Diagnostics diag;
    DepthImage back;
    ASSERT_TRUE(readZFile(path, back, diag));
    EXPECT_EQ(back.width, 37);
    EXPECT_EQ(back.height, 23);
    EXPECT_EQ(back.z, img.z);
    EXPECT_TRUE(back.lightFromWorld == img.lightFromWorld);
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) EXPECT_NEAR(back.ndcFromWorld.m[i][j], img.ndcFromWorld.m[i][j], 1e-6f);
    EXPECT_EQ(back.projection, Projection::Perspective);
}

// A map of moving casters made the way exporters make maps (a zfile, then
// MakeShadow) must still say when each texel holds its casters, or moving
// receivers shadow themselves (docs/motion.md): umbra's zfile carries the
// times after the depths, where readers of w x h depths stop. A trailer
// that is not a table of times is dropped; bytes that are not a trailer
// are an error, as before.
TEST(ZFile, CarriesTheTexelTimesOfAMapOfMovingCastersAfterItsDepths) {
    DepthImage img(9, 5);
    for (int y = 0; y < 5; ++y)
        for (int x = 0; x < 9; ++x) img.at(x, y) = 1.0f + float(x + y);
    test::setRasterIsWorld(img);
    img.timeTile = 4;
    img.texelTimes.resize(32 * 32);
    for (size_t k = 0; k < img.texelTimes.size(); ++k) img.texelTimes[k] = (float((k * 7) % 16) + 0.5f) / 16.0f;
    const std::string path = scratchFile("times.z");
    ASSERT_TRUE(writeZFile(path, img));
    const size_t depthsEnd = 136u + 9u * 5u * 4u;
    EXPECT_EQ(std::filesystem::file_size(path), depthsEnd + 8u + 4u + 4u + 32u * 32u * 4u);
    const std::string bytes = readBytes(path);
    EXPECT_EQ(bytes.substr(depthsEnd, 8), "umbraTIM");

    Diagnostics diag;
    DepthImage back;
    ASSERT_TRUE(readZFile(path, back, diag));
    EXPECT_EQ(back.z, img.z);
    EXPECT_EQ(back.timeTile, 4);
    EXPECT_EQ(back.texelTimes, img.texelTimes);
    const std::string exr = scratchFile("times.exr");
    ASSERT_TRUE(makeShadow(path, exr, diag));
    auto map = ShadowMap::open(exr, diag);
    ASSERT_TRUE(map);
    EXPECT_EQ(map->timeTile(), 4);
    EXPECT_TRUE(map->knowsTexelTimes());

    // Not a table of times (one above 1): the depths are read, the times not.
    std::string bad = bytes;
    const float late = 2.0f;
    std::memcpy(&bad[depthsEnd + 16 + 4 * 5], &late, 4);
    writeBytes(path, bad);
    ASSERT_TRUE(readZFile(path, back, diag));
    EXPECT_EQ(back.z, img.z);
    EXPECT_TRUE(back.texelTimes.empty());
    // Not a trailer at all: the size is wrong, as it was.
    bad = bytes;
    bad[depthsEnd] = 'U';
    writeBytes(path, bad);
    Diagnostics d2;
    d2.setRecord(true);
    d2.setPolicy(Diagnostics::Policy::Ignore);
    EXPECT_FALSE(readZFile(path, back, d2));
    EXPECT_EQ(d2.recorded().at(0).message,
              fmt::format("cannot read zfile \"{}\": {} bytes, expected {} for 9x5 depths", path, bytes.size(),
                          depthsEnd));
}

TEST(ZFile, BigEndianFilesAndBadFiles) {
    // A 2x1 big-endian zfile built by hand: depths 1.5 and 1e30 (empty).
    std::string be;
    auto put32 = [&](uint32_t v) {
        for (int s = 24; s >= 0; s -= 8) be.push_back(char((v >> s) & 0xff));
    };
    auto putf = [&](float f) {
        uint32_t v;
        std::memcpy(&v, &f, 4);
        put32(v);
    };
    put32(0x2f0867abU);
    be.push_back(0); be.push_back(2);
    be.push_back(0); be.push_back(1);
    for (int m = 0; m < 2; ++m)
        for (int i = 0; i < 16; ++i) putf(i % 5 == 0 ? 1.0f : 0.0f);
    putf(1.5f);
    putf(1e30f);
    const std::string path = scratchFile("be.z");
    writeBytes(path, be);
    Diagnostics diag;
    DepthImage img;
    ASSERT_TRUE(readZFile(path, img, diag));
    EXPECT_EQ(img.width, 2);
    EXPECT_EQ(img.at(0, 0), 1.5f);
    EXPECT_EQ(img.at(1, 0), kInfinity);
    EXPECT_TRUE(img.lightFromWorld == Mat4::identity());
    EXPECT_EQ(img.projection, Projection::Orthographic);

    const std::string cut = scratchFile("cut.z");
    writeBytes(cut, be.substr(0, be.size() - 2));
    Diagnostics d2;
    d2.setRecord(true);
    d2.setPolicy(Diagnostics::Policy::Ignore);
    EXPECT_FALSE(readZFile(cut, img, d2));
    EXPECT_EQ(d2.recorded().at(0).message,
              "cannot read zfile \"" + cut + "\": 142 bytes, expected 144 for 2x1 depths (truncated)");
    EXPECT_FALSE(makeShadow(cut, scratchFile("cut.exr"), d2));
    EXPECT_FALSE(std::filesystem::exists(scratchFile("cut.exr")));
    EXPECT_FALSE(makeShadow(scratchFile("nothing.z"), scratchFile("n.exr"), d2));
    EXPECT_EQ(d2.recorded().back().message, "MakeShadow: cannot open \"" + scratchFile("nothing.z") + "\"");
}

TEST(MakeShadow, FromZFileReproducesTheDepths) {
    DepthImage img(70, 45);
    for (int y = 10; y < 40; ++y)
        for (int x = 5; x < 60; ++x) img.at(x, y) = 2.0f + float((x * 13 + y * 7) % 17);
    test::setRasterIsWorld(img);
    const std::string z = scratchFile("ms.z"), exr = scratchFile("ms.exr");
    ASSERT_TRUE(writeZFile(z, img));
    Diagnostics diag;
    ASSERT_TRUE(makeShadow(z, exr, diag));
    auto map = ShadowMap::open(exr, diag);
    ASSERT_TRUE(map);
    EXPECT_EQ(map->dataMinX(), 5);
    EXPECT_EQ(map->dataMaxX(), 59);
    EXPECT_EQ(map->dataMinY(), 10);
    EXPECT_EQ(map->dataMaxY(), 39);
    EXPECT_EQ(map->projection(), Projection::Orthographic);
    for (int y = 0; y < 45; ++y)
        for (int x = 0; x < 70; ++x) ASSERT_EQ(map->texel(x, y), img.at(x, y));
    EXPECT_TRUE(map->lightFromWorld() == img.lightFromWorld);
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) EXPECT_NEAR(map->ndcFromWorld().m[i][j], img.ndcFromWorld.m[i][j], 1e-7f);
}

TEST(MakeShadow, FromScanlineExrWithMatrices) {
    // A scanline float image written by OIIO with the standard matrices.
    const std::string in = scratchFile("scan.exr"), out = scratchFile("scan_map.exr");
    OIIO::ImageSpec spec(50, 40, 1, OIIO::TypeDesc::FLOAT);
    spec.channelnames = {"Z"};
    Mat4 w2c = Mat4::translate(Vec3(1, 2, 3));
    Mat4 w2n = Mat4::scale(Vec3(0.02f, 0.025f, 1)) * w2c;
    float a[16], b[16];
    w2c.toRib(a);
    w2n.toRib(b);
    spec.attribute("worldtocamera", OIIO::TypeMatrix, a);
    spec.attribute("worldtoscreen", OIIO::TypeMatrix, b);
    spec.attribute("worldToNDC", OIIO::TypeMatrix, b);
    std::vector<float> px(50 * 40, kInfinity);
    for (int y = 5; y < 20; ++y)
        for (int x = 30; x < 45; ++x) px[size_t(y) * 50 + x] = float(x - y);
    auto o = OIIO::ImageOutput::create(in);
    ASSERT_TRUE(o->open(in, spec));
    ASSERT_TRUE(o->write_image(OIIO::TypeDesc::FLOAT, px.data()));
    o->close();
    Diagnostics diag;
    ASSERT_TRUE(makeShadow(in, out, diag));
    auto map = ShadowMap::open(out, diag);
    ASSERT_TRUE(map);
    EXPECT_TRUE(map->lightFromWorld() == w2c);
    EXPECT_TRUE(map->ndcFromWorld() == w2n);
    EXPECT_EQ(map->dataMinX(), 30);
    EXPECT_EQ(map->dataMaxY(), 19);
    for (int y = 0; y < 40; ++y)
        for (int x = 0; x < 50; ++x) ASSERT_EQ(map->texel(x, y), px[size_t(y) * 50 + x]);
}

// A light's depth pass leaves the pages of texels no caster reached
// untouched (zeros): the image's written window says so, and every writer
// and the map read them as empty, never as depth 0.
TEST(DepthMap, TexelsOutsideTheWrittenWindowAreEmptyWhateverTheirStorageHolds) {
    const DepthImage reference = sampleImage();  // finite depths in [13, 81] x [7, 66]
    DepthImage windowed = sampleImage();
    windowed.writtenX0 = 10, windowed.writtenX1 = 90, windowed.writtenY0 = 5, windowed.writtenY1 = 68;
    for (int y = 0; y < 70; ++y)
        for (int x = 0; x < 100; ++x)
            if (x < 10 || x >= 90 || y < 5 || y >= 68) windowed.z[size_t(y) * 100 + size_t(x)] = 0.0f;
    EXPECT_EQ(std::as_const(windowed).at(0, 0), kInfinity);
    EXPECT_FALSE(windowed.whole());
    Diagnostics diag;
    DepthImage a, b;
    ASSERT_TRUE(writeDepthMap(scratchFile("window-ref.exr"), reference, diag));
    ASSERT_TRUE(writeDepthMap(scratchFile("window.exr"), windowed, diag));
    ASSERT_TRUE(readDepthImage(scratchFile("window-ref.exr"), a, diag));
    ASSERT_TRUE(readDepthImage(scratchFile("window.exr"), b, diag));
    EXPECT_EQ(a.z, b.z);
    ASSERT_TRUE(writeZFile(scratchFile("window.z"), windowed));
    DepthImage z;
    ASSERT_TRUE(readZFile(scratchFile("window.z"), z, diag));
    EXPECT_EQ(z.z, reference.z);
    // Nothing written: an empty map, though every texel's storage is 0.
    DepthImage none(100, 70);
    std::fill(none.z.begin(), none.z.end(), 0.0f);
    none.writtenX0 = none.writtenX1 = 40, none.writtenY0 = none.writtenY1 = 30;
    test::setRasterIsWorld(none);
    auto map = ShadowMap::fromImage(none, scratchFile("none.exr"), {}, diag, {});
    ASSERT_TRUE(map);
    EXPECT_TRUE(map->empty());
    ASSERT_TRUE(writeDepthMap(scratchFile("none.exr"), none, diag));
    DepthImage back;
    ASSERT_TRUE(readDepthImage(scratchFile("none.exr"), back, diag));
    for (float v : back.z) ASSERT_EQ(v, kInfinity);
    EXPECT_EQ(diag.errorCount(), 0);
}

}  // namespace
}  // namespace umbra
