// Light contributions by the RenderMan convention: a light's float
// parameter `__nondiffuse` (1: excluded) takes it out of diffuse(),
// `__nonspecular` out of specular() and phong(); PRMan, Pixie and Aqsis
// honour them, and exporters (Maya's "emit diffuse / emit specular") write
// them. Checked on a flat plane against the closed-form Lambert, Blinn and
// Phong sums over the lights that should count.

#include "shading_test_util.h"
#include "support/params.h"

#include <cmath>

using namespace umbra;
using namespace umbra::shading;
using namespace umbra::shading::testing;
using umbra::testsupport::floatParam;

namespace {

/// A distant light along `dir` (shader space = camera space here), with
/// the two category parameters (uniform, as most lights declare them, or
/// varying); `body` may set them in the light's body.
std::string lightSource(const std::string& body = "", const std::string& storage = "") {
    return "light cat(color lc = 1; vector dir = vector(0, 0, 1);\n"
           "          output " + storage + " float __nondiffuse = 0; output " + storage +
           " float __nonspecular = 0;) {\n"
           "  solar(dir, 0) { Cl = lc; }\n" +
           body + "}\n";
}

struct Light {
    Vec3 dir;  // the direction light travels
    Vec3 colour;
    float nondiffuse = 0, nonspecular = 0;
};

std::shared_ptr<const ShaderInstance> makeLight(Harness& h, const Light& l, const std::string& body = "") {
    auto sh = h.sys.compileSource(lightSource(body), "cat.sl");
    EXPECT_TRUE(sh) << h.messages();
    if (!sh) return nullptr;
    scene::ShaderRecord rec;
    rec.name = sh->name();
    rec.params.add(floatParam("lc", ri::ParamType::Color, {l.colour.x, l.colour.y, l.colour.z}));
    rec.params.add(floatParam("dir", ri::ParamType::Vector, {l.dir.x, l.dir.y, l.dir.z}));
    rec.params.add(floatParam("__nondiffuse", ri::ParamType::Float, {l.nondiffuse}));
    rec.params.add(floatParam("__nonspecular", ri::ParamType::Float, {l.nonspecular}));
    return h.sys.instantiate(sh, rec);
}

/// A plane at z = 2 facing the camera at the origin, x, y in [-1, 1].
ShadingGrid plane() {
    return makeGrid(5, 4, [](float u, float v) { return Vec3(2 * u - 1, 2 * v - 1, 2); });
}

constexpr float kRoughness = 0.2f, kPhongSize = 20;

const char* const kDiffuse = "surface d() { Ci = diffuse(faceforward(normalize(N), I)); }";
const char* const kSpecular =
    "surface s() { Ci = specular(faceforward(normalize(N), I), -normalize(I), 0.2); }";
const char* const kPhong = "surface p() { Ci = phong(faceforward(normalize(N), I), -normalize(I), 20); }";

/// The closed forms at P on the plane (normal (0, 0, -1) towards the eye),
/// each light weighted by 1 - its category value.
struct Expected {
    Vec3 diffuse{0.f}, specular{0.f}, phong{0.f};
};

Expected closedForm(const Vec3& P, const std::vector<Light>& lights) {
    const Vec3 N(0, 0, -1), V = -normalize(P);
    Expected e;
    for (const Light& l : lights) {
        const Vec3 Ln = -normalize(l.dir);
        const float c = dot(Ln, N);
        if (c <= 0) continue;
        e.diffuse += l.colour * (c * (1 - l.nondiffuse));
        const Vec3 H = normalize(Ln + V);
        e.specular += l.colour * ((1 - l.nonspecular) * std::pow(std::max(0.f, dot(N, H)), 8 / kRoughness));
        const Vec3 R = -V - N * (2 * dot(-V, N));
        e.phong += l.colour * ((1 - l.nonspecular) * std::pow(std::max(0.f, dot(R, Ln)), kPhongSize));
    }
    return e;
}

/// Shades the plane with each of the three surfaces and compares.
void checkAll(Harness& h, const std::vector<Light>& lights, const std::vector<const ShaderInstance*>& instances) {
    for (const char* src : {kDiffuse, kSpecular, kPhong}) {
        ShadingGrid g = plane();
        h.surface(src, g, instances);
        for (int i = 0; i < g.size(); ++i) {
            const Expected e = closedForm(g.P[size_t(i)], lights);
            const Vec3 want = src == kDiffuse ? e.diffuse : src == kSpecular ? e.specular : e.phong;
            SCOPED_TRACE(std::string(src) + " at point " + std::to_string(i));
            expectNear(g.Ci[size_t(i)], want, 1e-4f);
        }
    }
    EXPECT_EQ(h.diag.errorCount(), 0) << h.messages();
}

// Two lights from different sides, so that each sum is told apart: one
// over the viewer's shoulder (a strong highlight on the plane), one
// grazing from the right.
const Vec3 kShoulder = normalize(Vec3(0.2f, -0.3f, 1.0f));
const Vec3 kGrazing = normalize(Vec3(-1.0f, 0.1f, 0.8f));

}  // namespace

