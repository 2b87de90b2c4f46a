// TIFF output through libtiff.
//
// Strips of 32 rows, contiguous (interleaved) samples: 8/16-bit unsigned or
// 32-bit IEEE float. One or two channels are min-is-black, three or more
// RGB; channels past the photometric ones are ExtraSamples, "associated
// alpha" for the alpha channel (the film's colour is premultiplied) and
// "unspecified" for the rest (z, AOVs). A crop region is written as the
// image, placed by XPosition/YPosition (in pixels: no resolution tags) and
// the Pixar full-size tags, the convention OpenImageIO and PRMan read. Depth
// outputs carry the Pixar world-to-camera and world-to-screen matrices.

#include "image_file.h"

#include "umbra/util/parallel.h"
#include <tiffio.h>
#include <libdeflate.h>

#include <sys/stat.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdarg>
#include <cstddef>
#include <cstring>
#include <memory>
#include <optional>
#include <vector>

namespace umbra::film {

namespace {

/// TIFF's horizontal differencing predictor (Predictor 2) on one row of
/// `count` samples of `channels` interleaved channels, in place.
template <typename T>
void horizontalDifference(T* row, size_t count, int channels) {
    for (size_t i = count; i-- > size_t(channels);) row[i] = T(row[i] - row[i - size_t(channels)]);
}

/// The client handle libtiff passes to the I/O callbacks; the first error
/// (from the stream or from libtiff) is kept for the caller's message.
struct TiffSink {
    std::FILE* file;
    std::string failure;
    void ioFailed() {
        if (failure.empty()) failure = std::strerror(errno ? errno : EIO);
    }
};

int onError(TIFF*, void* user, const char* module, const char* fmt, va_list ap) {
    auto* sink = static_cast<TiffSink*>(user);
    if (sink->failure.empty()) {
        char buf[512];
        std::vsnprintf(buf, sizeof buf, fmt, ap);
        sink->failure = module && *module ? std::string(module) + ": " + buf : std::string(buf);
    }
    return 1;  // handled: not passed on to libtiff's global stderr handler
}

int onWarning(TIFF*, void*, const char*, const char*, va_list) { return 1; }

tmsize_t readProc(thandle_t h, void* buf, tmsize_t n) {
    auto* s = static_cast<TiffSink*>(h);
    return tmsize_t(std::fread(buf, 1, size_t(n), s->file));
}

tmsize_t writeProc(thandle_t h, void* buf, tmsize_t n) {
    auto* s = static_cast<TiffSink*>(h);
    size_t done = std::fwrite(buf, 1, size_t(n), s->file);
    if (done != size_t(n)) s->ioFailed();
    return tmsize_t(done);
}

toff_t seekProc(thandle_t h, toff_t offset, int whence) {
    auto* s = static_cast<TiffSink*>(h);
    if (::fseeko(s->file, off_t(offset), whence) != 0) {
        s->ioFailed();
        return toff_t(-1);
    }
    return toff_t(::ftello(s->file));
}

int closeProc(thandle_t) { return 0; }  // the caller owns and closes the stream

toff_t sizeProc(thandle_t h) {
    auto* s = static_cast<TiffSink*>(h);
    std::fflush(s->file);
    struct stat st {};
    if (::fstat(::fileno(s->file), &st) != 0) return 0;
    return toff_t(st.st_size);
}

int mapProc(thandle_t, void**, toff_t*) { return 0; }
void unmapProc(thandle_t, void*, toff_t) {}

std::optional<uint16_t> tiffCompression(const std::string& name) {
    if (name.empty() || name == "zip" || name == "deflate") return uint16_t(COMPRESSION_ADOBE_DEFLATE);
    if (name == "none") return uint16_t(COMPRESSION_NONE);
    if (name == "lzw") return uint16_t(COMPRESSION_LZW);
    if (name == "packbits") return uint16_t(COMPRESSION_PACKBITS);
    return std::nullopt;
}

struct DeflateFree {
    void operator()(libdeflate_compressor* c) const { libdeflate_free_compressor(c); }
};

/// Closes the TIFF handle on every path.
struct TiffCloser {
    void operator()(TIFF* t) const { TIFFClose(t); }
};

}  // namespace

bool tiffCompressionKnown(const std::string& name) { return tiffCompression(name).has_value(); }

struct TiffStream::Impl {
    ImageData image;  // the tags' values (no pixels)
    int nch = 0;
    SampleType type = SampleType::UInt8;
    int bytesPerSample = 1;
    size_t rowValues = 0;
    uint16_t compression = COMPRESSION_ADOBE_DEFLATE;
    uint32_t nStrips = 0;
    TiffSink sink{nullptr, {}};
    std::unique_ptr<TIFF, TiffCloser> tif;
    std::vector<unsigned char> strip;  // writeStrip's packed samples

