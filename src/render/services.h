#pragma once
// The renderer's answers to running shaders (shading::RendererServices):
// named coordinate systems, shadow maps, attributes and options.

#include "render/frame.h"

#include "umbra/shading/renderer_services.h"
#include "umbra/shadow/shadow_map.h"

#include <atomic>
#include <map>
#include <memory>
#include <mutex>
#include <string>

namespace umbra::render {

/// Who asks for a map: the RIB location of the primitive whose shader
/// called shadow(), and that call in the shader's source (file, line,
/// column). Pointers, so that a lookup of an open map copies nothing.
struct MapCaller {
    const FileLoc* primitive = nullptr;
    const std::string* shaderFile = nullptr;
    int line = 0, column = 0;
};

/// Shadow maps opened by name for a render, shared by every light and thread.
class MapCatalog {
public:
    MapCatalog(Diagnostics& diag, std::shared_ptr<TileCache> cache) : m_diag(diag), m_cache(std::move(cache)) {}
    /// The map called `name` (opened on first use), or null after reporting
    /// once that it cannot be read, at the first caller's primitive and
    /// naming its shadow() call (as unreadable textures are reported).
    std::shared_ptr<ShadowMap> get(const std::string& name, const MapCaller& caller = {});
    /// Forgets a map so the next get() reopens it (a depth pass rewrote it).
    void invalidate(const std::string& name);
    /// Registers a map rendered in this frame under `name` ("auto" maps).
    void put(const std::string& name, std::shared_ptr<ShadowMap> map);
    TileCache& cache() { return *m_cache; }
    /// Replaces the tile cache (a new memory bound); open maps are forgotten.
    void setCache(std::shared_ptr<TileCache> cache);
    /// Where a map named by a relative path is looked for: Option
    /// "searchpath" "texture", as PRMan, Pixie and Aqsis look for shadow
    /// maps (MakeShadow's output is a texture file). Maps found on an older
    /// path are forgotten when it changes.
    void setSearchPath(std::vector<std::string> dirs);

private:
    /// `name` on the search path, or `name` itself when no directory holds it.
    std::string resolve(const std::string& name) const;

    Diagnostics& m_diag;
    std::shared_ptr<TileCache> m_cache;
    std::mutex m_mutex;
    std::map<std::string, std::shared_ptr<ShadowMap>> m_maps;  // null: failed
    std::vector<std::string> m_searchPath;
    std::vector<std::string> m_opened;  // names get() opened from files
};

class Services : public shading::RendererServices {
public:
    Services(Diagnostics& diag, MapCatalog& maps) : m_diag(diag), m_maps(maps) {}

    bool getMatrix(const shading::ShadingGrid& grid, const std::string& space, Mat4* currentFromSpace) override;
    bool shadow(const shading::ShadingGrid& grid, const shading::ShadowQuery& query, float* result) override;
    FileLoc primitiveLocation(const shading::ShadingGrid& grid) override;
    bool attribute(const shading::ShadingGrid& grid, const std::string& name, shading::ShadeValue* out) override;
    bool option(const std::string& name, shading::ShadeValue* out) override;

    /// Lookup counters of every thread, summed.
    ShadowStats shadowStats() const;
    void resetStats();
    /// Time spent inside shadow-map lookups (filtering, region transforms),
    /// summed over threads.
    double lookupSeconds() const { return double(m_lookupNanoseconds.load()) * 1e-9; }
    void setFrame(const FrameState* frame) { m_frame = frame; }

private:
    /// A shadow() call that gives no bias gets RenderMan's Option "shadow"
    /// "bias" (or "bias0"/"bias1"); 0.225 when unset, as PRMan.
    void applyDefaultBias(const ShadowMap& map, ShadowParams& params) const;
    /// Warns once per map when a moving surface looks up a map of moving
    /// casters whose texels' times are unknown (a map made before maps
    /// recorded them) further than the bias (it may shadow itself:
    /// docs/motion.md).
    void warnMovingReceiver(const shading::ShadingGrid& grid, const shading::ShadowQuery& q, const ShadowMap& map,
                            const ShadowParams& params, const Mat4& worldFromCurrent,
                            const std::vector<Vec3>& pathOffsets);
    static constexpr float kDefaultShadowBias = 0.225f;
    /// Exact shadows by tracing towards the light (reference mode).
    bool raytrace(const GridState& st, const shading::ShadowQuery& q, float* result);

    Diagnostics& m_diag;
    MapCatalog& m_maps;
    const FrameState* m_frame = nullptr;
    mutable std::mutex m_statsMutex;
    ShadowStats m_stats;
    std::atomic<uint64_t> m_lookupNanoseconds{0};
};

}  // namespace umbra::render