TEST(LightContributions, NonSpecularLightLightsDiffuseOnly) {
    Harness h;
    std::vector<Light> lights = {{kShoulder, Vec3(1, 0.8f, 0.6f), 0, 1}, {kGrazing, Vec3(0.3f, 0.5f, 1.0f), 0, 0}};
    auto a = makeLight(h, lights[0]);
    auto b = makeLight(h, lights[1]);
    ASSERT_TRUE(a && b);
    checkAll(h, lights, {a.get(), b.get()});
    // The excluded light's highlight is the larger one at the centre of the
    // plane: leaving it out is a visible difference, not a rounding.
    const Expected with = closedForm(Vec3(0, 0, 2), {{kShoulder, Vec3(1, 0.8f, 0.6f)}});
    EXPECT_GT(with.specular.x, 0.1f);
}

TEST(LightContributions, NonDiffuseLightLightsSpecularOnly) {
    Harness h;
    std::vector<Light> lights = {{kShoulder, Vec3(1, 0.8f, 0.6f), 1, 0}, {kGrazing, Vec3(0.3f, 0.5f, 1.0f), 0, 0}};
    auto a = makeLight(h, lights[0]);
    auto b = makeLight(h, lights[1]);
    ASSERT_TRUE(a && b);
    checkAll(h, lights, {a.get(), b.get()});
}

TEST(LightContributions, ExcludedFromBothAndNeither) {
    Harness h;
    std::vector<Light> lights = {{kShoulder, Vec3(1, 1, 1), 1, 1}, {kGrazing, Vec3(0.3f, 0.5f, 1.0f), 0, 0}};
    auto a = makeLight(h, lights[0]);
    auto b = makeLight(h, lights[1]);
    ASSERT_TRUE(a && b);
    checkAll(h, lights, {a.get(), b.get()});
    // A fraction scales the light's part, as Advanced RenderMan's shaders
    // weigh it by 1 - value.
    Harness h2;
    std::vector<Light> half = {{kShoulder, Vec3(1, 1, 1), 0.25f, 0.5f}};
    auto c = makeLight(h2, half[0]);
    ASSERT_TRUE(c);
    checkAll(h2, half, {c.get()});
}

TEST(LightContributions, ValueSetInTheLightsBodyCounts) {
    // The value read is the one the light left after running: a light
    // that decides in its body (as exporters' lights do from their "emit
    // specular" switch) is honoured too, point by point.
    Harness h;
    auto sh = h.sys.compileSource(lightSource("  __nonspecular = xcomp(Ps) > 0 ? 1 : 0;\n", "varying"), "cat.sl");
    ASSERT_TRUE(sh) << h.messages();
    scene::ShaderRecord rec;
    rec.name = sh->name();
    rec.params.add(floatParam("dir", ri::ParamType::Vector, {kShoulder.x, kShoulder.y, kShoulder.z}));
    auto light = h.sys.instantiate(sh, rec);
    ASSERT_TRUE(light);
    ShadingGrid g = plane();
    h.surface(kSpecular, g, {light.get()});
    int off = 0, on = 0;
    for (int i = 0; i < g.size(); ++i) {
        const Vec3& P = g.P[size_t(i)];
        const Expected e = closedForm(P, {{kShoulder, Vec3(1), 0, P.x > 0 ? 1.0f : 0.0f}});
        expectNear(g.Ci[size_t(i)], e.specular, 1e-4f);
        (P.x > 0 ? off : on)++;
    }
    EXPECT_GT(off, 0);
    EXPECT_GT(on, 0);
}

