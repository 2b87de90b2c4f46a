// Film storage and Display output.
//
// Images are written by the formats' own libraries (OpenEXR, libtiff,
// libpng; see image_file.h), not OpenImageIO, whose shared-library closure
// costs a tenth of a second at every process start.
//
// Drivers (RenderMan `Display` names):
//   "tiff"                   TIFF
//   "openexr", "exr"         OpenEXR; half by default, "string type"
//                            "float" for 32-bit (z is always float).
//                            EXR keeps unquantised values: Quantize is an
//                            integer-format setting (PRMan's openexr driver
//                            behaves the same).
//   "png"                    PNG (integers only: unquantised data is written
//                            as 16-bit, one = 65535); at most 4 channels,
//                            alpha last; colour is unpremultiplied (PNG
//                            alpha is straight) before quantisation
//   "file"                   by the name's extension (.exr .png .tif .tiff),
//                            TIFF otherwise, as RenderMan's "file" is TIFF
//   "framebuffer"            umbra has no window: the image is written to a
//                            file named after the display, by its extension,
//                            ".tif" appended when it has none of the above,
//                            unless another Display writes that file
//   "zfile", "shadow"        depth maps, handed to the DepthWriter hook
// Modes: letters out of r g b a z ("rgb", "rgba", "rgbaz", "z", "a", ...),
// or one AOV (see parseDisplayMode). Channel names: R G B A Z; an AOV of three
// components is R G B, a float AOV is named after the AOV.
// Exposure applies to r g b only: c' = (gain c)^(1/gamma). Quantize "rgba"
// covers r g b a and AOVs, Quantize "z" covers z; a display's own
// "quantize" [zero one min max] and "dither" parameters override them. A
// quantised file stores 8-bit integers when [min, max] fits in [0, 255],
// 16-bit when it fits in [0, 65535], float otherwise; when some channels are
// quantised and others not (rgbaz with float z), the integer formats get
// float data without quantisation (a warning says so). A display's
// "compression" names the codec: EXR none/rle/zips/zip/piz/pxr24/b44/b44a/
// dwaa/dwab, TIFF none/lzw/zip/packbits; zip by default, at the deflate
// levels of image_file.h (4 for integers, 6 for floats); "zip:N" picks one.

#include "umbra/film/film.h"
#include "umbra/scene/builder.h"
#include "umbra/util/file.h"
#include "umbra/util/parallel.h"

#include "image_file.h"

#include "umbra/util/rng.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <mutex>
#include <system_error>
#include <unistd.h>

#include <tbb/blocked_range.h>

