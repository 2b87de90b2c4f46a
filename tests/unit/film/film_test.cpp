#include "umbra/film/film.h"

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <unistd.h>

using namespace umbra;
using umbra::film::Film;
using umbra::film::PixelFilter;

namespace fs = std::filesystem;

namespace {

/// A fresh, empty directory for one test's files.
fs::path testDir(const std::string& name) {
    fs::path d = fs::path(testing::TempDir()) / fmt::format("umbra_film_{}_{}", name, ::getpid());
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
}

scene::DisplayRecord display(const std::string& name, const std::string& driver, const std::string& mode) {
    scene::DisplayRecord d;
    d.name = name;
    d.driver = driver;
    d.mode = mode;
    d.loc = FileLoc::inFile("scene.rib", 12, 3);
    return d;
}

/// A film whose pixels hold a known pattern: r = x/w, g = y/h, b = 0.5, a = 1
/// (a = 0.25 at (0,0)), z = 1 + x + 10 y.
Film patternFilm(int xres, int yres, const float crop[4], std::vector<film::AovChannel> aovs = {}) {
    Film f(xres, yres, crop, PixelFilter(film::FilterKind::Box, 1, 1), std::move(aovs));
    for (int y = f.y0(); y < f.y1(); ++y)
        for (int x = f.x0(); x < f.x1(); ++x) {
            float* p = f.rgba(x, y);
            p[0] = float(x) / float(xres);
            p[1] = float(y) / float(yres);
            p[2] = 0.5f;
            p[3] = (x == f.x0() && y == f.y0()) ? 0.25f : 1.0f;
            f.z(x, y) = 1.0f + float(x) + 10.0f * float(y);
            for (int k = 0; k < f.aovFloats(); ++k) f.aov(x, y)[k] = float(k + 1) * 0.1f + float(x) * 0.01f;
        }
    return f;
}

struct ReadImage {
    OIIO::ImageSpec spec;
    std::vector<float> pixels;  // native integers converted to float as their integer values
    std::vector<float> normalised;
};

ReadImage readImage(const fs::path& p) {
    ReadImage r;
    auto in = OIIO::ImageInput::open(p.string());
    EXPECT_TRUE(in) << OIIO::geterror();
    if (!in) return r;
    r.spec = in->spec();
    size_t n = size_t(r.spec.width) * size_t(r.spec.height) * size_t(r.spec.nchannels);
    r.normalised.resize(n);
    EXPECT_TRUE(in->read_image(0, 0, 0, r.spec.nchannels, OIIO::TypeDesc::FLOAT, r.normalised.data()));
    r.pixels = r.normalised;
    if (r.spec.format == OIIO::TypeDesc::UINT8)
        for (float& v : r.pixels) v = std::round(v * 255.0f);
    if (r.spec.format == OIIO::TypeDesc::UINT16)
        for (float& v : r.pixels) v = std::round(v * 65535.0f);
    return r;
}

/// Diagnostics that record instead of printing.
struct QuietDiagnostics : Diagnostics {
    QuietDiagnostics() {
        setRecord(true);
        setSink([](const Diagnostic&) {});
    }
};

const float kFull[4] = {0, 1, 0, 1};

}  // namespace

