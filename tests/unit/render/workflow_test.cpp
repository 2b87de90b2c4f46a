// RenderMan workflows end to end: the two-RIB shadow pipeline (zfile,
// MakeShadow, shadow lookups), automatic maps, textures made in the RIB.

#include "support/render_harness.h"

#include "umbra/shadow/shadow_map.h"

#include <OpenImageIO/imageio.h>

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <filesystem>
#include <fstream>
#include <iterator>

using namespace umbra;
using umbra::test::Image;
using umbra::test::ScratchDir;

namespace {

/// A sphere of radius 0.5, 1.5 above the ground plane y = 0, lit straight
/// down by a distant light: the shadow is the disk x^2 + z^2 < 0.25 on the
/// ground. The sphere is invisible to the camera but casts shadows, so the
/// whole shadow can be seen from above.
/// The camera looks straight down too (orthographic, from y = 10; camera
/// +z is world -y, camera +y is world +z), so raster position maps linearly
/// to ground coordinates: x in [-3,3] left to right, z in [3,-3] top to
/// bottom, over 120x120 pixels.
const char* kDownCamera = R"(
Format 120 120 1
ScreenWindow -3 3 -3 3
Projection "orthographic"
Rotate -90 1 0 0
Translate 0 -10 0
)";

std::string world(const std::string& light) {
    return fmt::format(R"(
WorldBegin
  {}
  Surface "matte"
  AttributeBegin
    Attribute "visibility" "transmission" [0]
    Polygon "P" [-5 0 -5  -5 0 5  5 0 5  5 0 -5]
  AttributeEnd
  AttributeBegin
    Attribute "visibility" "camera" [0]
    Translate 0 1.5 0
    Sphere 0.5 -0.5 0.5 360
  AttributeEnd
WorldEnd
)", light);
}

/// Pass 1 of the RenderMan shadow workflow: the scene seen by
/// `lightCamera` (its projection and placement) into `<map>.z`, made into
/// the shadow map `<map>.shd` by MakeShadow.
void renderShadowMap(const ScratchDir& dir, const std::string& lightCamera, const std::string& map, Diagnostics& diag) {
    test::renderRib(fmt::format(R"(
Display "{0}" "zfile" "z"
Format 128 128 1
PixelSamples 1 1
Hider "hidden" "jitter" [0]
{1}
{2}
MakeShadow "{0}" "{3}"
)", dir.file(map + ".z"), lightCamera, world(""), dir.file(map + ".shd")),
                    diag);
}

/// Pass 2: the scene from above (kDownCamera) with `light`.
Image renderFromAbove(const ScratchDir& dir, const std::string& light, Diagnostics& diag) {
    return test::renderImage(fmt::format(R"(Display "{}" "openexr" "rgba" "string type" "float"
PixelSamples 2 2
{}
{})", dir.file("beauty.exr"), kDownCamera, world(light)),
                             dir.file("beauty.exr"), diag);
}

/// Brightness of the ground at world (x, z), read from the image.
float groundAt(const Image& img, float x, float z) {
    int px = int((x + 3) / 6 * img.width), py = int((3 - z) / 6 * img.height);
    return img.at(px, py, 0);
}

}  // namespace

TEST(Workflow, ZfileMakeShadowThenLookup) {
    ScratchDir dir("zfile");
    Diagnostics diag;
    // Pass 1: the light's view, orthographic straight down, to a zfile.
    renderShadowMap(dir, "ScreenWindow -3 3 -3 3\nProjection \"orthographic\"\nRotate -90 1 0 0\nTranslate 0 -10 0",
                    "light", diag);
    ASSERT_EQ(diag.errorCount(), 0);
    ASSERT_TRUE(std::filesystem::exists(dir.file("light.shd")));
    // Pass 2: the beauty render looks the map up.
    const Image img = renderFromAbove(
        dir,
        fmt::format(R"(LightSource "shadowdistant" 1 "from" [0 1 0] "to" [0 0 0] "shadowname" ["{}"] "bias" [0.05])",
                    dir.file("light.shd")),
        diag);
    ASSERT_EQ(diag.errorCount(), 0);
    ASSERT_EQ(img.width, 120);
    // Lit ground outside the shadow disk, shadowed inside.
    EXPECT_GT(groundAt(img, 0.8f, 0), 0.5f);
    EXPECT_GT(groundAt(img, 0, -2.0f), 0.5f);
    EXPECT_LT(groundAt(img, 0.0f, 0.0f), 0.05f);
    EXPECT_LT(groundAt(img, 0.3f, 0.1f), 0.05f);
}

