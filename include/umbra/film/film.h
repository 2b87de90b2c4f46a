#pragma once
// The film: the filtered image of one render, and its output to the
// `Display` requests of the frame.
//
// Pixel coordinates are raster pixels of the full resolution (pixel (x, y)
// covers [x, x+1) x [y, y+1), y down). The film stores only the crop
// window's pixels (RenderMan `CropWindow`); see Film::cropPixels.

#include "umbra/film/pixel_filter.h"
#include "umbra/scene/scene.h"
#include "umbra/util/error.h"
#include "umbra/util/math.h"
#include "umbra/util/zeroed_allocator.h"

#include <sys/mman.h>

#include <atomic>
#include <cstdlib>
#include <functional>
#include <memory>
#include <new>
#include <optional>
#include <string>
#include <vector>

namespace umbra::film {

/// A named arbitrary output variable (AOV) the film stores per pixel, e.g.
/// {"N", 3} or {"myfloat", 1}. The hider's per-vertex AOV data lists the
/// film's AOVs in order, components consecutive.
struct AovChannel {
    std::string name;
    int components = 1;
};

/// A parsed `Display` mode: either a combination of the standard channels
/// ("rgb", "rgba", "z", "rgbaz", "a", ... : letters out of r g b a z, each at
/// most once, in the order given) or one AOV ("color myaov", "float foo",
/// "varying normal N", or a standard variable name alone: "Ci", "N", "s").
struct DisplayMode {
    std::string standard;   // the r/g/b/a/z letters; empty for an AOV
    std::string aovName;    // the AOV's name; empty for standard channels
    int aovComponents = 0;  // 1 or 3
    bool isAov() const { return !aovName.empty(); }
};
/// Parses a display mode; false (and *error says what was expected) when it
/// is not one.
bool parseDisplayMode(const std::string& mode, DisplayMode* out, std::string* error);

/// Whether a display reads the film's depth: a zfile or shadow driver, or
/// a mode with z. A mode that does not parse counts as reading it (the
/// film keeps depth, and Film::write reports the mode).
bool displayReadsDepth(const scene::DisplayRecord& display);
/// Whether a display is a depth map (the zfile or shadow driver), which
/// Film::write hands to its DepthWriter.
bool writesDepthMap(const scene::DisplayRecord& display);

/// The AOV channels a film needs so that every AOV display in `displays`
/// can be written, in first-seen order, each name once. Modes that do not
/// parse are skipped here (Film::write reports them).
std::vector<AovChannel> aovChannelsFor(const std::vector<scene::DisplayRecord>& displays);

/// RenderMan's `Quantize`: value = round(one * v + dither * r), r uniform in
/// [-1, 1) from a hash of the pixel, clamped to [min, max]; one = 0 means
/// floating-point output (no quantisation).
struct Quantize {
    float one = 0, min = 0, max = 0, dither = 0;
    bool enabled() const { return one != 0; }
};

/// What the renderer knows about the frame for output metadata.
struct OutputMetadata {
    double renderSeconds = -1;          // < 0: not written
    std::string dateTime;               // "YYYY:MM:DD HH:MM:SS"; empty: not written
    std::optional<Mat4> cameraFromWorld;  // written as worldToCamera on z outputs
    std::optional<Mat4> ndcFromWorld;     // written as worldToNDC on z outputs
};

/// The pixel filter a display is resolved with: its own `"string filter"`
/// and `"float[2] filterwidth"` (one float: both widths) when it gives
/// them, else the frame's. A name without widths takes the frame's
/// widths; widths without a name, the frame's filter shape. Displays of
/// depth only ("z", and the "zfile"/"shadow" drivers) are never filtered:
/// nullopt, as for a display without a filter of its own. An unknown name
/// or bad widths are reported (when diag is given) as a warning at the
/// parameter, naming the display, and give nullopt: the frame's filter.
std::optional<PixelFilter> displayFilter(const scene::DisplayRecord& display, const PixelFilter& frameFilter,
                                         Diagnostics* diag);
/// True when two filters weight every sample alike (same shape and widths).
bool sameFilter(const PixelFilter& a, const PixelFilter& b);

class Film;
struct PreparedOutput;
struct FilmStream;
/// Writes a depth-map display ("zfile", "shadow" drivers); the renderer
/// wires it to the shadow module. Returns false after reporting an error.
using DepthWriter = std::function<bool(const scene::DisplayRecord&, const Film&)>;

/// The filtered image of one render: r g b a, z (nearest opaque depth, camera
/// space, +infinity where nothing was hit), optionally z2 (the depth pass's
/// second-nearest depth), and the AOV channels, for the crop window's pixels.
/// A depth film holds only z (and z2 for a two-layer depth pass): its colour
/// reads as black. Buckets resolve into disjoint pixel ranges, so concurrent
/// writers need no lock.
enum class FilmContent {
    Colour,     ///< r g b a, z and the AOVs
    ColourOnly, ///< r g b a and the AOVs, no z: a colour frame none of whose displays reads depth
    Depth,      ///< z only (depth passes of one layer)
    DepthPair,  ///< z and z2 (depth passes of two layers)
};

inline bool contentHasColour(FilmContent c) { return c == FilmContent::Colour || c == FilmContent::ColourOnly; }

class Film {
public:
    /// How a film's depths start: at +infinity, or unset (see settleDepth).
    enum class DepthStart { Infinity, Unset };
    Film(int xResolution, int yResolution, const float cropWindow[4], PixelFilter filter,
         std::vector<AovChannel> aovs = {}, FilmContent content = FilmContent::Colour,
         DepthStart depthStart = DepthStart::Infinity);
    ~Film();  // an open stream is abandoned: its temporary files removed
    Film(Film&&) noexcept;
    Film& operator=(Film&&) noexcept;
    /// Bytes a film of this size and content allocates (its cropped pixels,
    /// filter layers not counted).
    static uint64_t bytesFor(int xResolution, int yResolution, const float cropWindow[4],
                             const std::vector<AovChannel>& aovs, FilmContent content);
    /// From the frame options (resolution, crop window, pixel filter). An
    /// unknown filter is reported at the options' location and replaced by
    /// RenderMan's default (gaussian 2 x 2). `displays`: the frame's
    /// displays; the colour displays with filters of their own
    /// (displayFilter) get a filter layer for each distinct filter other
    /// than the frame's; an unknown one is reported here.
    static Film fromOptions(const scene::Options& options, std::vector<AovChannel> aovs, FilmContent content,
                            Diagnostics& diag, const std::vector<scene::DisplayRecord>& displays = {},
                            DepthStart depthStart = DepthStart::Infinity);

