// Language forms the Aqsis and Pixie shader compilers accept: storage-class
// polymorphism of built-ins, mixed-type built-ins, the two-value and
// parameterised filterstep, transform from a named space by a matrix,
// arraylength, shadername, incident/opposite, I in light shaders, imager
// shaders and #include along the search path. Each result is checked
// against the same formula written here in C++, on grids whose points
// differ, so a value computed once where it varies (or per point where it
// is uniform) shows.

#include "shading_test_util.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

using namespace umbra;
using namespace umbra::shading;
using namespace umbra::shading::testing;

namespace {

/// A line of n points, P = (u, 0, 1), s = u = i / (n - 1).
ShadingGrid line(int n = 11) {
    return makeGrid(n, 1, [](float u, float) { return Vec3(u, 0, 1); });
}

/// The RI filters filterstep() takes, in units of the footprint w (the
/// supports Pixie uses): box [-1/2, 1/2], triangle [-1, 1], Catmull-Rom
/// (B = 0, C = 1/2) [-2, 2], gaussian exp(-8 x^2).
double kernel(const std::string& filter, double x) {
    const double a = std::fabs(x);
    if (filter == "box") return a <= 0.5 ? 1 : 0;
    if (filter == "triangle") return std::max(0.0, 1 - a);
    if (filter == "gaussian") return std::exp(-8 * x * x);
    if (a < 1) return 1.5 * a * a * a - 2.5 * a * a + 1;
    if (a < 2) return -0.5 * a * a * a + 2.5 * a * a - 4 * a + 2;
    return 0;
}

/// The step at `edge` filtered over a footprint w centred on `mid`:
/// the kernel's area below (mid - edge) / w over its whole area, summed
/// numerically (midpoint rule), clamped to [0, 1].
float filteredStep(const std::string& filter, float edge, float mid, float w) {
    if (!(w > 0)) return mid < edge ? 0.f : 1.f;
    const double u = (double(mid) - double(edge)) / double(w);
    const int n = 200000;
    double below = 0, all = 0;
    for (int k = 0; k < n; ++k) {
        const double x = -3 + 6 * (k + 0.5) / n;
        const double f = kernel(filter, x);
        all += f;
        if (x < u) below += f;
    }
    return float(std::clamp(below / all, 0.0, 1.0));
}

}  // namespace

TEST(Compat, RandomStoredInAUniformIsOneValuePerGrid) {
    Harness h;
    const std::string src =
        "surface t() {\n"
        "  uniform color c = color(random(), random(), random());\n"
        "  uniform float f; f = random();\n"
        "  float v = random();\n"
        "  Ci = c; Oi = color(f, v, 0);\n"
        "}\n";
    auto sh = h.sys.compileSource(src, "t.sl");
    ASSERT_TRUE(sh) << h.messages();
    const std::string l = sh->listing();
    EXPECT_NE(l.find("reg c uniform color"), std::string::npos) << l;
    EXPECT_NE(l.find("reg v varying float"), std::string::npos) << l;
    ShadingGrid g = line(8);
    h.surface(src, g);
    const Vec3 c = g.Ci[0];
    for (float x : {c.x, c.y, c.z}) {
        EXPECT_GE(x, 0.f);
        EXPECT_LT(x, 1.f);
    }
    EXPECT_FALSE(c.x == c.y && c.y == c.z);  // three calls, three values
    bool vDiffers = false;
    for (size_t i = 1; i < 8; ++i) {
        EXPECT_TRUE(g.Ci[i].x == c.x && g.Ci[i].y == c.y && g.Ci[i].z == c.z) << "point " << i;
        EXPECT_EQ(g.Oi[i].x, g.Oi[0].x);
        vDiffers = vDiffers || g.Oi[i].y != g.Oi[0].y;
    }
    EXPECT_TRUE(vDiffers) << "random() into a varying variable gives each point its own value";
}

TEST(Compat, BuiltinOfUniformArgumentsIsUniform) {
    Harness h;
    const std::string src =
        "surface t() {\n"
        "  uniform float a = sin(0.5) + pow(2, 3) + max(1, 4, 2);\n"
        "  uniform color c = pow(color(0.5, 0.25, 2), 2) * a;\n"
        "  Ci = c;\n"
        "}\n";
    ShadingGrid g = line(3);
    h.surface(src, g);
    const float a = std::sin(0.5f) + 8 + 4;
    for (size_t i = 0; i < 3; ++i) expectNear(g.Ci[i], Vec3(0.25f * a, 0.0625f * a, 4 * a), 1e-4f);
    // A built-in of a varying argument is varying.
    h.expectRefused("surface t() { uniform float b = sin(u); }",
                    "cannot assign a varying value to uniform variable 'b'");
    // So is random() outside a uniform store, even added to a uniform one.
    EXPECT_FALSE(h.sys.compileSource("surface t() { float v = random(); uniform float b = random() + v; }", "t.sl"));
}

