// libFuzzer entry point for the files lookups read: any bytes, written as
// a depth map or a texture file and then looked up as both, so damaged
// headers, tiles and matrices reach ShadowMap::open, its tile reads and
// shadow() filtering, and the texture backend (OpenImageIO's texture()).
// Must never crash, hang or leak.
//
// The first byte picks the file's extension (.shd .tx .tif .exr: readers
// choose their format by it first); the rest is the file.

#include "umbra/shading/texture_backend.h"
#include "umbra/shadow/shadow_map.h"
#include "umbra/shadow/tile_cache.h"

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <unistd.h>

namespace {

using namespace umbra;

std::string g_dir;

// 16 points spread over the map's view: a 4 x 4 pattern in light space
// at depths across the map's range (or around the light when it has
// none), with footprints and normals, so lookups cull, filter, and take
// the second-depth path's virtual samples.
void lookUpShadows(const ShadowMap& map) {
    constexpr int kPoints = 16;
    const Mat4 worldFromLight = map.lightFromWorld().inverse();
    Vec3 P[kPoints], du[kPoints], dv[kPoints], N[kPoints];
    for (int k = 0; k < kPoints; ++k) {
        const float x = float(k % 4) / 3 - 0.5f, y = float(k / 4) / 3 - 0.5f;
        const float z = 0.5f + float(k) * 0.75f;
        const Vec3 light(x * z, y * z, z);
        P[k] = worldFromLight.point(light);
        du[k] = worldFromLight.vector(Vec3(0.01f * float(k + 1), 0, 0));
        dv[k] = worldFromLight.vector(Vec3(0, 0.01f, 0.001f * float(k)));
        N[k] = worldFromLight.vector(Vec3(0.1f * x, 0.1f * y, -1));
    }
    ShadowBatch batch;
    batch.count = kPoints;
    batch.P = P;
    batch.dPdu_du = du;
    batch.dPdv_dv = dv;
    batch.N = N;
    batch.seed = 7;
    float out[kPoints];
    ShadowStats stats;
    ShadowParams plain;
    map.lookup(batch, plain, out, stats);
    ShadowParams wide;
    wide.samples = 64;
    wide.setWidth(4);
    wide.blur = 0.05f;
    wide.bias0 = 0.01f;
    wide.bias1 = 0.2f;
    wide.filter = ShadowParams::Filter::Gaussian;
    wide.sampling = ShadowParams::Sampling::Gaussian;
    wide.tileCulling = false;
    map.lookup(batch, wide, out, stats);
    batch.dPdu_du = batch.dPdv_dv = nullptr;
    batch.N = nullptr;
    map.lookupPoint(batch, plain, out, stats);
}

void lookUpTexture(const std::string& path) {
    std::string error;
    shading::TextureBackend* backend = shading::textureBackend(&error);
    if (!backend) return;
    float rgb[4];
    float resolution[2];
    backend->textureInfoFloats(path, "resolution", 2, resolution);
    shading::TextureOptions opt;
    backend->texture(path, opt, 0.25f, 0.75f, 0.01f, 0, 0, 0.01f, 3, rgb);
    opt.firstChannel = 1;
    opt.sblur = opt.tblur = 0.2f;
    backend->texture(path, opt, 0.9f, 0.1f, 0.5f, 0.1f, 0.1f, 0.5f, 4, rgb);
    backend->environment(path, opt, Vec3(0, 0, 1), Vec3(0.1f, 0, 0), Vec3(0, 0.1f, 0), 3, rgb);
    // The next input is written under the same name.
    backend->invalidate(path);
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    char dir[] = "/tmp/umbra-fuzz-maps-XXXXXX";
    if (!mkdtemp(dir)) std::abort();
    g_dir = dir;
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    if (size < 1) return 0;
    static const char* const kExtensions[] = {".shd", ".tx", ".tif", ".exr"};
    const std::string path = g_dir + "/map" + kExtensions[data[0] % 4];
    {
        std::ofstream f(path, std::ios::binary | std::ios::trunc);
        f.write(reinterpret_cast<const char*>(data + 1), std::streamsize(size - 1));
    }
    Diagnostics diag;
    diag.setSink([](const Diagnostic&) {});
    if (auto map = ShadowMap::open(path, diag, {}, std::make_shared<TileCache>(size_t(1) << 20))) {
        lookUpShadows(*map);
        if (map->isCube())
            for (int f = 0; f < 6; ++f) lookUpShadows(map->face(f));
    }
    lookUpTexture(path);
    std::remove(path.c_str());
    return 0;
}
