// The shading VM against hand-written C++: `plastic` under three lights
// (two distant lights and a point light) on a 16 x 16 grid. The target is
// the VM within 1.5x of the native version.

#include "umbra/shading/shading_system.h"
#include "support/params.h"

#include <benchmark/benchmark.h>

#include <cmath>

using namespace umbra;
using namespace umbra::shading;

namespace {

constexpr int kSide = 16;

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
        const float Ks = 0.5f, Kd = 0.5f, Ka = 1, roughness = 0.1f;
        const Vec3 specularcolor(1, 1, 1);
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
        for (int i = 0; i < n; ++i) {
            Vec3 Nn = normalize(g.N[size_t(i)]);
            Vec3 Nf = dot(g.I[size_t(i)], g.Ng[size_t(i)]) < 0 ? Nn : -Nn;
            Vec3 V = -normalize(g.I[size_t(i)]);
            Vec3 diff(0.f), spec(0.f);
            for (int l = 0; l < 3; ++l) {
                Vec3 Ln = normalize(-L[l][size_t(i)]);
                float c = dot(Ln, Nf);
                if (c <= 0) continue;
                diff += Cl[l][size_t(i)] * c;
                Vec3 H = normalize(Ln + V);
                spec += Cl[l][size_t(i)] * std::pow(std::max(0.f, dot(Nf, H)), 1 / roughness);
            }
            Vec3 ambient(0.f);
            g.Oi[size_t(i)] = g.Os[size_t(i)];
            g.Ci[size_t(i)] = g.Os[size_t(i)] * (g.Cs[size_t(i)] * (ambient * Ka + diff * Kd) + specularcolor * spec * Ks);
        }
    }
};

void BM_PlasticNative(benchmark::State& state) {
    ShadingGrid g = makeGrid();
    NativePlastic native;
    for (auto _ : state) {
        native.shade(g);
        benchmark::DoNotOptimize(g.Ci.data());
    }
    state.SetItemsProcessed(int64_t(state.iterations()) * g.size());
}
BENCHMARK(BM_PlasticNative);

void BM_PlasticVM(benchmark::State& state) {
    Scene s;
    ShadingGrid g = makeGrid();
    ShadeRequest req;
    req.surface = s.plastic.get();
    req.lights = {s.key.get(), s.fill.get(), s.bulb.get()};
    for (auto _ : state) {
        s.sys.shade(g, req, s.svc);
        benchmark::DoNotOptimize(g.Ci.data());
    }
    state.SetItemsProcessed(int64_t(state.iterations()) * g.size());
    // Both versions compute the same image.
    ShadingGrid ref = makeGrid();
    NativePlastic().shade(ref);
    float maxDiff = 0;
    for (int i = 0; i < g.size(); ++i) {
        Vec3 d = g.Ci[size_t(i)] - ref.Ci[size_t(i)];
        maxDiff = std::max(maxDiff, std::max(std::fabs(d.x), std::max(std::fabs(d.y), std::fabs(d.z))));
    }
    state.counters["max_diff_vs_native"] = maxDiff;
}

BENCHMARK(BM_PlasticVM);

}  // namespace

BENCHMARK_MAIN();