TEST(LightContributions, IlluminanceLoopsStillSeeEveryLight) {
    // The categories are a convention of the built-ins: a shader's own
    // illuminance loop sees every light and can read the value itself
    // with lightsource(), as the books' shaders do.
    Harness h;
    std::vector<Light> lights = {{kShoulder, Vec3(1, 0.8f, 0.6f), 1, 1}, {kGrazing, Vec3(0.3f, 0.5f, 1.0f), 0, 0}};
    auto a = makeLight(h, lights[0]);
    auto b = makeLight(h, lights[1]);
    ASSERT_TRUE(a && b);
    ShadingGrid g = plane();
    h.surface("surface loop() {\n"
              "  normal Nf = faceforward(normalize(N), I);\n"
              "  color all = 0, kept = 0;\n"
              "  illuminance(P, Nf, PI/2) {\n"
              "    float c = normalize(L) . Nf;\n"
              "    float nd = 0;\n"
              "    lightsource(\"__nondiffuse\", nd);\n"
              "    all += Cl * c;\n"
              "    kept += (1 - nd) * Cl * c;\n"
              "  }\n"
              "  Ci = all; Oi = kept;\n"
              "}\n",
              g, {a.get(), b.get()});
    for (int i = 0; i < g.size(); ++i) {
        std::vector<Light> every = lights;
        for (Light& l : every) l.nondiffuse = 0;
        expectNear(g.Ci[size_t(i)], closedForm(g.P[size_t(i)], every).diffuse, 1e-4f);
        expectNear(g.Oi[size_t(i)], closedForm(g.P[size_t(i)], lights).diffuse, 1e-4f);
    }
    EXPECT_EQ(h.diag.errorCount(), 0) << h.messages();
}

TEST(LightContributions, LightsourceReadsIntoAUniformVariable) {
    // Shaders written for PRMan and BMRT read a light's uniform output
    // into a uniform variable (the RenderMan Repository's MKfancysurf);
    // Pixie's and Aqsis's compilers take it. umbra's refused to compile
    // it ("cannot assign a varying value to uniform variable").
    Harness h;
    std::vector<Light> lights = {{kShoulder, Vec3(1, 0.8f, 0.6f), 1, 1}, {kGrazing, Vec3(0.3f, 0.5f, 1.0f), 0, 0}};
    auto a = makeLight(h, lights[0]);
    auto b = makeLight(h, lights[1]);
    ASSERT_TRUE(a && b);
    ShadingGrid g = plane();
    h.surface("surface loop() {\n"
              "  normal Nf = faceforward(normalize(N), I);\n"
              "  uniform float nd = 0;\n"
              "  color kept = 0;\n"
              "  illuminance(P, Nf, PI/2) {\n"
              "    lightsource(\"__nondiffuse\", nd);\n"
              "    kept += (1 - nd) * Cl * (normalize(L) . Nf);\n"
              "  }\n"
              "  Ci = kept; Oi = 1;\n"
              "}\n",
              g, {a.get(), b.get()});
    EXPECT_EQ(h.diag.errorCount(), 0) << h.messages();
    for (int i = 0; i < g.size(); ++i) expectNear(g.Ci[size_t(i)], closedForm(g.P[size_t(i)], lights).diffuse, 1e-4f);
}

TEST(LightContributions, PlasticHonoursThem) {
    // The standard plastic: Ka ambient() + Kd diffuse() + Ks specular().
    Harness h;
    std::vector<Light> lights = {{kShoulder, Vec3(1, 0.8f, 0.6f), 0, 1}, {kGrazing, Vec3(0.3f, 0.5f, 1.0f), 1, 0}};
    auto a = makeLight(h, lights[0]);
    auto b = makeLight(h, lights[1]);
    auto plastic = h.standard("plastic");
    ASSERT_TRUE(a && b && plastic);
    ShadingGrid g = plane();
    ShadeRequest req;
    req.surface = plastic.get();
    req.lights = {a.get(), b.get()};
    h.sys.shade(g, req, h.svc);
    // plastic's defaults: Ka 1, Kd 0.5, Ks 0.5, roughness 0.1, white
    // specularcolor; no ambient light. Light a only lights diffuse(),
    // light b only specular().
    for (int i = 0; i < g.size(); ++i) {
        const Vec3 N(0, 0, -1), V = -normalize(g.P[size_t(i)]);
        const Vec3 La = -normalize(lights[0].dir), Lb = -normalize(lights[1].dir);
        const Vec3 diffuse = lights[0].colour * std::max(0.f, dot(La, N));
        const Vec3 specular = lights[1].colour * std::pow(std::max(0.f, dot(N, normalize(Lb + V))), 8 / 0.1f);
        expectNear(g.Ci[size_t(i)], diffuse * 0.5f + specular * 0.5f, 1e-4f);
    }
}