TEST(Workflow, ShadowpointPicksItsFaceMapsAlongTheWorldAxes) {
    // The six maps of a shadowpoint are made by cameras along the world
    // axes; Pixar's shadowpoint (and Pixie's, Aqsis's copy) picks the face
    // by the world direction to the point. umbra's picked it by the light's
    // shader-space axes, so a light placed with a rotation looked the floor
    // up in the wrong face's (empty) map: no shadow. Light at y = 4 placed
    // with a turn about z, only its -y map given.
    ScratchDir dir("shadowpoint-faces");
    Diagnostics diag;
    renderShadowMap(dir, "Projection \"perspective\" \"fov\" 90\nRotate -90 1 0 0\nTranslate 0 -4 0", "ny", diag);
    ASSERT_EQ(diag.errorCount(), 0);
    const Image img = renderFromAbove(dir,
                                      fmt::format(R"(TransformBegin Translate 0 4 0 Rotate 90 0 0 1
  LightSource "shadowpoint" 1 "intensity" [16] "sfny" ["{}"] "bias" [0.05]
TransformEnd)",
                                                  dir.file("ny.shd")),
                                      diag);
    ASSERT_EQ(diag.errorCount(), 0);
    ASSERT_EQ(img.width, 120);
    // The sphere (radius 0.5 at height 1.5) seen from the light at height
    // 4 shadows a disc of radius 4 tan(asin(0.5 / 2.5)) = 0.82 on the floor.
    EXPECT_LT(groundAt(img, 0.0f, 0.0f), 0.02f);
    EXPECT_LT(groundAt(img, 0.5f, 0.3f), 0.02f);
    EXPECT_GT(groundAt(img, 1.2f, 0.0f), 0.3f);
    EXPECT_GT(groundAt(img, 0.0f, -1.5f), 0.3f);
}

// A light's frame written as a zfile hands its film's depths to the file
// (the film starts unset, its empty buckets never touched): texels no
// caster reaches must still read +infinity, with and without a crop
// window (which keeps the copy), and the caster's texels its depth.
TEST(Workflow, ASparseZfileHoldsInfinityWhereNoCasterIs) {
    ScratchDir dir("sparse-zfile");
    for (const char* crop : {"", "CropWindow 0.25 1 0 0.75"}) {
        Diagnostics diag;
        // Orthographic, 16 texels a unit; a unit sphere 10 units away.
        test::renderRib(fmt::format(R"(
Display "{0}" "zfile" "z"
Format 256 256 1
{1}
PixelSamples 1 1
Hider "hidden" "jitter" [0]
ScreenWindow -8 8 -8 8
Projection "orthographic"
WorldBegin
Translate 0 0 10
Sphere 1 -1 1 360
WorldEnd
)", dir.file("light.z"), crop),
                        diag);
        ASSERT_EQ(diag.errorCount(), 0) << crop;
        DepthImage z;
        ASSERT_TRUE(readZFile(dir.file("light.z"), z, diag)) << crop;
        ASSERT_EQ(z.width, 256);
        int finite = 0;
        for (int y = 0; y < z.height; ++y)
            for (int x = 0; x < z.width; ++x) {
                const float d = z.at(x, y);
                if (d == kInfinity) continue;
                ++finite;
                // Every finite texel lies on the sphere's near half.
                const float u = (x + 0.5f - 128) / 16, v = (y + 0.5f - 128) / 16;
                EXPECT_NEAR(d, 10 - std::sqrt(std::max(0.0f, 1 - u * u - v * v)), 0.05f) << crop << " " << x << "," << y;
            }
        // The disc of radius 1 covers pi 16^2 = 804 texels (its edge, a
        // texel wide, is 100 texels).
        EXPECT_NEAR(finite, 804, 60) << crop;
        EXPECT_EQ(z.at(0, 0), kInfinity) << crop;
        EXPECT_EQ(z.at(255, 255), kInfinity) << crop;
        EXPECT_NEAR(z.at(128, 128), 9.0f, 0.01f) << crop;
    }
}

