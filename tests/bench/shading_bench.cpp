// The shading VM against hand-written C++ on a 16 x 16 grid:
//  - `plastic` under three lights (two distant lights and a point light);
//  - `plastic` under three shadowed spotlights (`shadowspot`, 16 samples a
//    lookup), the lights of the production frame (issue 21).
// The target is the VM within 1.5x of the native version. Both versions of
// the shadowed frame look their maps up through the same RendererServices,
// so what differs is what the VM adds around the lookups.

#include "umbra/shading/shading_system.h"
#include "umbra/shadow/shadow_map.h"
#include "umbra/util/rng.h"
#include "support/params.h"

#include <benchmark/benchmark.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <map>

using namespace umbra;
using namespace umbra::shading;

namespace {

constexpr int kSide = 16;
/// Largest difference of Ci between the two versions of a benchmark: float
/// rounding in a different order, not a different computation.
constexpr float kSameImage = 1e-4f;

struct BenchServices : RendererServices {
    bool getMatrix(const ShadingGrid&, const std::string&, Mat4* m) override {
        *m = Mat4::identity();
        return true;
    }
};

ShadingGrid makeGrid() {
    ShadingGrid g;
    g.resize(kSide, kSide);
    g.du = g.dv = 1.0f / float(kSide - 1);
    for (int j = 0; j < kSide; ++j)
        for (int i = 0; i < kSide; ++i) {
            size_t k = size_t(j * kSide + i);
            float u = float(i) * g.du, v = float(j) * g.dv;
            float a = (u - 0.5f) * 1.5f, b = (v - 0.5f) * 1.5f;
            g.P[k] = Vec3(std::sin(a), std::sin(b), 3 + std::cos(a) * std::cos(b));
            g.N[k] = g.Ng[k] = normalize(Vec3(std::sin(a), std::sin(b), -std::cos(a) * std::cos(b)));
            g.I[k] = g.P[k];
            g.u[k] = g.s[k] = u;
            g.v[k] = g.t[k] = v;
            g.Cs[k] = Vec3(0.8f, 0.5f, 0.3f);
            g.Os[k] = Vec3(1, 1, 1);
        }
    return g;
}

using umbra::testsupport::floatParam;

/// plastic's ambient + diffuse + specular at every point of the grid, over
/// three lights' L (from the light) and Cl; `lit[l]`, when given, says
/// where light l reached (else everywhere). Both native versions end so.
void nativePlastic(ShadingGrid& g, const std::vector<Vec3> (&L)[3], const std::vector<Vec3> (&Cl)[3],
                   const std::vector<uint8_t>* lit = nullptr) {
    const float Ks = 0.5f, Kd = 0.5f, Ka = 1, roughness = 0.1f;
    const Vec3 specularcolor(1, 1, 1), ambient(0.f);
    for (int i = 0; i < g.size(); ++i) {
        Vec3 Nn = normalize(g.N[size_t(i)]);
        Vec3 Nf = dot(g.I[size_t(i)], g.Ng[size_t(i)]) < 0 ? Nn : -Nn;
        Vec3 V = -normalize(g.I[size_t(i)]);
        Vec3 diff(0.f), spec(0.f);
        for (int l = 0; l < 3; ++l) {
            if (lit && !lit[l][size_t(i)]) continue;
            Vec3 Ln = normalize(-L[l][size_t(i)]);
            float c = dot(Ln, Nf);
            if (c <= 0) continue;
            diff += Cl[l][size_t(i)] * c;
            Vec3 H = normalize(Ln + V);
            spec += Cl[l][size_t(i)] * std::pow(std::max(0.f, dot(Nf, H)), 8 / roughness);
        }
        g.Oi[size_t(i)] = g.Os[size_t(i)];
        g.Ci[size_t(i)] = g.Os[size_t(i)] * (g.Cs[size_t(i)] * (ambient * Ka + diff * Kd) + specularcolor * spec * Ks);
    }
}

/// Times `shadeOnce` (which shades `g`) as one grid an iteration.
template <class Shade>
void timeGrids(benchmark::State& state, const ShadingGrid& g, Shade shadeOnce) {
    for (auto _ : state) {
        shadeOnce();
        benchmark::DoNotOptimize(g.Ci.data());
    }
    state.SetItemsProcessed(int64_t(state.iterations()) * g.size());
}

/// Reports the largest difference of Ci between the VM's grid and the
/// native one, and refuses the timing beyond kSameImage. A ratio between
/// two different computations means nothing: when the native plastic fell
/// behind the shaders (specular()'s exponent became 8/roughness), the
/// numbers were still printed, 0.5 apart.
void checkSameImage(benchmark::State& state, const ShadingGrid& vm, const ShadingGrid& native) {
    float m = 0;
    for (int i = 0; i < vm.size(); ++i) {
        Vec3 d = vm.Ci[size_t(i)] - native.Ci[size_t(i)];
        m = std::max(m, std::max(std::fabs(d.x), std::max(std::fabs(d.y), std::fabs(d.z))));
    }
    state.counters["max_diff_vs_native"] = m;
    if (m > kSameImage) state.SkipWithError("the VM and the native version compute different images");
}

struct Scene {
    Diagnostics diag;
    ShadingSystem sys{diag, {std::string(UMBRA_SOURCE_DIR) + "/shaders_dsl"}};
    std::shared_ptr<const ShaderInstance> plastic, key, fill, bulb;
    BenchServices svc;
    Scene() {
        scene::ShaderRecord rec;
        rec.name = "plastic";
        plastic = sys.instantiate(rec, ShaderKind::Surface);
        scene::ShaderRecord k;
        k.name = "distantlight";
        k.params.add(floatParam("to", ri::ParamType::Point, {0.3f, -0.5f, 1}));
        key = sys.instantiate(k, ShaderKind::Light);
        scene::ShaderRecord f;
        f.name = "distantlight";
        f.params.add(floatParam("intensity", ri::ParamType::Float, {0.4f}));
        f.params.add(floatParam("to", ri::ParamType::Point, {-0.6f, 0.2f, 1}));
        fill = sys.instantiate(f, ShaderKind::Light);
        scene::ShaderRecord b;
        b.name = "pointlight";
        b.params.add(floatParam("intensity", ri::ParamType::Float, {6}));
        b.params.add(floatParam("from", ri::ParamType::Point, {1, 2, 0}));
        bulb = sys.instantiate(b, ShaderKind::Light);
    }
};

/// The same computation written directly: each light evaluated over the
/// grid, then plastic's ambient + diffuse + specular per point.
struct NativePlastic {
    struct Light {
        bool distant;
        Vec3 dirOrFrom;
        float intensity;
    };
    const Light lights[3] = {{true, Vec3(0.3f, -0.5f, 1), 1}, {true, Vec3(-0.6f, 0.2f, 1), 0.4f}, {false, Vec3(1, 2, 0), 6}};
    std::vector<Vec3> L[3], Cl[3];