TEST(Film, CropWindowSelectsPixelsAsTheSpecRounds) {
    // RI Spec 3.2, CropWindow: columns ceil(xres * xmin) to
    // ceil(xres * xmax - 1) inclusive, rows likewise (x1, y1 here are one
    // past the last). umbra selected pixels by centre: 0.24-0.76 of 10
    // columns gave 2..7 where the spec, Pixie and Aqsis give 3..7.
    int x0, x1, y0, y1;
    const float crop[4] = {0.25f, 0.75f, 0.1f, 0.5f};
    Film::cropPixels(640, 15, crop, &x0, &x1, &y0, &y1);
    EXPECT_EQ(x0, 160);  // ceil(160)
    EXPECT_EQ(x1, 480);  // ceil(480 - 1) = 479 is the last
    EXPECT_EQ(y0, 2);    // ceil(1.5)
    EXPECT_EQ(y1, 8);    // ceil(7.5 - 1) = 7 is the last
    const float midPixel[4] = {0.24f, 0.76f, 0.05f, 0.95f};
    Film::cropPixels(10, 10, midPixel, &x0, &x1, &y0, &y1);
    EXPECT_EQ(std::vector<int>({x0, x1, y0, y1}), std::vector<int>({3, 8, 1, 10}));
    const float odd[4] = {0.13f, 0.71f, 0.27f, 0.93f};
    Film::cropPixels(37, 23, odd, &x0, &x1, &y0, &y1);
    EXPECT_EQ(std::vector<int>({x0, x1, y0, y1}), std::vector<int>({5, 27, 7, 22}));  // 22 x 15 at (5, 7)
    Film::cropPixels(640, 480, kFull, &x0, &x1, &y0, &y1);
    EXPECT_EQ(x0, 0);
    EXPECT_EQ(x1, 640);
    EXPECT_EQ(y1, 480);
    Film f(640, 15, crop, PixelFilter(film::FilterKind::Box, 1, 1));
    EXPECT_EQ(f.width(), 320);
    EXPECT_EQ(f.height(), 6);
    EXPECT_TRUE(f.contains(160, 2));
    EXPECT_FALSE(f.contains(159, 2));
    EXPECT_FALSE(f.contains(160, 1));
    EXPECT_EQ(f.z(200, 3), kInfinity);
}

TEST(Film, DisplayModes) {
    film::DisplayMode m;
    std::string err;
    ASSERT_TRUE(film::parseDisplayMode("rgbaz", &m, &err));
    EXPECT_EQ(m.standard, "rgbaz");
    EXPECT_FALSE(m.isAov());
    ASSERT_TRUE(film::parseDisplayMode("color myaov", &m, &err));
    EXPECT_EQ(m.aovName, "myaov");
    EXPECT_EQ(m.aovComponents, 3);
    ASSERT_TRUE(film::parseDisplayMode("varying float foo", &m, &err));
    EXPECT_EQ(m.aovName, "foo");
    EXPECT_EQ(m.aovComponents, 1);
    ASSERT_TRUE(film::parseDisplayMode("N", &m, &err));
    EXPECT_EQ(m.aovComponents, 3);
    EXPECT_FALSE(film::parseDisplayMode("rgbb", &m, &err));
    EXPECT_EQ(err, "display mode \"rgbb\" repeats a channel");
    EXPECT_FALSE(film::parseDisplayMode("string s", &m, &err));
    EXPECT_EQ(err, "display mode \"string s\": unsupported AOV type \"string\" (expected float, color, point, vector "
                   "or normal)");
    EXPECT_FALSE(film::parseDisplayMode("myaov", &m, &err));

    std::vector<scene::DisplayRecord> ds = {display("a.tif", "file", "rgba"), display("b.exr", "openexr", "color diff"),
                                            display("c.exr", "openexr", "float depth"),
                                            display("d.exr", "openexr", "color diff"), display("e.exr", "exr", "N")};
    std::vector<film::AovChannel> aovs = film::aovChannelsFor(ds);
    ASSERT_EQ(aovs.size(), 3u);
    EXPECT_EQ(aovs[0].name, "diff");
    EXPECT_EQ(aovs[0].components, 3);
    EXPECT_EQ(aovs[1].name, "depth");
    EXPECT_EQ(aovs[1].components, 1);
    EXPECT_EQ(aovs[2].name, "N");
    Film f(4, 4, kFull, PixelFilter(film::FilterKind::Box, 1, 1), aovs);
    EXPECT_EQ(f.aovFloats(), 7);
    EXPECT_EQ(f.findAov("N"), 2);
    EXPECT_EQ(f.aovOffset(2), 4);
    EXPECT_EQ(f.findAov("nope"), -1);
}

