// PNG output through libpng.
//
// 8 or 16 bits per sample; one to four channels as gray, gray + alpha, RGB,
// RGBA (PNG's alpha is straight: the film unpremultiplies before it
// quantises). A crop region's origin goes into oFFs (pixels), "Software"
// and "umbra:rendertime" into tEXt chunks, the date into tIME; OpenImageIO
// reads these back as Software, umbra:rendertime and DateTime.
//
// libpng reports errors by longjmp: everything with a destructor is built
// before encode(), whose only locals are libpng's own handles.

#include "image_file.h"

#include <png.h>

#include <algorithm>
#include <cerrno>
#include <csetjmp>
#include <cstring>
#include <vector>

namespace umbra::film {

namespace {

/// libpng's user pointer: the stream and the first failure's text.
struct PngSink {
    std::FILE* file;
    char failure[256];
};

void remember(PngSink* s, const char* what) {
    if (s->failure[0] == 0) std::snprintf(s->failure, sizeof s->failure, "%s", what);
}

[[noreturn]] void onError(png_structp png, png_const_charp message) {
    remember(static_cast<PngSink*>(png_get_error_ptr(png)), message);
    png_longjmp(png, 1);
}

void onWarning(png_structp, png_const_charp) {}

void writeData(png_structp png, png_bytep data, size_t length) {
    auto* s = static_cast<PngSink*>(png_get_io_ptr(png));
    if (std::fwrite(data, 1, length, s->file) != length) {
        remember(s, std::strerror(errno ? errno : EIO));
        png_error(png, "write failed");
    }
}

void flushData(png_structp png) {
    auto* s = static_cast<PngSink*>(png_get_io_ptr(png));
    std::fflush(s->file);
}

/// Everything libpng needs, prepared beforehand so that encode() owns
/// nothing a longjmp could leak.
struct PngJob {
    png_uint_32 width, height;
    int bitDepth, colorType;
    int x, y;  // oFFs, pixels
    bool hasTime;
    png_time stamp;
    png_text* text;
    int textCount;
    png_bytepp rows;
    int level;  // deflate 1-9
};

bool encode(const PngJob* job, PngSink* sink) {
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, sink, onError, onWarning);
    if (!png) {
        remember(sink, "libpng could not start");
        return false;
    }
    png_infop info = png_create_info_struct(png);
    if (!info) {
        png_destroy_write_struct(&png, nullptr);
        remember(sink, "libpng could not start");
        return false;
    }
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        return false;
    }
    png_set_write_fn(png, sink, writeData, flushData);
    png_set_compression_level(png, job->level);
    png_set_IHDR(png, info, job->width, job->height, job->bitDepth, job->colorType, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    if (job->x != 0 || job->y != 0) png_set_oFFs(png, info, job->x, job->y, PNG_OFFSET_PIXEL);
    if (job->hasTime) png_set_tIME(png, info, &job->stamp);
    png_set_text(png, info, job->text, job->textCount);
    png_write_info(png, info);
    png_write_image(png, job->rows);
    png_write_end(png, info);
    png_destroy_write_struct(&png, &info);
    return true;
}

}  // namespace

bool writePng(const ImageData& image, std::FILE* file, std::string* error) {
    const int nch = image.channels();
    const bool sixteen = image.types[0] == SampleType::UInt16;
    const size_t bps = sixteen ? 2 : 1;
    const size_t rowBytes = size_t(image.width) * size_t(nch) * bps;

    // Pack the rows (PNG's 16-bit samples are big-endian).
    std::vector<png_byte> bytes(rowBytes * size_t(image.height));
    const size_t n = size_t(image.width) * size_t(image.height) * size_t(nch);
    if (sixteen) {
        for (size_t i = 0; i < n; ++i) {
            auto v = static_cast<uint16_t>(image.pixels[i]);
            bytes[2 * i] = png_byte(v >> 8);
            bytes[2 * i + 1] = png_byte(v & 0xff);
        }
    } else {
        for (size_t i = 0; i < n; ++i) bytes[i] = static_cast<png_byte>(image.pixels[i]);
    }
    std::vector<png_bytep> rows(size_t(image.height));
    for (size_t y = 0; y < rows.size(); ++y) rows[y] = bytes.data() + y * rowBytes;

    std::string keySoftware = "Software", keyRenderTime = "umbra:rendertime";
    std::string software = image.software, renderTime = image.renderTime;
    std::vector<png_text> text(image.renderTime.empty() ? 1 : 2);
    for (png_text& t : text) std::memset(&t, 0, sizeof t);
    text[0].compression = PNG_TEXT_COMPRESSION_NONE;
    text[0].key = keySoftware.data();
    text[0].text = software.data();
    text[0].text_length = software.size();
    if (text.size() > 1) {
        text[1].compression = PNG_TEXT_COMPRESSION_NONE;
        text[1].key = keyRenderTime.data();
        text[1].text = renderTime.data();
        text[1].text_length = renderTime.size();
    }
    png_time stamp{};
    int year = 0, month = 0, day = 0, hour = 0, minute = 0, second = 0;
    const bool hasTime = std::sscanf(image.dateTime.c_str(), "%d:%d:%d %d:%d:%d", &year, &month, &day, &hour,
                                     &minute, &second) == 6;
    stamp.year = png_uint_16(year);
    stamp.month = png_byte(month);
    stamp.day = png_byte(day);
    stamp.hour = png_byte(hour);
    stamp.minute = png_byte(minute);
    stamp.second = png_byte(second);
    const int colorType = nch == 1   ? PNG_COLOR_TYPE_GRAY
                          : nch == 2 ? PNG_COLOR_TYPE_GRAY_ALPHA
                          : nch == 3 ? PNG_COLOR_TYPE_RGB
                                     : PNG_COLOR_TYPE_RGBA;

    PngJob job{png_uint_32(image.width), png_uint_32(image.height), sixteen ? 16 : 8, colorType, image.x, image.y,
               hasTime, stamp, text.data(), int(text.size()), rows.data(), image.zipLevel()};
    PngSink sink{file, {0}};
    if (!encode(&job, &sink)) {
        *error = sink.failure[0] ? sink.failure : "libpng failed";
        return false;
    }
    return true;
}

}  // namespace umbra::film
