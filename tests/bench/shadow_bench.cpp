// Cost of one shadow() lookup per shading point: 16 jittered samples on a
// 1024x1024 map, with and without per-tile culling. Points arrive as grids
// do: batches of 256 points covering a small patch of the map.

#include "umbra/shadow/shadow_map.h"
#include "umbra/util/rng.h"

#include <benchmark/benchmark.h>
#include <unistd.h>

#include <filesystem>

namespace umbra {
namespace {

constexpr int kRes = 1024;
constexpr int kGrid = 16;  // 16x16 points per batch

struct Fixture {
    std::string path;
    std::shared_ptr<ShadowMap> map;
    std::vector<Vec3> P, du, dv;
    Diagnostics diag;

    Fixture() {
        // Boxes at various depths over an empty background, raster = world x, y.
        DepthImage img(kRes, kRes);
        img.ndcFromWorld = Mat4::scale(Vec3(1.0f / kRes, 1.0f / kRes, 1));
        img.projection = Projection::Orthographic;
        Rng rng(3);
        for (int k = 0; k < 60; ++k) {
            int x0 = int(rng.uniform() * kRes), y0 = int(rng.uniform() * kRes);
            int w = 16 + int(rng.uniform() * 200), h = 16 + int(rng.uniform() * 200);
            float z = 10 + 80 * rng.uniform();
            for (int y = y0; y < std::min(kRes, y0 + h); ++y)
                for (int x = x0; x < std::min(kRes, x0 + w); ++x) img.at(x, y) = std::min(img.at(x, y), z);
        }
        path = (std::filesystem::temp_directory_path() / ("umbra_shadow_bench_" + std::to_string(getpid()) + ".exr"))
                   .string();
        writeDepthMap(path, img, diag);
        map = ShadowMap::open(path, diag);
        // 64 grids at random places; micropolygons about one texel across,
        // depths spread over the scene so every outcome occurs.
        for (int g = 0; g < 64; ++g) {
            float gx = rng.uniform() * (kRes - kGrid), gy = rng.uniform() * (kRes - kGrid);
            float gz = 100 * rng.uniform();
            for (int j = 0; j < kGrid; ++j)
                for (int i = 0; i < kGrid; ++i) {
                    P.push_back(Vec3(gx + float(i), gy + float(j), gz + 0.1f * float(i)));
                    du.push_back(Vec3(1, 0, 0));
                    dv.push_back(Vec3(0, 1, 0));
                }
        }
    }
    ~Fixture() { std::filesystem::remove(path); }
};

Fixture& fixture() {
    static Fixture f;
    return f;
}

void lookupBench(benchmark::State& state, bool culling, float width) {
    Fixture& f = fixture();
    ShadowParams params;
    params.tileCulling = culling;
    params.setWidth(width);
    params.bias = 0.2f;
    std::vector<float> out(kGrid * kGrid);
    ShadowStats stats;
    const int batches = int(f.P.size()) / (kGrid * kGrid);
    int b = 0;
    for (auto _ : state) {
        ShadowBatch batch;
        batch.count = kGrid * kGrid;
        batch.P = f.P.data() + size_t(b) * batch.count;
        batch.dPdu_du = f.du.data() + size_t(b) * batch.count;
        batch.dPdv_dv = f.dv.data() + size_t(b) * batch.count;
        batch.seed = uint32_t(b);
        f.map->lookup(batch, params, out.data(), stats);
        benchmark::DoNotOptimize(out.data());
        b = (b + 1) % batches;
    }
    state.SetItemsProcessed(int64_t(state.iterations()) * kGrid * kGrid);
    state.counters["samples/pt"] = double(stats.samples) / double(std::max<uint64_t>(1, stats.points));
    state.counters["culled%"] =
        100.0 * double(stats.culledLit + stats.culledShadowed) / double(std::max<uint64_t>(1, stats.points));
}

void BM_Lookup16Culling(benchmark::State& s) { lookupBench(s, true, 4); }
void BM_Lookup16NoCulling(benchmark::State& s) { lookupBench(s, false, 4); }
void BM_Lookup16Width1(benchmark::State& s) { lookupBench(s, true, 1); }
BENCHMARK(BM_Lookup16Culling);
BENCHMARK(BM_Lookup16NoCulling);
BENCHMARK(BM_Lookup16Width1);

}  // namespace
}  // namespace umbra

BENCHMARK_MAIN();