TEST(Film, TiffRoundTripQuantised) {
    fs::path dir = testDir("tiff");
    const float crop[4] = {0.25f, 0.75f, 0, 1};
    Film f = patternFilm(16, 8, crop);
    scene::Options o;
    o.quantizeDither = 0;
    QuietDiagnostics diag;
    film::OutputMetadata meta;
    meta.renderSeconds = 1.5;
    meta.dateTime = "2024:01:02 03:04:05";
    ASSERT_TRUE(f.writeDisplay(display((dir / "out.tif").string(), "tiff", "rgba"), o, meta, diag));
    EXPECT_EQ(diag.errorCount(), 0);
    ReadImage r = readImage(dir / "out.tif");
    ASSERT_EQ(r.spec.width, 8);
    ASSERT_EQ(r.spec.height, 8);
    ASSERT_EQ(r.spec.nchannels, 4);
    EXPECT_EQ(r.spec.format, OIIO::TypeDesc::UINT8);
    EXPECT_EQ(r.spec.x, 4);
    EXPECT_EQ(r.spec.alpha_channel, 3);
    EXPECT_EQ(r.spec.get_string_attribute("Software"), "umbra 0.1");
    EXPECT_EQ(r.spec.get_string_attribute("DateTime"), "2024:01:02 03:04:05");
    for (int y = 0; y < 8; ++y)
        for (int x = 4; x < 12; ++x) {
            const float* p = &r.pixels[size_t((y * 8 + (x - 4)) * 4)];
            EXPECT_EQ(p[0], std::round(255.0f * float(x) / 16.0f));
            EXPECT_EQ(p[1], std::round(255.0f * float(y) / 8.0f));
            EXPECT_EQ(p[2], 128.0f);  // round(127.5)
            EXPECT_EQ(p[3], (x == 4 && y == 0) ? 64.0f : 255.0f);
        }
    // Only the image: no temporary file is left.
    EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
}

// TIFF takes its rows from the film strip by strip (no converted copy of
// the frame): an image of several 32-row strips, through both the parallel
// deflate path and libtiff's own encoder, holds every pixel's value.
TEST(Film, TiffManyStripsBothEncoders) {
    fs::path dir = testDir("tiffstrips");
    const float crop[4] = {0, 1, 0.1f, 1};
    Film f = patternFilm(24, 100, crop);  // rows 10..99: 90 rows, 3 strips
    ASSERT_EQ(f.y0(), 10);
    scene::Options o;
    o.quantizeDither = 0;
    for (const char* compression : {"", "none", "lzw"}) {
        QuietDiagnostics diag;
        scene::DisplayRecord d = display((dir / "out.tif").string(), "tiff", "rgba");
        if (*compression) {
            ri::Param p;
            p.decl.name = "compression";
            p.decl.type = ri::ParamType::String;
            p.strings = {compression};
            d.params.add(p);
        }
        ASSERT_TRUE(f.writeDisplay(d, o, {}, diag)) << compression;
        ReadImage r = readImage(dir / "out.tif");
        ASSERT_EQ(r.spec.width, 24);
        ASSERT_EQ(r.spec.height, 90);
        ASSERT_EQ(r.spec.nchannels, 4);
        EXPECT_EQ(r.spec.format, OIIO::TypeDesc::UINT8);
        for (int y = 10; y < 100; ++y)
            for (int x = 0; x < 24; ++x) {
                const float* p = &r.pixels[size_t(((y - 10) * 24 + x) * 4)];
                EXPECT_EQ(p[0], std::round(255.0f * float(x) / 24.0f)) << compression << " " << x << "," << y;
                EXPECT_EQ(p[1], std::round(255.0f * float(y) / 100.0f)) << compression << " " << x << "," << y;
                EXPECT_EQ(p[2], 128.0f);
                EXPECT_EQ(p[3], (x == 0 && y == 10) ? 64.0f : 255.0f);
            }
    }
    // Floating point (z is not quantised, so "rgbaz" is written as float).
    QuietDiagnostics diag;
    ASSERT_TRUE(f.writeDisplay(display((dir / "float.tif").string(), "tiff", "rgbaz"), o, {}, diag));
    ReadImage r = readImage(dir / "float.tif");
    ASSERT_EQ(r.spec.nchannels, 5);
    EXPECT_EQ(r.spec.format, OIIO::TypeDesc::FLOAT);
    for (int y = 10; y < 100; ++y)
        for (int x = 0; x < 24; ++x) {
            const float* p = &r.pixels[size_t(((y - 10) * 24 + x) * 5)];
            EXPECT_EQ(p[0], float(x) / 24.0f);
            EXPECT_EQ(p[1], float(y) / 100.0f);
            EXPECT_EQ(p[4], 1.0f + float(x) + 10.0f * float(y));
        }
}