    void shade(ShadingGrid& g) {
        int n = g.size();
        for (int l = 0; l < 3; ++l) {
            L[l].resize(size_t(n));
            Cl[l].resize(size_t(n));
            for (int i = 0; i < n; ++i) {
                if (lights[l].distant) {
                    L[l][size_t(i)] = lights[l].dirOrFrom;
                    Cl[l][size_t(i)] = Vec3(lights[l].intensity);
                } else {
                    Vec3 d = g.P[size_t(i)] - lights[l].dirOrFrom;
                    L[l][size_t(i)] = d;
                    Cl[l][size_t(i)] = Vec3(lights[l].intensity / dot(d, d));
                }
            }
        }
        nativePlastic(g, L, Cl);
    }
};

void BM_PlasticNative(benchmark::State& state) {
    ShadingGrid g = makeGrid();
    NativePlastic native;
    timeGrids(state, g, [&] { native.shade(g); });
}
BENCHMARK(BM_PlasticNative);

void BM_PlasticVM(benchmark::State& state) {
    Scene s;
    ShadingGrid g = makeGrid();
    ShadeRequest req;
    req.surface = s.plastic.get();
    req.lights = {s.key.get(), s.fill.get(), s.bulb.get()};
    timeGrids(state, g, [&] { s.sys.shade(g, req, s.svc); });
    // Both versions compute the same image.
    ShadingGrid ref = makeGrid();
    NativePlastic().shade(ref);
    checkSameImage(state, g, ref);
}

BENCHMARK(BM_PlasticVM);

// --- plastic under three shadowed spotlights ----------------------------

constexpr int kMapRes = 512;

/// Three orthographic depth maps looking along +z over the grid (raster x,
/// y cover camera x, y in [-1, 1]), each with its own boxes of casters at
/// depths inside the grid's range (3.53 to 4), so that every lookup
/// outcome occurs: lit, shadowed, and filtered at a box's edge.
struct ShadowMaps {
    Diagnostics diag;
    std::map<std::string, std::shared_ptr<ShadowMap>> byName;
    std::vector<std::string> paths;
    ShadowMaps() {
        for (int m = 0; m < 3; ++m) {
            DepthImage img(kMapRes, kMapRes);
            img.ndcFromWorld = Mat4::scale(Vec3(0.5f, 0.5f, 1)) * Mat4::translate(Vec3(1, 1, 0));
            img.projection = Projection::Orthographic;
            Rng rng(uint32_t(11 + m));
            for (int k = 0; k < 12; ++k) {
                int x0 = int(rng.uniform() * kMapRes), y0 = int(rng.uniform() * kMapRes);
                int w = 16 + int(rng.uniform() * 100), h = 16 + int(rng.uniform() * 100);
                float z = 3.4f + 0.5f * rng.uniform();
                for (int y = y0; y < std::min(kMapRes, y0 + h); ++y)
                    for (int x = x0; x < std::min(kMapRes, x0 + w); ++x) img.at(x, y) = std::min(img.at(x, y), z);
            }
            std::string name = "spot" + std::to_string(m) + ".shd";
            std::string path = (std::filesystem::temp_directory_path() /
                                ("umbra_shading_bench_" + std::to_string(getpid()) + "_" + name))
                                   .string();
            writeDepthMap(path, img, diag);
            byName[name] = ShadowMap::open(path, diag);
            paths.push_back(path);
        }
    }
    ~ShadowMaps() {
        for (const std::string& p : paths) std::filesystem::remove(p);
    }
};

ShadowMaps& shadowMaps() {
    static ShadowMaps maps;
    return maps;
}

/// Looks maps up as the renderer does: the query's points, footprints and
/// vertex indices handed to ShadowMap::lookup, "samples" from the call, a
/// fixed bias. The seed is the map's, so both versions draw the same samples.
struct ShadowServices : BenchServices {
    bool shadow(const ShadingGrid&, const ShadowQuery& q, float* result) override {
        auto it = shadowMaps().byName.find(q.mapName);
        if (it == shadowMaps().byName.end()) return false;
        ShadowBatch batch;
        batch.count = q.count;
        batch.P = q.P;
        batch.dPdu_du = q.dPdu;
        batch.dPdv_dv = q.dPdv;
        batch.N = q.N;
        batch.seed = uint32_t(q.mapName[4]);
        batch.pointId = q.indices;
        ShadowParams params;
        params.bias = 0.01f;
        for (const ShadeValue& v : q.params)
            if (v.name == "samples") params.samples = std::max(1, int(v.floatOr(16)));
        ShadowStats stats;
        it->second->lookup(batch, params, result, stats);
        return true;
    }
};

struct Spot {
    Vec3 from, to;
    float intensity;
    const char* map;
};
const Spot kSpots[3] = {{Vec3(1, 2, 0), Vec3(0, 0, 3.8f), 6, "spot0.shd"},
                        {Vec3(-2, 1, 0.5f), Vec3(0.2f, 0, 3.8f), 5, "spot1.shd"},
                        {Vec3(0, -2, 1), Vec3(0, 0.2f, 3.8f), 4, "spot2.shd"}};
const float kConeAngle = 0.7f, kConeDelta = 0.1f, kBeam = 2, kSamples = 16;

struct ShadowedScene {
    Diagnostics diag;
    ShadingSystem sys{diag, {std::string(UMBRA_SOURCE_DIR) + "/shaders_dsl"}};
    std::shared_ptr<const ShaderInstance> plastic, spots[3];
    ShadowServices svc;
    ShadowedScene() {
        scene::ShaderRecord rec;
        rec.name = "plastic";
        plastic = sys.instantiate(rec, ShaderKind::Surface);
        for (int l = 0; l < 3; ++l) {
            scene::ShaderRecord s;
            s.name = "shadowspot";
            const Spot& sp = kSpots[l];
            s.params.add(floatParam("intensity", ri::ParamType::Float, {sp.intensity}));
            s.params.add(floatParam("from", ri::ParamType::Point, {sp.from.x, sp.from.y, sp.from.z}));
            s.params.add(floatParam("to", ri::ParamType::Point, {sp.to.x, sp.to.y, sp.to.z}));
            s.params.add(floatParam("coneangle", ri::ParamType::Float, {kConeAngle}));
            s.params.add(floatParam("conedeltaangle", ri::ParamType::Float, {kConeDelta}));
            s.params.add(floatParam("samples", ri::ParamType::Float, {kSamples}));
            ri::Param name;
            name.decl.name = "shadowname";
            name.decl.type = ri::ParamType::String;
            name.strings = {sp.map};
            s.params.add(name);
            spots[l] = sys.instantiate(s, ShaderKind::Light);
        }
    }
};

/// shadowspot x 3 and plastic written directly: each light's cone test,
/// one lookup over the points inside its cone (footprints by the grid
/// differences the VM's Du(P)*du gives), its attenuation; then plastic.
struct NativeShadowedPlastic {
    std::vector<Vec3> L[3], Cl[3];
    std::vector<uint8_t> lit[3];
    std::vector<int> inside;
    std::vector<Vec3> P, dPdu, dPdv, N;
    std::vector<float> shadowed;
    /// Points looked up; of them, those partly shadowed (0 < f < 1) and
    /// those wholly shadowed.
    int lookups = 0, partlyShadowed = 0, whollyShadowed = 0;