TEST(Compat, UniformVariableStoredUnderAVaryingConditionHoldsEachPointsValue) {
    // Pixie and Aqsis compile a uniform value stored into a variable
    // declared uniform under varying control, and each point keeps what its
    // own path stored (both render b = 1 exactly where u > 0.5); umbra's
    // compiler refused it. A varying value stays an error, as in both.
    Harness h;
    ShadingGrid g = line(8);
    h.surface("surface t() { uniform float b = 0; if (u > 0.5) b = 1; Ci = b; }", g);
    EXPECT_EQ(h.diag.errorCount(), 0) << h.messages();
    for (size_t i = 0; i < g.Ci.size(); ++i) expectNear(g.Ci[i], Vec3(g.u[i] > 0.5f ? 1.0f : 0.0f), 0);
    h.expectRefused("surface t() { uniform float b = 0; if (u > 0.5) b = u; }",
                    "cannot assign a varying value to uniform variable 'b'");
}

TEST(Compat, UniformValuesDerivedFromAVariableStoredUnderAVaryingConditionStayUniform) {
    // K-3D's lens flare and soft boxes shaders: uniform locals declared
    // inside a varying `if` (or a function called inside solar()), each
    // computed from the one before. Both peers compile them; umbra refused
    // the second, because the first had been made varying to hold each
    // point's path. A value computed from uniform ones is uniform.
    Harness h;
    ShadingGrid g = line(8);
    h.surface("surface t(float a = 1, b = 2) { Ci = 0;\n"
              "  if (u > 0.5) { uniform float x = a + b; uniform float y = x * 0.25; Ci = y; } }",
              g);
    EXPECT_EQ(h.diag.errorCount(), 0) << h.messages();
    for (size_t i = 0; i < g.Ci.size(); ++i) expectNear(g.Ci[i], Vec3(g.u[i] > 0.5f ? 0.75f : 0.0f), 0);
    EXPECT_TRUE(h.sys.compileSource("float half(uniform float w, e) { uniform float hw = w / 2;\n"
                                    "  uniform float we = max(e, -hw); return hw + we; }\n"
                                    "light l(float width = 1, edge = 0.1) { solar() { Cl = half(width, edge); } }",
                                    "l.sl"))
        << h.messages();
    // A varying value still may not reach one, however many steps away.
    h.expectRefused("surface t() { if (u > 0.5) { uniform float x = 1; float v = x * u;\n"
                    "  uniform float y = v + x; } }",
                    "cannot assign a varying value to uniform variable 'y'");
}

TEST(Compat, StringConditionalOperatorWithAUniformCondition) {
    // `string space = (which > 0.5) ? "world" : "object";` (adapted from
    // Advanced RenderMan's texdust): both peers compile it. Strings are
    // uniform, so the condition must be.
    Harness h;
    ShadingGrid g = line(4);
    h.surface("surface t(float which = 1) { string a = which > 0.5 ? \"yes\" : \"no\";\n"
              "  string b = which > 2 ? \"yes\" : \"no\";\n"
              "  Ci = color(match(\"yes\", a), match(\"no\", b), match(\"no\", a)); }",
              g);
    EXPECT_EQ(h.diag.errorCount(), 0) << h.messages();
    for (size_t i = 0; i < g.Ci.size(); ++i) expectNear(g.Ci[i], Vec3(1, 1, 0), 0);
    h.expectRefused("surface t() { string a = u > 0.5 ? \"yes\" : \"no\"; }",
                    "'?:' between strings needs a uniform condition");
}

TEST(Compat, StringsChosenInsideAVaryingIf) {
    // Inside an if on a varying condition, a string ?: whose condition is
    // uniform (its register stored varying there) was refused; both peers
    // compile it. A string given a value that differs between points, or
    // stored in two places one of them under such an if, holds the last
    // value stored on every point (strings are uniform, as in Pixie): said
    // by a warning now, as is not a string local to the branch.
    Harness h;
    ShadingGrid g = line(4);  // u = 0, 1/3, 2/3, 1
    h.surface("surface t() { uniform float a = 1; Ci = 0.2;\n"
              "  if (u > 0.5) { string q = (a > 2) ? \"x\" : \"y\"; string l = \"k\"; Ci = (q == \"y\" && l == \"k\") ? 0.8 : 0.5; } }",
              g);
    EXPECT_EQ(h.diag.errorCount(), 0) << h.messages();
    EXPECT_EQ(h.diag.warningCount(), 0) << h.messages();
    for (size_t i = 0; i < g.Ci.size(); ++i) expectNear(g.Ci[i], Vec3(g.u[i] > 0.5f ? 0.8f : 0.2f), 1e-6f);
    for (const char* differs : {"surface t() { string q = \"a\"; if (u > 0.5) q = \"b\"; Ci = (q == \"b\") ? 1 : 0; }",
                                "surface t() { string q = format(\"%.0f\", u); Ci = (q == \"1\") ? 1 : 0; }"}) {
        Harness w;
        ShadingGrid wg = line(4);
        w.surface(differs, wg);
        EXPECT_EQ(w.diag.warningCount(), 1) << differs;
        EXPECT_NE(w.messages().find("string 'q' is given"), std::string::npos) << w.messages();
    }
}

