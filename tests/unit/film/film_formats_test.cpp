// The film's own EXR/TIFF/PNG writers, checked against independent readers:
// OpenImageIO (as every downstream tool reads the files), and the formats'
// libraries directly for what OIIO hides (EXR attribute types, TIFF tags).

#include "umbra/film/film.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfMatrixAttribute.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <tiffio.h>

#include <cmath>
#include <filesystem>
#include <unistd.h>

using namespace umbra;
using umbra::film::Film;
using umbra::film::PixelFilter;

namespace fs = std::filesystem;

namespace {

fs::path freshDir(const std::string& name) {
    fs::path d = fs::path(testing::TempDir()) / fmt::format("umbra_film_formats_{}_{}", name, ::getpid());
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
}

scene::DisplayRecord display(const fs::path& name, const std::string& driver, const std::string& mode) {
    scene::DisplayRecord d;
    d.name = name.string();
    d.driver = driver;
    d.mode = mode;
    d.loc = FileLoc::inFile("frame.rib", 7, 1);
    return d;
}

void addString(scene::DisplayRecord& d, const std::string& name, const std::string& value) {
    ri::Param p;
    p.decl.name = name;
    p.decl.type = ri::ParamType::String;
    p.strings = {value};
    d.params.add(p);
}

void addInts(scene::DisplayRecord& d, const std::string& name, std::vector<int> values) {
    ri::Param p;
    p.decl.name = name;
    p.decl.type = ri::ParamType::Integer;
    p.decl.arraySize = int(values.size());
    p.ints = std::move(values);
    d.params.add(p);
}

struct QuietDiagnostics : Diagnostics {
    QuietDiagnostics() {
        setRecord(true);
        setSink([](const Diagnostic&) {});
    }
};

/// Values that no format rounds by accident: r = (x + 1) / 7, g = (y + 1) / 9,
/// b = 0.3, a = 0.5 except 1 at odd x and 0 at (x0, y0) (where colour stays
/// 0.3: glow without coverage); z = 2 + x + 100 y, +infinity at (x1-1, y0).
/// AOV float k = 0.125 (k + 1) + x / 16 + y / 1024.
Film knownFilm(int xres, int yres, const float crop[4], std::vector<film::AovChannel> aovs = {}) {
    Film f(xres, yres, crop, PixelFilter(film::FilterKind::Box, 1, 1), std::move(aovs));
    for (int y = f.y0(); y < f.y1(); ++y)
        for (int x = f.x0(); x < f.x1(); ++x) {
            float* p = f.rgba(x, y);
            p[3] = (x == f.x0() && y == f.y0()) ? 0.0f : (x % 2 ? 1.0f : 0.5f);
            p[0] = float(x + 1) / 7.0f;
            p[1] = float(y + 1) / 9.0f;
            p[2] = 0.3f;
            f.z(x, y) = (x == f.x1() - 1 && y == f.y0()) ? kInfinity : 2.0f + float(x) + 100.0f * float(y);
            for (int k = 0; k < f.aovFloats(); ++k)
                f.aov(x, y)[k] = 0.125f * float(k + 1) + float(x) / 16.0f + float(y) / 1024.0f;
        }
    return f;
}

struct ReadBack {
    OIIO::ImageSpec spec;
    std::vector<float> values;  // integers as their integer values, floats as stored
    const float* at(int px, int py) const {
        return &values[(size_t(py - spec.y) * size_t(spec.width) + size_t(px - spec.x)) * size_t(spec.nchannels)];
    }
};

/// Reads through OIIO; `straightAlpha` keeps PNG's alpha unassociated (OIIO
/// premultiplies by default).
ReadBack readBack(const fs::path& p, bool straightAlpha = false) {
    ReadBack r;
    OIIO::ImageSpec config;
    if (straightAlpha) config.attribute("oiio:UnassociatedAlpha", 1);
    auto in = OIIO::ImageInput::open(p.string(), &config);
    EXPECT_TRUE(in) << OIIO::geterror();
    if (!in) return r;
    r.spec = in->spec();
    r.values.resize(size_t(r.spec.width) * size_t(r.spec.height) * size_t(r.spec.nchannels));
    EXPECT_TRUE(in->read_image(0, 0, 0, r.spec.nchannels, OIIO::TypeDesc::FLOAT, r.values.data()));
    float scale = r.spec.format == OIIO::TypeDesc::UINT8    ? 255.0f
                  : r.spec.format == OIIO::TypeDesc::UINT16 ? 65535.0f
                                                            : 0.0f;
    if (scale != 0)
        for (float& v : r.values) v = std::round(v * scale);
    return r;
}

float q16(float v) { return float(std::lround(65535.0 * double(v))); }

const float kFull[4] = {0, 1, 0, 1};

}  // namespace