// A light-view frame (Display "zfile") is cut into 64-texel buckets unless
// the user gives a size, as automatic maps are: the map is the same
// whatever the size, and a size given by Option "limits" or --bucket-size
// is kept.
TEST(Workflow, ALightViewFramesBucketsAre64TexelsUnlessGivenAndItsZfileIsTheSame) {
    ScratchDir dir("zfile-buckets");
    struct Run {
        std::vector<int> bucketSize;
        int buckets = 0;
        std::string bytes;
    };
    auto run = [&](const std::string& option, int flag) {
        Diagnostics diag;
        const nlohmann::json stats = test::renderRib(fmt::format(R"(
{0}
Display "{1}" "zfile" "z"
Format 200 136 1
PixelSamples 1 1
Hider "hidden" "jitter" [0]
Projection "perspective" "fov" [40]
WorldBegin
  Translate 0 0 6
  Sphere 1 -1 1 360
  Translate 1.5 0.5 1
  Sphere 0.8 -0.8 0.8 360
  Translate -3 -1 -0.5
  Rotate 30 1 1 0
  Cylinder 0.6 -0.5 0.5 360
WorldEnd
)", option, dir.file("light.z")),
                                                     diag, 2, flag);
        EXPECT_EQ(diag.errorCount(), 0) << option << flag;
        Run r;
        for (const auto& p : stats["frames"][0]["passes"])
            if (p["name"] == "camera") {
                r.bucketSize = p["bucket_size"].get<std::vector<int>>();
                r.buckets = p["counts"]["buckets"].get<int>();
            }
        std::ifstream f(dir.file("light.z"), std::ios::binary);
        r.bytes.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
        return r;
    };
    const Run automatic = run("", 0);
    EXPECT_EQ(automatic.bucketSize, (std::vector<int>{64, 64}));
    EXPECT_EQ(automatic.buckets, 4 * 3);  // 200 x 136 texels
    const Run option = run("Option \"limits\" \"bucketsize\" [16 16]", 0);
    EXPECT_EQ(option.bucketSize, (std::vector<int>{16, 16}));
    EXPECT_EQ(option.buckets, 13 * 9);
    const Run flag = run("", 16);
    EXPECT_EQ(flag.bucketSize, (std::vector<int>{16, 16}));
    const Run odd = run("Option \"limits\" \"bucketsize\" [24 8]", 0);
    EXPECT_EQ(odd.bucketSize, (std::vector<int>{24, 8}));
    // 136 bytes of header and 200 x 136 depths, the same in every run, and
    // the casters are in it.
    ASSERT_EQ(automatic.bytes.size(), size_t(136 + 200 * 136 * 4));
    EXPECT_EQ(automatic.bytes, option.bytes);
    EXPECT_EQ(automatic.bytes, flag.bytes);
    EXPECT_EQ(automatic.bytes, odd.bytes);
    DepthImage z;
    Diagnostics diag;
    ASSERT_TRUE(readZFile(dir.file("light.z"), z, diag));
    int finite = 0;
    for (float d : z.z) finite += d < kInfinity;
    EXPECT_GT(finite, 2000);
    EXPECT_LT(finite, 200 * 136 / 2);
}

TEST(Workflow, AutomaticMapMatchesRayTracedShadow) {
    // The same scene with an automatic map and with exact ray-traced shadows:
    // the shadowed areas must agree except along the edge.
    ScratchDir dir("auto");
    Diagnostics diag;
    auto frame = [&](const std::string& out, const std::string& shadowName) {
        return fmt::format(R"(Display "{}" "openexr" "rgba" "string type" "float"
PixelSamples 2 2
Option "umbra" "shadowmapsize" [512]
{}
{})", out, kDownCamera,
                           world(fmt::format(R"(LightSource "shadowdistant" 1 "from" [0 1 0] "to" [0 0 0] "shadowname" ["{}"] "samples" [16])",
                                             shadowName)));
    };
    test::renderRib(frame(dir.file("map.exr"), "auto"), diag);
    test::renderRib(frame(dir.file("ray.exr"), "raytrace"), diag);
    ASSERT_EQ(diag.errorCount(), 0);
    Image a, b;
    ASSERT_TRUE(test::readImage(dir.file("map.exr"), &a));
    ASSERT_TRUE(test::readImage(dir.file("ray.exr"), &b));
    int differ = 0, shadowed = 0, lit = 0;
    for (int y = 0; y < a.height; ++y)
        for (int x = 0; x < a.width; ++x) {
            bool sa = a.at(x, y, 0) < 0.5f, sb = b.at(x, y, 0) < 0.5f;
            differ += sa != sb;
            shadowed += sb;
            lit += !sb;
        }
    // The shadow disk covers pi 0.25 / (6/120)^2 = 314 pixels.
    EXPECT_NEAR(shadowed, 314, 40);
    EXPECT_GT(lit, 10000);
    EXPECT_LT(groundAt(b, 0.0f, 0.0f), 0.05f);
    EXPECT_GT(groundAt(b, 0.8f, 0.0f), 0.5f);
    // Only pixels on the outline may differ: it is 2 pi 0.5 / (6/120) = 63
    // pixels long.
    EXPECT_LT(differ, 63);
}