TEST(Compat, OneVariableForAnInputAndAnOutput) {
    // f(r, r) with f(float a; output float b) { b = a * 2; }: the input
    // reads r's value at the call and the output writes r, as in Pixie and
    // Aqsis (0.4). umbra refused it ("'b' is not an output parameter").
    // Also from inside a function, with the outer output given twice.
    Harness h;
    ShadingGrid g = line(2);
    h.surface("void twice(float a; output float b) { b = a * 2; }\n"
              "void step(output float x) { twice(x, x); x += 1; twice(x, x); }\n"
              "surface t() { float r = 0.2, q = 0.5; twice(r, r); step(q); Ci = color(r, q, 0); }",
              g);
    EXPECT_EQ(h.diag.errorCount(), 0) << h.messages();
    expectNear(g.Ci[0], Vec3(0.4f, 4.0f, 0));  // q: 0.5 -> 1 -> 2 -> 4
}

TEST(Compat, AFloatIsPromotedInDotAndCrossProducts) {
    // RI Spec 3.2 section 13.1: a float with a triple in a binary operator
    // is duplicated into each component; umbra refused '^' and '.' so.
    Harness h;
    ShadingGrid g = line(2);
    h.surface("surface t() { vector c = vector(1, 0, 0) ^ 2; float d = vector(1, 2, 3) . 0.1, e = 2 . vector(1, 1, 1);\n"
              "  Ci = color(ycomp(c), zcomp(c), d + e); }",
              g);
    EXPECT_EQ(h.diag.errorCount(), 0) << h.messages();
    expectNear(g.Ci[0], Vec3(-2, 2, 6.6f), 1e-5f);
}

TEST(Compat, ClampTestsTheMinimumFirst) {
    // RI Spec 3.2: clamp(a, min, max) is min if a is below min, else max if
    // a is above max, else a; a min above max (ARMan's smoke clamps its
    // last ray-march step so) gives min below min and max elsewhere, as in
    // Pixie and Aqsis. umbra gave max everywhere, and smoke's march stepped
    // by 0 until the loop limit.
    Harness h;
    ShadingGrid g = line(11);
    h.surface("surface t() { Ci = color(clamp(u, 0.5, 0.2), clamp(u, 0.2, 0.5), 0);\n"
              "  Oi = clamp(color(u, u, u), color(0.5, 0.2, 0.3), color(0.2, 0.5, 0.3)); }",
              g);
    auto spec = [](float a, float lo, float hi) { return a < lo ? lo : (a > hi ? hi : a); };
    for (size_t i = 0; i < g.Ci.size(); ++i) {
        const float u = g.u[i];
        expectNear(g.Ci[i], Vec3(spec(u, 0.5f, 0.2f), spec(u, 0.2f, 0.5f), 0), 0);
        expectNear(g.Oi[i], Vec3(spec(u, 0.5f, 0.2f), spec(u, 0.2f, 0.5f), 0.3f), 0);
    }
}

TEST(Compat, IlluminanceGathersAtThePositionItIsGiven) {
    // illuminance(position) runs the lights for that position (RI Spec
    // 3.2; Ps is the light's "position being illuminated"). umbra ran them
    // once per grid, at the first loop's position, and gave every later
    // loop those results: a second position, or a volume's ray-march steps
    // (ARMan's smoke), saw the first one's light.
    Harness h;
    auto light = h.instance("light l() { illuminate(point(0, 0, 0)) { Cl = color(1 / (L . L)); } }");
    ASSERT_TRUE(light);
    ShadingGrid g = line(5);
    h.surface("surface t() { color a = 0, b = 0, c = 0;\n"
              "  illuminance(P) { a += Cl; }\n"
              "  illuminance(P + vector(0, 0, 1)) { b += Cl; }\n"
              "  float k; for (k = 0; k < 3; k += 1) { illuminance(P + vector(0, 0, k)) { c += Cl; } }\n"
              "  Ci = color(comp(a, 0), comp(b, 0), comp(c, 0)); }",
              g, {light.get()});
    EXPECT_EQ(h.diag.errorCount(), 0) << h.messages();
    for (size_t i = 0; i < g.Ci.size(); ++i) {
        const Vec3 P = g.P[i];
        auto at = [&](float k) { const Vec3 q = P + Vec3(0, 0, k); return 1 / dot(q, q); };
        expectNear(g.Ci[i], Vec3(at(0), at(1), at(0) + at(1) + at(2)), 1e-5f);
    }
}

