#include "umbra/render/renderer.h"
#include "umbra/util/cpu_time.h"
#include "umbra/util/file.h"
#include "umbra/util/frame_set.h"
#include "umbra/util/interrupt.h"
#include "umbra/util/parallel.h"
#include "umbra/util/search_path.h"

#include "render/frame.h"
#include "render/light_view.h"
#include "render/map_reuse.h"
#include "render/progress.h"
#include "render/services.h"
#include "render/surface_pipeline.h"

#include "umbra/film/film.h"
#include "umbra/geometry/procedural.h"
#include "umbra/render/make_files.h"
#include "umbra/hider/bucket_scheduler.h"
#include "umbra/ri/parser.h"
#include "umbra/scene/builder.h"
#include "umbra/shadow/depth_image.h"
#include "umbra/util/rng.h"

#include <fmt/chrono.h>
#include <fmt/ranges.h>
#include <tbb/task_arena.h>

#include <optional>

#include <fcntl.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <future>

namespace umbra::render {

namespace {

/// How far (map pixels) a micropolygon of an automatic nearest-depth map
/// may stand off its surface: a quarter of a texel moves a shadow's edge
/// by less than percentage-closer filtering blurs it, and its depth by a
/// quarter of a texel's width, far less than the bias such maps need.
constexpr float kDepthFlatness = 0.25f;

constexpr const char* kUmbraVersion = "0.1.0";
/// Bucket sizes (pixels) when neither --bucket-size nor Option "limits"
/// "bucketsize" gives one: a camera pass's, and a depth pass's (one sample
/// a texel, so about as many samples a bucket).
constexpr int kCameraBucketSize = 32;
constexpr int kDepthBucketSize = 64;

double peakResidentMiB() {
    rusage ru{};
    getrusage(RUSAGE_SELF, &ru);
    return double(ru.ru_maxrss) / 1024.0;  // ru_maxrss is in KiB on Linux
}

/// Wall and CPU time of a stretch of work.
struct Stopwatch {
    std::chrono::steady_clock::time_point wall0 = std::chrono::steady_clock::now();
    double cpu0 = processCpuSeconds();
    double wall() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count(); }
    double cpu() const { return processCpuSeconds() - cpu0; }
};

/// How messages name a world: "frame 12", or "the world at scene.rib:4:1"
/// outside FrameBegin/FrameEnd (which has no number, -1 in the statistics).
std::string frameName(const scene::WorldRecord& world) {
    if (world.frameNumber >= 0) return fmt::format("frame {}", world.frameNumber);
    return world.loc.file ? "the world at " + world.loc.str() : std::string("the world");
}

std::string nowDateTime() {
    std::time_t t = std::time(nullptr);
    std::tm tm{};
    localtime_r(&t, &tm);
    return fmt::format("{:%Y:%m:%d %H:%M:%S}", tm);
}

/// The reproducible-builds convention (reproducible-builds.org/specs/
/// source-date-epoch): $SOURCE_DATE_EPOCH, seconds since 1970 UTC, is the
/// date images carry, in UTC, and no render time is written, so a frame
/// rendered on a farm is byte for byte the one rendered at a desk. Nothing
/// when unset; a warning (and the render's own date) when not a number.
std::optional<std::string> sourceDateTime(Diagnostics& diag) {
    const char* text = std::getenv("SOURCE_DATE_EPOCH");
    if (!text || !*text) return std::nullopt;
    char* end = nullptr;
    errno = 0;
    const long long seconds = std::strtoll(text, &end, 10);
    if (errno != 0 || *end != '\0' || seconds < 0 || seconds > 253402300799LL) {  // up to 9999-12-31
        diag.warningOnce("SOURCE_DATE_EPOCH", FileLoc{},
                         "SOURCE_DATE_EPOCH=\"{}\" is not a count of seconds since 1970; images carry the date "
                         "and time of the render",
                         text);
        return std::nullopt;
    }
    const std::time_t t = std::time_t(seconds);
    std::tm tm{};
    gmtime_r(&t, &tm);
    return fmt::format("{:%Y:%m:%d %H:%M:%S}", tm);
}

/// Option "statistics" "endofframe" [2]: after the summary, each pass,
/// each automatic map, and the shadow lookups' and tile cache's counters,
/// from the frame's statistics record.
void printDetailedStatistics(const nlohmann::json& f) {
    std::string text = "  passes\n";
    for (const auto& p : f["passes"]) {
        const auto& c = p["counts"];
        text += fmt::format("    {:<20} {:8.3f} s wall {:8.3f} s cpu  {} buckets, {} grids, {} micropolygons, {} samples\n",
                            p["name"].get<std::string>(), p["wall_seconds"].get<double>(),
                            p["cpu_seconds"].get<double>(), c["buckets"].get<uint64_t>(), c["grids"].get<uint64_t>(),
                            c["micropolygons"].get<uint64_t>(), p["samples"].get<uint64_t>());
    }
    if (!f["maps"].empty()) text += "  maps\n";
    for (const auto& m : f["maps"])
        text += fmt::format("    {:<20} {} ({}) {}\n", m["light"].get<std::string>(),
                            m["reused"].get<bool>() ? "reused" : "rendered", m["reason"].get<std::string>(),
                            m["path"].get<std::string>());
    const auto& s = f["shadow"];
    const auto& t = s["tile_cache"];
    text += fmt::format("  lookups     {} points ({} outside the map), {} samples, {} tile fetches, {:.3f} s\n",
                        s["points"].get<uint64_t>(), s["outside"].get<uint64_t>(), s["samples"].get<uint64_t>(),
                        s["tile_fetches"].get<uint64_t>(), s["lookup_seconds"].get<double>());
    text += fmt::format("  tile cache  {} lookups, {} hits, {} misses, {} tiles read, {} evictions, {:.1f} MiB peak\n",
                        t["lookups"].get<uint64_t>(), t["hits"].get<uint64_t>(), t["misses"].get<uint64_t>(),
                        t["tiles_read"].get<uint64_t>(), t["evictions"].get<uint64_t>(),
                        double(t["peak_bytes"].get<uint64_t>()) / (1 << 20));
    text += fmt::format("  film        {}, {} rows held at most\n",
                        f["film_streamed"].get<bool>() ? "streamed to its TIFFs while rendering" : "written whole",
                        f["film_rows_held_peak"].get<int>());
    text += fmt::format("  map files   {:.3f} s writing, {:.3f} s waiting, {} in the background\n",
                        s["map_write_seconds"].get<double>(), s["map_write_wait_seconds"].get<double>(),
                        s["background_map_writes"].get<int>());
    fmt::print(stderr, "{}", text);
}

nlohmann::json schedulerJson(const hider::SchedulerStats& s) {
    return {{"primitives", s.primitives}, {"culled", s.culled},     {"occlusion_culled", s.occlusionCulled},
            {"splits", s.splits},         {"grids", s.grids},       {"micropolygons", s.micropolygons},
            {"buckets", s.buckets},       {"peak_grids_alive", s.peakGridsAlive},
            {"blur", {{"micropolygons", s.blur.micropolygons},
                      {"sample_tests", s.blur.sampleTests},
                      {"sample_hits", s.blur.sampleHits}}}};
}

/// The frame's displays with modes that name a DisplayChannel replaced by
/// the channel's declaration ("myaov" -> "color myaov"), as PRMan reads them;
/// the channel's pixel filter ("filter", "filterwidth") applies to a
/// display of it that names none.
std::vector<scene::DisplayRecord> withDisplayChannels(const scene::Options& options) {
    std::vector<scene::DisplayRecord> displays = options.displays;
    for (auto& d : displays)
        for (const auto& channel : options.displayChannels) {
            const std::string& decl = channel.name;  // e.g. "varying color myaov"
            size_t space = decl.find_last_of(' ');
            const bool named = decl == d.mode || (space != std::string::npos && decl.substr(space + 1) == d.mode);
            if (!named) continue;
            d.mode = decl;
            if (!d.params.find("filter") && !d.params.find("filterwidth"))
                for (const char* name : {"filter", "filterwidth"})
                    if (const ri::Param* p = channel.params.find(name)) d.params.add(*p);
        }
    return displays;
}

nlohmann::json tileCacheJson(const TileCacheStats& c) {
    return {{"lookups", c.lookups}, {"hits", c.hits},           {"misses", c.misses},
            {"tiles_read", c.tilesRead}, {"preloaded", c.preloaded}, {"evictions", c.evictions},
            {"peak_bytes", c.peakBytes}};
}

/// The result of one pass through the REYES core.
struct PassResult {
    hider::SchedulerStats counters;
    double wall = 0, cpu = 0;
    uint64_t samples = 0;
    int bucketSize[2] = {0, 0};  // the buckets the pass was cut into
    /// A depth pass of moving casters (Pass::timeTile): when each texel
    /// holds its casters (DepthImage::texelTimes).
    std::vector<float> texelTimes;
};

/// An automatic map's file being written on a thread of its own while the
/// frame goes on.
struct MapWrite {
    std::shared_future<bool> written;  // the writer's result
    std::future<void> thread;          // joins the writer when waited for or destroyed
};

/// An automatic map to make: its light's depth passes (one, or a point
/// light's six cube faces) and where its file goes.
struct LightMapJob {
    std::vector<Pass> passes;
    bool cube = false;
    int size = 0;
    DepthFilter filter = DepthFilter::Min;
    float dualOffset = 0;
    std::string path;
    FileLoc loc;
};

/// An automatic map made: its path ("" when none could be made; the light
/// is then unshadowed), its passes' statistics, the map for the catalogue,
/// and its file's writer when that runs in the background.
struct LightMap {
    std::string path;
    nlohmann::json passes = nlohmann::json::array();
    std::shared_ptr<ShadowMap> map;
    std::optional<MapWrite> write;
    std::shared_future<bool> written;  // its file's writer's result, for later frames reusing it
    bool failed = false;
    double buildSeconds = 0;  // making it usable: building from memory, writes done at once
};

}  // namespace