namespace umbra::film {

namespace fs = std::filesystem;

namespace {

std::string lower(std::string s) {
    for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

int componentsOfTypeName(const std::string& t) {
    if (t == "float") return 1;
    if (t == "color" || t == "point" || t == "vector" || t == "normal") return 3;
    return 0;
}

/// Components of the standard shading-language variables a display may name
/// without a type.
int standardVariableComponents(const std::string& name) {
    static const char* kThree[] = {"Ci", "Oi", "Cs", "Os", "P", "N", "Ng", "I", "E", "L", "Cl", "Ol", "dPdu", "dPdv"};
    static const char* kOne[] = {"s", "t", "u", "v", "du", "dv", "ncomps", "time", "alpha"};
    for (const char* n : kThree)
        if (name == n) return 3;
    for (const char* n : kOne)
        if (name == n) return 1;
    return 0;
}

std::vector<std::string> splitWords(const std::string& s) {
    std::vector<std::string> words;
    size_t i = 0;
    while (i < s.size()) {
        while (i < s.size() && std::isspace(static_cast<unsigned char>(s[i]))) ++i;
        size_t j = i;
        while (j < s.size() && !std::isspace(static_cast<unsigned char>(s[j]))) ++j;
        if (j > i) words.push_back(s.substr(i, j - i));
        i = j;
    }
    return words;
}

enum class Format { Tiff, Exr, Png };

const char* formatName(Format f) {
    switch (f) {
    case Format::Tiff: return "TIFF";
    case Format::Exr: return "OpenEXR";
    case Format::Png: return "PNG";
    }
    return "TIFF";
}

/// Closes a stdio stream on every path unless released.
struct FileCloser {
    void operator()(std::FILE* f) const { std::fclose(f); }
};

std::optional<Format> formatOfExtension(const std::string& path) {
    std::string ext = lower(fs::path(path).extension().string());
    if (ext == ".exr") return Format::Exr;
    if (ext == ".png") return Format::Png;
    if (ext == ".tif" || ext == ".tiff") return Format::Tiff;
    return std::nullopt;
}

}  // namespace

/// Drivers that write the file their Display names; any other driver (a
/// window such as "framebuffer", or one umbra lacks) falls back to a file.
static bool writesItsOwnFile(const std::string& driver) {
    const std::string d = lower(driver);
    return d == "file" || d == "tiff" || d == "openexr" || d == "exr" || d == "png" || d == "zfile" || d == "shadow";
}

std::string displayFilePath(const scene::DisplayRecord& display) {
    if (writesItsOwnFile(display.driver)) return display.name;
    return formatOfExtension(display.name) ? display.name : display.name + ".tif";
}

namespace {

/// One output channel: where its value comes from and how it is encoded.
struct ChannelSource {
    enum Kind { R, G, B, A, Z, Aov } kind;
    int aovFloat = 0;  // for Aov: float offset within the pixel's AOV floats
    std::string name;
    Quantize quantize;
    bool exposure = false;
};

/// std::round (halves away from zero) without the libm call baseline
/// x86-64 needs for it: exact, since v - trunc(v) is exact in float.
/// Branch-free: with dither the halves fall at random, and a mispredicted
/// branch per value cost more than the rest of the conversion.
inline float roundHalfAway(float v) {
    if (!(std::abs(v) < 8388608.0f)) return v;  // 2^23 and beyond are integers already; NaN stays NaN
    const float t = float(int(v));               // truncated toward zero
    const float frac = v - t;
    return t + float(frac >= 0.5f) - float(frac <= -0.5f);
}

/// Dither noise of a pixel: one hash for each group of four channels, a
/// byte each (a chain of hashes per value cost 27 ns a channel, most of a
/// frame's serial output time). Fixed per pixel and channel: the same image
/// every run.
uint32_t ditherBits(int x, int y, int channelGroup) {
    return hash32(uint32_t(x) * 0x9e3779b1u ^ uint32_t(y) * 0x85ebca77u ^ uint32_t(channelGroup) * 0xc2b2ae3du ^
                  0x51ed27u);
}
/// Channel c's noise from its group's bits: uniform in (-1, 1), steps of 1/128.
float ditherNoise(uint32_t bits, int channel) {
    return (float((bits >> (8 * (channel & 3))) & 0xffu) + 0.5f) * (1.0f / 128.0f) - 1.0f;
}

}  // namespace

bool parseDisplayMode(const std::string& mode, DisplayMode* out, std::string* error) {
    *out = DisplayMode{};
    std::vector<std::string> words = splitWords(mode);
    auto fail = [&](const std::string& msg) {
        if (error) *error = msg;
        return false;
    };
    if (words.empty()) return fail("empty display mode (expected \"rgb\", \"rgba\", \"z\", \"rgbaz\" or an AOV)");
    if (words.size() == 1) {
        const std::string& w = words[0];
        bool standard = w.find_first_not_of("rgbaz") == std::string::npos;
        if (standard) {
            for (char c : std::string("rgbaz"))
                if (std::count(w.begin(), w.end(), c) > 1)
                    return fail(fmt::format("display mode \"{}\" repeats a channel", mode));
            out->standard = w;
            return true;
        }
        int n = standardVariableComponents(w);
        if (n == 0)
            return fail(fmt::format("unknown display mode \"{}\" (expected letters of \"rgbaz\", a standard "
                                    "variable such as \"Ci\" or \"N\", or a typed AOV such as \"color {}\")",
                                    mode, w));
        out->aovName = w;
        out->aovComponents = n;
        return true;
    }
    // [class] type name, e.g. "varying color myaov".
    size_t k = 0;
    if (words.size() == 3) {
        if (words[0] != "varying" && words[0] != "uniform" && words[0] != "vertex" && words[0] != "constant")
            return fail(fmt::format("display mode \"{}\": expected \"[class] type name\"", mode));
        k = 1;
    } else if (words.size() != 2) {
        return fail(fmt::format("display mode \"{}\": expected \"[class] type name\"", mode));
    }
    int n = componentsOfTypeName(words[k]);
    if (n == 0)
        return fail(fmt::format("display mode \"{}\": unsupported AOV type \"{}\" (expected float, color, point, "
                                "vector or normal)",
                                mode, words[k]));
    out->aovName = words[k + 1];
    out->aovComponents = n;
    return true;
}

bool writesDepthMap(const scene::DisplayRecord& display) {
    const std::string driver = lower(display.driver);
    return driver == "zfile" || driver == "shadow";
}

bool displayReadsDepth(const scene::DisplayRecord& display) {
    DisplayMode mode;
    std::string why;
    return writesDepthMap(display) || !parseDisplayMode(display.mode, &mode, &why) ||
           (!mode.isAov() && mode.standard.find('z') != std::string::npos);
}

std::vector<AovChannel> aovChannelsFor(const std::vector<scene::DisplayRecord>& displays) {
    std::vector<AovChannel> aovs;
    for (const scene::DisplayRecord& d : displays) {
        DisplayMode m;
        if (!parseDisplayMode(d.mode, &m, nullptr) || !m.isAov()) continue;
        bool seen = std::any_of(aovs.begin(), aovs.end(), [&](const AovChannel& a) { return a.name == m.aovName; });
        if (!seen) aovs.push_back({m.aovName, m.aovComponents});
    }
    return aovs;
}

namespace {

/// True when a display writes no colour or AOV channel: depth only.
bool depthOnlyDisplay(const scene::DisplayRecord& display) {
    const std::string driver = lower(display.driver);
    if (driver == "zfile" || driver == "shadow") return true;
    DisplayMode mode;
    if (!parseDisplayMode(display.mode, &mode, nullptr)) return false;
    return !mode.isAov() && mode.standard.find_first_of("rgba") == std::string::npos;
}

}  // namespace

bool sameFilter(const PixelFilter& a, const PixelFilter& b) {
    return a.kind() == b.kind() && a.xWidth() == b.xWidth() && a.yWidth() == b.yWidth();
}

std::optional<PixelFilter> displayFilter(const scene::DisplayRecord& display, const PixelFilter& frameFilter,
                                         Diagnostics* diag) {
    const ri::Param* name = display.params.find("filter");
    const ri::Param* width = display.params.find("filterwidth");
    if (!name && !width) return std::nullopt;
    const FileLoc& at = name ? name->loc : width->loc;
    if (depthOnlyDisplay(display)) {
        // Depth keeps each pixel's nearest sample: RenderMan's "min"
        // ("zmin") depth filter, which is what is written anyway.
        const std::string n = name && !name->strings.empty() ? lower(name->stringAt(0)) : std::string();
        if (diag && n != "min" && n != "zmin")
            diag->warningOnce("display-filter-depth:" + display.name, at,
                              "display \"{}\": depth is not filtered (each pixel keeps its nearest sample); its "
                              "\"filter\"/\"filterwidth\" are ignored",
                              display.name);
        return std::nullopt;
    }
    std::string kind = frameFilter.name();
    if (name) {
        if (name->strings.size() != 1) {
            if (diag)
                diag->warning(name->loc, "display \"{}\": \"filter\" expects one filter name; using the frame's "
                              "PixelFilter \"{}\" {} {}",
                              display.name, frameFilter.name(), frameFilter.xWidth(), frameFilter.yWidth());
            return std::nullopt;
        }
        kind = name->stringAt(0);
    }
    float xw = frameFilter.xWidth(), yw = frameFilter.yWidth();
    if (width) {
        std::vector<float> w = width->floats;
        for (int i : width->ints) w.push_back(float(i));
        if ((w.size() != 1 && w.size() != 2) || !(w[0] > 0) || !(w.back() > 0) || !std::isfinite(w[0]) ||
            !std::isfinite(w.back())) {
            if (diag)
                diag->warning(width->loc, "display \"{}\": \"filterwidth\" expects one or two positive widths; using "
                              "the frame's PixelFilter \"{}\" {} {}",
                              display.name, frameFilter.name(), frameFilter.xWidth(), frameFilter.yWidth());
            return std::nullopt;
        }
        xw = w[0];
        yw = w.back();
        if (xw > scene::kMaxFilterWidth || yw > scene::kMaxFilterWidth) {
            // As PixelFilter's: every bucket samples the widest reach around it.
            const float cx = std::min(xw, scene::kMaxFilterWidth), cy = std::min(yw, scene::kMaxFilterWidth);
            if (diag)
                diag->warning(width->loc, "display \"{}\": \"filterwidth\" {} {} exceeds the maximum of {} pixels; "
                              "clamped to {} {}",
                              display.name, xw, yw, scene::kMaxFilterWidth, cx, cy);
            xw = cx;
            yw = cy;
        }
    }
    std::optional<PixelFilter> f = PixelFilter::create(kind, xw, yw);
    if (!f && diag)
        diag->warning(at, "display \"{}\": unknown pixel filter \"{}\" (expected box, triangle, gaussian, "
                      "catmull-rom, sinc, lanczos, mitchell, separable-catmull-rom, blackman-harris, disk or bessel); using "
                      "the frame's PixelFilter \"{}\" {} {}",
                      display.name, kind, frameFilter.name(), frameFilter.xWidth(), frameFilter.yWidth());
    return f;
}

void Film::cropPixels(int xres, int yres, const float crop[4], int* x0, int* x1, int* y0, int* y1) {
    // RI Spec 3.2: columns ceil(xres * xmin) to ceil(xres * xmax - 1)
    // inclusive (rows likewise), as Pixie and Aqsis crop; umbra kept the
    // pixels whose centres lay inside, a column more or less where an edge
    // fell mid-pixel. The tolerance keeps decimal windows like 0.1 (stored
    // as 0.100000001) from gaining a pixel where the edge is on a border.
    auto edge = [](int res, float ndc) { return int(std::ceil(double(res) * double(ndc) - 1e-4)); };
    *x0 = clamp(edge(xres, crop[0]), 0, xres);
    *x1 = clamp(edge(xres, crop[1]), *x0, xres);
    *y0 = clamp(edge(yres, crop[2]), 0, yres);
    *y1 = clamp(edge(yres, crop[3]), *y0, yres);
}

struct Film::DepthBook {
    std::mutex mutex;
    DepthWindow written{std::numeric_limits<int>::max(), std::numeric_limits<int>::max(),
                        std::numeric_limits<int>::min(), std::numeric_limits<int>::min()};
    std::vector<DepthWindow> empty;
};

Film::Film(int xResolution, int yResolution, const float cropWindow[4], PixelFilter filter,
           std::vector<AovChannel> aovs, FilmContent content, DepthStart depthStart)
    : m_xres(xResolution), m_yres(yResolution), m_filter(std::move(filter)), m_aovs(std::move(aovs)),
      m_content(content) {
    UMBRA_CHECK(xResolution > 0 && yResolution > 0, "bad film resolution {}x{}", xResolution, yResolution);
    int x1, y1;
    cropPixels(m_xres, m_yres, cropWindow, &m_x0, &x1, &m_y0, &y1);
    m_width = x1 - m_x0;
    m_height = y1 - m_y0;
    for (const AovChannel& a : m_aovs) {
        UMBRA_CHECK(a.components > 0, "AOV {} has no components", a.name);
        m_aovOffsets.push_back(m_aovFloats);
        m_aovFloats += a.components;
    }
    size_t n = size_t(m_width) * size_t(m_height);
    // Depth passes never touch colour: not allocating it saves clearing
    // 16 bytes a pixel (6.5 MB for a 640^2 map) per pass.
    if (hasColour()) m_rgba.resize(4 * n);  // zeros (ZeroedAllocator)
    if (hasDepth() && depthStart == DepthStart::Unset) {
        // Untouched zero pages until a bucket writes them (settleDepth).
        m_unsetDepth = std::make_unique<DepthBook>();
        m_z.resize(n);
        if (content == FilmContent::DepthPair) m_z2.resize(n);
    } else {
        if (hasDepth()) m_z.assign(n, kInfinity);
        if (content == FilmContent::DepthPair) m_z2.assign(n, kInfinity);
    }
    m_aov.resize(n * size_t(m_aovFloats));
}

uint64_t Film::bytesFor(int xResolution, int yResolution, const float cropWindow[4],
                        const std::vector<AovChannel>& aovs, FilmContent content) {
    int x0, x1, y0, y1;
    cropPixels(xResolution, yResolution, cropWindow, &x0, &x1, &y0, &y1);
    uint64_t floats = (content == FilmContent::ColourOnly ? 0 : 1) + (contentHasColour(content) ? 4 : 0) +
                      (content == FilmContent::DepthPair ? 1 : 0);
    for (const AovChannel& a : aovs) floats += uint64_t(std::max(a.components, 0));
    return uint64_t(std::max(x1 - x0, 0)) * uint64_t(std::max(y1 - y0, 0)) * floats * sizeof(float);
}

Film Film::fromOptions(const scene::Options& o, std::vector<AovChannel> aovs, FilmContent content,
                       Diagnostics& diag, const std::vector<scene::DisplayRecord>& displays, DepthStart depthStart) {
    std::optional<PixelFilter> f = PixelFilter::create(o.pixelFilter, o.filterWidth[0], o.filterWidth[1]);
    if (!f) {
        diag.error(o.loc, "unknown pixel filter \"{}\" with widths {} {} (expected box, triangle, gaussian, "
                   "catmull-rom, sinc, mitchell, separable-catmull-rom, blackman-harris, disk or bessel with positive "
                   "widths); using gaussian 2 2",
                   o.pixelFilter, o.filterWidth[0], o.filterWidth[1]);
        f = PixelFilter(FilterKind::Gaussian, 2, 2);
    }
    // Displays with filters of their own: one layer per distinct filter
    // other than the frame's (depth films have none: depth is not filtered).
    std::vector<PixelFilter> layers;
    for (const scene::DisplayRecord& d : displays) {
        std::optional<PixelFilter> own = displayFilter(d, *f, &diag);
        if (!own || !contentHasColour(content) || sameFilter(*own, *f)) continue;
        if (std::none_of(layers.begin(), layers.end(), [&](const PixelFilter& l) { return sameFilter(l, *own); }))
            layers.push_back(*own);
    }
    uint64_t bytes = bytesFor(o.xResolution, o.yResolution, o.cropWindow, aovs, content);
    if (!layers.empty()) {
        int x0, x1, y0, y1;
        cropPixels(o.xResolution, o.yResolution, o.cropWindow, &x0, &x1, &y0, &y1);
        uint64_t perLayer = 4;
        for (const AovChannel& a : aovs) perLayer += uint64_t(std::max(a.components, 0));
        bytes += uint64_t(layers.size()) * perLayer * uint64_t(x1 - x0) * uint64_t(y1 - y0) * sizeof(float);
    }
    const std::string what = fmt::format("the {}x{} film with {} samples per pixel", o.xResolution, o.yResolution,
                                         o.pixelSamples[0] * o.pixelSamples[1]);
    return allocating(o.loc, bytes, what, [&] {
        Film film(o.xResolution, o.yResolution, o.cropWindow, *f, std::move(aovs), content, depthStart);
        for (const PixelFilter& l : layers) film.addFilterLayer(l);
        return film;
    });
}

int Film::findFilterLayer(const PixelFilter& filter) const {
    if (sameFilter(filter, m_filter)) return 0;
    for (size_t i = 0; i < m_layers.size(); ++i)
        if (sameFilter(filter, m_layers[i].filter)) return int(i) + 1;
    return -1;
}

int Film::addFilterLayer(const PixelFilter& filter) {
    if (int found = findFilterLayer(filter); found >= 0) return found;
    UMBRA_CHECK(hasColour(), "a depth film has no filter layers");
    const size_t n = size_t(m_width) * size_t(m_height);
    FilterLayer layer{filter, {}, {}};
    layer.rgba.resize(4 * n);  // zeros (ZeroedAllocator)
    layer.aov.resize(n * size_t(m_aovFloats));
    m_layers.push_back(std::move(layer));
    return int(m_layers.size());
}

int Film::filterMargin() const {
    int m = m_filter.margin();
    for (const FilterLayer& l : m_layers) m = std::max(m, l.filter.margin());
    return m;
}

int Film::findAov(const std::string& name) const {
    for (size_t i = 0; i < m_aovs.size(); ++i)
        if (m_aovs[i].name == name) return int(i);
    return -1;
}

bool Film::write(const std::vector<scene::DisplayRecord>& displays, const scene::Options& options,
                 const OutputMetadata& metadata, Diagnostics& diag, const DepthWriter& depthWriter) const {
    // Scenes pair a file with a window showing the same image under the
    // same name (Display "out.tif" "file" ..., then "+out.tif"
    // "framebuffer"): the window's stand-in file must not overwrite the
    // file the user asked for.
    std::vector<std::string> filesAskedFor;
    for (const scene::DisplayRecord& d : displays)
        if (writesItsOwnFile(d.driver)) filesAskedFor.push_back(d.name);
    bool ok = true;
    for (const scene::DisplayRecord& d : displays) {
        if (!writesItsOwnFile(d.driver)) {
            const std::string standIn = displayFilePath(d);
            if (std::find(filesAskedFor.begin(), filesAskedFor.end(), standIn) != filesAskedFor.end()) {
                diag.warningOnce("display-driver:" + lower(d.driver), d.loc,
                                 "display driver \"{}\": umbra has no window, and \"{}\" is written by another "
                                 "Display; this one is skipped", d.driver, standIn);
                continue;
            }
        }
        ok = writeDisplay(d, options, metadata, diag, depthWriter) && ok;
    }
    return ok;
}

/// A display ready to write: where, which channels of which filter layer,
/// and how they are converted (Film::prepareOutput).
struct PreparedOutput {
    std::string name;  // the display's
    FileLoc loc;
    std::string path;  // resolved (links followed)
    Format format = Format::Tiff;
    std::vector<ChannelSource> channels;
    int layer = 0;
    bool unpremultiply = false;
    float gain = 1, invGamma = 1;
    bool exposeIdentity = true;
    ImageData image;  // everything but the pixels
};

bool Film::prepareOutput(const scene::DisplayRecord& display, const scene::Options& options,
                         const OutputMetadata& metadata, Diagnostics& diag, PreparedOutput* out) const {
    const std::string driver = lower(display.driver);
    std::string path = display.name;
    Format format;
    if (driver == "tiff") {
        format = Format::Tiff;
    } else if (driver == "openexr" || driver == "exr") {
        format = Format::Exr;
    } else if (driver == "png") {
        format = Format::Png;
    } else if (driver == "file") {
        format = formatOfExtension(path).value_or(Format::Tiff);
    } else {
        // A window ("framebuffer", "it", "x11", ...) or a driver umbra does
        // not have: one unusable Display must not cost the frame, so the
        // image goes to a file as the "file" driver would write it.
        path = displayFilePath(display);
        format = formatOfExtension(path).value_or(Format::Tiff);
        diag.warningOnce("display-driver:" + driver, display.loc,
                         "display driver \"{}\": {}; writing \"{}\" instead", display.driver,
                         driver == "framebuffer" || driver == "it" || driver == "x11" || driver == "windows"
                             ? "umbra has no window"
                             : "not a driver umbra has (it has file, tiff, openexr, png, zfile and shadow)",
                         path);
    }
    if (path.empty()) {
        diag.error(display.loc, "display has an empty file name (expected a file name)");
        return false;
    }

    DisplayMode mode;
    std::string modeError;
    if (!parseDisplayMode(display.mode, &mode, &modeError)) {
        diag.error(display.loc, "display \"{}\": {}", display.name, modeError);
        return false;
    }

    Quantize rgbaQ{options.quantizeOne, options.quantizeMin, options.quantizeMax, options.quantizeDither};
    Quantize zQ{options.zQuantizeOne, options.zQuantizeMin, options.zQuantizeMax, options.zQuantizeDither};
    if (const ri::Param* q = display.params.find("quantize")) {
        if (q->floats.size() + q->ints.size() != 4) {
            diag.error(q->loc, "display \"{}\": \"quantize\" needs 4 values [zero one min max]", display.name);
            return false;
        }
        auto at = [&](size_t i) { return q->floats.empty() ? float(q->intAt(i)) : q->floatAt(i); };
        rgbaQ.one = at(1);
        rgbaQ.min = at(2);
        rgbaQ.max = at(3);
        zQ = rgbaQ;
    }
    if (const ri::Param* d = display.params.find("dither")) {
        float v = d->floats.empty() ? float(d->intAt(0)) : d->floatAt(0);
        rgbaQ.dither = v;
        zQ.dither = v;
    }

    // The display's own pixel filter: its layer (reported, when unknown,
    // where the film was made).
    int layer = 0;
    if (std::optional<PixelFilter> own = displayFilter(display, m_filter, nullptr)) {
        layer = findFilterLayer(*own);
        if (layer < 0) {
            diag.warningOnce("display-filter-layer:" + display.name, display.loc,
                             "display \"{}\": this film was not resolved with the display's own \"{}\" {} {} "
                             "filter; using the frame's PixelFilter",
                             display.name, own->name(), own->xWidth(), own->yWidth());
            layer = 0;
        }
    }
    std::vector<ChannelSource> channels;
    if (mode.isAov()) {
        int idx = findAov(mode.aovName);
        if (idx < 0) {
            diag.error(display.loc, "display \"{}\": AOV \"{}\" was not rendered (the film has no such channel)",
                       display.name, mode.aovName);
            return false;
        }
        int comps = m_aovs[size_t(idx)].components;
        // `Quantize "name" ...` for this output, unless the Display says.
        Quantize aovQ = rgbaQ;
        if (auto nq = options.namedQuantize.find(mode.aovName);
            nq != options.namedQuantize.end() && !display.params.find("quantize"))
            aovQ = Quantize{nq->second[0], nq->second[1], nq->second[2], display.params.find("dither") ? rgbaQ.dither
                                                                                                        : nq->second[3]};
        if (comps != mode.aovComponents)
            diag.warning(display.loc, "display \"{}\": AOV \"{}\" has {} components, the mode asks for {}",
                         display.name, mode.aovName, comps, mode.aovComponents);
        static const char* kRgb[] = {"R", "G", "B"};
        for (int c = 0; c < comps; ++c) {
            std::string name = comps == 3 ? kRgb[c] : (comps == 1 ? mode.aovName : fmt::format("{}.{}", mode.aovName, c));
            channels.push_back({ChannelSource::Aov, aovOffset(idx) + c, name, aovQ, false});
        }
    } else {
        for (char c : mode.standard) {
            switch (c) {
            case 'r': channels.push_back({ChannelSource::R, 0, "R", rgbaQ, true}); break;
            case 'g': channels.push_back({ChannelSource::G, 0, "G", rgbaQ, true}); break;
            case 'b': channels.push_back({ChannelSource::B, 0, "B", rgbaQ, true}); break;
            case 'a': channels.push_back({ChannelSource::A, 0, "A", rgbaQ, false}); break;
            case 'z': channels.push_back({ChannelSource::Z, 0, "Z", zQ, false}); break;
            }
        }
    }
    const int nch = int(channels.size());
    if (!hasDepth() && std::any_of(channels.begin(), channels.end(),
                                   [](const ChannelSource& c) { return c.kind == ChannelSource::Z; })) {
        diag.error(display.loc, "display \"{}\": mode \"{}\" reads depth, which this film was made without",
                   display.name, display.mode);
        return false;
    }

    if (m_width == 0 || m_height == 0) {
        diag.error(display.loc, "display \"{}\": the crop window selects no pixels (expected a window covering at "
                   "least one pixel centre)",
                   display.name);
        return false;
    }
    const int alphaChannel = [&] {
        for (int c = 0; c < nch; ++c)
            if (channels[size_t(c)].kind == ChannelSource::A) return c;
        return -1;
    }();
    if (format == Format::Png) {
        if (nch > 4) {
            diag.error(display.loc, "display \"{}\": PNG holds at most 4 channels, mode \"{}\" has {}; write it to "
                       "OpenEXR or TIFF",
                       display.name, display.mode, nch);
            return false;
        }
        if ((alphaChannel >= 0 || nch == 2 || nch == 4) && alphaChannel != nch - 1) {
            diag.error(display.loc, "display \"{}\": PNG needs alpha as the last of 2 or 4 channels (mode \"{}\"); "
                       "write it to OpenEXR or TIFF",
                       display.name, display.mode);
            return false;
        }
    }
    // "compression" "name" or "name:level" (OIIO's spelling): a deflate
    // level 1-9 for zip, zips and PNG, 1-1000 for dwaa/dwab.
    std::string compression;
    int compressionLevel = 0;
    if (const ri::Param* comp = display.params.find("compression"); comp && !comp->strings.empty()) {
        const std::string given = lower(comp->stringAt(0));
        compression = given;
        bool known = true;
        if (size_t colon = given.find(':'); colon != std::string::npos) {
            compression = given.substr(0, colon);
            const std::string digits = given.substr(colon + 1);
            char* end = nullptr;
            long level = std::strtol(digits.c_str(), &end, 10);
            const bool zipFamily = compression == "zip" || compression == "zips" || compression == "deflate";
            const bool dwa = format == Format::Exr && (compression == "dwaa" || compression == "dwab");
            known = !digits.empty() && *end == 0 && level >= 1 &&
                    ((zipFamily && level <= 9) || (dwa && level <= 1000));
            compressionLevel = known ? int(level) : 0;
        }
        if (format == Format::Exr) known = known && exrCompressionKnown(compression);
        if (format == Format::Tiff) known = known && tiffCompressionKnown(compression);
        if (!known) {
            diag.warning(comp->loc, "display \"{}\": unknown {} compression \"{}\" (expected {}, zip with a level "
                         "1-9 as \"zip:6\"); using zip",
                         display.name, formatName(format), given,
                         format == Format::Exr ? "none, rle, zips, zip, piz, pxr24, b44, b44a, dwaa or dwab"
                         : format == Format::Tiff ? "none, lzw, zip or packbits"
                                                  : "zip");
            compression.clear();
            compressionLevel = 0;
        }
    }

    // Sample type: integers when every channel is quantised (and the format
    // takes them), float otherwise.
    bool allQuantised = std::all_of(channels.begin(), channels.end(), [](const ChannelSource& c) { return c.quantize.enabled(); });
    bool anyQuantised = std::any_of(channels.begin(), channels.end(), [](const ChannelSource& c) { return c.quantize.enabled(); });
    SampleType sampleType = SampleType::Float;
    if (format == Format::Exr) {
        for (ChannelSource& c : channels) c.quantize = Quantize{};
        std::string type = lower(display.params.getString("type", "half"));
        if (type != "half" && type != "float") {
            diag.error(display.loc, "display \"{}\": \"type\" \"{}\" (expected \"half\" or \"float\")", display.name, type);
            return false;
        }
        sampleType = type == "float" ? SampleType::Float : SampleType::Half;
    } else {
        if (anyQuantised && !allQuantised) {
            if (format == Format::Png) {
                diag.error(display.loc, "display \"{}\": PNG cannot mix quantised and floating-point channels (mode "
                           "\"{}\"); write it to OpenEXR or TIFF",
                           display.name, display.mode);
                return false;
            }
            diag.warningOnce("mixed-quantize:" + display.name, display.loc,
                             "display \"{}\": mode \"{}\" mixes quantised and floating-point channels; writing "
                             "floating point",
                             display.name, display.mode);
            for (ChannelSource& c : channels) c.quantize = Quantize{};
            allQuantised = false;
        }
        if (!allQuantised && format == Format::Png) {
            for (ChannelSource& c : channels) c.quantize = Quantize{65535, 0, 65535, 0.5f};
            allQuantised = true;
        }
        if (allQuantised) {
            float lo = kInfinity, hi = -kInfinity;
            for (const ChannelSource& c : channels) {
                lo = std::min(lo, c.quantize.min);
                hi = std::max(hi, c.quantize.max);
            }
            if (lo >= 0 && hi <= 255)
                sampleType = SampleType::UInt8;
            else if (lo >= 0 && hi <= 65535)
                sampleType = SampleType::UInt16;
            else if (format == Format::Png) {
                diag.error(display.loc, "display \"{}\": PNG needs quantize min/max within [0, 65535] (have [{}, {}])",
                           display.name, lo, hi);
                return false;
            }
        }
    }
    // PNG's alpha is straight; the film's colour is premultiplied.
    const bool unpremultiply = format == Format::Png && alphaChannel >= 0;

    // Convert the pixels.
    // A display's own "exposure" [gain gamma] replaces the frame's, and then
    // applies to its AOV's channels too.
    float gain = options.exposureGain, gamma = options.exposureGamma;
    bool ownExposure = false;
    if (const ri::Param* e = display.params.find("exposure"); e && e->floats.size() == 2) {
        gain = e->floats[0];
        gamma = e->floats[1];
        ownExposure = true;
    } else if (e) {
        diag.warning(e->loc, "display \"{}\": \"exposure\" expects [gain gamma] (ignored)", display.name);
    }
    if (ownExposure)
        for (ChannelSource& c : channels) c.exposure = c.exposure || c.kind == ChannelSource::Aov;
    const float invGamma = gamma > 0 ? 1.0f / gamma : 1.0f;
    const bool exposeIdentity = gain == 1.0f && invGamma == 1.0f;
    ImageData image;
    image.width = m_width;
    image.height = m_height;
    image.x = m_x0;
    image.y = m_y0;
    image.fullWidth = m_xres;
    image.fullHeight = m_yres;
    bool hasZ = false;
    for (const ChannelSource& c : channels) {
        image.channelNames.push_back(c.name);
        ChannelRole role = ChannelRole::Other;
        if (c.kind == ChannelSource::R || c.kind == ChannelSource::G || c.kind == ChannelSource::B)
            role = ChannelRole::Color;
        else if (c.kind == ChannelSource::A)
            role = ChannelRole::Alpha;
        else if (c.kind == ChannelSource::Z)
            role = ChannelRole::Depth;
        hasZ = hasZ || role == ChannelRole::Depth;
        image.roles.push_back(role);
        // Half has 11 bits of mantissa: depth needs float.
        image.types.push_back(role == ChannelRole::Depth && sampleType == SampleType::Half ? SampleType::Float
                                                                                          : sampleType);
    }
    image.software = "umbra 0.1";
    image.dateTime = metadata.dateTime;
    if (metadata.renderSeconds >= 0) image.renderTime = fmt::format("{:.3f}", metadata.renderSeconds);
    if (hasZ) {
        // Row-vector order, as EXR/Imath and TIFF's Pixar tags store them.
        std::array<float, 16> m;
        if (metadata.cameraFromWorld) {
            metadata.cameraFromWorld->toRib(m.data());
            image.worldToCamera = m;
        }
        if (metadata.ndcFromWorld) {
            metadata.ndcFromWorld->toRib(m.data());
            image.worldToNDC = m;
        }
    }
    image.compression = compression;
    if (compressionLevel > 0) image.compressionLevel = compressionLevel;

    // Write under a temporary name in the same directory, then rename; a
    // link is written through, a directory or special file refused.
    {
        std::string resolved, why;
        if (!resolveOutputPath(path, &resolved, &why)) {
            diag.error(display.loc, "display \"{}\": cannot write \"{}\": {}", display.name, path, why);
            return false;
        }
        path = resolved;
    }
    out->name = display.name;
    out->loc = display.loc;
    out->path = path;
    out->format = format;
    out->channels = std::move(channels);
    out->layer = layer;
    out->unpremultiply = unpremultiply;
    out->gain = gain;
    out->invGamma = invGamma;
    out->exposeIdentity = exposeIdentity;
    out->image = std::move(image);
    return true;
}

// One row of the display's samples, width * nch values: every pixel stands
// alone.
void Film::convertRow(const PreparedOutput& o, int y, float* out) const {
    const std::vector<ChannelSource>& channels = o.channels;
    const int nch = int(channels.size());
    const int layer = o.layer;
    const bool unpremultiply = o.unpremultiply, exposeIdentity = o.exposeIdentity;
    const float gain = o.gain, invGamma = o.invGamma;
    for (int x = m_x0; x < x1(); ++x) {
        const size_t base = size_t(x - m_x0) * size_t(nch);
        const float* p = rgba(layer, x, y);
        const float* a = m_aovFloats > 0 ? aov(layer, x, y) : nullptr;
        uint32_t bits = 0;
        for (int c = 0; c < nch; ++c) {
            const ChannelSource& src = channels[size_t(c)];
            if ((c & 3) == 0) bits = ditherBits(x, y, c >> 2);
            float v = 0;
            switch (src.kind) {
            case ChannelSource::R: v = p[0]; break;
            case ChannelSource::G: v = p[1]; break;
            case ChannelSource::B: v = p[2]; break;
            case ChannelSource::A: v = p[3]; break;
            case ChannelSource::Z: v = z(x, y); break;
            case ChannelSource::Aov: v = a[src.aovFloat]; break;
            }
            if (src.exposure && !exposeIdentity) {
                v *= gain;
                if (invGamma != 1.0f) v = v > 0 ? std::pow(v, invGamma) : 0.0f;
            }
            // Alpha 0 keeps its colour: emission without coverage.
            if (unpremultiply && src.exposure && p[3] > 0) v /= p[3];
            if (src.quantize.enabled()) {
                const Quantize& q = src.quantize;
                float noise = q.dither != 0 ? q.dither * ditherNoise(bits, c) : 0.0f;
                float qv = roundHalfAway(q.one * v + noise);
                if (!(qv >= q.min)) qv = q.min;  // NaN goes to min
                if (qv > q.max) qv = q.max;
                v = qv;
            }
            out[base + size_t(c)] = v;
        }
    }
}

bool Film::writeDisplay(const scene::DisplayRecord& display, const scene::Options& options,
                        const OutputMetadata& metadata, Diagnostics& diag, const DepthWriter& depthWriter) const {
    const std::string driver = lower(display.driver);
    if (driver == "zfile" || driver == "shadow") {
        if (!depthWriter) {
            diag.error(display.loc, "display \"{}\": driver \"{}\" writes depth maps, which this render cannot "
                       "produce here",
                       display.name, display.driver);
            return false;
        }
        if (!hasDepth()) {
            diag.error(display.loc, "display \"{}\": driver \"{}\" reads depth, which this film was made without",
                       display.name, display.driver);
            return false;
        }
        return depthWriter(display, *this);
    }

    PreparedOutput o;
    if (!prepareOutput(display, options, metadata, diag, &o)) return false;
    const std::string& path = o.path;
    const Format format = o.format;
    const int nch = int(o.channels.size());
    const size_t npix = size_t(m_width) * size_t(m_height);
    std::unique_ptr<float[]> data;
    if (format != Format::Tiff) {
        // Uninitialised: every value is written below, by the row's thread.
        data.reset(new float[npix * size_t(nch)]);
        // Rows in parallel: the frame's serial tail.
        parallelForRange(tbb::blocked_range<int>(m_y0, y1(), 16), [&](const tbb::blocked_range<int>& rows) {
            for (int y = rows.begin(); y < rows.end(); ++y)
                convertRow(o, y, data.get() + size_t(y - m_y0) * size_t(m_width) * size_t(nch));
        });
    }

    ImageData image = o.image;
    image.pixels = data.get();
    if (!data) {
        // TIFF takes its strips row by row (converted in parallel strips as
        // it compresses them): the display never holds a second copy of
        // the frame, 16 bytes a pixel for rgba (33 MB at 1920 x 1080).
        image.fillRows = [&](int row0, int rows, float* out) {
            for (int r = 0; r < rows; ++r)
                convertRow(o, m_y0 + row0 + r, out + size_t(r) * size_t(m_width) * size_t(nch));
        };
    }
    fs::path target(path);
    fs::path tmp = target.parent_path() / fmt::format(".{}.umbra-tmp-{}", target.filename().string(), ::getpid());
    std::error_code ec;
    auto failWith = [&](const std::string& why) {
        diag.error(display.loc, "display \"{}\": cannot write \"{}\": {}", display.name, path, why);
        fs::remove(tmp, ec);
        return false;
    };
    std::unique_ptr<std::FILE, FileCloser> file(std::fopen(tmp.c_str(), "w+b"));
    if (!file) {
        std::string why = std::strerror(errno);
        diag.error(display.loc, "display \"{}\": cannot write \"{}\": {}", display.name, path, why);
        return false;  // nothing was created
    }
    std::string why;
    bool written = false;
    switch (format) {
    case Format::Exr: written = writeExr(image, file.get(), &why); break;
    case Format::Tiff: written = writeTiff(image, file.get(), &why); break;
    case Format::Png: written = writePng(image, file.get(), &why); break;
    }
    if (!written) return failWith(why);
    // fclose flushes: a full disk shows up here.
    errno = 0;
    if (std::fclose(file.release()) != 0) return failWith(std::strerror(errno ? errno : EIO));
    if (!moveIntoPlace(tmp.string(), target.string())) return failWith(std::strerror(errno));
    return true;
}

template <typename Plane>
void Film::releasePages(Plane& plane, size_t from, size_t to) {
    using T = typename Plane::value_type;
    const size_t bytes = plane.size() * sizeof(T);
    if (bytes < kReleasableBytes || to <= from) return;
    // Whole pages only, inside the plane's block (its first and last
    // partial pages stay): rows before `from` were given back already.
    static const uintptr_t page = uintptr_t(::sysconf(_SC_PAGESIZE));
    const uintptr_t base = reinterpret_cast<uintptr_t>(plane.data());
    const uintptr_t firstWhole = (base + page - 1) / page * page;  // malloc's header sits before base
    const uintptr_t begin = std::max(firstWhole, (base + from * sizeof(T)) / page * page);
    const uintptr_t end = (base + std::min(to, plane.size()) * sizeof(T)) / page * page;
    if (end > begin) ::madvise(reinterpret_cast<void*>(begin), end - begin, MADV_DONTNEED);
}

/// A streamed film's outputs and its bookkeeping of finished rows.
struct FilmStream {
    struct Output {
        PreparedOutput prepared;
        fs::path tmp;
        std::FILE* file = nullptr;
        std::unique_ptr<TiffStream> tiff;  // closed before `file`
        std::string failure;               // the first error; the file is then gone
        std::vector<float> rows;           // one strip's converted rows
        ~Output() {
            if (file) discard();
        }
        /// Closes and removes the temporary file (a failed or abandoned output).
        void discard() {
            tiff.reset();  // libtiff may still write into the file: before fclose
            if (file) std::fclose(file);
            file = nullptr;
            std::error_code ec;
            fs::remove(tmp, ec);
        }
    };
    std::vector<std::unique_ptr<Output>> outputs;
    int strips = 0;
    std::unique_ptr<std::atomic<int>[]> rowPixels;  // per row of the crop region: pixels resolved
    std::unique_ptr<std::atomic<int>[]> stripRows;  // per strip: rows complete
    std::mutex writeMutex;
    int stripsWritten = 0;           // under writeMutex
    std::atomic<int> rowsReleased{0};
    std::atomic<int> rowEnd{0};      // one past the lowest row resolved into
    std::atomic<int> heldPeak{0};
    bool finished = false;
    int rowsOfStrip(int s, int height) const { return std::min(kTiffRowsPerStrip, height - s * kTiffRowsPerStrip); }
};

bool Film::streamable(const std::vector<scene::DisplayRecord>& displays) {
    if (displays.empty()) return false;
    std::vector<std::string> filesAskedFor;
    for (const scene::DisplayRecord& d : displays)
        if (writesItsOwnFile(d.driver)) filesAskedFor.push_back(d.name);
    for (const scene::DisplayRecord& d : displays) {
        const std::string driver = lower(d.driver);
        if (driver == "tiff") continue;
        if (driver == "zfile" || driver == "shadow" || driver == "openexr" || driver == "exr" || driver == "png")
            return false;
        const std::string path = displayFilePath(d);
        if (!writesItsOwnFile(d.driver) &&
            std::find(filesAskedFor.begin(), filesAskedFor.end(), path) != filesAskedFor.end())
            continue;  // a window whose stand-in another display writes: skipped
        if (formatOfExtension(path).value_or(Format::Tiff) != Format::Tiff) return false;
    }
    return true;
}

bool Film::openStream(const std::vector<scene::DisplayRecord>& displays, const scene::Options& options,
                      const OutputMetadata& metadata, Diagnostics& diag) {
    UMBRA_CHECK(!m_stream, "the film is streamed already");
    auto stream = std::make_unique<FilmStream>();
    std::vector<std::string> filesAskedFor;
    for (const scene::DisplayRecord& d : displays)
        if (writesItsOwnFile(d.driver)) filesAskedFor.push_back(d.name);
    bool ok = true;
    for (const scene::DisplayRecord& d : displays) {
        if (!writesItsOwnFile(d.driver)) {  // as write() does
            const std::string standIn = displayFilePath(d);
            if (std::find(filesAskedFor.begin(), filesAskedFor.end(), standIn) != filesAskedFor.end()) {
                diag.warningOnce("display-driver:" + lower(d.driver), d.loc,
                                 "display driver \"{}\": umbra has no window, and \"{}\" is written by another "
                                 "Display; this one is skipped", d.driver, standIn);
                continue;
            }
        }
        auto out = std::make_unique<FilmStream::Output>();
        if (!prepareOutput(d, options, metadata, diag, &out->prepared)) {
            ok = false;
            continue;
        }
        UMBRA_CHECK(out->prepared.format == Format::Tiff, "display \"{}\" is not a TIFF", d.name);
        const fs::path target(out->prepared.path);
        // The display's index keeps two displays of one file apart; the
        // last renamed wins, as the last written does in write().
        out->tmp = target.parent_path() / fmt::format(".{}.umbra-tmp-{}-{}", target.filename().string(), ::getpid(),
                                                      stream->outputs.size());
        out->file = std::fopen(out->tmp.c_str(), "w+b");
        if (!out->file) {
            diag.error(d.loc, "display \"{}\": cannot write \"{}\": {}", d.name, out->prepared.path,
                       std::strerror(errno));
            ok = false;
            continue;
        }
        out->tiff = std::make_unique<TiffStream>();
        std::string why;
        if (!out->tiff->open(out->prepared.image, out->file, &why)) {
            diag.error(d.loc, "display \"{}\": cannot write \"{}\": {}", d.name, out->prepared.path, why);
            out->discard();
            ok = false;
            continue;
        }
        stream->outputs.push_back(std::move(out));
    }
    const int rows = std::max(m_height, 0);
    stream->strips = (rows + kTiffRowsPerStrip - 1) / kTiffRowsPerStrip;
    stream->rowPixels = std::make_unique<std::atomic<int>[]>(size_t(rows));
    stream->stripRows = std::make_unique<std::atomic<int>[]>(size_t(stream->strips));
    for (int r = 0; r < rows; ++r) stream->rowPixels[size_t(r)] = 0;
    for (int t = 0; t < stream->strips; ++t) stream->stripRows[size_t(t)] = 0;
    m_stream = std::move(stream);
    // The depth planes start at +infinity (touching every page): a streamed
    // film gives them back at once, and each bucket writes its own depths
    // (colour buckets always do; empty depth buckets by clearDepth).
    m_stream->rowsReleased = 0;
    releasePages(m_z, 0, m_z.size());
    releasePages(m_z2, 0, m_z2.size());
    return ok;
}

void Film::noteDepthWritten(int x0, int y0, int x1, int y1) {
    std::lock_guard<std::mutex> lock(m_unsetDepth->mutex);
    DepthWindow& w = m_unsetDepth->written;
    w = {std::min(w.x0, x0), std::min(w.y0, y0), std::max(w.x1, x1), std::max(w.y1, y1)};
}

Film::DepthWindow Film::settleDepth() {
    if (!m_unsetDepth) return {m_x0, m_y0, x1(), y1()};
    DepthBook& book = *m_unsetDepth;
    DepthWindow w = book.written;
    w = {std::max(w.x0, m_x0), std::max(w.y0, m_y0), std::min(w.x1, x1()), std::min(w.y1, y1())};
    if (w.x0 >= w.x1 || w.y0 >= w.y1) w = {m_x0, m_y0, m_x0, m_y0};
    for (const DepthWindow& e : book.empty) {
        const int ex0 = std::max(e.x0, w.x0), ex1 = std::min(e.x1, w.x1);
        for (int y = std::max(e.y0, w.y0); y < std::min(e.y1, w.y1) && ex0 < ex1; ++y) {
            std::fill(&z(ex0, y), &z(ex0, y) + (ex1 - ex0), kInfinity);
            if (hasDepthPair()) std::fill(&z2(ex0, y), &z2(ex0, y) + (ex1 - ex0), kInfinity);
        }
    }
    m_unsetDepth.reset();  // settled: the window's depths are all defined
    return w;
}

void Film::clearDepth(int x0, int y0, int x1, int y1) {
    if (m_unsetDepth) {
        std::lock_guard<std::mutex> lock(m_unsetDepth->mutex);
        m_unsetDepth->empty.push_back({x0, y0, x1, y1});
        return;
    }
    if (!m_stream || !hasDepth()) return;
    x0 = std::max(x0, m_x0), y0 = std::max(y0, m_y0), x1 = std::min(x1, this->x1()), y1 = std::min(y1, this->y1());
    for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) {
            z(x, y) = kInfinity;
            if (hasDepthPair()) z2(x, y) = kInfinity;
        }
}

void Film::bucketDone(int x0, int y0, int x1, int y1) {
    if (!m_stream) return;
    FilmStream& s = *m_stream;
    x0 = std::max(x0, m_x0), y0 = std::max(y0, m_y0), x1 = std::min(x1, this->x1()), y1 = std::min(y1, this->y1());
    if (x0 >= x1 || y0 >= y1) return;
    // Rows held: from the first row not yet released to the lowest row
    // resolved into, as this bucket ends (before it releases any).
    int end = s.rowEnd.load();
    while (y1 - m_y0 > end && !s.rowEnd.compare_exchange_weak(end, y1 - m_y0)) {
    }
    const int held = std::max(end, y1 - m_y0) - s.rowsReleased.load();
    int peak = s.heldPeak.load();
    while (held > peak && !s.heldPeak.compare_exchange_weak(peak, held)) {
    }
    bool stripComplete = false;
    for (int y = y0; y < y1; ++y) {
        const int r = y - m_y0;
        if (s.rowPixels[size_t(r)].fetch_add(x1 - x0, std::memory_order_acq_rel) + (x1 - x0) != m_width) continue;
        const int strip = r / kTiffRowsPerStrip;
        if (s.stripRows[size_t(strip)].fetch_add(1, std::memory_order_acq_rel) + 1 == s.rowsOfStrip(strip, m_height))
            stripComplete = true;
    }
    if (!stripComplete) return;
    std::lock_guard<std::mutex> lock(s.writeMutex);
    writeCompleteStrips();
}

void Film::writeCompleteStrips() {
    FilmStream& s = *m_stream;
    while (s.stripsWritten < s.strips &&
           s.stripRows[size_t(s.stripsWritten)].load(std::memory_order_acquire) ==
               s.rowsOfStrip(s.stripsWritten, m_height)) {
        const int strip = s.stripsWritten;
        const int rows = s.rowsOfStrip(strip, m_height);
        for (auto& o : s.outputs) {
            if (!o->failure.empty()) continue;
            const size_t rowValues = size_t(m_width) * o->prepared.channels.size();
            o->rows.resize(rowValues * size_t(rows));
            for (int r = 0; r < rows; ++r)
                convertRow(o->prepared, m_y0 + strip * kTiffRowsPerStrip + r, o->rows.data() + rowValues * size_t(r));
            std::string why;
            if (!o->tiff->writeStrip(uint32_t(strip), o->rows.data(), &why)) {
                o->failure = why.empty() ? "libtiff could not write a strip" : why;
                o->discard();  // no temporary file outlives a failed write
            }
        }
        ++s.stripsWritten;
        releaseRows(strip * kTiffRowsPerStrip + rows);
    }
}

void Film::releaseRows(int rows) {
    const int before = m_stream->rowsReleased.load();
    if (rows <= before) return;
    const size_t pixels0 = size_t(before) * size_t(m_width), pixels1 = size_t(rows) * size_t(m_width);
    auto plane = [&](auto& v, size_t perPixel) { releasePages(v, pixels0 * perPixel, pixels1 * perPixel); };
    plane(m_rgba, 4);
    plane(m_aov, size_t(m_aovFloats));
    plane(m_z, 1);
    plane(m_z2, 1);
    for (FilterLayer& l : m_layers) {
        plane(l.rgba, 4);
        plane(l.aov, size_t(m_aovFloats));
    }
    m_stream->rowsReleased = rows;
}

bool Film::finishStream(Diagnostics& diag) {
    if (!m_stream || m_stream->finished) return false;
    FilmStream& s = *m_stream;
    {
        std::lock_guard<std::mutex> lock(s.writeMutex);
        writeCompleteStrips();
    }
    s.finished = true;
    if (s.stripsWritten < s.strips) {  // rows never resolved: an interrupted render
        for (auto& o : s.outputs) o->discard();
        return false;
    }
    bool ok = true;
    for (auto& o : s.outputs) {
        const PreparedOutput& p = o->prepared;
        auto failWith = [&](const std::string& why) {
            diag.error(p.loc, "display \"{}\": cannot write \"{}\": {}", p.name, p.path, why);
            o->discard();
            ok = false;
        };
        if (!o->failure.empty()) {
            failWith(o->failure);
            continue;
        }
        std::string why;
        if (!o->tiff->finish(&why)) {
            failWith(why);
            continue;
        }
        o->tiff.reset();
        // fclose flushes: a full disk shows up here.
        errno = 0;
        const int closed = std::fclose(o->file);
        o->file = nullptr;
        if (closed != 0) {
            failWith(std::strerror(errno ? errno : EIO));
            continue;
        }
        if (!moveIntoPlace(o->tmp.string(), p.path)) failWith(std::strerror(errno));
    }
    return ok;
}

void Film::abandonStream() {
    if (!m_stream) return;
    std::lock_guard<std::mutex> lock(m_stream->writeMutex);
    m_stream->finished = true;
    for (auto& o : m_stream->outputs) o->discard();
}

int Film::rowsHeldPeak() const { return m_stream ? m_stream->heldPeak.load() : m_height; }

Film::~Film() {
    if (m_stream && !m_stream->finished) abandonStream();
}
Film::Film(Film&&) noexcept = default;
Film& Film::operator=(Film&&) noexcept = default;

}  // namespace umbra::film