    bool fail(const char* what, std::string* error) {
        *error = sink.failure.empty() ? std::string(what) : sink.failure;
        return false;
    }
    /// Rows as the file's samples, in native byte order (the order libtiff
    /// writes the file in).
    void pack(const float* src, uint32_t rows, unsigned char* dst) const {
        const size_t n = rowValues * rows;
        switch (type) {
        case SampleType::UInt8:
            for (size_t i = 0; i < n; ++i) dst[i] = static_cast<unsigned char>(src[i]);
            break;
        case SampleType::UInt16: {
            auto* d = reinterpret_cast<uint16_t*>(dst);
            for (size_t i = 0; i < n; ++i) d[i] = static_cast<uint16_t>(src[i]);
            break;
        }
        case SampleType::Half:
        case SampleType::Float: std::memcpy(dst, src, n * sizeof(float)); break;
        }
    }
};

TiffStream::TiffStream() : m(std::make_unique<Impl>()) {}
TiffStream::~TiffStream() = default;

uint32_t TiffStream::strips() const { return m->nStrips; }
uint32_t TiffStream::rowsOf(uint32_t s) const {
    return std::min(uint32_t(kTiffRowsPerStrip), uint32_t(m->image.height) - s * uint32_t(kTiffRowsPerStrip));
}
bool TiffStream::precompresses() const {
    return m->compression == COMPRESSION_ADOBE_DEFLATE &&
           (m->type == SampleType::UInt8 || m->type == SampleType::UInt16);
}

bool TiffStream::open(const ImageData& imageIn, std::FILE* file, std::string* error) {
    m->image = imageIn;
    m->image.pixels = nullptr;
    m->image.fillRows = nullptr;
    const ImageData& image = m->image;
    const int nch = m->nch = image.channels();
    const SampleType type = m->type = image.types[0];
    const int bytesPerSample = m->bytesPerSample =
        type == SampleType::UInt8 ? 1 : type == SampleType::UInt16 ? 2 : 4;
    const size_t rowValues = m->rowValues = size_t(image.width) * size_t(nch);
    const size_t rawBytes = rowValues * size_t(image.height) * size_t(bytesPerSample);

    m->sink = TiffSink{file, {}};
    TIFFOpenOptions* opts = TIFFOpenOptionsAlloc();
    TIFFOpenOptionsSetErrorHandlerExtR(opts, onError, &m->sink);
    TIFFOpenOptionsSetWarningHandlerExtR(opts, onWarning, &m->sink);
    // Classic TIFF addresses 4 GiB; bigger images need BigTIFF.
    const char* mode = rawBytes > (uint64_t(3) << 30) ? "w8" : "w";
    m->tif.reset(TIFFClientOpenExt("umbra image", mode, &m->sink, readProc, writeProc, seekProc, closeProc, sizeProc,
                                   mapProc, unmapProc, opts));
    TIFFOpenOptionsFree(opts);
    if (!m->tif) return m->fail("libtiff could not start the file", error);
    TIFF* t = m->tif.get();

    const uint16_t compression = m->compression =
        tiffCompression(image.compression).value_or(uint16_t(COMPRESSION_ADOBE_DEFLATE));
    const uint32_t rowsPerStrip = kTiffRowsPerStrip;
    const int photometricChannels = nch >= 3 ? 3 : 1;
    std::vector<uint16_t> extra;
    for (int c = photometricChannels; c < nch; ++c)
        extra.push_back(image.roles[size_t(c)] == ChannelRole::Alpha ? uint16_t(EXTRASAMPLE_ASSOCALPHA)
                                                                    : uint16_t(EXTRASAMPLE_UNSPECIFIED));
    bool ok = TIFFSetField(t, TIFFTAG_IMAGEWIDTH, uint32_t(image.width)) &&
              TIFFSetField(t, TIFFTAG_IMAGELENGTH, uint32_t(image.height)) &&
              TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, uint16_t(nch)) &&
              TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, uint16_t(8 * bytesPerSample)) &&
              TIFFSetField(t, TIFFTAG_SAMPLEFORMAT,
                           uint16_t(type == SampleType::Float ? SAMPLEFORMAT_IEEEFP : SAMPLEFORMAT_UINT)) &&
              TIFFSetField(t, TIFFTAG_PHOTOMETRIC,
                           uint16_t(photometricChannels == 3 ? PHOTOMETRIC_RGB : PHOTOMETRIC_MINISBLACK)) &&
              TIFFSetField(t, TIFFTAG_PLANARCONFIG, uint16_t(PLANARCONFIG_CONTIG)) &&
              TIFFSetField(t, TIFFTAG_ORIENTATION, uint16_t(ORIENTATION_TOPLEFT)) &&
              TIFFSetField(t, TIFFTAG_ROWSPERSTRIP, rowsPerStrip) &&
              TIFFSetField(t, TIFFTAG_COMPRESSION, compression) &&
              TIFFSetField(t, TIFFTAG_SOFTWARE, image.software.c_str());
    if (ok && !extra.empty()) ok = TIFFSetField(t, TIFFTAG_EXTRASAMPLES, uint16_t(extra.size()), extra.data());
    if (ok && (compression == COMPRESSION_ADOBE_DEFLATE || compression == COMPRESSION_LZW))
        ok = TIFFSetField(t, TIFFTAG_PREDICTOR,
                          uint16_t(type == SampleType::Float ? PREDICTOR_FLOATINGPOINT : PREDICTOR_HORIZONTAL));
    if (ok && compression == COMPRESSION_ADOBE_DEFLATE)
        ok = TIFFSetField(t, TIFFTAG_ZIPQUALITY, image.zipLevel());
    if (ok && !image.dateTime.empty()) ok = TIFFSetField(t, TIFFTAG_DATETIME, image.dateTime.c_str());
    if (ok && (image.x != 0 || image.y != 0))
        ok = TIFFSetField(t, TIFFTAG_XPOSITION, float(image.x)) && TIFFSetField(t, TIFFTAG_YPOSITION, float(image.y));
    if (ok && (image.width != image.fullWidth || image.height != image.fullHeight))
        ok = TIFFSetField(t, TIFFTAG_PIXAR_IMAGEFULLWIDTH, uint32_t(image.fullWidth)) &&
             TIFFSetField(t, TIFFTAG_PIXAR_IMAGEFULLLENGTH, uint32_t(image.fullHeight));
    if (ok && image.worldToCamera)
        ok = TIFFSetField(t, TIFFTAG_PIXAR_MATRIX_WORLDTOCAMERA, image.worldToCamera->data());
    if (ok && image.worldToNDC) ok = TIFFSetField(t, TIFFTAG_PIXAR_MATRIX_WORLDTOSCREEN, image.worldToNDC->data());
    if (!ok) return m->fail("libtiff rejected a tag", error);
    m->nStrips = (uint32_t(image.height) + rowsPerStrip - 1) / rowsPerStrip;
    return true;
}