    /// The pixels a crop window selects: those whose centres lie in the
    /// window (PRMan's rule), x in [x0, x1), y in [y0, y1), with
    /// x0 = clamp(ceil(xres * xmin - 0.5), 0, xres),
    /// x1 = clamp(ceil(xres * xmax - 0.5), x0, xres), the same for y (NDC y
    /// is down, as raster y); edges within 1e-4 pixel count as inside.
    static void cropPixels(int xResolution, int yResolution, const float cropWindow[4], int* x0, int* x1, int* y0,
                           int* y1);

    int xResolution() const { return m_xres; }
    int yResolution() const { return m_yres; }
    int x0() const { return m_x0; }
    int y0() const { return m_y0; }
    int x1() const { return m_x0 + m_width; }
    int y1() const { return m_y0 + m_height; }
    int width() const { return m_width; }
    int height() const { return m_height; }
    bool contains(int x, int y) const { return x >= m_x0 && y >= m_y0 && x < x1() && y < y1(); }
    /// The frame's pixel filter: filter layer 0.
    const PixelFilter& filter() const { return m_filter; }

    /// Filter layers: the same samples resolved with another pixel filter,
    /// for the displays that ask for their own (a colour and an AOV plane
    /// each; depth is shared, never filtered). Layer 0 is the frame's
    /// filter, the planes rgba() and aov() reach.
    int filterLayers() const { return 1 + int(m_layers.size()); }
    const PixelFilter& filter(int layer) const { return layer == 0 ? m_filter : m_layers[size_t(layer - 1)].filter; }
    /// Adds a layer for `filter` (unless one has it); returns its index.
    int addFilterLayer(const PixelFilter& filter);
    /// The layer whose filter is `filter`, or -1.
    int findFilterLayer(const PixelFilter& filter) const;
    /// The widest reach of any layer's filter (see PixelFilter::margin):
    /// the margin buckets need around their pixels.
    int filterMargin() const;
    float* rgba(int layer, int x, int y) {
        return layer == 0 ? rgba(x, y) : &m_layers[size_t(layer - 1)].rgba[4 * index(x, y)];
    }
    const float* rgba(int layer, int x, int y) const {
        return layer == 0 ? rgba(x, y) : &m_layers[size_t(layer - 1)].rgba[4 * index(x, y)];
    }
    float* aov(int layer, int x, int y) {
        return layer == 0 ? aov(x, y) : m_layers[size_t(layer - 1)].aov.data() + size_t(m_aovFloats) * index(x, y);
    }
    const float* aov(int layer, int x, int y) const {
        return layer == 0 ? aov(x, y) : m_layers[size_t(layer - 1)].aov.data() + size_t(m_aovFloats) * index(x, y);
    }

