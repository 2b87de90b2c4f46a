#pragma once
// Private to the film module: the image-file writers behind Film::write.
// Each writer encodes one finished image (already exposed, unpremultiplied
// where the format wants it, and quantised) into an open stdio stream, using
// the format's own library (OpenEXR, libtiff, libpng) so that the renderer
// does not load OpenImageIO just to write pixels.

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace umbra::film {

/// Deflate levels when the display names none. Dithered integer samples
/// are noise to deflate: level 1 costs about what writing them uncompressed
/// does and is 8% bigger than level 4, which took 6 ms more on a 640x480
/// RGBA frame (and zlib's 6 took 2.5x level 4). Float samples compress much
/// better at 6 (-40% bytes) for ~20% more time.
inline constexpr int kDefaultZipLevelInteger = 1;
inline constexpr int kDefaultZipLevelFloat = 6;

/// How one channel is stored in the file. Integer types receive the
/// quantised integer values (already in [0, 255] or [0, 65535]).
enum class SampleType { UInt8, UInt16, Half, Float };

/// What a channel means, for the formats that record it (TIFF ExtraSamples,
/// PNG colour types).
enum class ChannelRole { Color, Alpha, Depth, Other };

/// One image ready for a file: the crop region of the frame, top row first,
/// channels interleaved.
struct ImageData {
    int width = 0, height = 0;          // data window size, pixels
    int x = 0, y = 0;                   // data window origin in raster pixels
    int fullWidth = 0, fullHeight = 0;  // the frame's resolution (display window)
    std::vector<std::string> channelNames;
    std::vector<ChannelRole> roles;
    std::vector<SampleType> types;  // per channel; TIFF and PNG need them all equal
    const float* pixels = nullptr;  // width * height * channels values; or null, and then:
    /// Fills rows [row0, row0 + rows) of the image (row 0 = the top row of
    /// the data window), width * channels values a row, into `out`; called
    /// concurrently for disjoint rows. Writers that take rows this way
    /// (TIFF) never hold the whole converted image: only the film and the
    /// strips in flight.
    std::function<void(int row0, int rows, float* out)> fillRows;

    std::string software;     // always written
    std::string dateTime;     // "YYYY:MM:DD HH:MM:SS"; empty: not written
    std::string renderTime;   // seconds as text; empty: not written
    // Row-vector (RIB, Imath) order; written on depth outputs only.
    std::optional<std::array<float, 16>> worldToCamera;
    std::optional<std::array<float, 16>> worldToNDC;
    std::string compression;  // the display's "compression"; empty: the format's default (zip)
    // Deflate level (zip, zips, PNG) or DWA level (dwaa, dwab); 0: the
    // defaults above (and OpenEXR's DWA default).
    int compressionLevel = 0;
    int zipLevel() const {
        if (compressionLevel > 0) return std::min(compressionLevel, 9);
        bool integer = !types.empty() && (types[0] == SampleType::UInt8 || types[0] == SampleType::UInt16);
        return integer ? kDefaultZipLevelInteger : kDefaultZipLevelFloat;
    }

    int channels() const { return int(channelNames.size()); }
    int findRole(ChannelRole r) const {
        for (size_t i = 0; i < roles.size(); ++i)
            if (roles[i] == r) return int(i);
        return -1;
    }
};

/// Compression names each writer accepts, for the "compression" parameter's
/// error message.
bool exrCompressionKnown(const std::string& name);
bool tiffCompressionKnown(const std::string& name);

/// Scanline OpenEXR: data window = the crop region, display window = the
/// full frame, ZIP unless told otherwise. On failure *error says why.
bool writeExr(const ImageData& image, std::FILE* file, std::string* error);
/// Strip TIFF, contiguous samples, 8/16-bit unsigned or 32-bit float.
bool writeTiff(const ImageData& image, std::FILE* file, std::string* error);

/// Rows of a TIFF strip (RowsPerStrip): every TIFF umbra writes has them.
inline constexpr int kTiffRowsPerStrip = 32;

/// A TIFF written strip by strip, in order: what writeTiff does, for a
/// caller that has the rows one strip at a time (the streamed film,
/// Film::openStream). The same calls in the same order as writeTiff's, so
/// the same bytes. Not thread-safe: one strip at a time.
class TiffStream {
public:
    TiffStream();
    ~TiffStream();
    TiffStream(const TiffStream&) = delete;
    TiffStream& operator=(const TiffStream&) = delete;
    /// Starts the file: header and tags from `image` (its pixels and
    /// fillRows are not used). On failure *error says why.
    bool open(const ImageData& image, std::FILE* file, std::string* error);
    uint32_t strips() const;
    /// Rows of strip s (kTiffRowsPerStrip, fewer for the last).
    uint32_t rowsOf(uint32_t s) const;
    /// True when strips are compressed by compress() (deflate, integer
    /// samples), which may run on any thread, then written by writeCompressed().
    bool precompresses() const;
    /// Strip s's file bytes from its rows (width * channels values a row,
    /// converted and quantised as ImageData describes). precompresses() only.
    bool compress(uint32_t s, const float* rows, std::vector<unsigned char>* out) const;
    bool writeCompressed(uint32_t s, const std::vector<unsigned char>& bytes, std::string* error);
    /// Encodes and writes strip s, the next one, from its rows.
    bool writeStrip(uint32_t s, const float* rows, std::string* error);
    /// Writes the directory and closes the TIFF (not the stdio stream).
    bool finish(std::string* error);

private:
    struct Impl;
    std::unique_ptr<Impl> m;
};
/// PNG, 8 or 16 bits, gray / gray-alpha / RGB / RGBA (alpha last, straight).
bool writePng(const ImageData& image, std::FILE* file, std::string* error);

}  // namespace umbra::film