TEST(Compat, PowOfAColorAndAFloat) {
    Harness h;
    ShadingGrid g = line();
    for (size_t i = 0; i < g.Cs.size(); ++i) g.Cs[i] = Vec3(g.u[i], 0.5f, 2 * g.u[i] - 1);
    h.surface("surface t(float e = 2.5) { Ci = pow(Cs, e); Oi = pow(Cs, 2); }", g);
    for (size_t i = 0; i < g.Cs.size(); ++i) {
        const float u = g.u[i], z = 2 * u - 1;
        // A negative base with a fractional exponent has no real power: 0.
        expectNear(g.Ci[i], Vec3(std::pow(u, 2.5f), std::pow(0.5f, 2.5f), z < 0 ? 0.f : std::pow(z, 2.5f)), 1e-5f);
        expectNear(g.Oi[i], Vec3(u * u, 0.25f, z * z), 1e-5f);
    }
}

TEST(Compat, FilterStepFiltersEachRiFilterOverTheFootprint) {
    // du = 0.1: s changes by 0.1 per micropolygon, the footprint w. Width 3
    // (w = 0.3) puts points inside every filter's support, an edge off the
    // points shows a filter that is not centred.
    for (const std::string filter : {"box", "triangle", "catmull-rom", "gaussian"}) {
        Harness h;
        ShadingGrid g = line();
        // The name comes through a parameter, as a probe scene passes it.
        h.surface("surface t(string f = \"" + filter + "\") {\n"
                  "  Ci = color(filterstep(0.53, s, \"filter\", f, \"width\", 3),\n"
                  "             filterstep(0.53, s, \"swidth\", 2, \"filter\", f),\n"
                  "             filterstep(0.53, s, \"filter\", f));\n"
                  "  Oi = color(filterstep(0.53, s - 0.1, s + 0.2, \"filter\", f),\n"
                  "             filterstep(0.53, s + 0.2, s - 0.1, \"filter\", f, \"width\", 0.5), 0);\n"
                  "}\n",
                  g);
        int ramp = 0;
        for (size_t i = 0; i < g.s.size(); ++i) {
            const float s = g.s[i];
            EXPECT_NEAR(g.Ci[i].x, filteredStep(filter, 0.53f, s, 0.3f), 2e-4f) << filter << " s = " << s;
            EXPECT_NEAR(g.Ci[i].y, filteredStep(filter, 0.53f, s, 0.2f), 2e-4f) << filter << " s = " << s;
            EXPECT_NEAR(g.Ci[i].z, filteredStep(filter, 0.53f, s, 0.1f), 2e-4f) << filter << " s = " << s;
            // [s1, s2] in either order: centred between them, w = |s2 - s1|.
            EXPECT_NEAR(g.Oi[i].x, filteredStep(filter, 0.53f, s + 0.05f, 0.3f), 2e-4f) << filter << " s = " << s;
            EXPECT_NEAR(g.Oi[i].y, filteredStep(filter, 0.53f, s + 0.05f, 0.15f), 2e-4f) << filter << " s = " << s;
            if (g.Ci[i].x > 0.01f && g.Ci[i].x < 0.99f) ++ramp;
        }
        EXPECT_GE(ramp, 2) << filter << ": the points must see the ramp, not only its ends";
        EXPECT_EQ(h.diag.warningCount(), 0) << h.messages();
    }
}

TEST(Compat, FilterStepDefaultsToCatmullRomAndWarnsOnceAboutUnknownNames) {
    Harness h;
    ShadingGrid g = line();
    // The RI Spec's default filter is catmull-rom.
    h.surface("surface t() { Ci = color(filterstep(0.53, s, \"width\", 3), filterstep(0.53, s, s + 0.3), 0); }", g);
    for (size_t i = 0; i < g.s.size(); ++i) {
        EXPECT_NEAR(g.Ci[i].x, filteredStep("catmull-rom", 0.53f, g.s[i], 0.3f), 2e-4f) << "s = " << g.s[i];
        EXPECT_NEAR(g.Ci[i].y, filteredStep("catmull-rom", 0.53f, g.s[i] + 0.15f, 0.3f), 2e-4f) << "s = " << g.s[i];
    }
    EXPECT_EQ(h.diag.warningCount(), 0) << h.messages();
    // An unknown filter warns once (not per point, not per grid) and is
    // taken as catmull-rom; an unknown parameter warns and is ignored.
    const char* src = "surface t() { Ci = filterstep(0.53, s, \"filter\", \"mitchell\", \"width\", 3); }";
    h.surface(src, g);
    h.surface(src, g);
    EXPECT_EQ(h.diag.warningCount(), 1) << h.messages();
    EXPECT_NE(h.messages().find("unknown filterstep filter 'mitchell'"), std::string::npos) << h.messages();
    for (size_t i = 0; i < g.s.size(); ++i)
        EXPECT_NEAR(g.Ci[i].x, filteredStep("catmull-rom", 0.53f, g.s[i], 0.3f), 2e-4f) << "s = " << g.s[i];
    h.surface("surface t() { Ci = filterstep(0.5, s, \"filter\", \"gaussian\", \"sharpness\", 2); }", g);
    EXPECT_EQ(h.diag.warningCount(), 2) << h.messages();
    EXPECT_NE(h.messages().find("unknown filterstep parameter 'sharpness'"), std::string::npos) << h.messages();
    // A footprint of zero (s the same everywhere) is the plain step.
    h.surface("surface t() { Ci = color(filterstep(0.5, 0.7), filterstep(0.5, 0.3), filterstep(0.5, 0.2, 0.2)); }", g);
    for (size_t i = 0; i < g.s.size(); ++i) expectNear(g.Ci[i], Vec3(1, 0, 0), 0);
}