struct Renderer::Impl {
    RenderSettings settings;
    Diagnostics& diag;
    std::unique_ptr<shading::ShadingSystem> shading;
    std::shared_ptr<TileCache> tileCache;
    size_t tileCacheBytes = size_t(64) << 20;
    std::unique_ptr<MapCatalog> maps;
    std::unique_ptr<Services> services;
    nlohmann::json frames = nlohmann::json::array();
    std::function<void(const nlohmann::json&)> frameSink;
    /// Records a finished frame's statistics.
    void addFrame(nlohmann::json f) {
        frames.push_back(std::move(f));
        if (frameSink) frameSink(frames.back());
    }
    /// Runs a map-file write, adding its thread's CPU time to the frame's.
    template <typename Write> bool timedMapWrite(Write write) {
        const double cpu0 = threadCpuSeconds();
        const bool ok = write();
        mapFileCpuNanoseconds += uint64_t((threadCpuSeconds() - cpu0) * 1e9);
        return ok;
    }
    // This frame's automatic maps: time spent making them usable (building
    // them from memory, preloading, writing those written at once), and
    // waiting at the end for the files written in the background.
    double mapWriteSeconds = 0, mapWriteWaitSeconds = 0;
    /// CPU time encoding and writing automatic maps' files, in the
    /// background or not (nanoseconds; writers add to it from their threads).
    std::atomic<uint64_t> mapFileCpuNanoseconds{0};
    int backgroundMapWrites = 0;

    /// The latest automatic map of each light handle, for later frames whose
    /// map would have the same content (docs/shadows.md).
    struct ReusableMap {
        MapContent content;
        std::string path;
        std::shared_future<bool> written;
    };
    std::map<std::string, ReusableMap> reusableMaps;
    /// What decides the texels of `job`'s map in this frame.
    MapContent mapContentOf(const FrameState& frame, const scene::LightRecord& light, const LightMapJob& job);

    /// Copies the map file `from` into the map cache as `to`, atomically
    /// (a warning when it cannot: the frame itself is complete).
    void addToMapCache(const std::string& from, const std::string& to);

    /// Every pass and the output run in this arena: no more threads than
    /// --threads. One arena for the renderer's life, so its workers stay
    /// with it from pass to pass.
    std::unique_ptr<tbb::task_arena> arena;
    int threadCount() const { return settings.threads > 0 ? settings.threads : tbb::this_task_arena::max_concurrency(); }

    Impl(const RenderSettings& s, Diagnostics& d) : settings(s), diag(d) {
        if (settings.shaderPath.empty()) settings.shaderPath = splitSearchPath(defaultShaderPath());
        if (settings.texturePath.empty()) settings.texturePath = splitSearchPath(defaultTexturePath());
        arena = std::make_unique<tbb::task_arena>(threadCount());
        shading = std::make_unique<shading::ShadingSystem>(diag, settings.shaderPath);
        tileCache = std::make_shared<TileCache>();
        maps = std::make_unique<MapCatalog>(diag, tileCache);
        services = std::make_unique<Services>(diag, *maps);
    }

    /// Resolves the shaders of every Attributes object primitives use.
    void prepareAttributes(const std::vector<geometry::PrimitivePtr>& prims, FrameState& frame) {
        std::map<const scene::ShaderRecord*, std::shared_ptr<const shading::ShaderInstance>> instances;
        auto instance = [&](const std::shared_ptr<const scene::ShaderRecord>& rec, shading::ShaderKind kind) {
            if (!rec) return std::shared_ptr<const shading::ShaderInstance>();
            auto it = instances.find(rec.get());
            if (it != instances.end()) return it->second;
            auto inst = shading->instantiate(*rec, kind);
            instances[rec.get()] = inst;
            return inst;
        };
        for (const auto& prim : prims) {
            const scene::Attributes* a = prim->record().attributes.get();
            if (frame.attributes.count(a)) continue;
            PreparedAttributes pa;
            pa.attributes = a;
            pa.surface = instance(a->surface, shading::ShaderKind::Surface);
            pa.displacement = instance(a->displacement, shading::ShaderKind::Displacement);
            pa.atmosphere = instance(a->atmosphere, shading::ShaderKind::Volume);
            chooseDetail(frame, pa);
            frame.attributes.emplace(a, std::move(pa));
        }
    }

    /// The level-of-detail window of an attribute set with a Detail. Every
    /// pass draws what the camera's view chooses, so a shadow is cast by the
    /// representation that is seen.
    static void chooseDetail(const FrameState& frame, PreparedAttributes& pa) {
        const scene::Attributes& a = *pa.attributes;
        if (!a.hasDetail) return;
        const scene::Options& o = frame.world->options;
        const float detail = rasterDetail(a.detailCorners, hider::Camera::fromOptions(o), o.relativeDetail);
        std::tie(pa.dissolveFrom, pa.dissolveBelow) = dissolveWindow(detail, a.detailRange);
    }

    /// Gives every attribute set the lights that illuminate it.
    static void attachLights(const std::vector<std::shared_ptr<const shading::ShaderInstance>>& lights, FrameState& frame) {
        for (auto& [a, pa] : frame.attributes) {
            pa.lights.clear();
            for (int l : a->lights)
                if (l >= 0 && size_t(l) < lights.size() && lights[size_t(l)]) pa.lights.push_back(lights[size_t(l)].get());
        }
    }

    void renderWorld(const scene::WorldRecord& world, int& failed);
    PassResult runPass(FrameState& frame, const Pass& pass, const std::vector<geometry::PrimitivePtr>& prims,
                       film::Film& film, const std::string& label);
    /// Runs the Imager shader over the filtered pixels, one row of the
    /// crop region per grid, before exposure and quantization.
    void runImager(const FrameState& frame, const Pass& pass, const scene::ShaderRecord& record, film::Film& film);
    /// The automatic depth map of `light` to make, or nothing (with a
    /// warning) when umbra cannot derive its view. Serial: it looks up the
    /// light's shader and reports what it finds in a fixed order.
    std::optional<LightMapJob> planLightMap(FrameState& frame, const scene::LightRecord& light,
                                            const std::vector<geometry::PrimitivePtr>& prims);
    /// Renders a planned map and makes it usable; safe to run for several
    /// lights at once. Its file may still be being written (the result's
    /// `write`).
    LightMap makeLightMap(FrameState& frame, LightMapJob& job, const std::vector<geometry::PrimitivePtr>& prims);
    DepthFilter depthFilterOf(const scene::Options& options, const FileLoc& loc);
    /// How many depth layers a depth pass keeps: the two-layer filters read
    /// the second, the others need one, which also lets occlusion culling
    /// skip hidden geometry (with two layers a sample is closed only once
    /// two surfaces cover it). Option "umbra" "depthlayers" overrides.
    static int depthLayersOf(const scene::Options& options, DepthFilter filter);
    static film::FilmContent depthFilmOf(const scene::Options& options, DepthFilter filter) {
        return depthLayersOf(options, filter) > 1 ? film::FilmContent::DepthPair : film::FilmContent::Depth;
    }
    float dualOffsetOf(const scene::Options& options);
    Pass::Cull depthCullOf(const scene::Options& options, const FileLoc& loc);
};

Renderer::Renderer(const RenderSettings& settings, Diagnostics& diag)
    : m_impl(std::make_unique<Impl>(settings, diag)) {}
Renderer::~Renderer() = default;

nlohmann::json Renderer::statistics() const {
    return {{"schema", kStatisticsSchema}, {"umbra_version", kUmbraVersion}, {"frames", m_impl->frames}};
}

void Renderer::onFrameStatistics(std::function<void(const nlohmann::json&)> sink) {
    m_impl->frameSink = std::move(sink);
}

void Renderer::renderWorld(const scene::WorldRecord& world) {
    // An unselected frame was parsed (its options scoped as usual) but
    // costs nothing more: no depth pass, no camera pass, no file.
    if (!selected(world.frameNumber)) return;
    const int before = m_failed;
    m_impl->renderWorld(world, m_failed);
    noteFailure(m_fileFrame >= 0 ? m_fileFrame : world.frameNumber, before);
}

void Renderer::frameBegin(int frameNumber, const FileLoc&) { m_frame = frameNumber; }
void Renderer::frameEnd(const FileLoc&) { m_frame = -1; }

