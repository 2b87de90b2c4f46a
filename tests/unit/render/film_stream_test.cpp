// The streamed film (Film::openStream): when every display is a TIFF and
// nothing reads the whole film afterwards, strips are written as bucket
// rows complete and their rows freed. The files must be byte for byte those
// of the whole-film path (RenderSettings::filmStream = false) at any thread
// count and bucket size; EXR displays and imagers keep the whole film; a
// write that fails mid-frame leaves no temporary file and the earlier image
// alone. At one thread the rows held follow from the bucket and strip
// heights alone (scanline order); at more they depend on scheduling, so no
// test bounds them there.

#include "support/child_run.h"
#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <sys/resource.h>

using namespace umbra;
using umbra::test::Image;
using umbra::test::ScratchDir;
namespace fs = std::filesystem;

namespace {

constexpr int kStripRows = 32;  // every TIFF umbra writes (film/image_file.h)

/// Renders RIB text as the harness does, with the film streamed or not;
/// returns the first frame's statistics.
nlohmann::json renderFrame(const std::string& rib, bool stream, int threads, int bucketSize, Diagnostics& diag,
                      int* failed = nullptr) {
    render::RenderSettings settings;
    settings.threads = threads;
    settings.bucketSize = bucketSize;
    settings.filmStream = stream;
    const nlohmann::json stats = test::renderRib(rib, diag, settings, failed);
    return stats["frames"].empty() ? nlohmann::json() : stats["frames"][0];
}

std::string bytesOf(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

const char* kAovShader = R"(
surface aovs(output varying color diffusecol = 0; output varying float mask = 0;) {
    normal Nf = faceforward(normalize(N), I);
    diffusecol = Cs * diffuse(Nf);
    mask = s;
    Ci = Cs * diffusecol + 0.1;
    Oi = 0.8;
}
)";

/// 140 x 130 pixels (4 full strips and one of 2 rows; planes of 64 KiB and
/// more are the film's own mappings, whose rows a stream gives back),
/// spheres partly transparent over one another, with `displays` and
/// `extra` options.
std::string frameRib(const ScratchDir& dir, const std::string& displays, const std::string& extra = "") {
    return fmt::format(R"(
Option "searchpath" "shader" ["{}:&"]
Format 140 130 1
PixelSamples 2 2
PixelFilter "gaussian" 2 2
{}
{}
Projection "perspective" "fov" 40
Translate 0 0 5
WorldBegin
LightSource "distantlight" 1 "from" [-1 1 -1] "to" [0 0 0]
Color [1 0.5 0.2]
Surface "aovs"
AttributeBegin
Translate -0.6 -0.4 0.5
Sphere 1 -1 1 360
AttributeEnd
Color [0.2 0.6 1]
AttributeBegin
Translate 0.5 0.6 0
Sphere 0.9 -0.9 0.9 360
AttributeEnd
WorldEnd
)",
                       dir.file(""), extra, displays);
}

/// Every form the TIFF writer has: 8-bit (deflate, parallel strips),
/// 16-bit LZW, float without compression, packbits, rgbaz and z, a
/// display's own filter, its own exposure, AOVs.
std::string manyForms(const ScratchDir& dir) {
    return fmt::format(R"(
Display "{0}" "file" "rgba"
Display "+{1}" "tiff" "rgb" "quantize" [0 65535 0 65535] "compression" "lzw"
Display "+{2}" "file" "rgbaz" "quantize" [0 0 0 0] "compression" "none"
Display "+{3}" "file" "z"
Display "+{4}" "file" "rgba" "filter" "box" "filterwidth" [1 1] "compression" "packbits"
Display "+{5}" "file" "rgb" "exposure" [1.5 2.2]
Display "+{6}" "file" "varying color diffusecol" "quantize" [0 0 0 0]
Display "+{7}" "file" "varying float mask"
Display "+{8}" "file" "rgba" "compression" "zip:6" "dither" [0.5]
)",
                       dir.file("a8.tif"), dir.file("b16.tif"), dir.file("cfloat.tif"), dir.file("z.tif"),
                       dir.file("box.tif"), dir.file("exposed.tif"), dir.file("diffuse.tif"), dir.file("mask.tif"),
                       dir.file("zip6.tif"));
}
const char* kManyFiles[] = {"a8.tif",      "b16.tif",     "cfloat.tif", "z.tif",   "box.tif",
                            "exposed.tif", "diffuse.tif", "mask.tif",   "zip6.tif"};