TEST(Compat, TransformFromANamedSpaceByAMatrix) {
    Harness h;
    h.svc.spaces["world"] = Mat4::translate(Vec3(10, 0, 0));  // currentFromWorld
    ShadingGrid g = line(4);
    h.surface("surface t() {\n"
              "  matrix m = matrix(2,0,0,0, 0,3,0,0, 0,0,4,0, 1,1,1,1);\n"
              "  point p = point(1 + s, 2, 3);\n"
              "  Ci = color(transform(\"world\", m, p));\n"
              "  Oi = color(vtransform(\"world\", m, vector p));\n"
              "  Cs = color(ntransform(\"world\", m, normal p));\n"
              "}\n",
              g);
    for (size_t i = 0; i < 4; ++i) {
        const float x = 1 + g.s[i];
        // From "world" to "current" (translated by 10 in x), then by m.
        expectNear(g.Ci[i], Vec3(2 * (x + 10) + 1, 3 * 2 + 1, 4 * 3 + 1), 1e-4f);
        expectNear(g.Oi[i], Vec3(2 * x, 6, 12), 1e-4f);
        expectNear(g.Cs[i], Vec3(x / 2, 2.f / 3, 3.f / 4), 1e-5f);
    }
}

TEST(Compat, ArrayLengthShaderNameIncidentAndOpposite) {
    Harness h;
    ShadingGrid g = line(3);
    h.surface("surface named(float k[3] = {1, 2, 3}) {\n"
              "  float a[5]; float o = 7 + s;\n"
              "  float f = incident(\"x\", o) + opposite(\"y\", o);\n"
              "  Ci = color(arraylength(k) * 10 + arraylength(a), f + o,\n"
              "             shadername() == \"named\" && shadername(\"surface\") == \"named\" &&\n"
              "             shadername(\"displacement\") == \"\" ? 1 : 0);\n"
              "}\n",
              g);
    // No interior or exterior volumes: incident() and opposite() find
    // nothing and leave their variable alone.
    for (size_t i = 0; i < 3; ++i) expectNear(g.Ci[i], Vec3(35, 7 + g.s[i], 1));
    EXPECT_FALSE(h.sys.compileSource("surface t() { float x = 1; Ci = arraylength(x); }", "t.sl"));
    EXPECT_NE(h.messages().find("arraylength() expects one array"), std::string::npos) << h.messages();
}

TEST(Compat, SpecularBrdfTakesLNVAndRoughness) {
    Harness h;
    ShadingGrid g = line(5);
    h.surface("surface t() {\n"
              "  vector Lv = vector(s, 1, -1); normal Nn = normal(0, 0.2, -1); vector V = normalize(vector(0, s, -1));\n"
              "  Ci = specularbrdf(Lv, Nn, V, 0.1 + s);\n"
              "}\n",
              g);
    for (size_t i = 0; i < 5; ++i) {
        const float s = g.s[i];
        const Vec3 H = normalize(normalize(Vec3(s, 1, -1)) + normalize(Vec3(0, s, -1)));
        const float want = std::pow(std::max(0.f, dot(normalize(Vec3(0, 0.2f, -1)), H)), 8 / (0.1f + s));  // PRMan's 8/roughness
        expectNear(g.Ci[i], Vec3(want), 1e-5f);
    }
}

