#pragma once
// Helpers for the shading tests: a RendererServices that records what the
// shaders ask for, and grids with known positions.

#include "umbra/shading/shading_system.h"

#include <gtest/gtest.h>

#include <functional>
#include <map>
#include <string>

namespace umbra::shading::testing {

/// Services with a table of named spaces, a scripted shadow() and a
/// captured printf().
struct TestServices : RendererServices {
    std::map<std::string, Mat4> spaces;  // currentFromSpace
    std::function<bool(const ShadowQuery&, float*)> shadowFn;
    std::vector<ShadowQuery> shadowQueries;
    std::string printed;
    std::map<std::string, ShadeValue> attributes;

    bool getMatrix(const ShadingGrid&, const std::string& space, Mat4* m) override {
        auto it = spaces.find(space);
        if (it == spaces.end()) return false;
        *m = it->second;
        return true;
    }
    bool shadow(const ShadingGrid&, const ShadowQuery& q, float* result) override {
        shadowQueries.push_back(q);
        return shadowFn ? shadowFn(q, result) : false;
    }
    bool attribute(const ShadingGrid&, const std::string& name, ShadeValue* out) override {
        auto it = attributes.find(name);
        if (it == attributes.end()) return false;
        *out = it->second;
        return true;
    }
    void print(const std::string& text) override { printed += text; }
};

/// A uVerts x vVerts grid over u, v in [0,1] with P = f(u, v), N = (0,0,-1)
/// (facing a camera at the origin looking down +z), I = P, s = u, t = v,
/// Cs = Os = 1.
inline ShadingGrid makeGrid(int uVerts, int vVerts, const std::function<Vec3(float, float)>& f) {
    ShadingGrid g;
    g.resize(uVerts, vVerts);
    g.du = uVerts > 1 ? 1.0f / float(uVerts - 1) : 0.f;
    g.dv = vVerts > 1 ? 1.0f / float(vVerts - 1) : 0.f;
    for (int j = 0; j < vVerts; ++j)
        for (int i = 0; i < uVerts; ++i) {
            size_t k = size_t(j * uVerts + i);
            float u = float(i) * g.du, v = float(j) * g.dv;
            g.u[k] = g.s[k] = u;
            g.v[k] = g.t[k] = v;
            g.P[k] = f(u, v);
            g.N[k] = g.Ng[k] = Vec3(0, 0, -1);
            g.I[k] = g.P[k];
            g.Cs[k] = g.Os[k] = Vec3(1, 1, 1);
            g.Ci[k] = g.Oi[k] = Vec3(0, 0, 0);
        }
    return g;
}

/// A shading system over the standard shaders, recording diagnostics.
struct Harness {
    Diagnostics diag;
    ShadingSystem sys;
    TestServices svc;
    Harness() : sys(init(diag), {std::string(UMBRA_SOURCE_DIR) + "/shaders_dsl"}) {}
    static Diagnostics& init(Diagnostics& d) {
        d.setRecord(true);
        d.setSink([](const Diagnostic&) {});
        return d;
    }
    std::string messages() const {
        std::string s;
        for (const Diagnostic& d : diag.recorded()) s += d.str() + "\n";
        return s;
    }
    /// Compiles source text and makes an instance without parameters.
    std::shared_ptr<const ShaderInstance> instance(const std::string& src, const Mat4& worldFromShader = Mat4()) {
        auto sh = sys.compileSource(src, "test.sl");
        EXPECT_TRUE(sh) << messages();
        if (!sh) return nullptr;
        scene::ShaderRecord rec;
        rec.name = sh->name();
        rec.worldFromShader = worldFromShader;
        return sys.instantiate(sh, rec);
    }
    std::shared_ptr<const ShaderInstance> standard(const std::string& name, const scene::ShaderRecord* rec = nullptr) {
        auto sh = sys.find(name);
        EXPECT_TRUE(sh) << messages();
        if (!sh) return nullptr;
        scene::ShaderRecord r;
        if (rec) r = *rec;
        r.name = name;
        return sys.instantiate(sh, r);
    }
    /// Expects the compiler to refuse `src` with a message containing `error`.
    void expectRefused(const std::string& src, const std::string& error) {
        EXPECT_FALSE(sys.compileSource(src, "t.sl")) << src;
        EXPECT_NE(messages().find(error), std::string::npos) << messages();
    }
    /// Runs a surface shader given as source over `g`.
    void surface(const std::string& src, ShadingGrid& g, std::vector<const ShaderInstance*> lights = {}) {
        auto inst = instance(src);
        ASSERT_TRUE(inst);
        ShadeRequest req;
        req.surface = inst.get();
        req.lights = std::move(lights);
        sys.shade(g, req, svc);
    }
};

inline void expectNear(const Vec3& a, const Vec3& b, float eps = 1e-5f) {
    EXPECT_NEAR(a.x, b.x, eps);
    EXPECT_NEAR(a.y, b.y, eps);
    EXPECT_NEAR(a.z, b.z, eps);
}

}  // namespace umbra::shading::testing