    static Vec3 gridDifference(const ShadingGrid& g, int i, int stride, int pos, int count) {
        if (count < 2) return Vec3(0.f);
        const int before = pos > 0 ? i - stride : i, after = pos < count - 1 ? i + stride : i;
        return (g.P[size_t(after)] - g.P[size_t(before)]) * (after - before == 2 * stride ? 0.5f : 1.0f);
    }
    static float smoothstep(float a, float b, float x) {
        if (x < a) return 0;
        if (x >= b) return 1;
        float t = (x - a) / (b - a);
        return t * t * (3 - 2 * t);
    }

    void shade(ShadingGrid& g, RendererServices& svc) {
        const int n = g.size();
        const float cosOutside = std::cos(kConeAngle), cosInside = std::cos(kConeAngle - kConeDelta);
        for (int l = 0; l < 3; ++l) {
            const Spot& sp = kSpots[l];
            const Vec3 A = (sp.to - sp.from) / length(sp.to - sp.from);
            const float axisLength = length(A);
            L[l].resize(size_t(n));
            Cl[l].resize(size_t(n));
            lit[l].assign(size_t(n), 0);
            inside.clear();
            for (int i = 0; i < n; ++i) {
                const Vec3 Li = g.P[size_t(i)] - sp.from;
                const float ll = length(Li);
                if (!(ll > 0) || dot(Li, A) < cosOutside * ll * axisLength) continue;
                L[l][size_t(i)] = Li;
                inside.push_back(i);
            }
            const size_t count = inside.size();
            P.resize(count);
            dPdu.resize(count);
            dPdv.resize(count);
            N.resize(count);
            shadowed.resize(count);
            for (size_t k = 0; k < count; ++k) {
                const int nu = g.uVertices(), nv = g.vVertices();
                const int i = inside[k], iu = i % nu, iv = i / nu;
                P[k] = g.P[size_t(i)];
                N[k] = dot(g.N[size_t(i)], g.I[size_t(i)]) > 0 ? -g.N[size_t(i)] : g.N[size_t(i)];
                dPdu[k] = gridDifference(g, i, 1, iu, nu);
                dPdv[k] = gridDifference(g, i, nu, iv, nv);
            }
            ShadowQuery q;
            q.mapName = sp.map;
            q.count = int(count);
            q.indices = inside.data();
            q.P = P.data();
            q.dPdu = dPdu.data();
            q.dPdv = dPdv.data();
            q.N = N.data();
            ShadeValue samples;
            samples.name = "samples";
            samples.floats = {kSamples};
            q.params = {samples};
            if (!svc.shadow(g, q, shadowed.data())) std::fill(shadowed.begin(), shadowed.end(), 0.0f);
            lookups += int(count);
            for (float f : shadowed) {
                partlyShadowed += f > 0 && f < 1;
                whollyShadowed += f == 1;
            }
            for (size_t k = 0; k < count; ++k) {
                const int i = inside[k];
                const Vec3 Li = L[l][size_t(i)];
                const float cosangle = dot(Li, A) / length(Li);
                float atten = std::pow(cosangle, kBeam) / dot(Li, Li);
                atten *= smoothstep(cosOutside, cosInside, cosangle);
                atten *= 1 - shadowed[k];
                Cl[l][size_t(i)] = Vec3(atten * sp.intensity);
                lit[l][size_t(i)] = 1;
            }
        }
        nativePlastic(g, L, Cl, lit);
    }
};

void BM_ShadowedPlasticNative(benchmark::State& state) {
    ShadowServices svc;
    ShadingGrid g = makeGrid();
    NativeShadowedPlastic native;
    timeGrids(state, g, [&] { native.shade(g, svc); });
}
BENCHMARK(BM_ShadowedPlasticNative);

void BM_ShadowedPlasticVM(benchmark::State& state) {
    ShadowedScene s;
    ShadingGrid g = makeGrid();
    ShadeRequest req;
    req.surface = s.plastic.get();
    req.lights = {s.spots[0].get(), s.spots[1].get(), s.spots[2].get()};
    timeGrids(state, g, [&] { s.sys.shade(g, req, s.svc); });
    // Both versions compute the same image, shadows and all.
    ShadingGrid ref = makeGrid();
    NativeShadowedPlastic native;
    native.shade(ref, s.svc);
    state.counters["lookups"] = native.lookups;
    state.counters["partly_shadowed"] = native.partlyShadowed;
    state.counters["wholly_shadowed"] = native.whollyShadowed;
    checkSameImage(state, g, ref);
}
BENCHMARK(BM_ShadowedPlasticVM);

}  // namespace

BENCHMARK_MAIN();