// A light shader reads the surface's I and N (Pixie's ambient lights do).
TEST(Compat, LightShadersReadTheSurfacesIAndN) {
    Harness h;
    auto light = h.instance("light l() { illuminate(point(0, 0, 0)) { Cl = color(I) + 10 * color(N); } }");
    ASSERT_TRUE(light);
    ShadingGrid g = line(5);
    for (size_t i = 0; i < 5; ++i) {
        g.I[i] = Vec3(g.s[i], 1, 2 * g.s[i]);
        g.N[i] = Vec3(0, g.s[i], -1);
    }
    h.surface("surface t() { Ci = 0; illuminance(P) { Ci += Cl; } }", g, {light.get()});
    for (size_t i = 0; i < 5; ++i) expectNear(g.Ci[i], g.I[i] + g.N[i] * 10.f, 1e-5f);
}

TEST(Compat, ImagerAndVolumeGlobals) {
    Harness h;
    EXPECT_TRUE(h.sys.compileSource("imager i() { Ci += (1 - alpha) * color(s, t, xcomp(P)); Oi = 1; alpha = 1; }", "i.sl"))
        << h.messages();
    EXPECT_TRUE(h.sys.compileSource("volume v() { Ci = mix(Ci, color 1, 1 - exp(-length(I))); Oi = Oi; }", "v.sl"))
        << h.messages();
    // alpha belongs to imagers: other shaders do not see it.
    EXPECT_FALSE(h.sys.compileSource("surface t() { Ci = alpha; }", "t.sl"));
}

TEST(Compat, ImagerSeesEachPixelAndRewritesColourAndAlpha) {
    Harness h;
    auto imager = h.instance("imager bg(color bgcolor = color(0.2, 0.4, 0.6)) {\n"
                             "  Ci += (1 - alpha) * bgcolor + color(xcomp(P), ycomp(P), s + t) * 0.001;\n"
                             "  Oi = 1; alpha = 1 - alpha * 0.5;\n"
                             "}\n");
    ASSERT_TRUE(imager);
    ShadingGrid g;
    g.resize(4, 1);
    g.alpha.resize(4);
    for (size_t i = 0; i < 4; ++i) {
        g.P[i] = Vec3(float(i) + 0.5f, 7.5f, 0);
        g.s[i] = g.P[i].x;
        g.t[i] = g.P[i].y;
        g.alpha[i] = float(i) / 3;
        g.Ci[i] = Vec3(0.1f, 0, 0) * g.alpha[i];
        g.Oi[i] = Vec3(g.alpha[i]);
    }
    h.sys.shadeImager(g, *imager, h.svc);
    for (size_t i = 0; i < 4; ++i) {
        const float a = float(i) / 3, x = float(i) + 0.5f;
        expectNear(g.Ci[i], Vec3(0.1f * a, 0, 0) + Vec3(0.2f, 0.4f, 0.6f) * (1 - a) + Vec3(x, 7.5f, x + 7.5f) * 0.001f,
                   1e-5f);
        expectNear(g.Oi[i], Vec3(1));
        EXPECT_NEAR(g.alpha[i], 1 - 0.5f * a, 1e-6f);
    }
}

// #include looks beside the including file first, then along the path.
TEST(Compat, IncludeSearchesBesideTheFileThenThePath) {
    namespace fs = std::filesystem;
    const fs::path root = fs::temp_directory_path() / "umbra_compat_include_test";
    fs::remove_all(root);
    fs::create_directories(root / "own");
    fs::create_directories(root / "lib");
    std::ofstream(root / "own" / "a.h") << "#define A 1\n";
    std::ofstream(root / "lib" / "a.h") << "#define A 2\n";
    std::ofstream(root / "lib" / "b.h") << "#define B 3\n";
    std::ofstream(root / "own" / "inc.sl") << "#include \"a.h\"\n#include \"b.h\"\nsurface inc() { Ci = A * 10 + B; }\n";
    Harness h;
    h.sys.setSearchPath({(root / "lib").string()});
    auto sh = h.sys.compile((root / "own" / "inc.sl").string());
    ASSERT_TRUE(sh) << h.messages();
    scene::ShaderRecord rec;
    auto inst = h.sys.instantiate(sh, rec);
    ShadingGrid g = line(2);
    ShadeRequest req;
    req.surface = inst.get();
    h.sys.shade(g, req, h.svc);
    expectNear(g.Ci[0], Vec3(13));
    // `umbra slc -I DIR` searches the same way.
    Diagnostics diag;
    diag.setSink([](const Diagnostic&) {});
    EXPECT_TRUE(compileFile((root / "own" / "inc.sl").string(), {(root / "lib").string()}, diag, nullptr));
    EXPECT_FALSE(compileFile((root / "own" / "inc.sl").string(), {}, diag, nullptr));  // b.h is on the path only
    fs::remove_all(root);
}