TEST(Workflow, MakeTextureThenTexture) {
    ScratchDir dir("texture");
    // A 2x1 picture: red on the left half, green on the right.
    {
        auto out = OIIO::ImageOutput::create(dir.file("pic.tif"));
        ASSERT_TRUE(out);
        OIIO::ImageSpec spec(64, 32, 3, OIIO::TypeDesc::FLOAT);
        ASSERT_TRUE(out->open(dir.file("pic.tif"), spec));
        std::vector<float> px(64 * 32 * 3, 0.0f);
        for (int y = 0; y < 32; ++y)
            for (int x = 0; x < 64; ++x) px[size_t((y * 64 + x) * 3 + (x < 32 ? 0 : 1))] = 1.0f;
        ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, px.data()));
        out->close();
    }
    Diagnostics diag;
    test::renderRib(fmt::format(R"(
MakeTexture "{0}" "{1}" "clamp" "clamp" "gaussian" 2 2
Display "{2}" "openexr" "rgba" "string type" "float"
Format 80 40 1
ScreenWindow -2 2 -1 1
Projection "orthographic"
Translate 0 0 5
WorldBegin
  Surface "paintedplastic" "texturename" ["{1}"] "Ka" [1] "Kd" [0] "Ks" [0]
  LightSource "ambientlight" 1 "intensity" [1]
  Polygon "P" [-2 -1 0  2 -1 0  2 1 0  -2 1 0] "st" [0 0  1 0  1 1  0 1]
WorldEnd
)", dir.file("pic.tif"), dir.file("pic.tx"), dir.file("out.exr")),
                    diag);
    ASSERT_EQ(diag.errorCount(), 0);
    Image img;
    ASSERT_TRUE(test::readImage(dir.file("out.exr"), &img));
    EXPECT_GT(img.at(10, 20, 0), 0.9f);
    EXPECT_LT(img.at(10, 20, 1), 0.1f);
    EXPECT_LT(img.at(70, 20, 0), 0.1f);
    EXPECT_GT(img.at(70, 20, 1), 0.9f);
}

TEST(Workflow, TinyTileCacheRendersTheSameImage) {
    // A 2048^2 map (16 MiB of depths) looked up through a 1 MiB tile cache
    // must give the same pixels as through the default 64 MiB one, while
    // actually evicting tiles.
    ScratchDir dir("tinycache");
    auto frame = [&](const std::string& out, int mb) {
        return fmt::format(R"(Display "{}" "openexr" "rgba" "string type" "float"
PixelSamples 2 2
Option "umbra" "shadowmapsize" [2048] "tilecachemb" [{}]
Option "shadow" "bias" [0.02]
{}
{})", out, mb, kDownCamera,
                           // The floor casts too, so lookups read tiles all over the map.
                           R"(WorldBegin
  LightSource "shadowspot" 1 "from" [0.5 4 0.3] "to" [0 0 0] "coneangle" [0.9] "intensity" [16] "shadowname" ["auto"]
  Surface "matte"
  Polygon "P" [-5 0 -5  -5 0 5  5 0 5  5 0 -5]
  AttributeBegin Translate 0 1.5 0 Sphere 0.5 -0.5 0.5 360 AttributeEnd
WorldEnd)");
    };
    Diagnostics diag;
    auto big = test::renderRib(frame(dir.file("big.exr"), 64), diag, 2);
    auto tiny = test::renderRib(frame(dir.file("tiny.exr"), 1), diag, 2);
    ASSERT_EQ(diag.errorCount(), 0);
    EXPECT_EQ(big["frames"][0]["shadow"]["tile_cache"]["evictions"].get<uint64_t>(), 0u);
    EXPECT_GT(tiny["frames"][0]["shadow"]["tile_cache"]["evictions"].get<uint64_t>(), 0u);
    // The map that fits is written in the background, the other at once.
    EXPECT_EQ(big["frames"][0]["shadow"]["background_map_writes"].get<int>(), 1);
    EXPECT_EQ(tiny["frames"][0]["shadow"]["background_map_writes"].get<int>(), 0);
    Image a, b;
    ASSERT_TRUE(test::readImage(dir.file("big.exr"), &a));
    ASSERT_TRUE(test::readImage(dir.file("tiny.exr"), &b));
    ASSERT_EQ(a.pixels.size(), b.pixels.size());
    double lit = 0;
    for (size_t i = 0; i < a.pixels.size(); ++i) {
        ASSERT_EQ(a.pixels[i], b.pixels[i]) << "at float " << i;
        lit += a.pixels[i];
    }
    EXPECT_GT(lit, 1000.0);
}

