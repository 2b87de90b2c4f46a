#include "render/services.h"

#include "umbra/util/cpu_time.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <vector>

namespace umbra::render {

std::shared_ptr<ShadowMap> MapCatalog::get(const std::string& name, const MapCaller& caller) {
    std::lock_guard<std::mutex> lock(m_mutex);
    auto it = m_maps.find(name);
    if (it != m_maps.end()) return it->second;
    // What opening says (why the map cannot be read) is reported where the
    // lookup was asked for, with the call that asked.
    Diagnostics opening;
    opening.setRecord(true);
    opening.setSink([](const Diagnostic&) {});
    const std::string path = resolve(name);
    auto map = ShadowMap::open(path, opening, FileLoc::inFile(path), m_cache);
    m_opened.push_back(name);
    const FileLoc where = caller.primitive ? *caller.primitive : FileLoc();
    const FileLoc calledAt =
        caller.shaderFile ? FileLoc::inFile(*caller.shaderFile, caller.line, caller.column) : FileLoc();
    for (const Diagnostic& d : opening.recorded()) {
        if (!where.file && !calledAt.file) {
            m_diag.report(d.severity, d.loc, d.message);
            continue;
        }
        std::string message = d.message;
        if (calledAt.file) message += fmt::format(" (shadow() at {})", calledAt.str());
        if (!map && d.severity >= Severity::Error) message += "; its lookups are lit";
        m_diag.report(d.severity, where.file ? where : calledAt, std::move(message));
    }
    m_maps[name] = map;
    return map;
}

std::string MapCatalog::resolve(const std::string& name) const {
    namespace fs = std::filesystem;
    std::error_code ec;
    if (name.empty() || fs::path(name).is_absolute()) return name;
    for (const std::string& dir : m_searchPath) {
        const fs::path candidate = dir.empty() || dir == "." ? fs::path(name) : fs::path(dir) / name;
        if (fs::is_regular_file(candidate, ec)) return candidate.string();
    }
    return name;
}

void MapCatalog::setSearchPath(std::vector<std::string> dirs) {
    std::lock_guard<std::mutex> lock(m_mutex);
    if (dirs == m_searchPath) return;
    m_searchPath = std::move(dirs);
    for (const std::string& name : m_opened) m_maps.erase(name);
    m_opened.clear();
}

void MapCatalog::invalidate(const std::string& name) {
    std::lock_guard<std::mutex> lock(m_mutex);
    m_maps.erase(name);
}

void MapCatalog::setCache(std::shared_ptr<TileCache> cache) {
    std::lock_guard<std::mutex> lock(m_mutex);
    m_maps.clear();
    m_cache = std::move(cache);
}

void MapCatalog::put(const std::string& name, std::shared_ptr<ShadowMap> map) {
    std::lock_guard<std::mutex> lock(m_mutex);
    m_maps[name] = std::move(map);
    std::erase(m_opened, name);
}

namespace {

const GridState& stateOf(const shading::ShadingGrid& grid) { return *static_cast<const GridState*>(grid.renderState); }

bool namedSampling(const std::string& s, ShadowParams::Sampling* out) {
    if (s == "jittered" || s == "jitter") *out = ShadowParams::Sampling::Jittered;
    else if (s == "uniform" || s == "regular") *out = ShadowParams::Sampling::Uniform;
    else if (s == "gaussian") *out = ShadowParams::Sampling::Gaussian;
    else return false;
    return true;
}

/// The shadow() call's optional parameters, with RenderMan's names.
ShadowParams paramsOf(const shading::ShadowQuery& q, Diagnostics& diag) {
    ShadowParams p;
    for (const auto& v : q.params) {
        const std::string& n = v.name;
        if (n == "samples") p.samples = std::max(1, int(v.floatOr(16)));
        else if (n == "width") p.setWidth(v.floatOr(1));
        else if (n == "swidth") p.sWidth = v.floatOr(1);
        else if (n == "twidth") p.tWidth = v.floatOr(1);
        else if (n == "blur") p.blur = v.floatOr(0);
        else if (n == "bias") p.bias = v.floatOr(0);
        else if (n == "bias0") p.bias0 = v.floatOr(0);
        else if (n == "bias1") p.bias1 = v.floatOr(0);
        else if (n == "minsamples") p.minSamples = std::max(1, int(v.floatOr(2)));
        else if (n == "minsize") p.minSize = v.floatOr(2);
        else if (n == "filter" && !v.strings.empty()) {
            if (v.strings[0] == "gaussian") p.filter = ShadowParams::Filter::Gaussian;
            else if (v.strings[0] == "box") p.filter = ShadowParams::Filter::Box;
            else diag.warningOnce("shadow filter " + v.strings[0], {}, "shadow(): unknown filter \"{}\" (expected \"box\" or \"gaussian\")", v.strings[0]);
        } else if ((n == "sampling" || n == "method") && !v.strings.empty()) {
            if (!namedSampling(v.strings[0], &p.sampling))
                diag.warningOnce("shadow sampling " + v.strings[0], {},
                                 "shadow(): unknown sampling \"{}\" (expected \"jittered\", \"uniform\" or \"gaussian\")",
                                 v.strings[0]);
        } else {
            diag.warningOnce("shadow param " + n, {}, "shadow(): unknown parameter \"{}\" ignored", n);
        }
    }
    return p;
}

}  // namespace

bool Services::getMatrix(const shading::ShadingGrid& grid, const std::string& space, Mat4* currentFromSpace) {
    const GridState& st = stateOf(grid);
    const hider::Camera& cam = st.pass->camera;
    if (space == "camera") {
        *currentFromSpace = Mat4::identity();
    } else if (space == "world") {
        *currentFromSpace = cam.cameraFromWorld;
    } else if (space == "object") {
        *currentFromSpace = st.cameraFromObject;
    } else if (space == "screen") {
        *currentFromSpace = cam.screenFromCamera().inverse();
    } else if (space == "NDC") {
        *currentFromSpace = (cam.ndcFromScreen() * cam.screenFromCamera()).inverse();
    } else if (space == "raster") {
        *currentFromSpace = cam.rasterFromCamera().inverse();
    } else {
        const auto& systems = st.frame->world->coordinateSystems;
        const Mat4* named = nullptr;
        if (st.record && st.record->attributes) {
            named = st.record->attributes->space(space, systems);
        } else if (auto it = systems.find(space); it != systems.end()) {
            named = &it->second;
        }
        if (!named) return false;
        *currentFromSpace = cam.cameraFromWorld * *named;
    }
    return true;
}

bool Services::shadow(const shading::ShadingGrid& grid, const shading::ShadowQuery& q, float* result) {
    const GridState& st = stateOf(grid);
    if (st.frame->noShadows) {  // --no-shadows: every lookup lit, no map read
        std::fill_n(result, q.count, 0.0f);
        return true;
    }
    if (q.mapName == "raytrace") return raytrace(st, q, result);
    auto map = m_maps.get(q.mapName, {st.record ? &st.record->loc : nullptr, q.callFile, q.callLine, q.callColumn});
    if (!map) return false;

    ShadowBatch batch;
    batch.count = q.count;
    batch.P = q.P;
    batch.dPdu_du = q.dPdu;
    batch.dPdv_dv = q.dPdv;
    batch.N = q.N;
    for (int c = 0; c < 4; ++c) batch.corners[c] = q.corners[c];
    batch.worldFromCurrent = st.pass->camera.cameraFromWorld.inverse();
    batch.seed = q.seed;
    batch.pointId = q.indices;
    ShadowParams params = paramsOf(q, m_diag);
    if (params.bias == 0 && params.bias0 == 0 && params.bias1 == 0) applyDefaultBias(*map, params);
    // A moving surface: its path over the shutter, point by point, for a
    // map of moving casters to compare each time with it where it is then.
    thread_local std::vector<Vec3> t_offsets;
    const size_t keys = grid.pathTimes.size();
    if (keys > 1 && map->timeTile() > 0) {
        t_offsets.resize(keys * size_t(q.count));
        const size_t n = size_t(grid.size());
        for (size_t k = 0; k < keys; ++k)
            for (int i = 0; i < q.count; ++i) {
                const size_t v = size_t(q.indices ? q.indices[i] : i);
                t_offsets[k * size_t(q.count) + size_t(i)] = v < n ? grid.pathOffsets[k * n + v] : Vec3();
            }
        if (map->knowsTexelTimes()) {
            batch.pathKeys = int(keys);
            batch.pathTimes = grid.pathTimes.data();
            batch.pathOffsets = t_offsets.data();
        } else {
            warnMovingReceiver(grid, q, *map, params, batch.worldFromCurrent, t_offsets);
        }
    }
    ShadowStats stats;
    // The thread's CPU clock, not the wall's: a lookup preempted on a busy
    // machine is not charged for the time it waited. Read for a sample of
    // the lookups, as for the shading time.
    thread_local uint64_t lookups = 0;
    const SampledCallTime lookupTime(lookups);
    map->lookup(batch, params, result, stats);
    m_lookupNanoseconds += lookupTime.nanoseconds();
    std::lock_guard<std::mutex> lock(m_statsMutex);
    m_stats += stats;
    return true;
}

void Services::warnMovingReceiver(const shading::ShadingGrid& grid, const shading::ShadowQuery& q, const ShadowMap& map,
                                  const ShadowParams& params, const Mat4& worldFromCurrent,
                                  const std::vector<Vec3>& pathOffsets) {
    // A map of moving casters holds each texel at one time of the shutter
    // (docs/motion.md); when it does not say which, a surface is looked up
    // at the shutter's opening: where it moves (in the light's space) by
    // more than the bias, the texels of later times hold it nearer the
    // light than the point compared with them, and it shadows itself.
    // Said once per map.
    const Mat4 lightFromCurrent = map.lightFromWorld() * worldFromCurrent;
    const float bias = std::max({params.bias, params.bias0, params.bias1});
    float largest = 0;
    for (const Vec3& offset : pathOffsets) largest = std::max(largest, length(lightFromCurrent.vector(offset)));
    if (!(largest > bias)) return;
    const GridState& st = stateOf(grid);
    m_diag.warningOnce("moving receiver " + q.mapName, st.record ? st.record->loc : FileLoc(),
                       "shadow(\"{}\"): this surface moves {:.3g} in the light's space during the shutter, more "
                       "than the bias {:.3g}, and the map does not say when its texels hold their casters (it was "
                       "made before maps did); it is compared at the shutter's opening with the casters of every "
                       "time, and may shadow itself (remake the map, give a bias above the motion, or make the "
                       "map with Shutter 0 0 for a sharp shadow: docs/motion.md)",
                       q.mapName, largest, bias);
}

FileLoc Services::primitiveLocation(const shading::ShadingGrid& grid) {
    const GridState& st = stateOf(grid);
    return st.record ? st.record->loc : FileLoc();
}

void Services::applyDefaultBias(const ShadowMap& map, ShadowParams& params) const {
    // Maps of nearest depths need a bias against self-shadowing; the
    // two-layer filters are built to need none (docs/shadows.md).
    DepthFilter f = map.depthFilter();
    if (f != DepthFilter::Min && f != DepthFilter::Max && f != DepthFilter::Average) return;
    const auto& user = m_frame->world->options.user;
    // Option "shadow" "bias" / "bias0" / "bias1": any one given (0 too)
    // replaces PRMan's default 0.225, the others then being 0.
    bool given = false;
    auto get = [&](const char* name) {
        auto it = user.find(name);
        if (it == user.end()) return 0.0f;
        const ri::Param& p = it->second;
        given = true;
        return !p.floats.empty() ? p.floats[0] : (!p.ints.empty() ? float(p.ints[0]) : 0.0f);
    };
    params.bias = get("shadow:bias");
    params.bias0 = get("shadow:bias0");
    params.bias1 = get("shadow:bias1");
    if (!given) params.bias = kDefaultShadowBias;
}

bool Services::raytrace(const GridState& st, const shading::ShadowQuery& q, float* result) {
    const FrameState& frame = *st.frame;
    if (!q.L) {
        m_diag.warningOnce("raytrace outside light", {},
                           "shadow(\"raytrace\", ...) is traced towards the light, so it must be called inside "
                           "illuminate() or solar() of a light shader; unshadowed elsewhere");
        return false;
    }
    std::call_once(frame.occlusionOnce, [&] {
        frame.occlusion = std::make_unique<trace::OcclusionScene>(*frame.primitives, trace::TessellationOptions{}, &m_diag);
    });
    const Mat4& cameraFromWorld = st.pass->camera.cameraFromWorld;
    const Mat4 worldFromCamera = cameraFromWorld.inverse();
    for (int k = 0; k < q.count; ++k) {
        Vec3 P = worldFromCamera.point(q.P[k]);
        Vec3 L = worldFromCamera.vector(q.L[k]);  // from the light towards P
        const Vec3* N = nullptr;
        Vec3 Nw;
        if (q.N) {
            Nw = normalize(Mat4::normal(cameraFromWorld, q.N[k]));
            N = &Nw;
        }
        trace::LightTarget target = q.lightAtInfinity ? trace::LightTarget::distant(L) : trace::LightTarget::point(P - L);
        result[k] = frame.occlusion->shadowFraction(P, target, N);
    }
    return true;
}

bool Services::attribute(const shading::ShadingGrid& grid, const std::string& name, shading::ShadeValue* out) {
    const GridState& st = stateOf(grid);
    if (!st.record) return false;  // an imager's grid of pixels has no primitive
    const scene::Attributes& a = *st.record->attributes;
    if (name == "ShadingRate") {
        out->floats = {a.shadingRate};
        return true;
    }
    if (name == "Sides") {
        out->floats = {float(a.sides)};
        return true;
    }
    if (name == "Matte") {
        out->floats = {a.matte ? 1.0f : 0.0f};
        return true;
    }
    if (name == "identifier:name") {
        out->strings = {a.name};
        return true;
    }
    if (name == "displacementbound:sphere") {
        out->floats = {a.displacementBound};
        return true;
    }
    auto it = a.user.find(name);
    if (it == a.user.end()) return false;
    out->floats = it->second.floats;
    for (int v : it->second.ints) out->floats.push_back(float(v));
    out->strings = it->second.strings;
    return true;
}

bool Services::option(const std::string& name, shading::ShadeValue* out) {
    if (!m_frame) return false;
    const scene::Options& o = m_frame->world->options;
    if (name == "Format") {
        out->floats = {float(o.xResolution), float(o.yResolution), o.pixelAspectRatio};
        return true;
    }
    if (name == "FrameAspectRatio") {
        out->floats = {o.frameAspectRatio > 0 ? o.frameAspectRatio
                                              : float(o.xResolution) * o.pixelAspectRatio / float(o.yResolution)};
        return true;
    }
    if (name == "Clipping") {
        out->floats = {o.nearClip, o.farClip};
        return true;
    }
    // The rest of RI Spec 3.2's table of option() names.
    if (name == "CropWindow") {
        out->floats.assign(o.cropWindow, o.cropWindow + 4);
        return true;
    }
    if (name == "DepthOfField") {
        out->floats = {o.fstop, o.focalLength, o.focalDistance};
        return true;
    }
    if (name == "Shutter") {
        out->floats.assign(o.shutter, o.shutter + 2);
        return true;
    }
    if (name == "PixelSamples") {
        out->floats = {float(o.pixelSamples[0]), float(o.pixelSamples[1])};
        return true;
    }
    if (name == "FrameNumber") {
        out->floats = {float(m_frame->world->frameNumber)};
        return true;
    }
    auto it = o.user.find(name);
    if (it == o.user.end()) return false;
    out->floats = it->second.floats;
    for (int v : it->second.ints) out->floats.push_back(float(v));
    out->strings = it->second.strings;
    return true;
}

ShadowStats Services::shadowStats() const {
    std::lock_guard<std::mutex> lock(m_statsMutex);
    return m_stats;
}

void Services::resetStats() {
    std::lock_guard<std::mutex> lock(m_statsMutex);
    m_stats = ShadowStats();
    m_lookupNanoseconds = 0;
}

}  // namespace umbra::render