// Compilers name their output after the shader (stripes-v2.sl declaring
// `surface stripes` gives stripes.slo, .slx, .sdr), and scenes name it so:
// the source on the path that declares it is found whatever its file name.
TEST(Compat, AShaderIsFoundByItsDeclaredName) {
    namespace fs = std::filesystem;
    const fs::path root = fs::temp_directory_path() / "umbra_compat_declared_name_test";
    fs::remove_all(root);
    fs::create_directories(root);
    std::ofstream(root / "stripes-v2.sl") << "/* surface wrong() */\nsurface\n  stripes(float k = 3) { Ci = k; }\n";
    std::ofstream(root / "other.sl") << "light stripesx() { }\n";
    Harness h;
    h.sys.setSearchPath({root.string()});
    auto sh = h.sys.find("stripes", FileLoc());
    ASSERT_TRUE(sh) << h.messages();
    EXPECT_EQ(sh->name(), "stripes");
    EXPECT_FALSE(h.sys.find("nosuch", FileLoc()));
    EXPECT_FALSE(h.sys.find("stripes(", FileLoc()));  // not a name: no search, no regex error
    // The file of a name declaring another shader is not that shader:
    // red.sl declaring `surface green` (a course's bump.sl declaring
    // emboss) gives green.slo in every compiler, and Pixie and Aqsis do not
    // find "red"; umbra ran green under the name red.
    std::ofstream(root / "red.sl") << "surface green() { Ci = color(0, 1, 0); }\n";
    std::ofstream(root / "made.sl") << "#define NAME made\nsurface NAME() { Ci = 1; }\n";
    EXPECT_FALSE(h.sys.find("red", FileLoc()));
    EXPECT_NE(h.messages().find("cannot find shader 'red' (red.sl declares 'green'; searched"), std::string::npos)
        << h.messages();
    auto green = h.sys.find("green", FileLoc());
    ASSERT_TRUE(green) << h.messages();
    EXPECT_EQ(green->name(), "green");
    // A declaration made by a macro is not seen: the file of the name is taken.
    auto made = h.sys.find("made", FileLoc());
    ASSERT_TRUE(made) << h.messages();
    EXPECT_EQ(made->name(), "made");
    fs::remove_all(root);
}

// Functions of one name that differ in their parameters' types: Gritz's
// noises.h (BMRT, Advanced RenderMan) defines fBm and turbulence for a float
// and for a point. Pixie's and Aqsis's compilers pick one by the
// arguments; umbra refused the shader ("defined twice").
TEST(Compat, UserFunctionsOverloadedByParameterTypes) {
    Harness h;
    ShadingGrid g = line(2);
    h.surface("float twice(float x) { return 2 * x; }\n"
              "float twice(point p) { return 2 * xcomp(p) + 10; }\n"
              "float twice(color c, float k) { return k * comp(c, 1); }\n"
              "surface t() {\n"
              "  point q = point(0.1, 0, 0); float f = 0.25;\n"
              "  Ci = color(twice(f), twice(q), twice(color(0, 3, 0), 2));\n"
              "  Oi = color(twice(0.5), twice(P + point(1, 0, 0)) - 2 * xcomp(P), twice(s * 0 + 1));\n"
              "}",
              g);
    for (int i = 0; i < 2; ++i) {
        expectNear(g.Ci[size_t(i)], Vec3(0.5f, 10.2f, 6));
        expectNear(g.Oi[size_t(i)], Vec3(1, 12, 2));
    }
    h.expectRefused("float twice(float x) { return 2 * x; }\nfloat twice(float y) { return y; }\n"
                    "surface t() { Ci = twice(1); }",
                    "function 'twice' is defined twice");
    h.expectRefused("float twice(float x) { return 2 * x; }\nfloat twice(point p) { return 1; }\n"
                    "surface t() { Ci = twice(\"a\"); }",
                    "no version of function 'twice' takes these arguments");
}

// An unknown colour space in ctransform() was taken as rgb without a word
// (Pixie warns); a colour cast already warned.
TEST(Compat, CtransformWarnsOfAnUnknownColourSpace) {
    Harness h;
    ShadingGrid g = line(2);
    h.surface("surface t() { Ci = ctransform(\"foo\", color(0.2, 0.4, 0.6)) + ctransform(\"hsv\", \"rgb\", color(0, 0, 0)); }", g);
    expectNear(g.Ci[0], Vec3(0.2f, 0.4f, 0.6f));
    EXPECT_NE(h.messages().find("unknown color space 'foo'"), std::string::npos) << h.messages();
    EXPECT_EQ(h.messages().find("unknown color space 'hsv'"), std::string::npos) << h.messages();
}