TEST(FilmFormats, FloatTiffRoundTripWithCropAndDepth) {
    fs::path dir = freshDir("ftiff");
    const float crop[4] = {0.25f, 1.0f, 0.5f, 1.0f};  // pixels x 3..11, y 3..5
    Film f = knownFilm(12, 6, crop);
    scene::Options o;
    o.quantizeOne = 0;
    o.zQuantizeOne = 0;
    QuietDiagnostics diag;
    film::OutputMetadata meta;
    meta.cameraFromWorld = Mat4::translate({4, 5, 6});
    meta.ndcFromWorld = Mat4::scale({0.5f, 0.25f, 1});
    ASSERT_TRUE(f.writeDisplay(display(dir / "f.tif", "tiff", "rgbaz"), o, meta, diag));
    EXPECT_EQ(diag.errorCount(), 0);

    ReadBack r = readBack(dir / "f.tif");
    ASSERT_EQ(r.spec.nchannels, 5);
    EXPECT_EQ(r.spec.format, OIIO::TypeDesc::FLOAT);
    EXPECT_EQ(r.spec.x, 3);
    EXPECT_EQ(r.spec.y, 3);
    EXPECT_EQ(r.spec.width, 9);
    EXPECT_EQ(r.spec.height, 3);
    EXPECT_EQ(r.spec.full_width, 12);
    EXPECT_EQ(r.spec.full_height, 6);
    EXPECT_EQ(r.spec.alpha_channel, 3);
    for (int y = 3; y < 6; ++y)
        for (int x = 3; x < 12; ++x) {
            const float* p = r.at(x, y);
            for (int c = 0; c < 4; ++c) EXPECT_EQ(p[c], f.rgba(x, y)[c]) << x << "," << y << " channel " << c;
            EXPECT_EQ(p[4], f.z(x, y));
        }
    EXPECT_EQ(r.at(11, 3)[4], kInfinity);
    const OIIO::ParamValue* m = r.spec.find_attribute("worldtocamera", OIIO::TypeMatrix);
    ASSERT_NE(m, nullptr);
    float rib[16];
    meta.cameraFromWorld->toRib(rib);
    for (int i = 0; i < 16; ++i) EXPECT_EQ(static_cast<const float*>(m->data())[i], rib[i]);
    EXPECT_NE(r.spec.find_attribute("worldtoscreen", OIIO::TypeMatrix), nullptr);

    // The tags OIIO does not show: associated alpha, then unspecified z.
    TIFF* t = TIFFOpen((dir / "f.tif").c_str(), "r");
    ASSERT_NE(t, nullptr);
    uint16_t count = 0, *kinds = nullptr, format = 0, planar = 0;
    ASSERT_TRUE(TIFFGetField(t, TIFFTAG_EXTRASAMPLES, &count, &kinds));
    ASSERT_EQ(count, 2);
    EXPECT_EQ(kinds[0], EXTRASAMPLE_ASSOCALPHA);
    EXPECT_EQ(kinds[1], EXTRASAMPLE_UNSPECIFIED);
    ASSERT_TRUE(TIFFGetField(t, TIFFTAG_SAMPLEFORMAT, &format));
    EXPECT_EQ(format, SAMPLEFORMAT_IEEEFP);
    ASSERT_TRUE(TIFFGetField(t, TIFFTAG_PLANARCONFIG, &planar));
    EXPECT_EQ(planar, PLANARCONFIG_CONTIG);
    TIFFClose(t);
}

