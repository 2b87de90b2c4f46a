// Whether an output file is a complete image: what `--resume` asks of a
// frame's files before it skips the frame. Each format is read to its last
// pixel with its own library, so a file cut short (a killed run, a full
// disk, a partial copy) is found, not just a missing one.

#include "umbra/film/film.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputPart.h>
#include <OpenEXR/ImfMultiPartInputFile.h>
#include <png.h>
#include <tiffio.h>

#include <fmt/format.h>

#include <csetjmp>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <memory>
#include <vector>

namespace umbra::film {

namespace {

/// Collects libtiff's first error instead of printing it.
int tiffMessage(TIFF*, void* user, const char*, const char* fmtText, va_list ap) {
    auto* why = static_cast<std::string*>(user);
    if (why->empty()) {
        char buf[512];
        std::vsnprintf(buf, sizeof buf, fmtText, ap);
        *why = buf;
    }
    return 1;
}
int tiffQuiet(TIFF*, void*, const char*, const char*, va_list) { return 1; }

bool tiffComplete(const std::string& path, std::string* why) {
    std::string failure;
    TIFFOpenOptions* opts = TIFFOpenOptionsAlloc();
    TIFFOpenOptionsSetErrorHandlerExtR(opts, tiffMessage, &failure);
    TIFFOpenOptionsSetWarningHandlerExtR(opts, tiffQuiet, nullptr);
    TIFF* t = TIFFOpenExt(path.c_str(), "r", opts);
    TIFFOpenOptionsFree(opts);
    if (!t) {
        *why = failure.empty() ? "not a readable TIFF file" : failure;
        return false;
    }
    bool ok = true;
    const bool tiled = TIFFIsTiled(t);
    const uint32_t n = tiled ? TIFFNumberOfTiles(t) : TIFFNumberOfStrips(t);
    std::vector<unsigned char> buf(size_t(tiled ? TIFFTileSize(t) : TIFFStripSize(t)));
    for (uint32_t i = 0; ok && i < n; ++i) {
        tmsize_t got = tiled ? TIFFReadEncodedTile(t, i, buf.data(), tmsize_t(buf.size()))
                             : TIFFReadEncodedStrip(t, i, buf.data(), tmsize_t(buf.size()));
        if (got < 0) {
            ok = false;
            *why = fmt::format("{} {} of {} cannot be read{}{}", tiled ? "tile" : "strip", i, n,
                               failure.empty() ? "" : ": ", failure);
        }
    }
    TIFFClose(t);
    if (ok && !failure.empty()) {
        *why = failure;
        ok = false;
    }
    return ok;
}

bool exrComplete(const std::string& path, std::string* why) {
    try {
        Imf::MultiPartInputFile file(path.c_str());
        for (int p = 0; p < file.parts(); ++p) {
            Imf::InputPart part(file, p);
            const Imf::Header& h = part.header();
            const Imath::Box2i dw = h.dataWindow();
            const size_t w = size_t(dw.max.x - dw.min.x + 1), rows = size_t(dw.max.y - dw.min.y + 1);
            std::vector<std::vector<float>> planes;
            Imf::FrameBuffer fb;
            for (auto c = h.channels().begin(); c != h.channels().end(); ++c) {
                planes.emplace_back(w * rows);
                char* base = reinterpret_cast<char*>(planes.back().data()) -
                             (ptrdiff_t(dw.min.x) + ptrdiff_t(dw.min.y) * ptrdiff_t(w)) * ptrdiff_t(sizeof(float));
                fb.insert(c.name(), Imf::Slice(Imf::FLOAT, base, sizeof(float), w * sizeof(float)));
            }
            part.setFrameBuffer(fb);
            part.readPixels(dw.min.y, dw.max.y);
        }
    } catch (const std::exception& e) {
        *why = e.what();
        return false;
    }
    return true;
}

struct PngState {
    std::jmp_buf jump;
    std::string failure;
};
void pngError(png_structp png, png_const_charp message) {
    auto* s = static_cast<PngState*>(png_get_error_ptr(png));
    s->failure = message;
    std::longjmp(s->jump, 1);
}
void pngWarning(png_structp, png_const_charp) {}

bool pngComplete(const std::string& path, std::string* why) {
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (!f) {
        *why = "cannot be opened";
        return false;
    }
    PngState state;
    png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &state, pngError, pngWarning);
    png_infop info = png ? png_create_info_struct(png) : nullptr;
    std::vector<unsigned char> row;
    if (!png || !info) {
        png_destroy_read_struct(&png, &info, nullptr);
        std::fclose(f);
        *why = "libpng could not start";
        return false;
    }
    if (setjmp(state.jump)) {
        png_destroy_read_struct(&png, &info, nullptr);
        std::fclose(f);
        *why = state.failure;
        return false;
    }
    png_init_io(png, f);
    png_read_info(png, info);
    const int passes = png_set_interlace_handling(png);
    png_read_update_info(png, info);
    row.resize(png_get_rowbytes(png, info));
    const png_uint_32 height = png_get_image_height(png, info);
    for (int p = 0; p < passes; ++p)
        for (png_uint_32 y = 0; y < height; ++y) png_read_row(png, row.data(), nullptr);
    png_read_end(png, nullptr);
    png_destroy_read_struct(&png, &info, nullptr);
    std::fclose(f);
    return true;
}

/// A zfile (the "zfile" driver's format): its size must be its header's
/// 136 bytes plus width * height depths.
bool zfileComplete(const std::string& path, const unsigned char* head, std::string* why) {
    const bool swapped = head[0] == 0x2f;
    auto i16 = [&](int at) {
        return swapped ? uint16_t(head[at] << 8 | head[at + 1]) : uint16_t(head[at] | head[at + 1] << 8);
    };
    const uint64_t expected = 136 + 4 * uint64_t(i16(4)) * i16(6);
    const uint64_t size = std::filesystem::file_size(path);
    if (size != expected) {
        *why = fmt::format("{} bytes where a {}x{} zfile has {}", size, i16(4), i16(6), expected);
        return false;
    }
    return true;
}

}  // namespace

bool imageFileComplete(const std::string& path, std::string* why) {
    std::string dummy;
    if (!why) why = &dummy;
    unsigned char head[8] = {};
    {
        std::ifstream in(path, std::ios::binary);
        if (!in) {
            *why = "missing";
            return false;
        }
        in.read(reinterpret_cast<char*>(head), sizeof head);
        if (in.gcount() < 8) {
            *why = "too short to be an image";
            return false;
        }
    }
    if ((head[0] == 'I' && head[1] == 'I') || (head[0] == 'M' && head[1] == 'M')) return tiffComplete(path, why);
    if (head[0] == 0x76 && head[1] == 0x2f && head[2] == 0x31 && head[3] == 0x01) return exrComplete(path, why);
    if (head[0] == 0x89 && head[1] == 'P' && head[2] == 'N' && head[3] == 'G') return pngComplete(path, why);
    const bool zfile = (head[0] == 0xab && head[1] == 0x67 && head[2] == 0x08 && head[3] == 0x2f) ||
                       (head[0] == 0x2f && head[1] == 0x08 && head[2] == 0x67 && head[3] == 0xab);
    if (zfile) return zfileComplete(path, head, why);
    *why = "not a TIFF, OpenEXR, PNG or zfile image";
    return false;
}

}  // namespace umbra::film