bool Renderer::selected(int frameNumber) const {
    const auto& frames = m_impl->settings.frames;
    return m_fileFrame >= 0 || frameNumber < 0 || !frames || frames->contains(frameNumber);
}

void Renderer::addFailedFrame(int frameNumber) {
    ++m_failed;
    noteFailure(frameNumber, m_failed - 1);
}

void Renderer::noteFailure(int frame, int before) {
    if (m_failed > before && std::find(m_failedNumbers.begin(), m_failedNumbers.end(), frame) == m_failedNumbers.end())
        m_failedNumbers.push_back(frame);
}

void Renderer::prepare(scene::Builder& builder, const std::string& ribFile) const {
    // Shaders and textures named in a scene are looked for in the current
    // directory, then beside the RIB file, then in the defaults. The
    // current directory is in the defaults ('@') too, as in Aqsis and
    // Pixie (".:$SHADERS"): course scenes write "./bin:@" for a shader
    // beside the RIB, which umbra did not find.
    std::string ribDir = std::filesystem::path(ribFile).parent_path().string();
    if (ribFile == "-" || ribDir == ".") ribDir.clear();
    const std::string initial = ribDir.empty() ? "@" : ".:" + ribDir + ":@";
    const RenderSettings& s = m_impl->settings;
    builder.setDefaultSearchPath("shader", expandSearchPath(".:@", "", joinSearchPath(s.shaderPath)));
    builder.setDefaultSearchPath("texture", expandSearchPath(".:@", "", joinSearchPath(s.texturePath)));
    builder.setSearchPath("shader", initial);
    builder.setSearchPath("texture", initial);
}

void Renderer::make(const scene::MakeRecord& make) {
    // A Make request inside an unselected frame is that frame's work.
    if (m_fileFrame < 0 && m_frame >= 0 && !selected(m_frame)) return;
    const int before = m_failed;
    if (!makeFile(make, m_impl->diag)) ++m_failed;
    noteFailure(m_fileFrame >= 0 ? m_fileFrame : m_frame, before);
    // A map made again under a name already read is read again.
    if (make.request == "MakeShadow") m_impl->maps->invalidate(make.output);
    // A map file made again is no longer the content an automatic map recorded.
    std::erase_if(m_impl->reusableMaps, [&](const auto& entry) { return entry.second.path == make.output; });
}

void Renderer::Impl::runImager(const FrameState& frame, const Pass& pass, const scene::ShaderRecord& record,
                               film::Film& film) {
    auto imager = shading->instantiate(record, shading::ShaderKind::Imager);
    if (!imager) return;  // reported by instantiate()
    GridState state;
    state.frame = &frame;
    state.pass = &pass;
    const int width = film.width();
    // Every filter layer (displays with filters of their own) is imaged alike.
    for (int layer = 0; layer < film.filterLayers(); ++layer) {
        parallelFor(film.y0(), film.y1(), [&](int y) {
            shading::ShadingGrid g;
            g.resize(width, 1);
            g.alpha.resize(size_t(width));
            g.renderState = &state;
            g.seed = uint32_t(y);
            g.time = frame.shutterOpen;
            g.dtime = frame.shutterClose - frame.shutterOpen;
            for (int i = 0; i < width; ++i) {
                const float* px = film.rgba(layer, film.x0() + i, y);
                const Vec3 p(float(film.x0() + i) + 0.5f, float(y) + 0.5f, 0.0f);
                g.P[size_t(i)] = g.I[size_t(i)] = p;
                g.s[size_t(i)] = g.u[size_t(i)] = p.x;
                g.t[size_t(i)] = g.v[size_t(i)] = p.y;
                g.N[size_t(i)] = g.Ng[size_t(i)] = Vec3(0, 0, -1);
                g.Ci[size_t(i)] = Vec3(px[0], px[1], px[2]);  // premultiplied, as filtered
                g.Oi[size_t(i)] = Vec3(px[3], px[3], px[3]);
                g.alpha[size_t(i)] = px[3];
            }
            shading->shadeImager(g, *imager, *services);
            for (int i = 0; i < width; ++i) {
                float* px = film.rgba(layer, film.x0() + i, y);
                const Vec3& c = g.Ci[size_t(i)];
                // RI Spec 3.2: an imager's outputs are Ci and Oi (Aqsis writes
                // Oi as the pixel's alpha); umbra's imagers may also set
                // alpha. The one the shader changed wins, alpha first.
                const float before = px[3], alpha = g.alpha[size_t(i)];
                const Vec3& o = g.Oi[size_t(i)];
                const bool oiSet = o.x != before || o.y != before || o.z != before;
                px[0] = c.x;
                px[1] = c.y;
                px[2] = c.z;
                px[3] = alpha != before ? alpha : oiSet ? (o.x + o.y + o.z) / 3.0f : before;
            }
        });
    }
}

PassResult Renderer::Impl::runPass(FrameState& frame, const Pass& pass, const std::vector<geometry::PrimitivePtr>& prims,
                                   film::Film& film, const std::string& label) {
    const scene::Options& options = frame.world->options;
    hider::SchedulerSettings ss;
    // Buckets: --bucket-size, else Option "limits" "bucketsize" (but for
    // automatic maps), else 32 pixels for a camera pass and 64 texels for a
    // depth pass (one sample a texel: about as many samples a bucket). A
    // bucket samples its pixels and the filter's margin around them: a 2 x
    // 2 filter's margin is 27% more samples around 16 pixels, 13% around
    // 32, and the benchmark frames took 6-10% fewer instructions at 32
    // ("Camera buckets of 32 pixels" in docs/performance.md); a moving
    // micropolygon's swept bound reaches fewer buckets ("Motion blur
    // cost"). 16-texel buckets cost a 2048^2 light-view frame 16,384 bucket
    // walks and 30-40% of its time ("Depth passes' buckets"). The pictures
    // and maps do not depend on the size.
    const bool automaticMap = pass.depthOnly && pass.name != "camera";
    ss.bucketSize[0] = ss.bucketSize[1] = pass.depthOnly ? kDepthBucketSize : kCameraBucketSize;
    if (settings.bucketSize > 0) {
        ss.bucketSize[0] = ss.bucketSize[1] = settings.bucketSize;
    } else if (options.bucketSizeSet && !automaticMap) {
        ss.bucketSize[0] = options.bucketSize[0];
        ss.bucketSize[1] = options.bucketSize[1];
    }
    ss.threads = settings.threads;
    ss.filterMargin = film.filterMargin();
    ss.sampling.frameSeed = frame.frameSeed;
    ss.sampling.aovCount = film.aovFloats();
    ss.sampling.nearClip = pass.camera.nearClip;
    ss.sampling.perspective = pass.camera.perspective;
    ss.sampling.farClip = pass.camera.farClip;
    ss.sampling.csg = frame.csg.empty() ? nullptr : &frame.csg;
    // Every pass of a blurred frame gives its samples times: moving casters
    // blur their depth maps' texels too (docs/motion.md).
    ss.sampling.motion = frame.motionBlur();
    ss.sampling.shutterOpening[0] = options.shutterOpening[0];
    ss.sampling.shutterOpening[1] = options.shutterOpening[1];
    if (pass.lensRadius > 0 && pass.camera.perspective) {
        ss.sampling.lens = true;
        const float perUnit = pass.lensRadius / pass.camera.tanHalfFov;
        float R[4];
        pass.camera.rasterFromProjected(R);
        if (pass.camera.screenDiagonal()) {
            // Signed: a mirroring screen transform mirrors the blur's offsets too.
            ss.sampling.lensScaleX = perUnit * R[0];
            ss.sampling.lensScaleY = perUnit * R[3];  // negative: raster y runs down
        } else {
            // The hider's lens offsets are per axis. The lens disc maps to
            // raster as R times the disc, an ellipse whose x and y extents
            // are the lengths of R's rows. A rotated or mirrored disc is the
            // same disc, so for a rotation with a uniform scale these scales
            // give the same blur (another pairing of samples with lens
            // positions); a shear or an uneven scale at a turn has its
            // ellipse approximated by the axis-aligned one of the same
            // extents.
            ss.sampling.lensScaleX = perUnit * std::hypot(R[0], R[1]);
            ss.sampling.lensScaleY = -perUnit * std::hypot(R[2], R[3]);
        }
        ss.sampling.inverseFocalDistance = 1.0f / pass.focalDistance;
    }
    if (pass.depthOnly) ss.filterMargin = 0;  // depths are per-pixel minima, never filtered
    if (pass.depthOnly) {
        // Depth maps, automatic or from a light-view RIB: one regular sample
        // at each texel centre (Reeves), whatever PixelSamples says. Every
        // filter's comparison assumes a texel holds its surfaces' depths at
        // its centre: the minimum of jittered samples is a point nearer the
        // light, and a two-layer map's virtual samples then see an open
        // floor shadow itself.
        ss.sampling.xSamples = ss.sampling.ySamples = 1;
        ss.sampling.jitter = false;
    } else {
        ss.sampling.xSamples = std::max(1, options.pixelSamples[0]);
        ss.sampling.ySamples = std::max(1, options.pixelSamples[1]);
        ss.sampling.jitter = options.jitter;
    }
    ss.sampling.mode = pass.depthOnly ? hider::HiderMode::Depth : hider::HiderMode::Colour;
    // "max" and "average" reduce each pixel's samples in colour frames'
    // depth outputs too (Pixie's values); the two-layer filters need a
    // depth-only frame (see cameraFrame).
    using Reduce = hider::SampleBufferConfig::DepthReduce;
    const DepthFilter filter = depthFilterOf(options, options.loc);
    ss.sampling.depthReduce = filter == DepthFilter::Max       ? Reduce::Max
                              : filter == DepthFilter::Average ? Reduce::Average
                                                               : Reduce::Min;
    if (pass.depthOnly) ss.sampling.depthLayers = depthLayersOf(options, filter);
    ss.maxEyeSplits = options.eyeSplits;
    Progress progress(settings.progress, label);
    ss.progress = [&](int done, int total, double workDone) { progress.update(done, total, workDone); };

    SurfacePipeline pipeline(frame, pass, *services, diag, film);
    hider::BucketScheduler scheduler(ss, pipeline);
    Stopwatch clock;
    PassResult r;
    r.counters = scheduler.render(prims, film);
    progress.finish();
    r.wall = clock.wall();
    r.cpu = clock.cpu();
    r.samples = uint64_t(film.width()) * film.height() * ss.sampling.xSamples * ss.sampling.ySamples;
    r.bucketSize[0] = ss.bucketSize[0];
    r.bucketSize[1] = ss.bucketSize[1];
    if (pass.timeTile > 0 && ss.sampling.motion) r.texelTimes = hider::SampleBuffer::periodTimes(ss.sampling);
    return r;
}

