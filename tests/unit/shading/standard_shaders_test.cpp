// The standard shaders compile, and the lighting ones give the closed-form
// Lambert / Blinn values at test points.

#include "shading_test_util.h"
#include "support/params.h"

#include <cmath>
#include <filesystem>

using namespace umbra;
using namespace umbra::shading;
using namespace umbra::shading::testing;
using umbra::testsupport::floatParam;

TEST(StandardShaders, AllCompile) {
    Harness h;
    const char* names[] = {"constant", "matte", "metal", "shinymetal", "plastic", "paintedplastic", "ambientlight",
                           "distantlight", "pointlight", "spotlight", "shadowspot", "shadowdistant", "shadowpoint",
                           "depthcue", "fog", "bumpy", "defaultsurface", "background"};
    for (const char* n : names) {
        auto sh = h.sys.find(n);
        EXPECT_TRUE(sh) << n << "\n" << h.messages();
        if (sh) {
            EXPECT_EQ(sh->name(), n);
        }
    }
    EXPECT_EQ(h.diag.errorCount(), 0) << h.messages();
    EXPECT_EQ(h.diag.warningCount(), 0) << h.messages();
}

namespace {

/// A grid on the plane z = 2 facing the camera, x, y in [-1, 1].
ShadingGrid plane() {
    return makeGrid(4, 3, [](float u, float v) { return Vec3(2 * u - 1, 2 * v - 1, 2); });
}

struct Reference {
    Vec3 Ka{1}, Kd{0.5f}, Ks{0.5f};
    float roughness = 0.1f;
    /// plastic at P with normal N for lights given as (L towards the light, Cl) pairs.
    Vec3 plastic(const Vec3& P, const Vec3& N, const std::vector<std::pair<Vec3, Vec3>>& lights, const Vec3& ambient) const {
        Vec3 Nn = normalize(N);
        Vec3 V = -normalize(P);
        Vec3 diff(0.f), spec(0.f);
        for (auto& [L, Cl] : lights) {
            Vec3 Ln = normalize(L);
            float c = dot(Ln, Nn);
            if (c <= 0) continue;
            diff += Cl * c;
            Vec3 H = normalize(Ln + V);
            spec += Cl * std::pow(std::max(0.f, dot(Nn, H)), 8 / roughness);  // PRMan's exponent
        }
        return (Ka * ambient + Kd * diff) + Ks * spec;
    }
};

}  // namespace

TEST(StandardShaders, PlasticUnderDistantAndAmbientLight) {
    Harness h;
    h.svc.spaces["world"] = Mat4::identity();
    // The light's shader space is rotated so that its +z points along dir.
    Mat4 worldFromLight = Mat4::rotate(30, Vec3(1, 0, 0)) * Mat4::rotate(-20, Vec3(0, 1, 0));
    Vec3 dir = normalize(worldFromLight.vector(Vec3(0, 0, 1)));
    scene::ShaderRecord rec;
    rec.worldFromShader = worldFromLight;
    rec.params.add(floatParam("intensity", ri::ParamType::Float, {0.8f}));
    rec.params.add(floatParam("lightcolor", ri::ParamType::Color, {1, 0.5f, 0.25f}));
    auto distant = h.standard("distantlight", &rec);
    scene::ShaderRecord amb;
    amb.params.add(floatParam("intensity", ri::ParamType::Float, {0.1f}));
    auto ambient = h.standard("ambientlight", &amb);
    auto plastic = h.standard("plastic");
    ASSERT_TRUE(distant && ambient && plastic);
    ShadingGrid g = plane();
    ShadeRequest req;
    req.surface = plastic.get();
    req.lights = {distant.get(), ambient.get()};
    h.sys.shade(g, req, h.svc);
    Reference ref;
    Vec3 Cl = Vec3(1, 0.5f, 0.25f) * 0.8f;
    for (int i = 0; i < g.size(); ++i) {
        Vec3 expect = ref.plastic(g.P[size_t(i)], Vec3(0, 0, -1), {{-dir, Cl}}, Vec3(0.1f));
        expectNear(g.Ci[size_t(i)], expect, 1e-4f);
        expectNear(g.Oi[size_t(i)], Vec3(1, 1, 1));
    }
    EXPECT_EQ(h.diag.warningCount(), 0) << h.messages();
}