bool TiffStream::compress(uint32_t s, const float* rowsIn, std::vector<unsigned char>* out) const {
    // Integer samples with deflate, the default: packed, differenced and
    // compressed (in parallel by writeTiff: the frame's serial tail), then
    // written in order as raw strips -- what libtiff's own encoder would
    // produce, with zlib's framing and the same horizontal predictor.
    const uint32_t rows = rowsOf(s);
    const size_t rowValues = m->rowValues;
    std::vector<unsigned char> raw(rowValues * rows * size_t(m->bytesPerSample));
    m->pack(rowsIn, rows, raw.data());
    for (uint32_t r = 0; r < rows; ++r) {
        if (m->type == SampleType::UInt8)
            horizontalDifference(raw.data() + r * rowValues, rowValues, m->nch);
        else
            horizontalDifference(reinterpret_cast<uint16_t*>(raw.data()) + r * rowValues, rowValues, m->nch);
    }
    // libdeflate: the same zlib stream as compress2 at about twice the
    // speed on dithered 8-bit pixels. A compressor per strip (they are not
    // shared between threads).
    std::unique_ptr<libdeflate_compressor, DeflateFree> compressor(libdeflate_alloc_compressor(m->image.zipLevel()));
    // Compressed into a scratch buffer of the worst-case size, then kept at
    // its own size: every strip of writeTiff waits until all are done, and
    // at the bound's capacity they held as much as the raw image (8 MB for
    // 1920 x 1080 RGBA) instead of its zip.
    size_t size = 0;
    if (compressor) {
        std::vector<unsigned char> buf(libdeflate_zlib_compress_bound(compressor.get(), raw.size()));
        size = libdeflate_zlib_compress(compressor.get(), raw.data(), raw.size(), buf.data(), buf.size());
        out->assign(buf.begin(), buf.begin() + std::ptrdiff_t(size));
    }
    return size != 0;
}