/// The rows held at one thread: buckets in scanline order, a strip freed
/// once the bucket row covering its last row ends; sampled as each bucket
/// ends, before it frees anything.
int rowsHeldAtOneThread(int height, int bucket) {
    int peak = 0;
    for (int k = 0; k * bucket < height; ++k) {
        const int resolved = std::min((k + 1) * bucket, height);
        const int freed = (k * bucket) / kStripRows * kStripRows;
        peak = std::max(peak, resolved - freed);
    }
    return peak;
}

void setSourceDate() { ::setenv("SOURCE_DATE_EPOCH", "1700000000", 1); }

/// Renders `rib` whole-film into `reference/` and streamed at 1, 2 and 3
/// threads and 16 and 24 pixel buckets; every file must be the reference's
/// bytes. The scene's files are named relative to `dir`, moved aside.
void expectStreamedEqualsWhole(const ScratchDir& dir, const std::string& rib, const std::vector<std::string>& files,
                               int height) {
    setSourceDate();
    Diagnostics diag;
    diag.setQuiet(true);
    diag.setRecord(true);
    int failed = -1;
    const nlohmann::json whole = renderFrame(rib, false, 2, 16, diag, &failed);
    ASSERT_EQ(diag.errorCount(), 0);
    ASSERT_EQ(failed, 0);
    EXPECT_FALSE(whole["film_streamed"].get<bool>());
    EXPECT_EQ(whole["film_rows_held_peak"].get<int>(), height);
    std::map<std::string, std::string> reference;
    for (const std::string& f : files) {
        reference[f] = bytesOf(dir.file(f));
        ASSERT_GT(reference[f].size(), 100u) << f;
        fs::remove(dir.file(f));
    }
    for (int threads : {1, 2, 3}) {
        for (int bucket : {16, 24}) {
            SCOPED_TRACE(fmt::format("{} threads, {} px buckets", threads, bucket));
            const nlohmann::json streamed = renderFrame(rib, true, threads, bucket, diag, &failed);
            EXPECT_EQ(diag.errorCount(), 0);
            EXPECT_EQ(failed, 0);
            EXPECT_TRUE(streamed["film_streamed"].get<bool>());
            const int held = streamed["film_rows_held_peak"].get<int>();
            if (threads == 1) {
                EXPECT_EQ(held, rowsHeldAtOneThread(height, bucket));
            }
            EXPECT_GT(held, 0);
            EXPECT_LE(held, height);
            for (const std::string& f : files) {
                EXPECT_TRUE(bytesOf(dir.file(f)) == reference[f]) << f << " differs from the whole-film file";
                fs::remove(dir.file(f));
            }
            for (const auto& e : fs::directory_iterator(dir.file("")))
                EXPECT_EQ(e.path().filename().string().find("umbra-tmp"), std::string::npos) << e.path();
        }
    }
    ::unsetenv("SOURCE_DATE_EPOCH");
}

}  // namespace

TEST(FilmStream, EveryTiffFormIsTheWholeFilmsBytesAtAnyThreadsAndBucketSize) {
    ScratchDir dir("film-stream-forms");
    std::ofstream(dir.file("aovs.sl")) << kAovShader;
    expectStreamedEqualsWhole(dir, frameRib(dir, manyForms(dir)),
                              std::vector<std::string>(std::begin(kManyFiles), std::end(kManyFiles)), 130);
    // The AOV files hold what the shader wrote (not an empty plane).
    Diagnostics diag;
    diag.setQuiet(true);
    renderFrame(frameRib(dir, manyForms(dir)), true, 2, 16, diag);
    EXPECT_EQ(diag.errorCount(), 0);
    Image diffuse;
    ASSERT_TRUE(test::readImage(dir.file("diffuse.tif"), &diffuse));
    EXPECT_GT(diffuse.channelSum(0), 10.0);
}