void Renderer::Impl::renderWorld(const scene::WorldRecord& world, int& failed) {
    Stopwatch frameClock;
    mapWriteSeconds = mapWriteWaitSeconds = 0;
    mapFileCpuNanoseconds = 0;
    backgroundMapWrites = 0;
    const scene::Options& options = world.options;
    const int errorsBefore = diag.errorCount();
    for (const auto& d : options.displays)
        if (d.implicitDefault)
            diag.warningOnce("display:default", d.loc,
                             "no Display before WorldBegin: writing the image to \"{}\" (a TIFF, as PRMan and "
                             "Aqsis name it)",
                             d.name);

    // --resume (farm restarts): a frame whose every output is a complete
    // image is not rendered again. A file cut short (a killed copy, a full
    // disk) makes the frame render again.
    if (settings.resume && !options.displays.empty()) {
        bool complete = true;
        for (const auto& d : options.displays) {
            const std::string path = film::displayFilePath(d);
            std::string why;
            if (film::imageFileComplete(path, &why)) continue;
            complete = false;
            if (why != "missing")
                diag.warning(d.loc, "--resume: {}: \"{}\" is not a complete image ({}); rendering it again",
                             frameName(world), path, why);
            break;
        }
        if (complete) {
            if (!settings.quiet) fmt::print(stderr, "umbra: {} is complete, skipped\n", frameName(world));
            addFrame({{"frame", world.frameNumber}, {"skipped", true}});
            return;
        }
    }

    // The builder expanded '&' and '@'; a builder no one prepared
    // (Renderer::prepare) leaves unset paths at ".:@".
    auto pathOf = [&](const char* kind, const std::vector<std::string>& builtin) {
        auto it = options.searchPaths.find(kind);
        if (it != options.searchPaths.end()) return splitSearchPath(it->second);
        std::vector<std::string> dirs{"."};
        dirs.insert(dirs.end(), builtin.begin(), builtin.end());
        return dirs;
    };
    shading->setSearchPath(pathOf("shader", settings.shaderPath));
    shading->setTextureSearchPath(pathOf("texture", settings.texturePath));
    maps->setSearchPath(pathOf("texture", settings.texturePath));

    // Option "umbra" "tilecachemb": the shadow tile cache's memory bound.
    if (auto it = options.user.find("umbra:tilecachemb"); it != options.user.end()) {
        int mb = !it->second.ints.empty() ? it->second.ints[0] : int(it->second.floatAt(0, 64));
        size_t bytes = size_t(std::max(1, mb)) << 20;
        if (!tileCache || tileCacheBytes != bytes) {
            tileCache = std::make_shared<TileCache>(bytes);
            tileCacheBytes = bytes;
            maps->setCache(tileCache);
        }
    }

    FrameState frame;
    frame.world = &world;
    frame.frameSeed = hash32(uint32_t(world.frameNumber + 1));
    frame.shutterOpen = options.shutter[0] + options.shutterOffset;
    frame.shutterClose = options.shutter[1] + options.shutterOffset;
    frame.shading = shading.get();
    frame.noShadows = settings.noShadows;
    for (const scene::SolidRecord& solid : world.solids) {
        using Op = hider::CsgForest::Op;
        const Op op = solid.operation == "union"          ? Op::Union
                      : solid.operation == "intersection" ? Op::Intersection
                      : solid.operation == "difference"   ? Op::Difference
                                                          : Op::Primitive;
        frame.csg.add(op, solid.parent);
    }
    services->setFrame(&frame);
    services->resetStats();

    // Procedurals measure their detail in the camera's view, whichever pass
    // expands them.
    hider::Camera detailCamera = hider::Camera::fromOptions(options);
    if (options.cameraMotion) detailCamera.cameraFromWorld = options.cameraMotion->at(frame.shutterOpen);
    auto procedurals = std::make_shared<geometry::ProceduralContext>(
        world, detailCamera.cameraFromWorld, detailCamera.rasterFromCamera(), detailCamera.perspective, diag);
    frame.prepareLate = [this, &frame](PreparedAttributes& pa) {
        const scene::Attributes& a = *pa.attributes;
        if (a.surface) pa.surface = shading->instantiate(*a.surface, shading::ShaderKind::Surface);
        if (a.displacement) pa.displacement = shading->instantiate(*a.displacement, shading::ShaderKind::Displacement);
        if (a.atmosphere) pa.atmosphere = shading->instantiate(*a.atmosphere, shading::ShaderKind::Volume);
        chooseDetail(frame, pa);
    };

    // Subdivision meshes dice their regular regions in blocks only where no
    // shader can tell the blocks' u, v from the faces' (geometry/primitive.h).
    const geometry::ParameterReaders parameterReaders = [this](const scene::Attributes& a) {
        if (a.displacement) return true;
        if (!a.surface) return false;  // defaultsurface reads neither
        const auto path = shading->findFile(a.surface->name);
        if (!path) return true;
        const auto shader = shading->compile(*path);
        return !shader || shader->readsSurfaceParameters();
    };
    std::vector<geometry::PrimitivePtr> prims;
    for (const auto& rec : world.primitives) {
        // Not owning: `world` outlives every primitive of this frame, and a
        // copy of each record doubled the scene's memory.
        const std::shared_ptr<const scene::PrimitiveRecord> borrowed(std::shared_ptr<void>(), &rec);
        try {
            auto made = geometry::makePrimitives(borrowed, diag, procedurals, parameterReaders);
            if (prims.empty()) {
                prims = std::move(made);  // a run of 10^6 polygons: not a second array
                continue;
            }
            for (auto& p : made) prims.push_back(std::move(p));
        } catch (const OutOfMemory&) {
            throw;
        } catch (const std::bad_alloc&) {
            // Its topology and primitive variables are about twice its values.
            uint64_t values = rec.floatArgs.size() + rec.intArgs.size();
            for (const auto& a : rec.intArrays) values += a.size();
            for (const ri::Param& p : rec.params.params()) values += p.floats.size() + p.ints.size();
            throw OutOfMemory(rec.loc, fmt::format("the {} primitive's records ({} values)", rec.type, values),
                              2 * 4 * values);
        }
    }

    prepareAttributes(prims, frame);
    frame.primitives = &prims;
    for (const auto& p : prims)
        frame.castersMove |= frame.motionBlur() && p->attributes().castsShadows && p->record().moving();

    // First pass: a depth map for every light whose shadowname is "auto".
    // The maps are planned in the lights' order, then rendered side by side:
    // a thread a short pass leaves idle (waiting on a primitive the other
    // thread splits, or while a map is built) takes another light's buckets.
    // Destroying `mapWrites` joins writers still running (when unwinding).
    std::vector<MapWrite> mapWrites;
    nlohmann::json passes = nlohmann::json::array();
    auto automatic = [&](const scene::LightRecord& light) {
        const ri::Param* shadowName = light.shader.params.find("shadowname");
        return shadowName && !shadowName->strings.empty() && shadowName->strings[0] == "auto";
    };
    std::vector<std::optional<LightMapJob>> jobs(world.lights.size());
    std::vector<LightMap> made(world.lights.size());
    // A planned map whose content matches the map this light had in an
    // earlier frame is that map: not rendered again, its file read as is.
    std::vector<MapContent> contents(world.lights.size());
    std::vector<std::string> reuseReasons(world.lights.size());
    std::vector<bool> reused(world.lights.size(), false);
    // --map-cache: where each map's content would be in the shared cache
    // (empty: no cache, or a map of this frame's seed alone).
    std::vector<std::string> cachePaths(world.lights.size());
    bool reuseOn = settings.reuseMaps;
    if (auto it = options.user.find("umbra:reusemaps"); it != options.user.end())
        reuseOn = reuseOn && (!it->second.ints.empty() ? it->second.ints[0] != 0 : it->second.floatAt(0, 1) != 0);
    auto handleOf = [](const scene::LightRecord& light) { return light.handle.empty() ? std::string("light") : light.handle; };
    Stopwatch firstPassClock;
    if (!settings.noShadows) {
        for (size_t i = 0; i < world.lights.size(); ++i) {
            if (!automatic(world.lights[i])) continue;
            jobs[i] = planLightMap(frame, world.lights[i], prims);
            if (!jobs[i]) continue;
            contents[i] = mapContentOf(frame, world.lights[i], *jobs[i]);
            if (!settings.mapCache.empty())
                if (std::optional<Digest> key = cacheDigest(contents[i]))
                    cachePaths[i] = (std::filesystem::path(settings.mapCache) / (key->hex() + ".shd")).string();
            auto before = reusableMaps.find(handleOf(world.lights[i]));
            if (before != reusableMaps.end() && !(before->second.written.valid() && before->second.written.get()))
                reuseReasons[i] = "earlier map not written";
            else
                reuseReasons[i] =
                    reuseReason(before != reusableMaps.end() ? &before->second.content : nullptr, contents[i]);
            if (reuseReasons[i] == kSameContent && !reuseOn) reuseReasons[i] = "reuse off";
            if (reuseReasons[i] == kSameContent) {
                reused[i] = true;
                made[i].path = before->second.path;
            } else if (reuseOn && !cachePaths[i].empty() && std::filesystem::exists(cachePaths[i])) {
                // Another process (or an earlier run) made this map: files
                // enter the cache complete, by rename.
                reused[i] = true;
                reuseReasons[i] = "map cache";
                made[i].path = cachePaths[i];
            }
        }
        runInArena(*arena, [&] {
            TaskGroup group;
            for (size_t i = 0; i < jobs.size(); ++i)
                if (jobs[i] && !reused[i]) group.run([&, i] { made[i] = makeLightMap(frame, *jobs[i], prims); });
            group.wait();
        });
    }
    nlohmann::json mapRecords = nlohmann::json::array();
    for (size_t i = 0; i < jobs.size(); ++i) {
        if (!jobs[i]) continue;
        const std::string handle = handleOf(world.lights[i]);
        if (!reused[i]) {
            if (made[i].map && !made[i].failed)
                reusableMaps[handle] = {contents[i], made[i].path, made[i].written};
            else
                reusableMaps.erase(handle);
        } else if (reuseReasons[i] == "map cache") {
            std::promise<bool> present;
            present.set_value(true);
            reusableMaps[handle] = {contents[i], made[i].path, present.get_future().share()};
        }
        mapRecords.push_back({{"light", handle},
                              {"path", made[i].path},
                              {"reused", bool(reused[i])},
                              {"reason", reuseReasons[i]}});
    }
    const double firstPassWall = firstPassClock.wall(), firstPassCpu = firstPassClock.cpu();
    std::vector<std::shared_ptr<const shading::ShaderInstance>> lights(world.lights.size());
    for (size_t i = 0; i < world.lights.size(); ++i) {
        const scene::LightRecord& light = world.lights[i];
        if (!automatic(light)) {
            lights[i] = shading->instantiate(light.shader, shading::ShaderKind::Light);
            continue;
        }
        LightMap& m = made[i];
        for (auto& p : m.passes) passes.push_back(std::move(p));
        if (m.failed) ++failed;
        if (m.map) maps->put(m.path, std::move(m.map));
        if (m.write) {
            mapWrites.push_back(std::move(*m.write));
            ++backgroundMapWrites;
        }
        mapWriteSeconds += m.buildSeconds;
        scene::ShaderRecord withMap = light.shader;
        ri::ParamList params;
        for (const ri::Param& p : light.shader.params.params()) {
            ri::Param q = p;
            if (q.decl.name == "shadowname") q.strings = {m.path};
            params.add(std::move(q));
        }
        withMap.params = std::move(params);
        lights[i] = shading->instantiate(withMap, shading::ShaderKind::Light);
    }
    attachLights(lights, frame);
    frame.lights = &lights;

    // Second pass: the camera. A frame whose displays are all depth ("z")
    // is a depth pass itself (RenderMan's two-RIB shadow workflow).
    Pass pass;
    pass.name = "camera";
    pass.camera = hider::Camera::fromOptions(options);
    if (frame.motionBlur() && options.cameraMotion && options.cameraMotion->moving()) {
        pass.cameraMotion = options.cameraMotion;
        pass.camera.cameraFromWorld = options.cameraMotion->at(frame.shutterOpen);
    }
    if (std::isfinite(options.fstop) && options.fstop > 0 && options.focalDistance > 0) {
        if (pass.camera.perspective) {
            pass.lensRadius = options.focalLength / (2.0f * options.fstop);
            pass.focalDistance = options.focalDistance;
        } else {
            diag.warningOnce("dof:orthographic", options.loc,
                             "DepthOfField: an orthographic camera has no lens; the image is sharp");
        }
    }
    const std::vector<scene::DisplayRecord> displays = withDisplayChannels(options);
    bool depthFrame = !displays.empty();
    for (const auto& d : displays) depthFrame = depthFrame && d.mode == "z";
    pass.depthOnly = depthFrame;
    if (depthFrame && frame.motionBlur() && (frame.castersMove || pass.cameraMotion)) pass.timeTile = hider::kTimeTile;
    if (depthFrame) {
        pass.cull = depthCullOf(options, options.loc);
        pass.openSurfacesAreOwnSecondLayer = depthFilterOf(options, options.loc) == DepthFilter::Second;
    }
    std::vector<film::AovChannel> aovs = depthFrame ? std::vector<film::AovChannel>{} : film::aovChannelsFor(displays);
    for (const auto& a : aovs) {
        frame.aovNames.push_back(a.name);
        frame.aovComponents.push_back(a.components);
    }
    // A colour frame keeps each pixel's depth only when a display reads it
    // (a mode with z, a zfile or shadow driver): 4 bytes a pixel otherwise
    // unused (8 MB at 1920 x 1080). A mode that does not parse keeps it
    // too; Film::write reports that mode.
    const bool depthRead = std::any_of(displays.begin(), displays.end(), film::displayReadsDepth);
    // A colour frame keeps one depth a sample: "midpoint", "second" and
    // "dual" need the second surface, which only a frame of depth displays
    // (mode "z") finds. Its depth outputs hold the nearest depth, all alike
    // (a zfile among them gave the nearest plus the dual offset).
    const DepthFilter frameDepthFilter = depthFilterOf(options, options.loc);
    const bool twoLayerFilter = frameDepthFilter == DepthFilter::Midpoint || frameDepthFilter == DepthFilter::Second ||
                                frameDepthFilter == DepthFilter::Dual;
    if (depthRead && !depthFrame && twoLayerFilter)
        diag.warningOnce("colour-frame-depthfilter", options.loc,
                         "Hider \"depthfilter\" \"{}\" needs a frame whose displays are all depth (mode \"z\"); "
                         "this frame also writes colour, so its depth outputs hold the nearest depth",
                         depthFilterName(frameDepthFilter));
    const film::FilmContent content = depthFrame ? depthFilmOf(options, depthFilterOf(options, options.loc))
                                      : depthRead ? film::FilmContent::Colour
                                                  : film::FilmContent::ColourOnly;
    // A frame whose one display is a depth map (Display "zfile" or "shadow",
    // as a light's frame is written) hands its film's depth plane to the
    // map's image, as an automatic map's pass does: its depths start unset,
    // the pages no caster reaches are never touched, and the image is not a
    // copy (a 2048^2 copy, filled with +infinity first, was 50 ms of a
    // 0.35 s frame, most of it page faults).
    const bool filmBecomesMap = depthFrame && displays.size() == 1 && film::writesDepthMap(displays[0]);
    film::Film film = film::Film::fromOptions(options, aovs, content, diag, displays,
                                              filmBecomesMap ? film::Film::DepthStart::Unset
                                                             : film::Film::DepthStart::Infinity);
    auto outputMetadata = [&] {
        film::OutputMetadata meta;
        if (std::optional<std::string> date = sourceDateTime(diag)) {
            meta.dateTime = *date;  // and no render time: reproducible files
        } else {
            meta.renderSeconds = frameClock.wall();
            meta.dateTime = nowDateTime();
        }
        meta.cameraFromWorld = pass.camera.cameraFromWorld;
        meta.ndcFromWorld = pass.camera.ndcFromScreen() * pass.camera.screenFromCamera() * pass.camera.cameraFromWorld;
        return meta;
    };
    // The film is written as its rows complete, and the rows freed, when
    // every display is a TIFF and nothing reads the whole film afterwards
    // (an imager, a depth map, an EXR or PNG): the same files, without
    // holding the frame (docs/pipeline.md, "Output while rendering").
    const bool imaged = options.imager && !depthFrame;
    bool streamOpened = true;
    if (settings.filmStream && !imaged && film::Film::streamable(displays))
        streamOpened = film.openStream(displays, options, outputMetadata(), diag);
    PassResult camera;
    runInArena(*arena, [&] { camera = runPass(frame, pass, prims, film, world.frameNumber >= 0 ? frameName(world) : std::string("image")); });
    if (imaged) runInArena(*arena, [&] { runImager(frame, pass, *options.imager, film); });
    passes.push_back({{"name", pass.name},
                      {"wall_seconds", camera.wall},
                      {"cpu_seconds", camera.cpu},
                      {"worker_cpu_seconds", camera.counters.workerCpuSeconds},
                      {"counts", schedulerJson(camera.counters)},
                      {"samples", camera.samples},
                      {"bucket_size", {camera.bucketSize[0], camera.bucketSize[1]}}});

    film::DepthWriter depthWriter = [&](const scene::DisplayRecord& d, const film::Film& f) {
        const DepthFilter filter = !depthFrame && twoLayerFilter ? DepthFilter::Min : depthFilterOf(options, d.loc);
        // The film is not read after its only display.
        DepthImage image = filmBecomesMap ? depthImageOf(std::move(film), pass, filter, dualOffsetOf(options))
                                          : depthImageOf(f, pass, filter, dualOffsetOf(options));
        image.texelTimes = camera.texelTimes;
        bool ok = d.driver == "zfile" ? writeZFile(d.name, image, diag, d.loc) : writeDepthMap(d.name, image, diag, d.loc);
        maps->invalidate(d.name);
        std::erase_if(reusableMaps, [&](const auto& entry) { return entry.second.path == d.name; });
        return ok;
    };
    // Output converts rows in parallel: on no more threads than --threads.
    // An interrupted frame is not written: its film is incomplete.
    bool wrote = false;
    if (interrupted()) {
        film.abandonStream();
        diag.error(options.loc, "{}: interrupted by signal {}; its images were not written", frameName(world),
                   interruptSignal());
    } else if (film.streaming()) {
        wrote = film.finishStream(diag) && streamOpened;
    } else {
        runInArena(*arena, [&] { wrote = film.write(displays, options, outputMetadata(), diag, depthWriter); });
    }
    // The frame is done when its maps' files are; a failed write (reported
    // by the writer, naming the file) fails the frame.
    Stopwatch waitClock;
    for (MapWrite& w : mapWrites) {
        w.thread.get();
        if (!w.written.get()) ++failed;
    }
    mapWrites.clear();
    mapWriteWaitSeconds = waitClock.wall();
    // --map-cache: each map rendered here, its file complete, enters the
    // cache under a temporary name and is renamed, so another process
    // never reads a partial map (two making the same one write the same
    // bytes; the last rename wins).
    for (size_t i = 0; i < jobs.size(); ++i)
        if (jobs[i] && !reused[i] && !cachePaths[i].empty() && !made[i].failed && made[i].written.valid() &&
            made[i].written.get())
            addToMapCache(made[i].path, cachePaths[i]);

    double wall = frameClock.wall(), cpu = frameClock.cpu();
    ShadowStats shadowStats = services->shadowStats();
    double shadingSeconds = double(frame.shadingNanoseconds.load()) * 1e-9;
    uint64_t micropolygons = 0;
    for (const auto& p : passes) micropolygons += p["counts"]["micropolygons"].get<uint64_t>();
    nlohmann::json f = {
        {"frame", world.frameNumber},
        {"resolution", {options.xResolution, options.yResolution}},
        {"wall_seconds", wall},
        {"cpu_seconds", cpu},
        {"threads", threadCount()},
        {"first_pass", {{"wall_seconds", firstPassWall}, {"cpu_seconds", firstPassCpu}}},
        {"peak_memory_mib", peakResidentMiB()},
        {"film_streamed", film.streaming()},
        {"film_rows_held_peak", film.rowsHeldPeak()},
        {"passes", passes},
        {"maps", mapRecords},
        {"micropolygons_per_second", camera.wall > 0 ? double(camera.counters.micropolygons) / camera.wall : 0.0},
        {"shading", {{"seconds", shadingSeconds}, {"share_of_cpu", cpu > 0 ? shadingSeconds / cpu : 0.0}}},
        {"shadow",
         {{"points", shadowStats.points},
          {"outside", shadowStats.outside},
          {"culled_lit", shadowStats.culledLit},
          {"culled_shadowed", shadowStats.culledShadowed},
          {"texel_range_lit", shadowStats.texelRangeLit},
          {"texel_range_shadowed", shadowStats.texelRangeShadowed},
          {"filtered", shadowStats.filtered},
          {"samples", shadowStats.samples},
          {"tile_fetches", shadowStats.tileFetches},
          {"second_depth_lit", shadowStats.secondLit},
          {"second_depth_shadowed", shadowStats.secondShadowed},
          {"virtual_sample_points", shadowStats.virtualPoints},
          {"stored_plane_lit", shadowStats.storedPlaneLit},
          {"stored_plane_grid_points", shadowStats.storedPlaneGridPoints},
          {"lookup_seconds", services->lookupSeconds()},
          {"map_write_seconds", mapWriteSeconds},
          {"map_write_wait_seconds", mapWriteWaitSeconds},
          {"map_file_cpu_seconds", double(mapFileCpuNanoseconds.load()) * 1e-9},
          {"background_map_writes", backgroundMapWrites},
          {"tile_cache", tileCacheJson(tileCache->stats())}}},
        {"motion_blur",
         {{"shutter", {frame.shutterOpen, frame.shutterClose}},
          {"depth_of_field", pass.lensRadius > 0},
          {"blurred_grids", frame.blurredGrids.load()},
          {"still_bound_pixels", frame.stillBoundPixels.load()},
          {"blurred_bound_pixels", frame.blurredBoundPixels.load()},
          {"bound_growth", frame.stillBoundPixels.load() > 0
                               ? double(frame.blurredBoundPixels.load()) / double(frame.stillBoundPixels.load())
                               : 1.0}}},
        {"procedurals",
         {{"expanded", procedurals->expanded.load()},
          {"archives_read", procedurals->archivesRead.load()},
          {"program_requests", procedurals->programRequests.load()},
          {"dso_calls", procedurals->dsoCalls.load()},
          {"failed", procedurals->failures.load()},
          {"primitives_made", procedurals->primitivesMade.load()}}},
        {"errors", diag.errorCount() - errorsBefore},
    };
    addFrame(f);
    if (options.statisticsEndOfFrame && !settings.quiet) {
        fmt::print(stderr,
                   "umbra: statistics of {}\n"
                   "  time        {:.3f} s wall ({:.3f} s depth maps, {:.3f} s camera), {:.3f} s cpu, {} threads\n"
                   "  shading     {:.3f} s in shaders ({:.0f}% of cpu)\n"
                   "  geometry    {} primitives, {} splits, {} grids, {} micropolygons ({:.2f} M/s)\n"
                   "  hiding      {} buckets, {} culled, {} occlusion-culled, {} peak grids\n"
                   "  shadows     {} lookups ({} culled lit, {} culled shadowed, {} filtered)\n"
                   "  memory      {:.1f} MiB peak\n",
                   frameName(world), wall, firstPassWall, camera.wall, cpu, f["threads"].get<int>(), shadingSeconds,
                   cpu > 0 ? 100 * shadingSeconds / cpu : 0.0, camera.counters.primitives, camera.counters.splits,
                   camera.counters.grids, micropolygons,
                   camera.wall > 0 ? double(camera.counters.micropolygons) / camera.wall * 1e-6 : 0.0,
                   camera.counters.buckets, camera.counters.culled, camera.counters.occlusionCulled,
                   camera.counters.peakGridsAlive, shadowStats.points, shadowStats.culledLit,
                   shadowStats.culledShadowed, shadowStats.filtered, peakResidentMiB());
        if (options.statisticsEndOfFrame >= 2) printDetailedStatistics(f);
        if (options.statisticsEndOfFrame >= 3) fmt::print(stderr, "  record      {}\n", f.dump(2));
    }
    services->setFrame(nullptr);
    if (!wrote || diag.aborted()) ++failed;
}