TEST(Workflow, SpotMapsStoreOnlyTheDiscOfTheCone) {
    // A floor fills the whole view of a spotlight looking straight down, so
    // every texel of the square map sees it; the map keeps only the disc
    // inscribed in the square (the cone and its margin).
    ScratchDir dir("disc");
    Diagnostics diag;
    test::renderRib(fmt::format(R"(Display "{}" "openexr" "rgba" "string type" "float"
Option "umbra" "shadowmapsize" [128]
{}
WorldBegin
  LightSource "shadowspot" 1 "from" [0 4 0] "to" [0 0 0] "coneangle" [0.6] "shadowname" ["auto"]
  Surface "matte"
  Polygon "P" [-50 0 -50  -50 0 50  50 0 50  50 0 -50]
WorldEnd)", dir.file("spot.exr"), kDownCamera),
                    diag);
    ASSERT_EQ(diag.errorCount(), 0);
    auto map = ShadowMap::open(dir.file("spot.1.shd"), diag);
    ASSERT_TRUE(map);
    EXPECT_EQ(map->texel(0, 0), kInfinity);
    EXPECT_EQ(map->texel(127, 127), kInfinity);
    EXPECT_EQ(map->texel(10, 10), kInfinity);  // (10.5, 10.5) is 1.19 half-widths from the centre
    // Inside the disc: the floor's depth, 4 along the axis (more off axis).
    EXPECT_NEAR(map->texel(64, 64), 4.0f, 1e-3f);
    EXPECT_LT(map->texel(2, 64), 10.0f);   // radius 0.95, on an axis
    EXPECT_LT(map->texel(64, 125), 10.0f);
    int finite = 0;
    for (int y = 0; y < 128; ++y)
        for (int x = 0; x < 128; ++x) {
            const float u = (float(x) + 0.5f) / 64.0f - 1.0f, v = (float(y) + 0.5f) / 64.0f - 1.0f;
            const bool inDisc = u * u + v * v <= 1.0f;
            ASSERT_EQ(map->texel(x, y) < kInfinity, inDisc) << x << "," << y;
            finite += inDisc;
        }
    EXPECT_NEAR(double(finite) / (128.0 * 128.0), kPi / 4, 0.01);
}

TEST(Workflow, ALightsOwnAttributeSetsItsMapSize) {
    // Attribute "umbra" "shadowmapsize" where a light is declared overrides
    // the frame's option for that light alone.
    ScratchDir dir("mapsize");
    Diagnostics diag;
    test::renderRib(fmt::format(R"(Display "{}" "openexr" "rgba" "string type" "float"
Option "umbra" "shadowmapsize" [128]
{}
WorldBegin
  AttributeBegin
    Attribute "umbra" "shadowmapsize" [96]
    LightSource "shadowspot" "own" "from" [0 4 0] "to" [0 0 0] "coneangle" [0.6] "shadowname" ["auto"]
  AttributeEnd
  Illuminate "own" 1
  LightSource "shadowspot" "frame" "from" [1 4 0] "to" [0 0 0] "coneangle" [0.6] "shadowname" ["auto"]
  Surface "matte"
  Polygon "P" [-50 0 -50  -50 0 50  50 0 50  50 0 -50]
WorldEnd)", dir.file("spot.exr"), kDownCamera),
                    diag);
    ASSERT_EQ(diag.errorCount(), 0);
    auto own = ShadowMap::open(dir.file("spot.own.shd"), diag), frame = ShadowMap::open(dir.file("spot.frame.shd"), diag);
    ASSERT_TRUE(own && frame);
    EXPECT_EQ(own->width(), 96);
    EXPECT_EQ(own->height(), 96);
    EXPECT_EQ(frame->width(), 128);
    EXPECT_NEAR(own->texel(48, 48), 4.0f, 1e-3f);  // the floor, 4 below the light on its axis
}