// A colour film made without depth (no display reads it) holds 16 bytes a
// pixel, writes rgba as a film with depth does, and refuses displays that
// read depth instead of reading memory it does not have.
TEST(Film, ColourOnlyFilmHasNoDepth) {
    EXPECT_EQ(Film::bytesFor(8, 4, kFull, {}, film::FilmContent::ColourOnly), 8u * 4u * 16u);
    EXPECT_EQ(Film::bytesFor(8, 4, kFull, {}, film::FilmContent::Colour), 8u * 4u * 20u);
    fs::path dir = testDir("colouronly");
    Film with = patternFilm(8, 4, kFull);
    Film without(8, 4, kFull, PixelFilter(film::FilterKind::Box, 1, 1), {}, film::FilmContent::ColourOnly);
    EXPECT_FALSE(without.hasDepth());
    EXPECT_TRUE(with.hasDepth());
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 8; ++x) std::copy_n(with.rgba(x, y), 4, without.rgba(x, y));
    scene::Options o;
    QuietDiagnostics diag;
    ASSERT_TRUE(with.writeDisplay(display((dir / "a.tif").string(), "tiff", "rgba"), o, {}, diag));
    ASSERT_TRUE(without.writeDisplay(display((dir / "b.tif").string(), "tiff", "rgba"), o, {}, diag));
    EXPECT_EQ(readImage(dir / "a.tif").pixels, readImage(dir / "b.tif").pixels);
    EXPECT_FALSE(without.writeDisplay(display((dir / "c.tif").string(), "tiff", "rgbaz"), o, {}, diag));
    film::DepthWriter hook = [](const scene::DisplayRecord&, const Film&) { return true; };
    EXPECT_FALSE(without.writeDisplay(display((dir / "d.z").string(), "zfile", "z"), o, {}, diag, hook));
    EXPECT_EQ(diag.errorCount(), 2);
    EXPECT_FALSE(fs::exists(dir / "c.tif"));
}

TEST(Film, ExrRoundTripWithDepthAndMatrices) {
    fs::path dir = testDir("exr");
    const float crop[4] = {0, 1, 0.5f, 1};
    Film f = patternFilm(8, 8, crop);
    scene::Options o;
    QuietDiagnostics diag;
    film::OutputMetadata meta;
    meta.renderSeconds = 2.25;
    meta.cameraFromWorld = Mat4::translate({1, 2, 3});
    meta.ndcFromWorld = Mat4::scale({2, 3, 4});
    ASSERT_TRUE(f.writeDisplay(display((dir / "out.exr").string(), "openexr", "rgbaz"), o, meta, diag));
    ReadImage r = readImage(dir / "out.exr");
    ASSERT_EQ(r.spec.nchannels, 5);
    EXPECT_EQ(r.spec.y, 4);
    EXPECT_EQ(r.spec.full_height, 8);
    EXPECT_EQ(r.spec.channelformat(0), OIIO::TypeDesc::HALF);
    EXPECT_EQ(r.spec.channelformat(4), OIIO::TypeDesc::FLOAT);
    EXPECT_EQ(r.spec.get_string_attribute("umbra:rendertime"), "2.250");
    EXPECT_EQ(r.spec.get_string_attribute("Software"), "umbra 0.1");
    for (int y = 4; y < 8; ++y)
        for (int x = 0; x < 8; ++x) {
            const float* p = &r.pixels[size_t(((y - 4) * 8 + x) * 5)];
            EXPECT_NEAR(p[0], float(x) / 8.0f, 1e-3f);  // half precision
            EXPECT_NEAR(p[1], float(y) / 8.0f, 1e-3f);
            EXPECT_EQ(p[4], 1.0f + float(x) + 10.0f * float(y));  // float z is exact
        }
    const OIIO::ParamValue* m = r.spec.find_attribute("worldtocamera", OIIO::TypeMatrix);
    ASSERT_NE(m, nullptr);
    const float* mv = static_cast<const float*>(m->data());
    float expect[16];
    meta.cameraFromWorld->toRib(expect);  // row-vector order: translation in the last row
    for (int i = 0; i < 16; ++i) EXPECT_EQ(mv[i], expect[i]);
    EXPECT_EQ(mv[12], 1.0f);
    EXPECT_NE(r.spec.find_attribute("worldToNDC", OIIO::TypeMatrix), nullptr);

    // "string type" "float": full precision colour.
    scene::DisplayRecord fd = display((dir / "f.exr").string(), "exr", "rgb");
    ri::Param type;
    type.decl.name = "type";
    type.decl.type = ri::ParamType::String;
    type.strings = {"float"};
    fd.params.add(type);
    ASSERT_TRUE(f.writeDisplay(fd, o, meta, diag));
    ReadImage rf = readImage(dir / "f.exr");
    EXPECT_EQ(rf.spec.format, OIIO::TypeDesc::FLOAT);
    EXPECT_EQ(rf.pixels[size_t((0 * 8 + 3) * 3)], 3.0f / 8.0f);
    EXPECT_EQ(diag.errorCount(), 0);
}

