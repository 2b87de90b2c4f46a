// OpenEXR output through the OpenEXR library directly.
//
// The layout matches what the shadow module and OpenImageIO expect of a
// RenderMan renderer's EXR: channels by name (R G B A Z, an AOV's R G B or
// its own name), the crop region as the data window inside the full-frame
// display window, "Software" and "capDate" (OpenEXR's standard date
// attribute, which OIIO reads as "DateTime"), "umbra:rendertime" as a
// string, and on depth outputs the matrices as m44f "worldToCamera",
// "worldToNDC" and "worldToScreen" (Imath's row-vector order, as in RIB).

#include "image_file.h"

#include <Imath/half.h>
#include <OpenEXR/IexBaseExc.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfMatrixAttribute.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfStringAttribute.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <exception>
#include <memory>

namespace umbra::film {

namespace {

/// An OpenEXR output stream over a stdio stream. OpenEXR writes the
/// line-offset table from OutputFile's destructor, which swallows
/// exceptions, so the first failure is also remembered here and checked
/// after the file object is gone.
class StdioOStream final : public Imf::OStream {
public:
    StdioOStream(std::FILE* file, const char* name) : Imf::OStream(name), m_file(file) {}

    void write(const char c[], int n) override {
        if (n > 0 && std::fwrite(c, 1, size_t(n), m_file) != size_t(n)) fail();
    }
    uint64_t tellp() override {
        off_t p = ::ftello(m_file);
        if (p < 0) fail();
        return uint64_t(p);
    }
    void seekp(uint64_t pos) override {
        if (::fseeko(m_file, off_t(pos), SEEK_SET) != 0) fail();
    }
    const std::string& failure() const { return m_failure; }

private:
    void fail() {
        if (m_failure.empty()) m_failure = std::strerror(errno ? errno : EIO);
        throw Iex::IoExc(m_failure);
    }
    std::FILE* m_file;
    std::string m_failure;
};

std::optional<Imf::Compression> exrCompression(const std::string& name) {
    if (name.empty() || name == "zip") return Imf::ZIP_COMPRESSION;
    if (name == "none") return Imf::NO_COMPRESSION;
    if (name == "rle") return Imf::RLE_COMPRESSION;
    if (name == "zips") return Imf::ZIPS_COMPRESSION;
    if (name == "piz") return Imf::PIZ_COMPRESSION;
    if (name == "pxr24") return Imf::PXR24_COMPRESSION;
    if (name == "b44") return Imf::B44_COMPRESSION;
    if (name == "b44a") return Imf::B44A_COMPRESSION;
    if (name == "dwaa") return Imf::DWAA_COMPRESSION;
    if (name == "dwab") return Imf::DWAB_COMPRESSION;
    return std::nullopt;
}

Imath::M44f toM44f(const std::array<float, 16>& m) {
    return Imath::M44f(m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8], m[9], m[10], m[11], m[12], m[13],
                       m[14], m[15]);
}

}  // namespace

bool exrCompressionKnown(const std::string& name) { return exrCompression(name).has_value(); }

bool writeExr(const ImageData& image, std::FILE* file, std::string* error) {
    const int nch = image.channels();
    const Imath::Box2i display(Imath::V2i(0, 0), Imath::V2i(image.fullWidth - 1, image.fullHeight - 1));
    const Imath::Box2i data(Imath::V2i(image.x, image.y),
                            Imath::V2i(image.x + image.width - 1, image.y + image.height - 1));
    Imf::Header header(display, data);
    header.compression() = exrCompression(image.compression).value_or(Imf::ZIP_COMPRESSION);
    if (header.compression() == Imf::DWAA_COMPRESSION || header.compression() == Imf::DWAB_COMPRESSION) {
        if (image.compressionLevel > 0) header.dwaCompressionLevel() = float(image.compressionLevel);
    } else {
        header.zipCompressionLevel() = image.zipLevel();
    }
    header.insert("Software", Imf::StringAttribute(image.software));
    if (!image.dateTime.empty()) Imf::addCapDate(header, image.dateTime);
    if (!image.renderTime.empty()) header.insert("umbra:rendertime", Imf::StringAttribute(image.renderTime));
    if (image.worldToCamera) header.insert("worldToCamera", Imf::M44fAttribute(toM44f(*image.worldToCamera)));
    if (image.worldToNDC) {
        header.insert("worldToNDC", Imf::M44fAttribute(toM44f(*image.worldToNDC)));
        // Earlier umbra files (written through OIIO) also carried the NDC
        // matrix as worldToScreen; tools that look for it keep working.
        header.insert("worldToScreen", Imf::M44fAttribute(toM44f(*image.worldToNDC)));
    }

    // Half channels get their own interleaved buffer with the float data's
    // layout; float channels point straight into the float data.
    const size_t npix = size_t(image.width) * size_t(image.height);
    const bool anyHalf =
        std::find(image.types.begin(), image.types.end(), SampleType::Half) != image.types.end();
    std::vector<Imath::half> halves(anyHalf ? npix * size_t(nch) : 0);
    if (anyHalf)
        for (size_t i = 0; i < npix * size_t(nch); ++i) halves[i] = Imath::half(image.pixels[i]);

    Imf::FrameBuffer frame;
    for (int c = 0; c < nch; ++c) {
        const bool half = image.types[size_t(c)] == SampleType::Half;
        Imf::PixelType type = half ? Imf::HALF : Imf::FLOAT;
        header.channels().insert(image.channelNames[size_t(c)], Imf::Channel(type));
        const size_t elem = half ? sizeof(Imath::half) : sizeof(float);
        const void* base = half ? static_cast<const void*>(halves.data() + c)
                                : static_cast<const void*>(image.pixels + c);
        frame.insert(image.channelNames[size_t(c)],
                     Imf::Slice::Make(type, base, data, elem * size_t(nch), elem * size_t(nch) * size_t(image.width)));
    }

    StdioOStream stream(file, "umbra image");
    try {
        Imf::OutputFile out(stream, header);
        out.setFrameBuffer(frame);
        out.writePixels(image.height);
    } catch (const std::exception& e) {
        *error = stream.failure().empty() ? e.what() : stream.failure();
        return false;
    }
    if (!stream.failure().empty()) {
        *error = stream.failure();
        return false;
    }
    return true;
}

}  // namespace umbra::film