std::optional<LightMapJob> Renderer::Impl::planLightMap(FrameState& frame, const scene::LightRecord& light,
                                                       const std::vector<geometry::PrimitivePtr>& prims) {
    const scene::Options& options = frame.world->options;
    std::string handle = light.handle.empty() ? "light" : light.handle;
    auto shader = shading->find(light.shader.name, light.shader.loc);
    LightGeometry geometry = lightGeometry(light, shader.get());
    LightMapJob job;
    job.loc = light.shader.loc;
    // The map's resolution: the light's own Attribute "umbra" "shadowmapsize",
    // else the frame's Option, else the image's larger side (Reeves' advice).
    // The builder has checked the values' range.
    job.size = std::max(options.xResolution, options.yResolution);
    for (const auto* settings : {&options.user, light.attributes ? &light.attributes->user : nullptr})
        if (settings)
            if (auto it = settings->find("umbra:shadowmapsize"); it != settings->end())
                job.size = !it->second.ints.empty() ? it->second.ints[0] : int(it->second.floatAt(0, float(job.size)));
    const DepthFilter filter = depthFilterOf(options, light.shader.loc);
    const Pass::Cull cull = depthCullOf(options, light.shader.loc);
    job.filter = filter;
    job.dualOffset = dualOffsetOf(options);
    // Nearest-depth maps are compared with a bias anyway: dice them at 4
    // pixels a micropolygon. The two-layer filters store the far sides of
    // curved solids, where coarser chords leak light (measured in
    // docs/shadow-quality.md), so they keep the surfaces' own rate.
    float depthRate = (filter == DepthFilter::Min || filter == DepthFilter::Max || filter == DepthFilter::Average) ? 4 : 0;
    if (auto it = options.user.find("umbra:depthshadingrate"); it != options.user.end() && !it->second.floats.empty())
        depthRate = it->second.floats[0];
    if (geometry.shape == LightShape::Point) {
        std::array<Pass, 6> faces = cubeFacePasses(geometry, job.size, "depth:" + handle);
        job.passes.assign(faces.begin(), faces.end());
        job.cube = true;
    } else {
        auto pass = lightPass(geometry, prims, job.size, "depth:" + handle, diag, job.loc);
        if (!pass) return std::nullopt;
        job.passes.push_back(std::move(*pass));
    }
    for (Pass& pass : job.passes) {
        pass.cull = cull;
        pass.openSurfacesAreOwnSecondLayer = filter == DepthFilter::Second;
        pass.minShadingRate = depthRate;
        pass.flatness = depthRate > 0 ? kDepthFlatness : 0;
        pass.timeTile = frame.motionBlur() && frame.castersMove ? hider::kTimeTile : 0;
    }
    // The map is written beside the first image, named after it and the
    // light: out.0012.tif's is out.0012.<light>.shd. A first image whose name
    // does not change from frame to frame gets the frame's number too
    // (still.tif in frame 12: still.0012.<light>.shd), so frames do not
    // overwrite each other's maps.
    const bool numbered = !options.displays.empty() && !options.displays[0].pattern.empty();
    std::filesystem::path base(options.displays.empty() ? std::string("umbra") : options.displays[0].name);
    std::string frameTag =
        frame.world->frameNumber >= 0 && !numbered ? fmt::format(".{:04d}", frame.world->frameNumber) : "";
    job.path = (base.parent_path() / fmt::format("{}{}.{}.shd", base.stem().string(), frameTag, handle)).string();
    return job;
}