TEST(FilmFormats, SixteenBitPngRoundTripIsStraightAlpha) {
    fs::path dir = freshDir("png16");
    Film f = knownFilm(5, 3, kFull);
    scene::Options o;
    QuietDiagnostics diag;
    scene::DisplayRecord d = display(dir / "c.png", "png", "rgba");
    addInts(d, "quantize", {0, 65535, 0, 65535});
    addInts(d, "dither", {0});
    ASSERT_TRUE(f.writeDisplay(d, o, {}, diag));
    ReadBack r = readBack(dir / "c.png", true);
    ASSERT_EQ(r.spec.nchannels, 4);
    EXPECT_EQ(r.spec.format, OIIO::TypeDesc::UINT16);
    for (int y = 0; y < 3; ++y)
        for (int x = 0; x < 5; ++x) {
            const float* film = f.rgba(x, y);
            const float a = film[3];
            const float* p = r.at(x, y);
            for (int c = 0; c < 3; ++c) {
                float straight = a > 0 ? film[c] / a : film[c];
                EXPECT_EQ(p[c], std::min(65535.0f, q16(straight))) << x << "," << y << " channel " << c;
            }
            EXPECT_EQ(p[3], q16(a));
        }
    EXPECT_EQ(r.at(0, 0)[2], q16(0.3f));  // alpha 0 keeps its colour

    // Unquantised data goes to 16-bit PNG with one = 65535 and half-step dither.
    o.quantizeOne = 0;
    ASSERT_TRUE(f.writeDisplay(display(dir / "g.png", "file", "g"), o, {}, diag));
    ReadBack g = readBack(dir / "g.png");
    ASSERT_EQ(g.spec.nchannels, 1);
    EXPECT_EQ(g.spec.format, OIIO::TypeDesc::UINT16);
    for (int y = 0; y < 3; ++y)
        for (int x = 0; x < 5; ++x) EXPECT_NEAR(g.at(x, y)[0], 65535.0 * double(f.rgba(x, y)[1]), 1.0);
    EXPECT_EQ(diag.errorCount(), 0);
}

TEST(FilmFormats, EightBitGrayAlphaPngAndPngLimits) {
    fs::path dir = freshDir("png8");
    Film f = knownFilm(4, 2, kFull);
    scene::Options o;
    o.quantizeDither = 0;
    QuietDiagnostics diag;
    ASSERT_TRUE(f.writeDisplay(display(dir / "ga.png", "png", "ra"), o, {}, diag));
    ReadBack r = readBack(dir / "ga.png", true);
    ASSERT_EQ(r.spec.nchannels, 2);
    EXPECT_EQ(r.spec.format, OIIO::TypeDesc::UINT8);
    EXPECT_EQ(r.spec.alpha_channel, 1);
    // (1, 1): alpha 1; (2, 1): alpha 0.5, so the straight value doubles.
    EXPECT_EQ(r.at(1, 1)[0], std::round(255.0f * (2.0f / 7.0f)));
    EXPECT_EQ(r.at(2, 1)[0], std::min(255.0f, std::round(255.0f * ((3.0f / 7.0f) / 0.5f))));
    EXPECT_EQ(r.at(2, 1)[1], 128.0f);  // round(127.5)

    const std::string five = (dir / "x.png").string();
    EXPECT_FALSE(f.writeDisplay(display(dir / "x.png", "png", "rgbaz"), o, {}, diag));
    EXPECT_EQ(diag.recorded().back().str(), "frame.rib:7:1: error: display \"" + five +
                                                "\": PNG holds at most 4 channels, mode \"rgbaz\" has 5; write it "
                                                "to OpenEXR or TIFF");
    EXPECT_FALSE(f.writeDisplay(display(dir / "x.png", "png", "ag"), o, {}, diag));
    EXPECT_EQ(diag.recorded().back().str(), "frame.rib:7:1: error: display \"" + five +
                                                "\": PNG needs alpha as the last of 2 or 4 channels (mode \"ag\"); "
                                                "write it to OpenEXR or TIFF");
    EXPECT_FALSE(fs::exists(dir / "x.png"));
}