TEST(Compat, MixedTypeFormsOfArithmeticCastsAndComparisons) {
    Harness h;
    ShadingGrid g = line(5);
    h.surface("surface t() {\n"
              "  color c = color(s, 0.5, 1);\n"
              "  color m = mix(color(0, 0.5, 1), color(1), c);\n"
              "  float eq = (c == color(s, 0.5, 1) ? 1 : 0) + (point(c) != point(s, 0.5, 1) ? 10 : 0);\n"
              "  Ci = m * 2 + 0.5 * color(s) + color(eq, 0, 0) - c / 2;\n"
              "  Oi = color(vector(c)) + color(normal(1));\n"
              "}\n",
              g);
    for (size_t i = 0; i < 5; ++i) {
        const float s = g.s[i];
        const Vec3 c(s, 0.5f, 1);
        const Vec3 m = Vec3(0, 0.5f, 1) + (Vec3(1) - Vec3(0, 0.5f, 1)) * c;
        expectNear(g.Ci[i], m * 2.f + Vec3(0.5f * s) + Vec3(1, 0, 0) - c * 0.5f, 1e-5f);
        expectNear(g.Oi[i], c + Vec3(1), 1e-6f);
    }
}

// Cl set by a function the illuminate() body calls, and a global
// written through `extern` inside a function.
TEST(Compat, LightFunctionsSetClAndExternReachesGlobals) {
    Harness h;
    auto light = h.instance("void shine(float k) { extern color Cl; Cl = color(k, 2 * k, xcomp(Ps)); }\n"
                            "light l(float k = 0.5) { illuminate(point(0, 0, 0)) { shine(k); } }\n");
    ASSERT_TRUE(light);
    ShadingGrid g = line(5);
    h.surface("void paint(color c) { extern color Ci; Ci = c; }\n"
              "surface t() { color acc = 0; illuminance(P) { acc += Cl * (normalize(L) . vector(0, 0, -1)); }\n"
              "  paint(acc); }\n",
              g, {light.get()});
    for (size_t i = 0; i < 5; ++i) {
        const Vec3 P = g.P[i];
        // L points from the surface to the light at the origin.
        const float cosine = dot(normalize(-P), Vec3(0, 0, -1));
        expectNear(g.Ci[i], Vec3(0.5f, 1.0f, P.x) * cosine, 1e-5f);
    }
}

// A volume shader runs as the atmosphere after the surface, on its Ci/Oi.
TEST(Compat, VolumeShaderGathersTheLightsInIlluminance) {
    // A lit atmosphere (Advanced RenderMan's smoke, BMRT's noisysmoke)
    // reads Cl and L inside illuminance (RI Spec 3.2 section 13.3); umbra's
    // compiler did not let a volume shader see them.
    Harness h;
    auto surf = h.instance("surface t() { Ci = color(s, 0, 1); Oi = 1; }");
    auto light = h.instance("light l() { illuminate(point(0, 0, 0)) { Cl = color(0, 1, 0) / (L . L); } }");
    auto vol = h.instance("volume v() { color li = 0; vector dir = 0;\n"
                          "  illuminance(P) { li += Cl; dir += L; }\n"
                          "  Ci = mix(Ci, li, 0.5); Oi = color(dir); }\n");
    ASSERT_TRUE(surf && light && vol) << h.messages();
    ShadingGrid g = makeGrid(5, 1, [](float u, float) { return Vec3(u, 0, 1 + 3 * u); });
    ShadeRequest req;
    req.surface = surf.get();
    req.atmosphere = vol.get();
    req.lights = {light.get()};
    h.sys.shade(g, req, h.svc);
    for (size_t i = 0; i < 5; ++i) {
        const Vec3 P = g.P[i], c(g.s[i], 0, 1);
        expectNear(g.Ci[i], (c + Vec3(0, 1 / dot(P, P), 0)) * 0.5f, 1e-5f);
        expectNear(g.Oi[i], -P, 1e-5f);  // L points from the shaded point to the light
    }
}

TEST(Compat, VolumeShaderRunsAsAtmosphere) {
    Harness h;
    auto surf = h.instance("surface t() { Ci = color(s, 0, 1); Oi = 1; }");
    auto vol = h.instance("volume v(float d = 2; color fogc = color(0.5, 0.5, 0.5)) {\n"
                          "  float f = 1 - exp(-length(I) / d);\n"
                          "  Ci = mix(Ci, fogc, f); Oi = mix(Oi, color 1, f);\n"
                          "}\n");
    ASSERT_TRUE(surf && vol);
    ShadingGrid g = makeGrid(5, 1, [](float u, float) { return Vec3(u, 0, 1 + 3 * u); });
    ShadeRequest req;
    req.surface = surf.get();
    req.atmosphere = vol.get();
    h.sys.shade(g, req, h.svc);
    for (size_t i = 0; i < 5; ++i) {
        const float f = 1 - std::exp(-length(g.I[i]) / 2);
        const Vec3 c(g.s[i], 0, 1);
        expectNear(g.Ci[i], c + (Vec3(0.5f) - c) * f, 1e-5f);
        expectNear(g.Oi[i], Vec3(1), 1e-6f);
    }
}