LightMap Renderer::Impl::makeLightMap(FrameState& frame, LightMapJob& job,
                                      const std::vector<geometry::PrimitivePtr>& prims) {
    const scene::Options& options = frame.world->options;
    const DepthFilter filter = job.filter;
    LightMap made;
    // One depth pass: rendered, recorded in the statistics, reduced to a map image.
    auto render = [&](Pass& pass) {
        float crop[4] = {0, 1, 0, 1};
        const film::FilmContent content = depthFilmOf(options, filter);
        film::Film film = allocating(
            job.loc, film::Film::bytesFor(job.size, job.size, crop, {}, content),
            fmt::format("the {0}x{0} film of the light's depth pass \"{1}\"", job.size, pass.name),
            [&] {
                // Depths start unset: the pages of texels no caster reaches
                // are never touched (depthImageOf settles the rest).
                return film::Film(job.size, job.size, crop, *film::PixelFilter::create("box", 1, 1), {}, content,
                                  film::Film::DepthStart::Unset);
            });
        PassResult r = runPass(frame, pass, prims, film, fmt::format("depth map {}", pass.name));
        made.passes.push_back({{"name", pass.name},
                               {"wall_seconds", r.wall},
                               {"cpu_seconds", r.cpu},
                               {"worker_cpu_seconds", r.counters.workerCpuSeconds},
                               {"counts", schedulerJson(r.counters)},
                               {"samples", r.samples},
                               {"bucket_size", {r.bucketSize[0], r.bucketSize[1]}}});
        DepthImage image = depthImageOf(std::move(film), pass, filter, job.dualOffset);
        image.texelTimes = std::move(r.texelTimes);
        return image;
    };

    // The map goes to this frame's lookups from memory: its header from the
    // image, its tiles handed to the cache. Its file, for later frames and
    // tools, is then written on a thread of its own, overlapping the next
    // passes, when every tile is cached; otherwise now, so the tiles that
    // did not fit are read from a complete file.
    const std::string path = job.path;
    const FileLoc loc = job.loc;
    std::packaged_task<bool()> write;
    std::shared_future<bool> written;
    bool everyTileCached = false;
    Stopwatch buildClock;  // restarted once the depth passes are done
    if (job.cube) {
        auto cube = std::make_shared<std::array<DepthImage, 6>>();
        for (size_t f = 0; f < 6; ++f) (*cube)[f] = render(job.passes[f]);
        buildClock = Stopwatch();
        write = std::packaged_task<bool()>([&d = diag, path, loc, cube, this] {
            return timedMapWrite([&] { return writeCubeDepthMap(path, *cube, d, loc); });
        });
        written = write.get_future().share();
        made.map = ShadowMap::fromCubeImages(*cube, path, written, diag, loc, tileCache, &everyTileCached);
    } else {
        auto image = std::make_shared<DepthImage>(render(job.passes[0]));
        buildClock = Stopwatch();
        write = std::packaged_task<bool()>([&d = diag, path, loc, image, this] {
            return timedMapWrite([&] { return writeDepthMap(path, *image, d, loc); });
        });
        written = write.get_future().share();
        made.map = ShadowMap::fromImage(*image, path, written, diag, loc, tileCache, &everyTileCached);
    }
    if (!made.map || interrupted()) {
        // An interrupted pass made an incomplete map: no file is written.
        made.failed = true;
        made.map.reset();
        return made;
    }
    // In the background only when the frame may use more than one thread:
    // --threads 1 means one core, writer included.
    if (everyTileCached && threadCount() > 1) {
        made.write = MapWrite{written, std::async(std::launch::async, std::move(write))};
    } else {
        write();
        if (!written.get()) {
            made.failed = true;
            made.map.reset();
            return made;
        }
    }
    made.path = path;
    made.written = written;
    made.buildSeconds = buildClock.wall();
    return made;
}