namespace {

/// A frame with three automatic maps: a spot light's, a distant light's and
/// a point light's cube map, all of `mapSize` texels a side.
std::string threeMapFrame(const std::string& image, int mapSize, int cacheMB) {
    return fmt::format(R"(Display "{}" "openexr" "rgba" "string type" "float"
PixelSamples 2 2
Option "umbra" "shadowmapsize" [{}] "tilecachemb" [{}]
Option "shadow" "bias" [0.05]
{}
WorldBegin
  LightSource "shadowspot" 1 "from" [0.5 4 0.3] "to" [0 0 0] "coneangle" [0.9] "intensity" [8] "shadowname" ["auto"]
  LightSource "shadowdistant" 2 "from" [1 3 0] "to" [0 0 0] "intensity" [0.3] "shadowname" ["auto"]
  LightSource "shadowpoint" 3 "from" [-1 2.5 -0.5] "intensity" [3] "shadowname" ["auto"]
  Surface "matte"
  Polygon "P" [-5 0 -5  -5 0 5  5 0 5  5 0 -5]
  AttributeBegin Translate 0 1.5 0 Sphere 0.5 -0.5 0.5 360 AttributeEnd
WorldEnd)",
                       image, mapSize, cacheMB, kDownCamera);
}

std::string fileBytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

/// The two image files hold the same pixels, bit for bit.
void expectSameImage(const std::string& first, const std::string& second) {
    Image a, b;
    ASSERT_TRUE(test::readImage(first, &a));
    ASSERT_TRUE(test::readImage(second, &b));
    ASSERT_EQ(a.pixels.size(), b.pixels.size());
    for (size_t i = 0; i < a.pixels.size(); ++i) ASSERT_EQ(a.pixels[i], b.pixels[i]) << "at float " << i;
}

bool anyTemporaryFile(const std::string& dir) {
    for (const auto& e : std::filesystem::directory_iterator(dir))
        if (e.path().extension() == ".tmp") return true;
    return false;
}

}  // namespace

TEST(Workflow, MapFilesWrittenInTheBackgroundAreCompleteWhenRenderReturns) {
    // The same frame with every map's tiles cached (files written in the
    // background) and with a cache too small for them (written at once):
    // the same files and the same image.
    ScratchDir bg("bgwrite"), now("nowwrite");
    Diagnostics diag;
    auto background = test::renderRib(threeMapFrame(bg.file("frame.exr"), 512, 64), diag, 2);
    auto atOnce = test::renderRib(threeMapFrame(now.file("frame.exr"), 512, 1), diag, 2);
    ASSERT_EQ(diag.errorCount(), 0);
    EXPECT_EQ(background["frames"][0]["shadow"]["background_map_writes"].get<int>(), 3);
    EXPECT_EQ(atOnce["frames"][0]["shadow"]["background_map_writes"].get<int>(), 0);
    // --threads 1 is one core: the files are written at once, not beside
    // the camera pass.
    ScratchDir one("onethread");
    auto oneThread = test::renderRib(threeMapFrame(one.file("frame.exr"), 512, 64), diag, 1);
    ASSERT_EQ(diag.errorCount(), 0);
    EXPECT_EQ(oneThread["frames"][0]["shadow"]["background_map_writes"].get<int>(), 0);
    EXPECT_TRUE(background["frames"][0]["shadow"]["map_write_wait_seconds"].is_number());
    EXPECT_FALSE(anyTemporaryFile(bg.file("")));
    for (const char* light : {"1", "2", "3"}) {
        SCOPED_TRACE(light);
        const std::string name = fmt::format("frame.{}.shd", light);
        // Complete: opens (OpenEXR and the chunk table agree it is whole)
        // and every texel reads back without an error.
        Diagnostics readDiag;
        auto map = ShadowMap::open(bg.file(name), readDiag, {}, std::make_shared<TileCache>());
        ASSERT_TRUE(map);
        EXPECT_EQ(map->isCube(), std::string(light) == "3");
        int64_t finite = 0;
        for (int f = 0; f < (map->isCube() ? 6 : 1); ++f) {
            const ShadowMap& face = map->isCube() ? map->face(f) : *map;
            for (int y = 0; y < face.height(); ++y)
                for (int x = 0; x < face.width(); ++x) finite += face.texel(x, y) < kInfinity;
        }
        EXPECT_GT(finite, 512 * 512 / 4);  // the floor fills much of every map
        EXPECT_EQ(readDiag.errorCount(), 0);
        EXPECT_EQ(fileBytes(bg.file(name)), fileBytes(now.file(name)));
        EXPECT_EQ(fileBytes(bg.file(name)), fileBytes(one.file(name)));
    }
    expectSameImage(bg.file("frame.exr"), now.file("frame.exr"));
}

