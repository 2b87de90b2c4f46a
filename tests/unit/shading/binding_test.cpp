// Instance parameters from scene records and primitive variables.

#include "shading_test_util.h"
#include "support/params.h"

using namespace umbra;
using namespace umbra::shading;
using namespace umbra::shading::testing;

using umbra::testsupport::floatParam;

TEST(Binding, RenderManTypeRulesAndWarningsOnce) {
    Harness h;
    auto sh = h.sys.compileSource("surface s(float Kd = 1, Ks = 2; color tint = 1; string name = \"\"; float arr[2] = {1, 2}) {\n"
                                  "  Ci = tint * Kd * Ks / 2 + color(arr[0], arr[1], name == \"hi\");\n}",
                                  "s.sl");
    ASSERT_TRUE(sh) << h.messages();
    scene::ShaderRecord rec;
    rec.name = "s";
    rec.loc = FileLoc::inFile("scene.rib", 12, 1);
    rec.params.add(floatParam("Kd", ri::ParamType::Float, {0.5f}));
    rec.params.add(floatParam("tint", ri::ParamType::Float, {0.25f}));  // float promotes to color
    rec.params.add(floatParam("arr", ri::ParamType::Float, {7, 8}));
    ri::Param name;
    name.decl.name = "name";
    name.decl.type = ri::ParamType::String;
    name.strings = {"hi"};
    rec.params.add(name);
    rec.params.add(floatParam("Kx", ri::ParamType::Float, {1}));                  // unknown
    rec.params.add(floatParam("Ks", ri::ParamType::Color, {1, 1, 1}));            // mistyped
    auto inst = h.sys.instantiate(sh, rec);
    auto inst2 = h.sys.instantiate(sh, rec);
    ASSERT_TRUE(inst && inst2);
    ShadingGrid g = makeGrid(2, 1, [](float u, float) { return Vec3(u, 0, 1); });
    ShadeRequest req;
    req.surface = inst.get();
    h.sys.shade(g, req, h.svc);
    expectNear(g.Ci[0], Vec3(0.125f + 7, 0.125f + 8, 0.125f + 1));
    EXPECT_EQ(h.messages(),
              "scene.rib:12:1: warning: shader 's' has no parameter 'Kx' (ignored)\n"
              "scene.rib:12:1: warning: parameter 'Ks' of shader 's' is float, but was given color (ignored)\n");
}

TEST(Binding, PointParametersAreInShaderSpace) {
    Harness h;
    h.svc.spaces["world"] = Mat4::translate(Vec3(0, 0, 5));  // currentFromWorld
    scene::ShaderRecord rec;
    rec.worldFromShader = Mat4::translate(Vec3(0, 1, 0));
    rec.params.add(floatParam("from", ri::ParamType::Point, {1, 0, 0}));
    auto light = h.standard("pointlight", &rec);
    auto surf = h.instance("surface s() { illuminance(P) { Ci = color(L); } }");
    ShadingGrid g = makeGrid(2, 1, [](float u, float) { return Vec3(u, 0, 1); });
    ShadeRequest req;
    req.surface = surf.get();
    req.lights = {light.get()};
    h.sys.shade(g, req, h.svc);
    Vec3 from(1, 1, 5);
    for (int i = 0; i < 2; ++i) expectNear(g.Ci[size_t(i)], from - g.P[size_t(i)]);
}

TEST(Binding, PrimitiveVariablesBindByName) {
    Harness h;
    auto inst = h.instance("surface s(varying float bump = 0; float k = 3; color tone = 0) { Ci = color(bump, k, comp(tone, 1)); }");
    ShadingGrid g = makeGrid(3, 1, [](float u, float) { return Vec3(u, 0, 1); });
    std::vector<geometry::GridVar> vars(3);
    vars[0].name = "bump";
    vars[0].data = {1, 2, 3};
    vars[1].name = "k";
    vars[1].perVertex = false;
    vars[1].data = {9};
    vars[2].name = "tone";
    vars[2].type = ri::ParamType::Color;
    vars[2].components = 3;
    vars[2].perVertex = false;
    vars[2].data = {0, 4, 0};
    g.primvars = &vars;
    ShadeRequest req;
    req.surface = inst.get();
    h.sys.shade(g, req, h.svc);
    for (int i = 0; i < 3; ++i) expectNear(g.Ci[size_t(i)], Vec3(float(i + 1), 9, 4));
}

TEST(Binding, WrongKindOrMissingShaderFails) {
    Harness h;
    scene::ShaderRecord rec;
    rec.name = "plastic";
    rec.loc = FileLoc::inFile("a.rib", 3, 1);
    EXPECT_FALSE(h.sys.instantiate(rec, ShaderKind::Light));
    rec.name = "nosuchshader";
    EXPECT_FALSE(h.sys.instantiate(rec, ShaderKind::Surface));
    auto d = h.diag.recorded();
    ASSERT_EQ(d.size(), 2u);
    EXPECT_EQ(d[0].str(), "a.rib:3:1: error: shader 'plastic' is a surface shader, but a light shader is needed here");
    EXPECT_EQ(d[1].str().rfind("a.rib:3:1: error: cannot find shader 'nosuchshader' (searched ", 0), 0u) << d[1].str();
}

TEST(Binding, DisplacementThenSurfaceThenAtmosphere) {
    Harness h;
    auto disp = h.instance("displacement d(float amount = 0.5) { P += amount * normalize(N); N = calculatenormal(P); }");
    auto surf = h.instance("surface s() { Ci = color(zcomp(P), 0, 0); Oi = 1; }");
    scene::ShaderRecord fogRec;
    fogRec.params.add(floatParam("distance", ri::ParamType::Float, {2}));
    fogRec.params.add(floatParam("background", ri::ParamType::Color, {0, 1, 0}));
    auto fog = h.standard("fog", &fogRec);
    ShadingGrid g = makeGrid(3, 3, [](float u, float v) { return Vec3(u, v, 2); });
    ShadeRequest req;
    req.displacement = disp.get();
    req.surface = surf.get();
    req.atmosphere = fog.get();
    h.sys.shade(g, req, h.svc);
    for (int i = 0; i < g.size(); ++i) {
        EXPECT_NEAR(g.P[size_t(i)].z, 1.5f, 1e-6f);  // moved along N = (0,0,-1)
        expectNear(g.N[size_t(i)], Vec3(0, 0, 1));   // du x dv of a flat plane
        float d = 1 - std::exp(-length(g.I[size_t(i)]) / 2);
        expectNear(g.Ci[size_t(i)], Vec3(1.5f * (1 - d), d, 0), 1e-5f);
        expectNear(g.Oi[size_t(i)], Vec3(1, 1, 1), 1e-6f);
    }
}
