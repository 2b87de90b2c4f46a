#pragma once
// Header attributes shared by the map writer and readers (private to the
// shadow module).

#include "umbra/shadow/depth_image.h"

#include <ImfDoubleAttribute.h>
#include <ImfFloatAttribute.h>
#include <ImfFloatVectorAttribute.h>
#include <ImfHeader.h>
#include <ImfIntAttribute.h>
#include <ImfMatrixAttribute.h>
#include <ImfStringAttribute.h>

#include <cmath>
#include <string>
#include <vector>

namespace umbra {

// Standard EXR names (RenderMan, OIIO and Nuke understand them).
inline constexpr const char* kAttrWorldToCamera = "worldToCamera";
inline constexpr const char* kAttrWorldToNDC = "worldToNDC";
// umbra's own, named "umbra:..." as the project's extensions are.
inline constexpr const char* kAttrProjection = "umbra:projection";
inline constexpr const char* kAttrDepthFilter = "umbra:depthfilter";
inline constexpr const char* kAttrDualOffset = "umbra:dualoffset";
/// Motion blur: texels hold their casters at times interleaved over tiles
/// of this many texels a side (hider/sample_buffer.h kTimeTile); 0: still.
inline constexpr const char* kAttrTimeTile = "umbra:timetile";
/// The time of each texel over one period of the pattern (DepthImage::texelTimes).
inline constexpr const char* kAttrTexelTimes = "umbra:texeltimes";
inline constexpr const char* kAttrTilesX = "umbra:tilesX";
inline constexpr const char* kAttrTilesY = "umbra:tilesY";
inline constexpr const char* kAttrTileMinZ = "umbra:tileMinZ";
inline constexpr const char* kAttrTileMaxZ = "umbra:tileMaxZ";
inline constexpr const char* kAttrMinZ = "umbra:minZ";
inline constexpr const char* kAttrMaxZ = "umbra:maxZ";
inline constexpr const char* kAttrFiniteCount = "umbra:finiteCount";

/// Imath matrix (row-vector convention) to Mat4 (column-vector convention).
Mat4 fromImath(const Imath::M44f& m);

/// One map (or cube face) as it is stored: its header, with every attribute
/// (OpenEXR writes the header when the file is opened, so all of them are
/// computed first), and the depths of its data window. The writer stores
/// exactly this, and a map built from memory (ShadowMap::fromImage) reads
/// its header, so the two cannot disagree.
struct PreparedMap {
    Imf::Header header;
    Imath::Box2i data;
    int tilesX = 0, tilesY = 0;  // kMapTileSize tiles covering the data window
    /// The image the tiles are read from (the data window, sanitised, as
    /// they are written: no cropped copy is made), which must outlive the
    /// write; and whether it holds no finite depth at all (the window is
    /// then one texel of +infinity).
    const DepthImage* image = nullptr;
    bool none = false;
};

/// Prepares `image` for storing (see writeDepthMap for what the header
/// holds). False with a reason in `why` when the image is malformed.
bool prepareMap(const DepthImage& image, PreparedMap& out, std::string& why);

/// The projection-related header fields of a map.
struct MapMatrices {
    Mat4 lightFromWorld, ndcFromWorld;
    Projection projection = Projection::Perspective;
    DepthFilter filter = DepthFilter::Min;
    float dualOffset = 0;
    int timeTile = 0;
    std::vector<float> texelTimes;  // empty, or a valid table (validTexelTimes)
};

/// A table of texel times a map can use: n * n times in [0, 1], n a
/// multiple of the time tile and at most 64.
inline bool validTexelTimes(const std::vector<float>& times, int timeTile) {
    const int n = int(std::lround(std::sqrt(double(times.size()))));
    if (timeTile <= 0 || n == 0 || size_t(n) * size_t(n) != times.size() || n > 64 || n % timeTile != 0) return false;
    for (float t : times)
        if (!(t >= 0.0f && t <= 1.0f)) return false;
    return true;
}

/// Reads worldToCamera/worldToNDC (required) and the umbra attributes
/// (optional: the projection is inferred from worldToNDC when absent).
/// False with a reason in `why` when something required is missing or
/// malformed.
inline bool readMapMatrices(const Imf::Header& header, MapMatrices& out, std::string& why) {
    auto* w2c = header.findTypedAttribute<Imf::M44fAttribute>(kAttrWorldToCamera);
    auto* w2n = header.findTypedAttribute<Imf::M44fAttribute>(kAttrWorldToNDC);
    if (!w2c || !w2n) {
        why = "expected the header matrices worldToCamera and worldToNDC (m44f)";
        return false;
    }
    out.lightFromWorld = fromImath(w2c->value());
    out.ndcFromWorld = fromImath(w2n->value());
    const auto& n = out.ndcFromWorld.m;
    out.projection = (n[3][0] == 0 && n[3][1] == 0 && n[3][2] == 0) ? Projection::Orthographic : Projection::Perspective;
    if (auto* a = header.findTypedAttribute<Imf::StringAttribute>(kAttrProjection)) {
        if (!parseProjection(a->value(), &out.projection)) {
            why = "unknown umbra:projection \"" + a->value() + "\" (expected \"perspective\" or \"orthographic\")";
            return false;
        }
    }
    if (auto* a = header.findTypedAttribute<Imf::StringAttribute>(kAttrDepthFilter)) {
        if (!parseDepthFilter(a->value(), &out.filter)) {
            why = "unknown umbra:depthfilter \"" + a->value() +
                  "\" (expected min, max, average, midpoint, second or dual)";
            return false;
        }
    }
    if (auto* a = header.findTypedAttribute<Imf::FloatAttribute>(kAttrDualOffset)) out.dualOffset = a->value();
    if (auto* a = header.findTypedAttribute<Imf::IntAttribute>(kAttrTimeTile))
        out.timeTile = std::clamp(a->value(), 0, 64);
    // Texel times another writer got wrong are dropped, not an error: the
    // map is still a map, looked up as one of unknown times.
    if (auto* a = header.findTypedAttribute<Imf::FloatVectorAttribute>(kAttrTexelTimes))
        if (validTexelTimes(a->value(), out.timeTile)) out.texelTimes = a->value();
    return true;
}

}  // namespace umbra