    const std::vector<AovChannel>& aovs() const { return m_aovs; }
    /// Floats per pixel over all AOVs.
    int aovFloats() const { return m_aovFloats; }
    /// Index of the AOV called `name`, or -1.
    int findAov(const std::string& name) const;
    /// First float of AOV `index` within a pixel's AOV floats.
    int aovOffset(int index) const { return m_aovOffsets[size_t(index)]; }
    bool hasDepthPair() const { return m_content == FilmContent::DepthPair; }
    /// False for a ColourOnly film, which has no z plane (z() must not be called).
    bool hasDepth() const { return m_content != FilmContent::ColourOnly; }
    bool hasColour() const { return contentHasColour(m_content); }

    /// Pixel access by raster coordinates (must be inside the crop region).
    float* rgba(int x, int y) { return &m_rgba[4 * index(x, y)]; }
    const float* rgba(int x, int y) const { return m_rgba.empty() ? kNoColour : &m_rgba[4 * index(x, y)]; }
    float& z(int x, int y) { return m_z[index(x, y)]; }
    float z(int x, int y) const { return m_z[index(x, y)]; }
    /// The depths of row y, from x0() to x1() (contiguous).
    const float* zRow(int y) const { return &m_z[index(m_x0, y)]; }
    const float* z2Row(int y) const { return &m_z2[index(m_x0, y)]; }
    float& z2(int x, int y) { return m_z2[index(x, y)]; }
    /// Hands the nearest-depth plane over, rows of the whole image, when
    /// the film covers its whole image (a depth pass's film becoming its
    /// map's image without a copy: on hosts where a page's first touch
    /// costs microseconds, the copy was a third of a small map's pass).
    /// Empty, the film unchanged, otherwise. The film has no depths after.
    FloatPlane takeDepth() {
        if (m_x0 != 0 || m_y0 != 0 || m_width != m_xres || m_height != m_yres) return {};
        return std::move(m_z);
    }
    float z2(int x, int y) const { return m_z2[index(x, y)]; }
    float* aov(int x, int y) { return m_aov.data() + size_t(m_aovFloats) * index(x, y); }
    const float* aov(int x, int y) const { return m_aov.data() + size_t(m_aovFloats) * index(x, y); }

    /// Writes every display of the frame (see docs in film.cpp for drivers
    /// and modes). Each file is written under a temporary name in its
    /// directory and renamed into place, so no half-written image is left.
    /// Errors are reported at the display's location; returns false if any
    /// display failed.
    bool write(const std::vector<scene::DisplayRecord>& displays, const scene::Options& options,
               const OutputMetadata& metadata, Diagnostics& diag, const DepthWriter& depthWriter = {}) const;
    /// Writes one display.
    bool writeDisplay(const scene::DisplayRecord& display, const scene::Options& options,
                      const OutputMetadata& metadata, Diagnostics& diag, const DepthWriter& depthWriter = {}) const;

    // --- Streamed output ------------------------------------------------
    // When every display of a frame is a TIFF and nothing else needs the
    // whole film afterwards (no imager, no depth-map or EXR/PNG display),
    // the film is written while the buckets render: each TIFF strip
    // (kTiffRowsPerStrip rows of the crop region) is converted, compressed
    // and written as soon as every bucket covering its rows has resolved,
    // and those rows' storage is given back to the system. The files are
    // byte for byte those of write(): the same conversion and the same
    // libtiff calls in the same order. Docs: docs/pipeline.md ("Output while
    // rendering").