TEST(StandardShaders, MatteUnderPointLightIsLambertOverDistanceSquared) {
    Harness h;
    h.svc.spaces["world"] = Mat4::translate(Vec3(0, 0, 1));  // currentFromWorld
    scene::ShaderRecord rec;
    rec.worldFromShader = Mat4::translate(Vec3(0.5f, 1, -1));
    rec.params.add(floatParam("intensity", ri::ParamType::Float, {3}));
    auto point = h.standard("pointlight", &rec);
    scene::ShaderRecord m;
    m.params.add(floatParam("Ka", ri::ParamType::Float, {0}));
    m.params.add(floatParam("Kd", ri::ParamType::Float, {0.7f}));
    auto matte = h.standard("matte", &m);
    ShadingGrid g = plane();
    for (auto& c : g.Cs) c = Vec3(0.2f, 0.4f, 0.6f);
    ShadeRequest req;
    req.surface = matte.get();
    req.lights = {point.get()};
    h.sys.shade(g, req, h.svc);
    Vec3 from(0.5f, 1, 0);  // camera space: world (0.5,1,-1) moved by +1 in z
    for (int i = 0; i < g.size(); ++i) {
        Vec3 L = from - g.P[size_t(i)];
        float c = std::max(0.f, dot(normalize(L), Vec3(0, 0, -1)));
        Vec3 expect = Vec3(0.2f, 0.4f, 0.6f) * (0.7f * 3 * c / dot(L, L));
        expectNear(g.Ci[size_t(i)], expect, 1e-5f);
    }
}

TEST(StandardShaders, PlasticUnderSpotlightMatchesConeFalloff) {
    Harness h;
    h.svc.spaces["world"] = Mat4::identity();
    scene::ShaderRecord rec;
    rec.params.add(floatParam("from", ri::ParamType::Point, {0, 0, 0}));
    rec.params.add(floatParam("to", ri::ParamType::Point, {0.2f, 0, 2}));
    rec.params.add(floatParam("coneangle", ri::ParamType::Float, {0.5f}));
    rec.params.add(floatParam("conedeltaangle", ri::ParamType::Float, {0.2f}));
    auto spot = h.standard("spotlight", &rec);
    auto plastic = h.standard("plastic");
    ShadingGrid g = makeGrid(7, 7, [](float u, float v) { return Vec3(3 * u - 1.5f, 3 * v - 1.5f, 2); });
    ShadeRequest req;
    req.surface = plastic.get();
    req.lights = {spot.get()};
    h.sys.shade(g, req, h.svc);
    Vec3 A = normalize(Vec3(0.2f, 0, 2));
    Reference ref;
    int lit = 0, dark = 0;
    for (int i = 0; i < g.size(); ++i) {
        Vec3 L = g.P[size_t(i)];  // from the light at the origin to the point
        float cosangle = dot(L, A) / length(L);
        Vec3 Cl(0.f);
        if (cosangle >= std::cos(0.5f)) {
            float t = (cosangle - std::cos(0.5f)) / (std::cos(0.3f) - std::cos(0.5f));
            float ss = t >= 1 ? 1 : t * t * (3 - 2 * t);
            Cl = Vec3(std::pow(cosangle, 2.f) / dot(L, L) * ss);
        }
        (Cl.x > 0 ? lit : dark)++;
        Vec3 expect = ref.plastic(g.P[size_t(i)], Vec3(0, 0, -1), {{-L, Cl}}, Vec3(0.f));
        expectNear(g.Ci[size_t(i)], expect, 1e-4f);
    }
    EXPECT_GT(lit, 0);
    EXPECT_GT(dark, 0);
}

// Subdivision blocks (docs/subdivision.md) number u and v across a block
// of faces, so they are used only when no shader reads u, v, s or t; a
// texture() call without coordinates reads s and t.
TEST(StandardShaders, ReadsSurfaceParametersSeesUVSTAndImplicitTextureCoordinates) {
    Harness h;
    for (const char* name : {"plastic", "matte", "metal", "constant"}) {
        auto sh = h.sys.find(name);
        ASSERT_TRUE(sh) << name;
        EXPECT_FALSE(sh->readsSurfaceParameters()) << name;
    }
    auto painted = h.sys.find("paintedplastic");
    ASSERT_TRUE(painted);
    EXPECT_TRUE(painted->readsSurfaceParameters());
    const std::pair<const char*, bool> sources[] = {
        {"surface a() { Ci = u; }", true},
        {"surface b() { Ci = color(0, v, 0); }", true},
        {"surface c() { Ci = color(s, t, 0); }", true},
        {"surface d() { float k = t * 2; Ci = k; }", true},
        {"surface e() { Ci = color texture(\"x.tx\"); }", true},
        {"surface f() { float uu = 1; Ci = uu * Cs; }", false},
        {"surface g() { Ci = Cs * normalize(N).(0, 0, 1); }", false},
    };
    for (const auto& [src, reads] : sources) {
        auto sh = h.sys.compileSource(src, "test.sl");
        ASSERT_TRUE(sh) << src << "\n" << h.messages();
        EXPECT_EQ(sh->readsSurfaceParameters(), reads) << src;
    }
}
