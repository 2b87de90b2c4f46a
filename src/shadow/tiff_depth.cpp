// Depth images in TIFF files, as a "file" (TIFF) display writes mode "z":
// MakeShadow takes "a file containing a depth image" (RI Spec 3.2), and
// the RenderMan books render it that way (`Display "zbuffer.tiff" "file"
// "z"`), as Pixie accepts.

#include "umbra/shadow/depth_image.h"

#include <tiffio.h>

#include <cmath>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

namespace umbra {


bool readTiffDepth(const std::string& path, DepthImage& out, Diagnostics& diag, const FileLoc& loc,
                   const char* what) {
    // libtiff's own messages would go to stderr unlocated: ours say it.
    TIFFSetWarningHandler(nullptr);
    TIFFSetErrorHandler(nullptr);
    std::unique_ptr<TIFF, void (*)(TIFF*)> t(TIFFOpen(path.c_str(), "r"), [](TIFF* p) {
        if (p) TIFFClose(p);
    });
    auto fail = [&](const std::string& why) {
        diag.error(loc, "{}cannot read the depth TIFF \"{}\": {}", what, path, why);
        return false;
    };
    if (!t) return fail("not a readable TIFF");
    uint32_t w = 0, h = 0;
    uint16_t spp = 1, bps = 0, format = SAMPLEFORMAT_UINT, planar = PLANARCONFIG_CONTIG;
    TIFFGetField(t.get(), TIFFTAG_IMAGEWIDTH, &w);
    TIFFGetField(t.get(), TIFFTAG_IMAGELENGTH, &h);
    TIFFGetFieldDefaulted(t.get(), TIFFTAG_SAMPLESPERPIXEL, &spp);
    TIFFGetFieldDefaulted(t.get(), TIFFTAG_BITSPERSAMPLE, &bps);
    TIFFGetFieldDefaulted(t.get(), TIFFTAG_SAMPLEFORMAT, &format);
    TIFFGetFieldDefaulted(t.get(), TIFFTAG_PLANARCONFIG, &planar);
    if (w == 0 || h == 0 || w > 32767 || h > 32767) return fail("unusable size");
    if (bps != 32 || format != SAMPLEFORMAT_IEEEFP || (spp != 1 && planar != PLANARCONFIG_CONTIG))
        return fail("expected 32-bit float depths (a \"z\" output)");
    if (TIFFIsTiled(t.get())) return fail("tiled TIFFs are not read as depth images (write scanlines, or a zfile)");
    float* worldToCamera = nullptr;
    float* worldToScreen = nullptr;
    if (!TIFFGetField(t.get(), TIFFTAG_PIXAR_MATRIX_WORLDTOCAMERA, &worldToCamera) || !worldToCamera ||
        !TIFFGetField(t.get(), TIFFTAG_PIXAR_MATRIX_WORLDTOSCREEN, &worldToScreen) || !worldToScreen)
        return fail("expected the Pixar world-to-camera and world-to-screen matrix tags a \"z\" output carries");
    // umbra's TIFFs, like its OpenEXR depth images, store world-to-NDC in
    // the world-to-screen tag; others store screen space.
    char* software = nullptr;
    const bool ours = TIFFGetField(t.get(), TIFFTAG_SOFTWARE, &software) && software &&
                      std::strncmp(software, "umbra", 5) == 0;
    const int width = int(w), height = int(h);
    DepthImage img(width, height);
    std::vector<float> row(size_t(TIFFScanlineSize(t.get())) / sizeof(float) + 1);
    for (uint32_t y = 0; y < h; ++y) {
        if (TIFFReadScanline(t.get(), row.data(), y, 0) < 0) return fail("the file is truncated or corrupt");
        for (uint32_t x = 0; x < w; ++x) {
            const float z = row[size_t(x) * spp];
            img.at(int(x), int(y)) = std::isfinite(z) && z < 1e30f ? z : kInfinity;
        }
    }
    img.lightFromWorld = Mat4::fromRib(worldToCamera);
    img.ndcFromWorld = ours ? Mat4::fromRib(worldToScreen)
                            : defaultNdcFromScreen(width, height) * Mat4::fromRib(worldToScreen);
    const auto& n = img.ndcFromWorld.m;
    img.projection =
        (n[3][0] == 0 && n[3][1] == 0 && n[3][2] == 0) ? Projection::Orthographic : Projection::Perspective;
    out = std::move(img);
    return true;
}

}  // namespace umbra
