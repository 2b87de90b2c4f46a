// libFuzzer entry point: compiles the input bytes as a shader source. Any
// input must be rejected with diagnostics or compiled, never crash or hang
// (the parser and preprocessor bound recursion depth and macro expansion).
// Compiled shaders are also run once on a small grid.

#include "umbra/shading/shading_system.h"

#include <cstddef>
#include <cstdint>
#include <string>

namespace {

struct NullServices : umbra::shading::RendererServices {
    bool getMatrix(const umbra::shading::ShadingGrid&, const std::string&, umbra::Mat4* m) override {
        *m = umbra::Mat4::identity();
        return true;
    }
    void print(const std::string&) override {}
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    using namespace umbra;
    static Diagnostics diag;
    static bool configured = [] {
        diag.setPolicy(Diagnostics::Policy::Ignore);
        return true;
    }();
    (void)configured;
    static shading::ShadingSystem sys(diag, {});
    std::string src(reinterpret_cast<const char*>(data), size);
    auto shader = sys.compileSource(src, "fuzz.sl");
    if (!shader) return 0;
    scene::ShaderRecord rec;
    auto inst = sys.instantiate(shader, rec);
    if (!inst) return 0;
    shading::ShadingGrid g;
    g.resize(3, 2);
    g.du = 0.5f;
    g.dv = 1.0f;
    for (int i = 0; i < g.size(); ++i) {
        g.P[size_t(i)] = Vec3(float(i % 3), float(i / 3), 1);
        g.N[size_t(i)] = g.Ng[size_t(i)] = Vec3(0, 0, -1);
        g.I[size_t(i)] = g.P[size_t(i)];
        g.Cs[size_t(i)] = g.Os[size_t(i)] = Vec3(1, 1, 1);
    }
    shading::ShadeRequest req;
    switch (shader->kind()) {
    case shading::ShaderKind::Surface: req.surface = inst.get(); break;
    case shading::ShaderKind::Displacement: req.displacement = inst.get(); break;
    case shading::ShaderKind::Volume: req.atmosphere = inst.get(); break;
    case shading::ShaderKind::Light: {
        static auto lit = sys.instantiate(sys.compileSource("surface lit() { Ci = diffuse(N) + ambient(); }", "lit.sl"), rec);
        req.surface = lit.get();
        req.lights.push_back(inst.get());
        break;
    }
    case shading::ShaderKind::Imager: return 0;
    }
    NullServices svc;
    sys.shade(g, req, svc);
    return 0;
}