TEST(Workflow, LightsMapsMadeSideBySideGiveTheSerialFrame) {
    // The three lights' maps are made side by side on two threads, one
    // after another on one: the same maps, the same image, the passes
    // reported in the lights' order, each with its times.
    ScratchDir two("sidebyside"), one("oneatatime");
    Diagnostics diag;
    auto parallel = test::renderRib(threeMapFrame(two.file("frame.exr"), 256, 64), diag, 2);
    auto serial = test::renderRib(threeMapFrame(one.file("frame.exr"), 256, 64), diag, 1);
    ASSERT_EQ(diag.errorCount(), 0);
    for (const char* light : {"1", "2", "3"}) {
        const std::string name = fmt::format("frame.{}.shd", light);
        EXPECT_EQ(fileBytes(two.file(name)), fileBytes(one.file(name))) << name;
    }
    expectSameImage(two.file("frame.exr"), one.file("frame.exr"));
    for (const auto* stats : {&parallel, &serial}) {
        const auto& frame = (*stats)["frames"][0];
        std::vector<std::string> names;
        for (const auto& p : frame["passes"]) {
            names.push_back(p["name"].get<std::string>());
            EXPECT_TRUE(p["wall_seconds"].is_number());
        }
        std::vector<std::string> expected = {"depth:1", "depth:2"};
        for (const char* face : {"+x", "-x", "+y", "-y", "+z", "-z"}) expected.push_back(fmt::format("depth:3{}", face));
        expected.push_back("camera");
        EXPECT_EQ(names, expected);
        // The times are reported, but a clock does not decide the test.
        EXPECT_TRUE(frame["first_pass"]["wall_seconds"].is_number());
        EXPECT_TRUE(frame["first_pass"]["cpu_seconds"].is_number());
        EXPECT_TRUE(frame["wall_seconds"].is_number());
    }
}

TEST(Workflow, AMapThatCannotBeWrittenFailsTheFrame) {
    // The spot light's map would replace a directory: the rename fails, in
    // the background (tiles cached) or at once (cache too small).
    for (int cacheMB : {64, 1}) {
        SCOPED_TRACE(cacheMB);
        ScratchDir dir("unwritable");
        const std::string blocked = dir.file("frame.1.shd");
        std::filesystem::create_directory(blocked);
        Diagnostics diag;
        diag.setRecord(true);
        diag.setPolicy(Diagnostics::Policy::Ignore);
        int failedFrames = 0;
        auto stats = test::renderRib(threeMapFrame(dir.file("frame.exr"), 512, cacheMB), diag, 0, 0, &failedFrames);
        EXPECT_EQ(failedFrames, 1);
        EXPECT_EQ(stats["frames"][0]["errors"].get<int>(), 1);
        const auto rec = diag.recorded();
        ASSERT_EQ(rec.size(), 1u);
        EXPECT_EQ(rec[0].message.rfind("cannot write depth map \"" + blocked + "\": ", 0), 0u) << rec[0].message;
        EXPECT_TRUE(std::filesystem::is_directory(blocked));
        EXPECT_FALSE(anyTemporaryFile(dir.file("")));
        // The other maps and the image are written.
        EXPECT_TRUE(std::filesystem::is_regular_file(dir.file("frame.2.shd")));
        EXPECT_TRUE(std::filesystem::is_regular_file(dir.file("frame.3.shd")));
        EXPECT_TRUE(std::filesystem::is_regular_file(dir.file("frame.exr")));
    }
}