TEST(FilmFormats, ExrAovChannelsReadByOpenExr) {
    fs::path dir = freshDir("exraov");
    const float crop[4] = {0, 0.5f, 0, 1};
    std::vector<film::AovChannel> aovs = {{"diff", 3}, {"depth", 1}, {"uv", 2}};
    Film f = knownFilm(8, 4, crop, aovs);
    scene::Options o;
    QuietDiagnostics diag;
    scene::DisplayRecord diff = display(dir / "diff.exr", "openexr", "color diff");
    addString(diff, "type", "float");
    ASSERT_TRUE(f.writeDisplay(diff, o, {}, diag));
    ASSERT_TRUE(f.writeDisplay(display(dir / "depth.exr", "exr", "float depth"), o, {}, diag));
    EXPECT_EQ(diag.errorCount(), 0);

    {
        Imf::InputFile in((dir / "diff.exr").c_str());
        const Imf::Header& h = in.header();
        EXPECT_EQ(h.dataWindow(), Imath::Box2i(Imath::V2i(0, 0), Imath::V2i(3, 3)));
        EXPECT_EQ(h.displayWindow(), Imath::Box2i(Imath::V2i(0, 0), Imath::V2i(7, 3)));
        EXPECT_EQ(h.compression(), Imf::ZIP_COMPRESSION);
        int n = 0;
        for (auto c = h.channels().begin(); c != h.channels().end(); ++c, ++n) EXPECT_EQ(c.channel().type, Imf::FLOAT);
        EXPECT_EQ(n, 3);
        ASSERT_NE(h.channels().findChannel("G"), nullptr);
        EXPECT_EQ(h.typedAttribute<Imf::StringAttribute>("Software").value(), "umbra 0.1");
    }
    ReadBack d = readBack(dir / "diff.exr");
    ASSERT_EQ(d.spec.nchannels, 3);
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 4; ++x)
            for (int c = 0; c < 3; ++c) EXPECT_EQ(d.at(x, y)[c], f.aov(x, y)[c]);  // float: exact

    {
        Imf::InputFile in((dir / "depth.exr").c_str());
        const Imf::Channel* c = in.header().channels().findChannel("depth");
        ASSERT_NE(c, nullptr);
        EXPECT_EQ(c->type, Imf::HALF);
    }
    ReadBack z = readBack(dir / "depth.exr");
    ASSERT_EQ(z.spec.nchannels, 1);
    EXPECT_EQ(z.spec.channelnames[0], "depth");
    // Half: 11 significant bits.
    EXPECT_NEAR(z.at(3, 2)[0], f.aov(3, 2)[3], f.aov(3, 2)[3] / 1024.0f);
}

TEST(FilmFormats, TwoComponentAovChannelNames) {
    fs::path dir = freshDir("exruv");
    Film f = knownFilm(2, 2, kFull, {{"st", 2}});
    QuietDiagnostics diag;
    ASSERT_TRUE(f.writeDisplay(display(dir / "st.exr", "exr", "float st"), scene::Options{}, {}, diag));
    EXPECT_EQ(diag.warningCount(), 1);  // 2 components, the mode asks for 1
    Imf::InputFile in((dir / "st.exr").c_str());
    EXPECT_NE(in.header().channels().findChannel("st.0"), nullptr);
    EXPECT_NE(in.header().channels().findChannel("st.1"), nullptr);
}

