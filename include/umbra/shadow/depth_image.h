#pragma once
// Depth images and depth-map files.
//
// A depth map is what the first (light) pass of a shadowed frame produces:
// for every pixel of the light's raster, the light camera-space z (world
// units along the light's +z axis) of the nearest surface, or +infinity
// where nothing was hit (Reeves et al. 1987, §3.1 footnote).
//
// Spaces used here, all RenderMan's:
//  - light camera space ("camera" of the light): left-handed, +z into the
//    scene; the map stores this z.
//  - NDC: x, y in [0,1] over the display window, (0,0) top-left, y down.
//  - raster: NDC scaled by the resolution; pixel (x,y) covers
//    [x,x+1) x [y,y+1), row 0 at the top.
//
// On disk a map is an OpenEXR tiled image (see docs/ and writeDepthMap);
// the matrices go in the standard `worldToCamera` / `worldToNDC` header
// attributes (row-vector convention, as RenderMan and OIIO use them).

#include "umbra/util/error.h"
#include "umbra/util/math.h"
#include "umbra/util/zeroed_allocator.h"

#include <algorithm>
#include <array>
#include <string>
#include <vector>

namespace umbra {

/// How the light projects: decides nothing in the lookup (both go through
/// worldToNDC) but is recorded for tools and for second-depth plane math.
enum class Projection { Perspective, Orthographic };

/// Which depth a map stores per pixel (see DESIGN.md "Shadows").
enum class DepthFilter { Min, Max, Average, Midpoint, Second, Dual };

const char* projectionName(Projection p);
const char* depthFilterName(DepthFilter f);
/// Parses "perspective"/"orthographic"; false if unknown.
bool parseProjection(const std::string& s, Projection* out);
/// Parses "min","max","average","midpoint","second","dual"; false if unknown.
bool parseDepthFilter(const std::string& s, DepthFilter* out);

/// A full-resolution depth image as the depth pass produces it, before it
/// is stored as a tiled map; also what reading a zfile or a whole map gives.
struct DepthImage {
    int width = 0, height = 0;
    /// width*height light camera-space depths, row-major, row 0 at the top;
    /// +infinity where no surface was hit.
    FloatPlane z;
    /// Optional second layer (second-nearest depth), same layout; empty if
    /// absent. Written as channel "Z2" (inside the bounding box of the
    /// finite first-layer depths, which holds every finite z2 when z2 >= z).
    FloatPlane z2;
    /// RenderMan "worldToCamera" of the light (column-vector convention here).
    Mat4 lightFromWorld;
    /// RenderMan "worldToNDC" of the light (column-vector convention here).
    Mat4 ndcFromWorld;
    Projection projection = Projection::Perspective;
    DepthFilter filter = DepthFilter::Min;
    /// Weiskopf & Ertl's offset for the "dual" filter (world units).
    float dualOffset = 0;
    /// Motion blur: each texel holds its casters at its own time, the
    /// times interleaved over tiles of timeTile x timeTile texels, so a
    /// lookup filters over at least one tile (docs/motion.md); 0: still.
    int timeTile = 0;
    /// Maps of moving casters: the time, in [0, 1) of the shutter, at which
    /// texel (x, y) holds its casters is texelTimes[(y % n) * n + x % n],
    /// n * n the table's size (the sample pattern's period, 32; n a multiple
    /// of timeTile). A lookup then compares each time's texels with a moving
    /// receiver where it is at that time (docs/motion.md). Empty: unknown.
    std::vector<float> texelTimes;
    /// The texels a light's depth pass wrote: outside [writtenX0, writtenX1)
    /// x [writtenY0, writtenY1) every texel is +infinity and its storage is
    /// never read (the pass left those pages untouched: on these hosts each
    /// page's first touch costs a fault of microseconds). Unset: the whole
    /// image.
    int writtenX0 = 0, writtenY0 = 0, writtenX1 = kWholeImage, writtenY1 = kWholeImage;
    static constexpr int kWholeImage = 1 << 30;
    /// The written window clipped to the image (empty when x1 <= x0).
    int rowBegin() const { return std::max(writtenY0, 0); }
    int rowEnd() const { return std::min(writtenY1, height); }
    int columnBegin() const { return std::max(writtenX0, 0); }
    int columnEnd() const { return std::min(writtenX1, width); }
    bool whole() const { return rowBegin() == 0 && rowEnd() == height && columnBegin() == 0 && columnEnd() == width; }