TEST(FilmStream, ACropWindowStreamsItsOwnRows) {
    // Rows 39..110 of 130 and columns 14..118: the strips are the crop
    // region's, its first row strip row 0, and buckets start at its corner.
    ScratchDir dir("film-stream-crop");
    std::ofstream(dir.file("aovs.sl")) << kAovShader;
    const std::string displays = fmt::format(R"(
Display "{}" "file" "rgba"
Display "+{}" "file" "rgbaz" "quantize" [0 0 0 0]
Display "+{}" "file" "varying float mask" "quantize" [0 65535 0 65535]
)",
                                             dir.file("crop.tif"), dir.file("cropz.tif"), dir.file("cropmask.tif"));
    const std::string rib = frameRib(dir, displays, "CropWindow 0.1 0.85 0.3 0.85");
    expectStreamedEqualsWhole(dir, rib, {"crop.tif", "cropz.tif", "cropmask.tif"}, 111 - 39);
}

TEST(FilmStream, ADepthFramesZTiffStreamsWithEmptyBucketsAtInfinity) {
    // A frame of "z" displays only is a depth pass: buckets no primitive
    // reaches are never sampled, and a streamed film sets their depths.
    ScratchDir dir("film-stream-depth");
    std::ofstream(dir.file("aovs.sl")) << kAovShader;
    const std::string displays = fmt::format("Display \"{}\" \"file\" \"z\"\n", dir.file("depth.tif"));
    expectStreamedEqualsWhole(dir, frameRib(dir, displays), {"depth.tif"}, 130);
    // Streamed once more: the corner nothing covers is +infinity, the
    // spheres' centres are near (camera z about 4).
    Diagnostics diag;
    diag.setQuiet(true);
    renderFrame(frameRib(dir, displays), true, 1, 16, diag);
    Image depth;
    ASSERT_TRUE(test::readImage(dir.file("depth.tif"), &depth));
    ASSERT_EQ(depth.channels, 1);
    EXPECT_TRUE(std::isinf(depth.at(0, 0, 0)));
    EXPECT_TRUE(std::isinf(depth.at(139, 129, 0)));
    EXPECT_LT(depth.at(70, 65, 0), 5.0f);
}

TEST(FilmStream, ExrDisplaysAndImagersKeepTheWholeFilm) {
    ScratchDir dir("film-stream-fallback");
    std::ofstream(dir.file("aovs.sl")) << kAovShader;
    std::ofstream(dir.file("under.sl")) << "imager under(color bg = color(0, 0, 1)) {\n"
                                           "  Ci += (1 - alpha) * bg;\n"
                                           "  alpha = 1;\n"
                                           "}\n";
    setSourceDate();
    Diagnostics diag;
    diag.setQuiet(true);
    int failed = -1;
    // The TIFF alone, streamed: the reference.
    const std::string tiffOnly = fmt::format("Display \"{}\" \"file\" \"rgba\"\n", dir.file("t.tif"));
    EXPECT_TRUE(renderFrame(frameRib(dir, tiffOnly), true, 2, 16, diag, &failed)["film_streamed"].get<bool>());
    const std::string streamed = bytesOf(dir.file("t.tif"));
    ASSERT_FALSE(streamed.empty());
    // With an EXR beside it: the whole film, both written, the TIFF the same.
    const std::string withExr = tiffOnly + fmt::format("Display \"+{}\" \"openexr\" \"rgba\"\n", dir.file("e.exr"));
    nlohmann::json stats = renderFrame(frameRib(dir, withExr), true, 2, 16, diag, &failed);
    EXPECT_EQ(failed, 0);
    EXPECT_FALSE(stats["film_streamed"].get<bool>());
    EXPECT_EQ(stats["film_rows_held_peak"].get<int>(), 130);
    EXPECT_TRUE(bytesOf(dir.file("t.tif")) == streamed);
    Image exr;
    ASSERT_TRUE(test::readImage(dir.file("e.exr"), &exr));
    EXPECT_GT(exr.channelSum(0), 10.0);
    // With an imager: the whole film, imaged (alpha 1 everywhere).
    stats = renderFrame(frameRib(dir, tiffOnly, "Imager \"under\""), true, 2, 16, diag, &failed);
    EXPECT_EQ(failed, 0);
    EXPECT_FALSE(stats["film_streamed"].get<bool>());
    Image imaged;
    ASSERT_TRUE(test::readImage(dir.file("t.tif"), &imaged));
    ASSERT_EQ(imaged.channels, 4);
    for (int y = 0; y < imaged.height; ++y)
        for (int x = 0; x < imaged.width; ++x) ASSERT_NEAR(imaged.at(x, y, 3), 1.0f, 1e-6f) << x << "," << y;
    EXPECT_EQ(diag.errorCount(), 0);
    ::unsetenv("SOURCE_DATE_EPOCH");
}