void Renderer::Impl::addToMapCache(const std::string& from, const std::string& to) {
    namespace fs = std::filesystem;
    static std::atomic<unsigned> serial{0};
    const std::string tmp = fmt::format("{}.tmp.{}.{}", to, ::getpid(), serial++);
    std::error_code ec;
    fs::copy_file(from, tmp, fs::copy_options::overwrite_existing, ec);
    if (!ec) fs::rename(tmp, to, ec);
    if (ec) {
        fs::remove(tmp);
        diag.warning(FileLoc::inFile(to), "--map-cache: cannot add \"{}\" to the cache: {}", from, ec.message());
    }
}

MapContent Renderer::Impl::mapContentOf(const FrameState& frame, const scene::LightRecord& light,
                                        const LightMapJob& job) {
    const scene::Options& options = frame.world->options;
    MapContent content;
    content.size = job.size;
    Hasher settingsHash, viewHash;
    settingsHash.i32(int(job.filter)).f32(job.dualOffset).flag(job.cube);
    settingsHash.i32(settings.bucketSize).i32(options.bucketSize[0]).i32(options.bucketSize[1]);
    settingsHash.i32(options.gridSize).i32(options.eyeSplits).i32(depthLayersOf(options, job.filter));
    settingsHash.f32(frame.shutterOpen).f32(frame.shutterClose).flag(frame.castersMove);
    settingsHash.f32(options.shutterOpening[0]).f32(options.shutterOpening[1]);
    // Options of umbra's own and the user's may steer depth passes; those
    // that cannot change a texel are left out so changing them keeps maps.
    for (const auto& [name, p] : options.user)
        if (name != "umbra:shadowmapsize" && name != "umbra:tilecachemb" && name != "umbra:reusemaps")
            settingsHash.str(name).floats(p.floats).ints(p.ints).strings(p.strings);
    viewHash.str(light.shader.name);
    for (const Pass& pass : job.passes) {
        settingsHash.i32(int(pass.cull)).f32(pass.minShadingRate).f32(pass.flatness).flag(pass.discOnly);
        settingsHash.flag(pass.openSurfacesAreOwnSecondLayer).i32(pass.timeTile);
        const hider::Camera& c = pass.camera;
        viewHash.flag(c.perspective).f32(c.tanHalfFov).bytes(c.screenWindow, sizeof c.screenWindow);
        viewHash.bytes(c.screenLinear, sizeof c.screenLinear).bytes(c.screenOffset, sizeof c.screenOffset);
        viewHash.i32(c.xResolution).i32(c.yResolution).f32(c.nearClip).f32(c.farClip).matrix(c.cameraFromWorld);
    }
    content.settings = settingsHash.value();
    content.view = viewHash.value();
    // A displacement shader may place points in named coordinate systems:
    // a displaced caster's shape follows them. The standard spaces are the
    // depth pass's own (Services::getMatrix), whatever the camera does.
    Hasher coordinateSystems;
    for (const auto& [name, m] : frame.world->coordinateSystems)
        if (name != "world" && name != "camera") coordinateSystems.str(name).matrix(m);
    // The frame's seed reaches a depth pass through sample times, and
    // displacement shaders may read other per-frame state (Shader::variesByFrame): such maps are this frame's alone.
    bool seeded = frame.motionBlur();
    for (const auto& rec : frame.world->primitives) {
        if (!rec.attributes || !rec.attributes->castsShadows) continue;
        Digest caster = casterDigest(rec);
        if (auto it = frame.attributes.find(rec.attributes.get()); it != frame.attributes.end() && it->second.displacement) {
            seeded |= it->second.displacement->shader().variesByFrame();
            caster = Hasher().digest(caster).digest(coordinateSystems.value()).value();
        }
        content.casters.push_back(caster);
    }
    if (seeded) content.seed = frame.frameSeed;
    return content;
}