TEST(Workflow, PrimitivesAPassNeverDrawsAreNotSplitThere) {
    // The ground plane is in no depth map (transmission 0) and the sphere
    // is in no camera image (camera 0): each must cost its pass nothing,
    // not be split to grid size and thrown away piece by piece. A pass's
    // work is compared with the same frame without the primitive it leaves
    // out (one thread: occlusion culling then does the same work each run).
    const std::string ground = R"(AttributeBegin
    Attribute "visibility" "transmission" [0]
    Polygon "P" [-5 0 -5  -5 0 5  5 0 5  5 0 -5]
  AttributeEnd)";
    const std::string sphere = R"(AttributeBegin
    Attribute "visibility" "camera" [0]
    Translate 0 1.5 0
    Sphere 0.5 -0.5 0.5 360
  AttributeEnd)";
    ScratchDir dir("nevercast");  // the image and its map go here
    auto passCounts = [&](bool withGround, bool withSphere, const std::string& passName) {
        Diagnostics diag;
        nlohmann::json stats = test::renderRib(fmt::format(R"(Display "{}" "openexr" "rgba"
PixelSamples 2 2
Option "umbra" "shadowmapsize" [1024]
{}
WorldBegin
  LightSource "shadowspot" 1 "from" [0 4 0] "to" [0 0 0] "coneangle" [0.7] "shadowname" ["auto"]
  Surface "matte"
  {}
  {}
WorldEnd)", dir.file("frame.exr"), kDownCamera, withGround ? ground : "", withSphere ? sphere : ""),
                                               diag, 1);
        EXPECT_EQ(diag.errorCount(), 0);
        for (const auto& pass : stats["frames"][0]["passes"])
            if (pass["name"] == passName) return pass["counts"];
        ADD_FAILURE() << "no pass " << passName;
        return nlohmann::json();
    };
    const nlohmann::json depthBoth = passCounts(true, true, "depth:1"), depthSphere = passCounts(false, true, "depth:1");
    const nlohmann::json cameraBoth = passCounts(true, true, "camera"), cameraGround = passCounts(true, false, "camera");
    for (const char* count : {"splits", "grids", "micropolygons"}) {
        EXPECT_EQ(depthBoth[count], depthSphere[count]) << count;
        EXPECT_EQ(cameraBoth[count], cameraGround[count]) << count;
    }
    EXPECT_GT(depthBoth["grids"].get<int>(), 0);  // the sphere is in the map
    EXPECT_GT(cameraBoth["grids"].get<int>(), 0);  // the ground is in the image
}

TEST(Workflow, FlatQuadsAreOneMicropolygonInADepthPassWithTheSameDepths) {
    // A tilted square seen by a perspective spot light, once as a Polygon
    // (a flat quad: one micropolygon in the depth pass) and once as the
    // same square as a bicubic patch (diced at the depth pass's rate). 1/z
    // is linear across a flat micropolygon, so both maps hold the plane's
    // depths: they must agree to float rounding, texel for texel.
    ScratchDir dir("flatquad");
    const char* corners[4] = {"-1 0.3 -1", "1 -0.2 -1", "-1 0.8 1", "1 0.3 1"};  // on the plane y = 0.3 - x/4 + z/4
    auto at = [&](float u, float v) {  // the bilinear (and bicubic) square at (u, v)
        return fmt::format("{} {} {}", 2 * u - 1, 0.3f - 0.25f * (2 * u - 1) + 0.25f * (2 * v - 1), 2 * v - 1);
    };
    std::string bezier;
    for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) bezier += at(i / 3.0f, j / 3.0f) + " ";
    auto render = [&](const std::string& name, const std::string& surface) {
        Diagnostics diag;
        nlohmann::json stats = test::renderRib(fmt::format(R"(Display "{}" "openexr" "rgba" "string type" "float"
Option "umbra" "shadowmapsize" [256]
{}
WorldBegin
  LightSource "shadowspot" "key" "from" [0.5 4 -2] "to" [0 0 0] "coneangle" [0.6] "shadowname" ["auto"]
  Surface "matte"
  {}
WorldEnd)", dir.file(name + ".exr"), kDownCamera, surface),
                                               diag);
        EXPECT_EQ(diag.errorCount(), 0);
        return stats["frames"][0]["passes"][0]["counts"];
    };
    const nlohmann::json polygon = render("polygon", fmt::format(R"(Polygon "P" [{} {} {} {}])", corners[0],
                                                                 corners[1], corners[3], corners[2]));
    render("patch", "Patch \"bicubic\" \"P\" [" + bezier + "]");
    EXPECT_EQ(polygon["micropolygons"], 1);
    Diagnostics diag;
    auto a = ShadowMap::open(dir.file("polygon.key.shd"), diag), b = ShadowMap::open(dir.file("patch.key.shd"), diag);
    ASSERT_TRUE(a && b);
    int stored = 0, outlineDiffers = 0;
    float worst = 0;
    for (int y = 0; y < 256; ++y)
        for (int x = 0; x < 256; ++x) {
            const float za = a->texel(x, y), zb = b->texel(x, y);
            if (std::isinf(za) != std::isinf(zb)) {
                ++outlineDiffers;  // a texel centre on the edge, within rounding
                continue;
            }
            if (std::isinf(za)) continue;
            ++stored;
            worst = std::max(worst, std::abs(za - zb) / zb);
        }
    EXPECT_GT(stored, 5000);
    EXPECT_LT(worst, 2e-6f);
    EXPECT_LE(outlineDiffers, 4);
}