TEST(FilmStream, AWriteThatFailsMidFrameLeavesNoTemporaryFileAndTheOldImage) {
    // A file size limit the first strip fits under and the whole image does
    // not (float rgba without compression: 140 x 32 x 16 = 71,680 bytes a
    // strip, 291,200 in all): the write fails mid-frame with EFBIG.
    ScratchDir dir("film-stream-fail");
    std::ofstream(dir.file("aovs.sl")) << kAovShader;
    const std::string old = "an earlier image, not to be touched";
    std::ofstream(dir.file("big.tif")) << old;
    const std::string displays = fmt::format(R"(
Display "{}" "file" "rgba" "quantize" [0 0 0 0] "compression" "none"
Display "+{}" "file" "rgba"
)",
                                             dir.file("big.tif"), dir.file("small.tif"));
    Diagnostics diag;
    diag.setQuiet(true);
    diag.setRecord(true);
    int failed = 0;
    rlimit saved{};
    ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &saved), 0);
    auto previous = std::signal(SIGXFSZ, SIG_IGN);  // EFBIG from write() instead of the signal
    rlimit limited = saved;
    limited.rlim_cur = 100000;
    ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &limited), 0);
    const nlohmann::json stats = renderFrame(frameRib(dir, displays), true, 1, 16, diag, &failed);
    ::setrlimit(RLIMIT_FSIZE, &saved);
    std::signal(SIGXFSZ, previous);
    EXPECT_TRUE(stats["film_streamed"].get<bool>());
    EXPECT_EQ(failed, 1);
    std::vector<std::string> errors;
    for (const Diagnostic& m : diag.recorded())
        if (m.severity == Severity::Error) errors.push_back(m.str());
    ASSERT_EQ(errors.size(), 1u);
    EXPECT_NE(errors[0].find("big.tif"), std::string::npos) << errors[0];
    EXPECT_EQ(bytesOf(dir.file("big.tif")), old);
    // The other display, within the limit, is written whole.
    Image small;
    ASSERT_TRUE(test::readImage(dir.file("small.tif"), &small));
    EXPECT_EQ(small.width, 140);
    for (const auto& e : fs::directory_iterator(dir.file("")))
        EXPECT_EQ(e.path().filename().string().find("umbra-tmp"), std::string::npos) << e.path();
}

TEST(FilmStream, TheCommandStreamsByDefaultAndNotWithNoFilmStream) {
    // `umbra render` streams a TIFF frame unless `--no-film-stream`; the
    // --stats record says which, and the two files are the same bytes.
    ScratchDir dir("film-stream-cli");
    std::ofstream(dir.file("aovs.sl")) << kAovShader;
    std::ofstream(dir.file("f.rib")) << frameRib(dir, fmt::format("Display \"{}\" \"file\" \"rgba\"\n", dir.file("f.tif")));
    const std::vector<std::string> env = {"SOURCE_DATE_EPOCH=1700000000"};
    test::ChildRun run = test::runIn(
        dir, UMBRA_APP, {"umbra", "render", "--threads", "2", "--quiet", "--stats", "s.json", "f.rib"}, env);
    ASSERT_EQ(run.status, 0) << run.messages;
    nlohmann::json stats = nlohmann::json::parse(test::readFile(dir.file("s.json")));
    EXPECT_TRUE(stats["frames"][0]["film_streamed"].get<bool>());
    const std::string streamed = bytesOf(dir.file("f.tif"));
    run = test::runIn(dir, UMBRA_APP,
                      {"umbra", "render", "--threads", "2", "--quiet", "--no-film-stream", "--stats", "s.json", "f.rib"},
                      env);
    ASSERT_EQ(run.status, 0) << run.messages;
    stats = nlohmann::json::parse(test::readFile(dir.file("s.json")));
    EXPECT_FALSE(stats["frames"][0]["film_streamed"].get<bool>());
    EXPECT_EQ(stats["frames"][0]["film_rows_held_peak"].get<int>(), 130);
    EXPECT_FALSE(streamed.empty());
    EXPECT_TRUE(bytesOf(dir.file("f.tif")) == streamed);
}