    /// True when write() of these displays could be streamed instead: each
    /// one that write() would write (not a window whose stand-in file
    /// another display writes) is a TIFF written by the film.
    static bool streamable(const std::vector<scene::DisplayRecord>& displays);
    /// Opens every display of `displays` (streamable()) under a temporary
    /// name in its directory. A display that cannot be written is reported
    /// here, as write() would report it, and left out. Returns false if any
    /// display failed; the others are still streamed. Call before rendering.
    bool openStream(const std::vector<scene::DisplayRecord>& displays, const scene::Options& options,
                    const OutputMetadata& metadata, Diagnostics& diag);
    bool streaming() const { return m_stream != nullptr; }
    /// A bucket has resolved the pixels [x0, x1) x [y0, y1) (clipped to the
    /// crop region). Thread-safe. When strips are then complete, this
    /// thread writes every complete strip not yet written, in order, under
    /// the stream's lock, and releases their rows' storage. Also counts the
    /// rows held (see rowsHeldPeak); without a stream nothing is written.
    void bucketDone(int x0, int y0, int x1, int y1);
    /// A depth bucket no primitive reaches: in a streamed film its depths
    /// are set to +infinity (a streamed film's depth starts unset); in a
    /// film whose depths start unset it is remembered for settleDepth.
    void clearDepth(int x0, int y0, int x1, int y1);
    /// A bucket resolved its depths into [x0, x1) x [y0, y1). Thread-safe.
    void depthWritten(int x0, int y0, int x1, int y1) {
        if (m_unsetDepth) noteDepthWritten(x0, y0, x1, y1);
    }
    /// The rectangle [x0, x1) x [y0, y1) of a film's written depths.
    struct DepthWindow {
        int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    };
    /// After a pass: the bounding box of the buckets that wrote depths,
    /// the buckets inside it that did not set to +infinity, so that every
    /// texel in the box is defined; outside it the depths are +infinity
    /// and their pages were never touched (a sparse light map's film costs
    /// only what its casters cover). A film whose depths started at
    /// +infinity: its whole crop region.
    DepthWindow settleDepth();
    /// Writes what is left, each file's directory, and renames the files
    /// into place. Errors (a failed write, here or while streaming) are
    /// reported at the display; a failed display leaves no file, and an
    /// earlier image at its path untouched. Returns false if any failed.
    /// A film whose rows are not all done (an interrupted render) writes
    /// nothing and returns false without a report.
    bool finishStream(Diagnostics& diag);
    /// Removes the stream's temporary files without writing (interrupts).
    void abandonStream();
    /// The most rows of film storage held at once: rows some bucket had
    /// resolved into and not yet released. The film's height unless streamed.
    int rowsHeldPeak() const;

private:
    size_t index(int x, int y) const { return size_t(y - m_y0) * size_t(m_width) + size_t(x - m_x0); }

    int m_xres, m_yres;
    int m_x0 = 0, m_y0 = 0, m_width = 0, m_height = 0;
    PixelFilter m_filter;
    std::vector<AovChannel> m_aovs;
    std::vector<int> m_aovOffsets;
    int m_aovFloats = 0;
    FilmContent m_content = FilmContent::Colour;
    static constexpr float kNoColour[4] = {0, 0, 0, 0};  // a depth film's pixels
    bool prepareOutput(const scene::DisplayRecord& display, const scene::Options& options,
                       const OutputMetadata& metadata, Diagnostics& diag, PreparedOutput* out) const;
    /// One row of a prepared display's samples, width * channels values.
    void convertRow(const PreparedOutput& out, int y, float* values) const;
    /// Writes the strips that are complete and not yet written; the stream's
    /// write lock held.
    void writeCompleteStrips();
    /// Gives rows [m_y0, m_y0 + rows) of every plane back to the system.
    void releaseRows(int rows);
    /// Gives the whole pages inside values [from, to) of a plane back to
    /// the system (they read as zeros after); those before `from` were
    /// given back already. Planes under kReleasableBytes keep theirs.
    template <typename Plane>
    static void releasePages(Plane& plane, size_t from, size_t to);

    /// Planes from this size up give finished rows back (releasePages).
    static constexpr size_t kReleasableBytes = size_t(64) << 10;
    FloatPlane m_rgba, m_aov;
    FloatPlane m_z, m_z2;
    struct FilterLayer {
        PixelFilter filter;
        FloatPlane rgba, aov;
    };
    std::vector<FilterLayer> m_layers;  // layers 1..
    std::unique_ptr<FilmStream> m_stream;  // openStream .. finishStream
    /// Depths that start unset: which buckets wrote them, which were empty.
    struct DepthBook;
    std::unique_ptr<DepthBook> m_unsetDepth;
    void noteDepthWritten(int x0, int y0, int x1, int y1);
};

/// The file `display` is written to: its name, with ".tif" appended for a
/// window or unknown driver when the name has no image extension (such a
/// display goes to a file, as the "file" driver would write it).
std::string displayFilePath(const scene::DisplayRecord& display);

/// True when `path` is a complete image umbra can have written: a TIFF,
/// OpenEXR (any parts, scanline or tiled), PNG or zfile whose header and
/// every pixel read back. Otherwise false, with `*why` saying what is
/// wrong ("missing", a truncated strip, ...). For `--resume`.
bool imageFileComplete(const std::string& path, std::string* why = nullptr);

}  // namespace umbra::film