TEST(Film, PngAndFloatTiffAndExposure) {
    fs::path dir = testDir("png");
    Film f = patternFilm(6, 4, kFull);
    scene::Options o;
    o.quantizeDither = 0;
    o.exposureGain = 2.0f;
    o.exposureGamma = 2.0f;
    QuietDiagnostics diag;
    ASSERT_TRUE(f.writeDisplay(display((dir / "a.png").string(), "file", "rgb"), o, {}, diag));
    ReadImage r = readImage(dir / "a.png");
    ASSERT_EQ(r.spec.nchannels, 3);
    EXPECT_EQ(r.spec.format, OIIO::TypeDesc::UINT8);
    for (int x = 0; x < 6; ++x) {
        float v = std::sqrt(2.0f * float(x) / 6.0f);  // (gain c)^(1/gamma)
        EXPECT_EQ(r.pixels[size_t((2 * 6 + x) * 3)], std::min(255.0f, std::round(255.0f * v)));
    }
    // Quantize one = 0: floating-point TIFF, exposure still applied to colour only.
    o.quantizeOne = 0;
    ASSERT_TRUE(f.writeDisplay(display((dir / "b.tif").string(), "file", "rgba"), o, {}, diag));
    ReadImage t = readImage(dir / "b.tif");
    EXPECT_EQ(t.spec.format, OIIO::TypeDesc::FLOAT);
    EXPECT_FLOAT_EQ(t.pixels[size_t((1 * 6 + 5) * 4)], std::sqrt(2.0f * 5.0f / 6.0f));
    EXPECT_EQ(t.pixels[size_t(3)], 0.25f);  // alpha: no exposure
    // 16-bit quantisation by a display's own "quantize".
    scene::DisplayRecord d16 = display((dir / "c.tif").string(), "tiff", "a");
    ri::Param q;
    q.decl.name = "quantize";
    q.decl.type = ri::ParamType::Integer;
    q.decl.arraySize = 4;
    q.ints = {0, 65535, 0, 65535};
    d16.params.add(q);
    ASSERT_TRUE(f.writeDisplay(d16, o, {}, diag));
    ReadImage t16 = readImage(dir / "c.tif");
    EXPECT_EQ(t16.spec.format, OIIO::TypeDesc::UINT16);
    EXPECT_EQ(t16.pixels[0], std::round(0.25f * 65535.0f));
    EXPECT_EQ(diag.errorCount(), 0);
}

TEST(Film, DitherPreservesTheMean) {
    fs::path dir = testDir("dither");
    Film f(64, 64, kFull, PixelFilter(film::FilterKind::Box, 1, 1));
    const float v = 76.3f / 255.0f;
    for (int y = 0; y < 64; ++y)
        for (int x = 0; x < 64; ++x) f.rgba(x, y)[0] = v;
    scene::Options o;  // RenderMan's default: one 255, dither 0.5
    QuietDiagnostics diag;
    ASSERT_TRUE(f.writeDisplay(display((dir / "d.tif").string(), "tiff", "r"), o, {}, diag));
    ReadImage r = readImage(dir / "d.tif");
    double sum = 0;
    int lo = 0, hi = 0;
    for (float p : r.pixels) {
        sum += p;
        lo += p == 76.0f;
        hi += p == 77.0f;
    }
    EXPECT_EQ(lo + hi, 64 * 64);  // only the two neighbouring levels
    EXPECT_NEAR(sum / (64 * 64), 76.3, 0.03);
    EXPECT_GT(hi, 64 * 64 / 5);
    // Without dither every pixel rounds down: the mean is off by 0.3.
    o.quantizeDither = 0;
    ASSERT_TRUE(f.writeDisplay(display((dir / "e.tif").string(), "tiff", "r"), o, {}, diag));
    ReadImage r0 = readImage(dir / "e.tif");
    for (float p : r0.pixels) ASSERT_EQ(p, 76.0f);
    // Dither is deterministic.
    ASSERT_TRUE(f.writeDisplay(display((dir / "d2.tif").string(), "tiff", "r"), scene::Options{}, {}, diag));
    EXPECT_EQ(readImage(dir / "d2.tif").pixels, r.pixels);
}