    DepthImage() = default;
    /// An image of the given size filled with +infinity.
    DepthImage(int w, int h) : width(w), height(h), z(size_t(w) * size_t(h), kInfinity) {}
    float at(int x, int y) const {
        if (x < columnBegin() || x >= columnEnd() || y < rowBegin() || y >= rowEnd()) return kInfinity;
        return z[size_t(y) * size_t(width) + size_t(x)];
    }
    float& at(int x, int y) { return z[size_t(y) * size_t(width) + size_t(x)]; }
};

/// Texel edge length of the square tiles maps are written with.
constexpr int kMapTileSize = 32;

/// Writes `image` as a tiled OpenEXR depth map: one FLOAT channel "Z" (and
/// "Z2" if the image has a second layer), 32x32 tiles, ZIP compression,
/// data window = bounding box of the finite depths (a 1x1 window at the
/// origin if there are none), display window = the full resolution, every
/// tile of the data window written, and in the header: worldToCamera,
/// worldToNDC, "umbra:projection", "umbra:depthfilter", "umbra:dualoffset",
/// "umbra:tilesX"/"umbra:tilesY", "umbra:tileMinZ"/"umbra:tileMaxZ" (per
/// tile, row by row from the data window's corner), "umbra:minZ"/"umbra:maxZ"
/// (finite range) and "umbra:finiteCount". The file appears atomically
/// (written to `path + ".tmp"`, then renamed). Errors go to `diag` at `loc`.
bool writeDepthMap(const std::string& path, const DepthImage& image, Diagnostics& diag, const FileLoc& loc = {});

/// Names of the six faces of a cube map, in part order: the faces of a
/// point light's omnidirectional map (Reeves §3.2: "cubical environment
/// maps").
extern const char* const kCubeFaceNames[6];

/// Writes a point light's six depth maps as one multi-part OpenEXR file:
/// part f is named kCubeFaceNames[f] and is exactly what writeDepthMap
/// writes for faces[f] (its own matrices, bounding box, tile ranges).
/// Lookups pick, per point, the face whose light camera-space z is largest,
/// so any assignment of the six view directions works as long as they are
/// the six axis directions of one frame around one light position.
bool writeCubeDepthMap(const std::string& path, const std::array<DepthImage, 6>& faces, Diagnostics& diag,
                       const FileLoc& loc = {});

/// Reads a whole depth image from any OpenEXR file (scanline or tiled) with
/// a FLOAT or HALF depth channel ("Z", else "R", else the only channel) and
/// worldToCamera / worldToNDC header matrices. Pixels outside the data
/// window are +infinity. False (with an error in `diag`) on failure.
bool readDepthImage(const std::string& path, DepthImage& out, Diagnostics& diag, const FileLoc& loc = {});

/// Writes a Pixar-style "zfile" (the `zfile` display driver), native
/// little-endian:
///   int32 magic 0x2f0867ab; int16 width; int16 height;
///   float Np[16]  world-to-screen, row-vector (RIB) order;
///   float Nl[16]  world-to-camera, row-vector (RIB) order;
///   float z[width*height]  camera-space depth, row 0 at the top.
/// Screen space is RenderMan's with the default screen window for the
/// image's aspect ratio ([-a,a]x[-1,1] for a=w/h >= 1, else
/// [-1,1]x[-1/a,1/a]); Np is derived from ndcFromWorld with that window.
/// Infinite depths are written as +infinity. Width and height must be
/// 1..32767. Atomic like writeDepthMap. False on I/O failure.
bool writeZFile(const std::string& path, const DepthImage& image);
/// Same, reporting failures through `diag`.
bool writeZFile(const std::string& path, const DepthImage& image, Diagnostics& diag, const FileLoc& loc);

/// Reads a zfile written as above; byte-swapped (big-endian) files are
/// recognised by their magic. Depths >= 1e30 (the "very large constant"
/// older renderers store for empty pixels) become +infinity. The projection
/// is inferred from Np (orthographic when its w column is (0,0,0,1)).
bool readZFile(const std::string& path, DepthImage& out, Diagnostics& diag, const FileLoc& loc = {});

/// NDC from RenderMan screen space for a w x h image with the default
/// screen window (as zfiles store their Np).
Mat4 defaultNdcFromScreen(int w, int h);

/// Reads a zfile (recognised by its magic), any OpenEXR depth image
/// readDepthImage accepts (a depth map written by writeDepthMap among
/// them), or a TIFF of one 32-bit float channel with the Pixar matrix tags
/// (a "file" display's "z" output).
/// False (with an error naming `loc` and the file) on failure.
bool readDepthFile(const std::string& path, DepthImage& out, Diagnostics& diag, const FileLoc& loc = {});

/// RenderMan's MakeShadow: converts `in` (what readDepthFile reads) into
/// the tiled map `out`. Errors name `loc` (the RIB request) and the file.
bool makeShadow(const std::string& in, const std::string& out, Diagnostics& diag, const FileLoc& loc = {});

}  // namespace umbra