TEST(FilmFormats, OiioReadsEveryFormatWithMetadata) {
    fs::path dir = freshDir("meta");
    Film f = knownFilm(6, 4, kFull);
    scene::Options o;
    QuietDiagnostics diag;
    film::OutputMetadata meta;
    meta.renderSeconds = 0.125;
    meta.dateTime = "2025:06:07 08:09:10";
    meta.cameraFromWorld = Mat4::translate({1, -2, 3});
    meta.ndcFromWorld = Mat4::scale({2, 2, 1});
    struct Case {
        const char* file;
        const char* driver;
        const char* mode;
        bool renderTime, matrices;
    };
    const Case cases[] = {{"a.exr", "openexr", "rgbaz", true, true},
                          {"b.tif", "tiff", "z", false, true},
                          {"c.tif", "file", "rgba", false, false},
                          {"d.png", "png", "rgba", true, false},
                          {"e.png", "file", "rgb", true, false}};
    for (const Case& c : cases) {
        SCOPED_TRACE(c.file);
        ASSERT_TRUE(f.writeDisplay(display(dir / c.file, c.driver, c.mode), o, meta, diag));
        ReadBack r = readBack(dir / c.file);
        EXPECT_EQ(r.spec.width, 6);
        EXPECT_EQ(r.spec.height, 4);
        EXPECT_EQ(r.spec.nchannels, int(std::string(c.mode).size()));
        EXPECT_EQ(r.spec.get_string_attribute("Software"), "umbra 0.1");
        EXPECT_EQ(r.spec.get_string_attribute("DateTime"), meta.dateTime);
        EXPECT_EQ(r.spec.get_string_attribute("umbra:rendertime"), c.renderTime ? "0.125" : "");
        const OIIO::ParamValue* m = r.spec.find_attribute("worldtocamera", OIIO::TypeMatrix);
        EXPECT_EQ(m != nullptr, c.matrices);
        if (m) {
            EXPECT_EQ(static_cast<const float*>(m->data())[13], -2.0f);  // translation row, RIB order
        }
    }
    // The shadow module reads the matrices as typed m44f attributes.
    Imf::InputFile in((dir / "a.exr").c_str());
    EXPECT_EQ(in.header().typedAttribute<Imf::M44fAttribute>("worldToNDC").value(),
              Imath::M44f(2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1));
    EXPECT_EQ(in.header().findTypedAttribute<Imf::M44fAttribute>("worldToCamera")->value()[3][1], -2.0f);
    EXPECT_EQ(diag.errorCount(), 0);
}

TEST(FilmFormats, CompressionParameter) {
    fs::path dir = freshDir("comp");
    Film f = knownFilm(4, 4, kFull);
    scene::Options o;
    QuietDiagnostics diag;
    scene::DisplayRecord e = display(dir / "p.exr", "openexr", "rgba");
    addString(e, "compression", "PIZ");
    ASSERT_TRUE(f.writeDisplay(e, o, {}, diag));
    EXPECT_EQ(Imf::InputFile((dir / "p.exr").c_str()).header().compression(), Imf::PIZ_COMPRESSION);

    scene::DisplayRecord t = display(dir / "l.tif", "tiff", "rgba");
    addString(t, "compression", "lzw");
    ASSERT_TRUE(f.writeDisplay(t, o, {}, diag));
    TIFF* tif = TIFFOpen((dir / "l.tif").c_str(), "r");
    ASSERT_NE(tif, nullptr);
    uint16_t comp = 0;
    TIFFGetField(tif, TIFFTAG_COMPRESSION, &comp);
    EXPECT_EQ(comp, COMPRESSION_LZW);
    TIFFClose(tif);
    EXPECT_EQ(diag.warningCount(), 0);

    scene::DisplayRecord u = display(dir / "u.tif", "tiff", "rgba");
    addString(u, "compression", "jpeg2000");
    ASSERT_TRUE(f.writeDisplay(u, o, {}, diag));
    ASSERT_EQ(diag.warningCount(), 1);
    EXPECT_EQ(diag.recorded().back().message,
              "display \"" + (dir / "u.tif").string() +
                  "\": unknown TIFF compression \"jpeg2000\" (expected none, lzw, zip or packbits, zip with a level "
                  "1-9 as \"zip:6\"); using zip");
    EXPECT_EQ(readBack(dir / "u.tif").spec.get_string_attribute("compression"), "zip");
    scene::DisplayRecord bad = display(dir / "v.exr", "exr", "rgba");
    addString(bad, "compression", "zip:10");
    ASSERT_TRUE(f.writeDisplay(bad, o, {}, diag));
    EXPECT_EQ(diag.warningCount(), 2);
    EXPECT_EQ(Imf::InputFile((dir / "v.exr").c_str()).header().compression(), Imf::ZIP_COMPRESSION);
}