TEST(Film, AovDisplays) {
    fs::path dir = testDir("aov");
    Film f = patternFilm(4, 4, kFull, {{"diff", 3}, {"depth", 1}});
    scene::Options o;
    o.quantizeOne = 0;
    QuietDiagnostics diag;
    ASSERT_TRUE(f.writeDisplay(display((dir / "diff.exr").string(), "openexr", "color diff"), o, {}, diag));
    ASSERT_TRUE(f.writeDisplay(display((dir / "depth.exr").string(), "openexr", "float depth"), o, {}, diag));
    ReadImage d = readImage(dir / "diff.exr");
    ASSERT_EQ(d.spec.nchannels, 3);
    EXPECT_EQ(d.spec.channelnames[0], "R");
    EXPECT_NEAR(d.pixels[size_t((1 * 4 + 2) * 3 + 1)], 0.2f + 0.02f, 1e-3f);
    ReadImage z = readImage(dir / "depth.exr");
    ASSERT_EQ(z.spec.nchannels, 1);
    EXPECT_EQ(z.spec.channelnames[0], "depth");
    EXPECT_NEAR(z.pixels[size_t(3 * 4 + 3)], 0.4f + 0.03f, 1e-3f);
    // A mode for an AOV the film does not hold.
    EXPECT_FALSE(f.writeDisplay(display((dir / "x.exr").string(), "openexr", "color spec"), o, {}, diag));
    ASSERT_EQ(diag.recorded().back().str(),
              "scene.rib:12:3: error: display \"" + (dir / "x.exr").string() +
                  "\": AOV \"spec\" was not rendered (the film has no such channel)");
}

TEST(Film, ErrorsLeaveNoFiles) {
    fs::path dir = testDir("errors");
    Film f = patternFilm(4, 4, kFull);
    scene::Options o;
    QuietDiagnostics diag;
    // Missing directory.
    std::string missing = (dir / "nodir" / "out.tif").string();
    EXPECT_FALSE(f.writeDisplay(display(missing, "tiff", "rgba"), o, {}, diag));
    ASSERT_EQ(diag.errorCount(), 1);
    EXPECT_EQ(diag.recorded().back().loc.str(), "scene.rib:12:3");
    EXPECT_NE(diag.recorded().back().message.find("cannot write \"" + missing + "\""), std::string::npos);
    // The target is a directory: the file is written, the rename fails, and
    // the temporary file is removed.
    fs::create_directories(dir / "taken.tif" / "inside");
    EXPECT_FALSE(f.writeDisplay(display((dir / "taken.tif").string(), "tiff", "rgba"), o, {}, diag));
    EXPECT_EQ(diag.errorCount(), 2);
    // An unknown mode.
    EXPECT_FALSE(f.writeDisplay(display((dir / "a.tif").string(), "tiff", "rgbq"), o, {}, diag));
    EXPECT_EQ(diag.errorCount(), 3);
    // A driver umbra does not have ("it", PRMan's viewer) is a warning: the
    // image goes to the file the "file" driver would write.
    const int warnings = diag.warningCount();
    EXPECT_TRUE(f.writeDisplay(display((dir / "viewer").string(), "it", "rgba"), o, {}, diag));
    EXPECT_EQ(diag.errorCount(), 3);
    EXPECT_EQ(diag.warningCount(), warnings + 1);
    EXPECT_EQ(diag.recorded().back().str(), "scene.rib:12:3: warning: display driver \"it\": umbra has no window; "
                                            "writing \"" + (dir / "viewer.tif").string() + "\" instead");
    ASSERT_TRUE(fs::exists(dir / "viewer.tif"));
    fs::remove(dir / "viewer.tif");
    // Nothing but the directory made above.
    std::vector<std::string> left;
    for (const auto& e : fs::directory_iterator(dir)) left.push_back(e.path().filename().string());
    ASSERT_EQ(left.size(), 1u);
    EXPECT_EQ(left[0], "taken.tif");
}