bool TiffStream::writeCompressed(uint32_t s, const std::vector<unsigned char>& bytes, std::string* error) {
    if (TIFFWriteRawStrip(m->tif.get(), s, const_cast<unsigned char*>(bytes.data()), tmsize_t(bytes.size())) < 0)
        return m->fail("libtiff could not write a strip", error);
    return true;
}

bool TiffStream::writeStrip(uint32_t s, const float* rows, std::string* error) {
    if (precompresses()) {
        std::vector<unsigned char> bytes;
        if (!compress(s, rows, &bytes)) return m->fail("libdeflate could not compress a strip", error);
        return writeCompressed(s, bytes, error);
    }
    // Through libtiff's encoders; they may modify their input (predictors
    // work in place), so each strip is a fresh copy.
    const size_t bytes = m->rowValues * rowsOf(s) * size_t(m->bytesPerSample);
    m->strip.resize(bytes);
    m->pack(rows, rowsOf(s), m->strip.data());
    if (TIFFWriteEncodedStrip(m->tif.get(), s, m->strip.data(), tmsize_t(bytes)) < 0)
        return m->fail("libtiff could not write a strip", error);
    return true;
}

bool TiffStream::finish(std::string* error) {
    if (!TIFFWriteDirectory(m->tif.get())) return m->fail("libtiff could not write the directory", error);
    m->tif.reset();
    if (!m->sink.failure.empty()) return m->fail("", error);
    return true;
}

bool writeTiff(const ImageData& image, std::FILE* file, std::string* error) {
    TiffStream tiff;
    if (!tiff.open(image, file, error)) return false;
    const size_t rowValues = size_t(image.width) * size_t(image.channels());
    // Rows [y0, y0 + rows): the image's own, or filled into `scratch`.
    auto rowsAt = [&](uint32_t y0, uint32_t rows, std::vector<float>& scratch) -> const float* {
        if (image.pixels) return image.pixels + rowValues * y0;
        scratch.resize(rowValues * rows);
        image.fillRows(int(y0), int(rows), scratch.data());
        return scratch.data();
    };
    const uint32_t nStrips = tiff.strips();
    if (tiff.precompresses()) {
        // Strips are converted and compressed in parallel, then written in order.
        std::vector<std::vector<unsigned char>> packed(nStrips);
        std::atomic<bool> deflateFailed{false};
        parallelFor(uint32_t(0), nStrips, [&](uint32_t s) {
            std::vector<float> scratch;
            if (!tiff.compress(s, rowsAt(s * uint32_t(kTiffRowsPerStrip), tiff.rowsOf(s), scratch), &packed[s]))
                deflateFailed = true;
        });
        if (deflateFailed) {
            *error = "libdeflate could not compress a strip";
            return false;
        }
        for (uint32_t s = 0; s < nStrips; ++s)
            if (!tiff.writeCompressed(s, packed[s], error)) return false;
    } else {
        std::vector<float> scratch;
        for (uint32_t s = 0; s < nStrips; ++s)
            if (!tiff.writeStrip(s, rowsAt(s * uint32_t(kTiffRowsPerStrip), tiff.rowsOf(s), scratch), error))
                return false;
    }
    return tiff.finish(error);
}

}  // namespace umbra::film