int Renderer::Impl::depthLayersOf(const scene::Options& options, DepthFilter filter) {
    if (auto it = options.user.find("umbra:depthlayers"); it != options.user.end() && !it->second.ints.empty())
        return std::clamp(it->second.ints[0], 1, 2);
    const bool oneLayer = filter == DepthFilter::Min || filter == DepthFilter::Max || filter == DepthFilter::Average;
    return oneLayer ? 1 : 2;
}

DepthFilter Renderer::Impl::depthFilterOf(const scene::Options& options, const FileLoc& loc) {
    DepthFilter f = DepthFilter::Min;
    std::string name = options.depthFilter;
    if (auto it = options.user.find("umbra:depthfilter"); it != options.user.end() && !it->second.strings.empty())
        name = it->second.strings[0];
    if (!parseDepthFilter(name, &f))
        diag.warningOnce("depthfilter " + name, loc,
                         "Hider: unknown \"depthfilter\" \"{}\" (expected min, max, average, midpoint, second or "
                         "dual); using min",
                         name);
    return f;
}

Pass::Cull Renderer::Impl::depthCullOf(const scene::Options& options, const FileLoc& loc) {
    auto it = options.user.find("umbra:depthcull");
    if (it == options.user.end() || it->second.strings.empty()) {
        // By default each filter culls as its paper does: a second-depth map
        // needs the far side of a solid (Wang & Molnar store it, culling
        // nothing), the others store the lit side (Weiskopf & Ertl cull
        // back faces). Only Sides 1 surfaces are ever culled.
        return depthFilterOf(options, loc) == DepthFilter::Second ? Pass::Cull::None : Pass::Cull::Back;
    }
    const std::string& v = it->second.strings[0];
    if (v == "none") return Pass::Cull::None;
    if (v == "front" || v == "lightfacing") return Pass::Cull::Front;
    if (v == "back") return Pass::Cull::Back;
    diag.warningOnce("depthcull " + v, loc,
                     "Option \"umbra\" \"depthcull\": unknown value \"{}\" (expected \"none\", \"front\" or "
                     "\"back\"); using back",
                     v);
    return Pass::Cull::Back;
}

float Renderer::Impl::dualOffsetOf(const scene::Options& options) {
    if (auto it = options.user.find("umbra:dualoffset"); it != options.user.end() && !it->second.floats.empty())
        return it->second.floats[0];
    if (const ri::Param* p = options.hiderParams.find("offset"); p && !p->floats.empty()) return p->floats[0];
    return 0.05f;
}

int renderFiles(const std::vector<std::string>& files, const RenderSettings& settingsIn, const std::string& statsPath,
                Diagnostics& diag) {
    const RenderSettings& settings = settingsIn;
    if (!settings.mapCache.empty()) {
        // The cache is made if missing; one that cannot be written is an
        // error before any frame (a farm task would otherwise render every
        // map it was meant to share).
        std::error_code ec;
        std::filesystem::create_directories(settings.mapCache, ec);
        if (ec || ::access(settings.mapCache.c_str(), W_OK | X_OK) != 0) {
            diag.error(FileLoc::inFile(settings.mapCache), "--map-cache: cannot use \"{}\" as the map cache: {}",
                       settings.mapCache, ec ? ec.message() : std::string(std::strerror(errno)));
            return 1;
        }
    }
    Renderer renderer(settings, diag);
    bool ok = true;
    // --stats FILE.jsonl: one line per frame, appended as the frame ends by
    // a single write to a file opened for appending, so a line is never cut
    // or interleaved, even with other umbra processes (a farm's tasks)
    // appending to the same file.
    const bool statsLines = statsPath.size() > 6 && statsPath.compare(statsPath.size() - 6, 6, ".jsonl") == 0;
    int statsFd = -1;
    if (statsLines) {
        std::string target, why;
        if (!resolveOutputPath(statsPath, &target, &why)) {
            diag.error(FileLoc::inFile(statsPath), "--stats: cannot write the statistics file: {}", why);
            return 1;
        }
        statsFd = ::open(target.c_str(), O_WRONLY | O_APPEND | O_CREAT | O_CLOEXEC, 0644);
        if (statsFd < 0) {
            diag.error(FileLoc::inFile(statsPath), "--stats: cannot open the statistics file: {}", std::strerror(errno));
            return 1;
        }
        renderer.onFrameStatistics([&](const nlohmann::json& frame) {
            nlohmann::json line = {{"schema", kStatisticsSchema}, {"umbra_version", kUmbraVersion}};
            line.update(frame);
            const std::string text = line.dump() + "\n";
            if (::write(statsFd, text.data(), text.size()) != ssize_t(text.size())) {
                diag.error(FileLoc::inFile(statsPath), "--stats: cannot append frame {} to the statistics file: {}",
                           frame.value("frame", -1), std::strerror(errno));
                ok = false;
            }
        });
    }
    // Reads one RIB file; `frame` >= 0 when it is that frame's own file.
    auto read = [&](const std::string& file, int frame) {
        scene::Builder builder(renderer, diag);
        renderer.prepare(builder, file);
        if (frame >= 0) builder.setDefaultFrame(frame);
        renderer.setFileFrame(frame);
        if (!ri::parseFile(file, builder, diag)) ok = false;
        renderer.setFileFrame(-1);
    };
    for (const auto& file : files) {
        if (file != "-" && hasFramePattern(file) && !std::filesystem::exists(file)) {
            // shot.####.rib: one file per selected frame.
            if (!settings.frames) {
                diag.error(FileLoc::inFile(file),
                           "\"{}\" names one RIB file per frame: give the frames with --frames (e.g. --frames 1-100)",
                           file);
                ok = false;
                continue;
            }
            for (int n : settings.frames->numbers()) {
                const std::string path = expandFramePattern(file, n);
                if (!std::ifstream(path)) {
                    diag.error(FileLoc::inFile(path), "frame {}: cannot open \"{}\" (from \"{}\")", n, path, file);
                    renderer.addFailedFrame(n);
                    ok = false;
                    continue;
                }
                read(path, n);
                if (diag.aborted() || interrupted()) break;
            }
        } else {
            read(file, -1);
        }
        if (diag.aborted()) {
            ok = false;
            break;
        }
    }
    if (settings.frames && renderer.statistics()["frames"].empty() && renderer.failedFrames() == 0)
        diag.warning(FileLoc{}, "--frames: no frame of the input was selected");
    if (const std::vector<int>& failed = renderer.failedFrameNumbers(); !failed.empty()) {
        std::vector<std::string> names;
        for (int f : failed) names.push_back(f >= 0 ? std::to_string(f) : "(outside FrameBegin)");
        fmt::print(stderr, "umbra: {} {} failed: {}\n", failed.size(), failed.size() == 1 ? "frame" : "frames",
                   fmt::join(names, ", "));
    }
    std::string statsTarget, statsWhy;
    if (!statsPath.empty() && !statsLines && !resolveOutputPath(statsPath, &statsTarget, &statsWhy)) {
        diag.error(FileLoc::inFile(statsPath), "--stats: cannot write the statistics file: {}", statsWhy);
        ok = false;
    } else if (!statsPath.empty() && !statsLines) {
        std::string tmp = statsTarget + ".tmp";
        std::ofstream out(tmp);
        out << renderer.statistics().dump(2) << "\n";
        out.close();
        if (!out || !moveIntoPlace(tmp, statsTarget)) {
            diag.error(FileLoc::inFile(statsPath), "--stats: cannot write the statistics file");
            std::remove(tmp.c_str());
            ok = false;
        }
    }
    if (statsFd >= 0 && ::close(statsFd) != 0) {
        diag.error(FileLoc::inFile(statsPath), "--stats: cannot write the statistics file: {}", std::strerror(errno));
        ok = false;
    }
    if (renderer.failedFrames() > 0) ok = false;
    if (diag.errorCount() > 0) ok = false;
    return ok ? 0 : 1;
}

}  // namespace umbra::render