TEST(FilmFormats, ZipLevelChangesTheSize) {
    // Dithered 8-bit noise: the deflate level shows in the file size, and
    // the pixels are the same at every level.
    fs::path dir = freshDir("level");
    Film f(64, 64, kFull, PixelFilter(film::FilterKind::Box, 1, 1));
    for (int y = 0; y < 64; ++y)
        for (int x = 0; x < 64; ++x)
            for (int c = 0; c < 4; ++c) f.rgba(x, y)[c] = 0.3f + 0.004f * float((x * 7 + y * 3 + c) % 11);
    scene::Options o;
    QuietDiagnostics diag;
    for (const char* ext : {"tif", "png"}) {
        SCOPED_TRACE(ext);
        fs::path fast = dir / fmt::format("l1.{}", ext), small = dir / fmt::format("l9.{}", ext);
        scene::DisplayRecord d1 = display(fast, "file", "rgba"), d9 = display(small, "file", "rgba");
        addString(d1, "compression", "zip:1");
        addString(d9, "compression", "ZIP:9");
        ASSERT_TRUE(f.writeDisplay(d1, o, {}, diag));
        ASSERT_TRUE(f.writeDisplay(d9, o, {}, diag));
        EXPECT_GT(fs::file_size(fast), fs::file_size(small));
        EXPECT_EQ(readBack(fast).values, readBack(small).values);
    }
    EXPECT_EQ(diag.warningCount(), 0);
}

TEST(FilmFormats, EmptyCropWindowIsAnError) {
    fs::path dir = freshDir("empty");
    const float crop[4] = {0.5f, 0.5f, 0, 1};
    Film f(8, 8, crop, PixelFilter(film::FilterKind::Box, 1, 1));
    QuietDiagnostics diag;
    EXPECT_FALSE(f.writeDisplay(display(dir / "e.tif", "tiff", "rgb"), scene::Options{}, {}, diag));
    EXPECT_EQ(diag.recorded().back().str(),
              "frame.rib:7:1: error: display \"" + (dir / "e.tif").string() +
                  "\": the crop window selects no pixels (expected a window covering at least one pixel centre)");
    EXPECT_TRUE(fs::is_empty(dir));
}

TEST(FilmFormats, NamedQuantizeAppliesToItsOutput) {
    // `Quantize "diff" 0 0 0 0` (RenderMan 13+): the "diff" output is
    // floating point while the rgba default (8 bits) stays for the rest.
    fs::path dir = freshDir("namedquantize");
    const float crop[4] = {0, 1, 0, 1};
    std::vector<film::AovChannel> aovs = {{"diff", 3}, {"spec", 3}};
    Film f = knownFilm(8, 4, crop, aovs);
    scene::Options o;
    o.namedQuantize["diff"] = {0, 0, 0, 0};
    QuietDiagnostics diag;
    ASSERT_TRUE(f.writeDisplay(display(dir / "diff.tif", "tiff", "color diff"), o, {}, diag));
    ASSERT_TRUE(f.writeDisplay(display(dir / "spec.tif", "tiff", "color spec"), o, {}, diag));
    EXPECT_EQ(diag.errorCount(), 0);
    EXPECT_EQ(readBack(dir / "diff.tif").spec.format, OIIO::TypeDesc::FLOAT);
    EXPECT_EQ(readBack(dir / "spec.tif").spec.format, OIIO::TypeDesc::UINT8);
    // 16 bits for "spec" by name.
    o.namedQuantize["spec"] = {65535, 0, 65535, 0};
    ASSERT_TRUE(f.writeDisplay(display(dir / "spec16.tif", "tiff", "color spec"), o, {}, diag));
    EXPECT_EQ(readBack(dir / "spec16.tif").spec.format, OIIO::TypeDesc::UINT16);
}