TEST(Film, DepthDriversUseTheHook) {
    Film f = patternFilm(4, 4, kFull);
    scene::Options o;
    QuietDiagnostics diag;
    std::vector<std::string> called;
    film::DepthWriter hook = [&](const scene::DisplayRecord& d, const Film& film) {
        called.push_back(d.name + ":" + d.driver);
        EXPECT_EQ(&film, &f);
        return true;
    };
    std::vector<scene::DisplayRecord> ds = {display("a.shd", "shadow", "z"), display("b.zfile", "zfile", "z")};
    EXPECT_TRUE(f.write(ds, o, {}, diag, hook));
    ASSERT_EQ(called.size(), 2u);
    EXPECT_EQ(called[1], "b.zfile:zfile");
    EXPECT_FALSE(f.write(ds, o, {}, diag));  // no hook: an error per display
    EXPECT_EQ(diag.errorCount(), 2);
}

TEST(Film, FramebufferWritesAFile) {
    fs::path dir = testDir("fb");
    Film f = patternFilm(4, 4, kFull);
    QuietDiagnostics diag;
    ASSERT_TRUE(f.writeDisplay(display((dir / "preview").string(), "framebuffer", "rgb"), scene::Options{}, {}, diag));
    EXPECT_TRUE(fs::exists(dir / "preview.tif"));
    EXPECT_EQ(diag.warningCount(), 1);
}

// A light's depth film whose depths start unset: buckets that wrote give
// the window, empty buckets inside it become +infinity, both layers.
TEST(Film, UnsetDepthsSettleToTheWindowTheBucketsWrote) {
    Film f(64, 64, kFull, PixelFilter(film::FilterKind::Box, 1, 1), {}, film::FilmContent::DepthPair,
           Film::DepthStart::Unset);
    auto written = [](int bx, int by) { return (bx == 1 && by == 1) || (bx == 2 && by == 2); };
    for (int by = 0; by < 4; ++by)
        for (int bx = 0; bx < 4; ++bx) {
            const int x0 = 16 * bx, y0 = 16 * by;
            if (!written(bx, by)) {
                f.clearDepth(x0, y0, x0 + 16, y0 + 16);
                continue;
            }
            for (int y = y0; y < y0 + 16; ++y)
                for (int x = x0; x < x0 + 16; ++x) {
                    f.z(x, y) = 1.0f + float(x);
                    f.z2(x, y) = 2.0f + float(y);
                }
            f.depthWritten(x0, y0, x0 + 16, y0 + 16);
        }
    const Film::DepthWindow w = f.settleDepth();
    EXPECT_EQ(w.x0, 16);
    EXPECT_EQ(w.y0, 16);
    EXPECT_EQ(w.x1, 48);
    EXPECT_EQ(w.y1, 48);
    for (int y = w.y0; y < w.y1; ++y)
        for (int x = w.x0; x < w.x1; ++x) {
            const bool wrote = written(x / 16, y / 16);
            ASSERT_EQ(f.z(x, y), wrote ? 1.0f + float(x) : kInfinity) << x << " " << y;
            ASSERT_EQ(f.z2(x, y), wrote ? 2.0f + float(y) : kInfinity) << x << " " << y;
        }
    // A film whose depths start at +infinity: its whole crop region.
    Film g(8, 6, kFull, PixelFilter(film::FilterKind::Box, 1, 1), {}, film::FilmContent::Depth);
    const Film::DepthWindow all = g.settleDepth();
    EXPECT_EQ(all.x1 - all.x0, 8);
    EXPECT_EQ(all.y1 - all.y0, 6);
    EXPECT_EQ(g.z(7, 5), kInfinity);
}
