// User functions: their inlining, `return` (early, varying, of calls, in
// loops and lighting loops), output parameters and globals read inside
// them. Each shader is checked against the same sum written here in C++,
// on grids where the points differ, so a point that runs under the wrong
// run mask shows.

#include "shading_test_util.h"

#include <algorithm>
#include <cmath>

using namespace umbra;
using namespace umbra::shading;
using namespace umbra::shading::testing;

namespace {

/// Six points at z = 1 around the origin (where the test lights stand),
/// with normals that lean differently at each point; some face away from
/// the origin.
ShadingGrid leaningGrid() {
    ShadingGrid g = makeGrid(6, 1, [](float u, float) { return Vec3(2 * u - 1, 0.5f * u, 1); });
    for (size_t i = 0; i < 6; ++i) {
        const float u = g.u[i];
        g.N[i] = g.Ng[i] = normalize(Vec3(u - 0.5f, 0.2f, i % 3 == 2 ? 1.0f : -1.0f));
    }
    return g;
}

/// The diffuse sum of a point light of colour `cl` at the origin, over the
/// hemisphere about faceforward(normalize(N), I), as an illuminance loop
/// about that normal with angle PI/2 computes it.
Vec3 pointLightDiffuse(const ShadingGrid& g, size_t i, const Vec3& cl) {
    Vec3 Nn = normalize(g.N[i]);
    if (dot(g.I[i], Nn) > 0) Nn = -Nn;  // faceforward(Nn, I)
    const Vec3 L = -g.P[i];              // from the surface to the light
    const float c = dot(normalize(L), Nn);
    if (c < 0) return Vec3(0.f);
    return cl * c;
}

const char* kPointLight = "light pt(color c = color(1, 0.5, 0.25)) { illuminate(point(0, 0, 0)) Cl = c; }";

}  // namespace

// The report: returning a call to a function that holds an illuminance loop.
TEST(FunctionReturn, ReturnOfACallHoldingIlluminance) {
    Harness h;
    h.svc.spaces["world"] = Mat4::identity();
    auto light = h.instance(kPointLight);
    const std::string lib =
        "color lit(normal Nf) { color c = 0; illuminance(P, Nf, PI/2) { c += Cl * (normalize(L).Nf); } return c; }\n";
    for (const char* direct : {"color direct(normal Nf) { return lit(Nf); }",
                               "color direct(normal Nf) { color r = lit(Nf); return r; }"}) {
        ShadingGrid g = leaningGrid();
        h.surface(lib + direct + "\nsurface s() { normal Nf = faceforward(normalize(N), I); Ci = direct(Nf); Oi = 1; }", g,
                  {light.get()});
        for (size_t i = 0; i < 6; ++i) expectNear(g.Ci[i], pointLightDiffuse(g, i, Vec3(1, 0.5f, 0.25f)), 1e-5f);
    }
}

namespace {

/// Runs a surface shader over a line of n points (P = (u, 0, 1), u = i/(n-1))
/// and returns the grid.
ShadingGrid runLine(Harness& h, const std::string& src, int n = 11) {
    ShadingGrid g = makeGrid(n, 1, [](float u, float) { return Vec3(u, 0, 1); });
    h.surface(src, g);
    return g;
}

}  // namespace

TEST(FunctionReturn, CallsNestedThreeDeepAndReturnedDirectly) {
    Harness h;
    ShadingGrid g = runLine(h,
                            "float a(float x) { return x * x + 1; }\n"
                            "float b(float x) { return a(x) * 2 + a(x + 1); }\n"
                            "float c(float x) { return b(a(x)) - x; }\n"
                            "color tri(float x) { return color(c(x), b(x), a(x)); }\n"
                            "surface s() { Ci = tri(u); Oi = color(c(u), b(c(u)), a(b(c(u)))); }");
    auto a = [](float x) { return x * x + 1; };
    auto b = [&](float x) { return a(x) * 2 + a(x + 1); };
    auto c = [&](float x) { return b(a(x)) - x; };
    for (size_t i = 0; i < g.Ci.size(); ++i) {
        const float u = g.u[i];
        expectNear(g.Ci[i], Vec3(c(u), b(u), a(u)), 1e-3f);
        const Vec3 o(c(u), b(c(u)), a(b(c(u))));  // up to about 1e6: compare relative to the size
        expectNear(g.Oi[i], o, 1e-5f * std::max({1.f, o.x, o.y, o.z}));
    }
}

TEST(FunctionReturn, CallsAsArgumentsOfCallsAndBuiltins) {
    Harness h;
    ShadingGrid g = runLine(h,
                            "float sq(float x) { return x * x; }\n"
                            "float add(float x, y) { return x + y; }\n"
                            "float pick(float x, y) { if (x > y) return x; return y; }\n"
                            "surface s() {\n"
                            "  Ci = color(add(sq(u), sq(1 - u)), pick(sq(u), add(u, -0.25)), mix(sq(u), add(u, 1), pick(u, 0.5)));\n"
                            "  Oi = color(u > 0.5 ? pick(u, sq(u)) : add(sq(u), 2), sqrt(add(sq(u), sq(2))), sq(pick(u, 1 - u)));\n"
                            "}");
    for (size_t i = 0; i < g.Ci.size(); ++i) {
        const float u = g.u[i];
        auto pick = [](float x, float y) { return x > y ? x : y; };
        const float m = pick(u, 0.5f);
        expectNear(g.Ci[i], Vec3(u * u + (1 - u) * (1 - u), pick(u * u, u - 0.25f), u * u * (1 - m) + (u + 1) * m));
        expectNear(g.Oi[i], Vec3(u > 0.5f ? pick(u, u * u) : u * u + 2, std::sqrt(u * u + 4), pick(u, 1 - u) * pick(u, 1 - u)));
    }
}

TEST(FunctionReturn, EarlyReturnsUnderVaryingConditions) {
    // Some points return at each of the returns; the rest go on, and what
    // they do afterwards must not reach the points that have returned.
    Harness h;
    ShadingGrid g = runLine(h,
                            "float piece(float x; output float path) {\n"
                            "  path = 0;\n"
                            "  if (x < 0.3) { path = 1; return x * 10; }\n"
                            "  path = 2;\n"
                            "  if (x > 0.7) {\n"
                            "    if (x > 0.85) { path = 3; return -1; }\n"
                            "    path = 4;\n"
                            "    return x + 100;\n"
                            "  } else if (x < 0.45) {\n"
                            "    path += 20;\n"
                            "  } else {\n"
                            "    path += 40;\n"
                            "    return 7;\n"
                            "  }\n"
                            "  path += 10;\n"
                            "  return x - 5;\n"
                            "}\n"
                            "float constant() { if (u > 0.5) return 1; return 2; }\n"
                            "void paint() { Oi = 1; if (u < 0.5) return; Oi = color(u, 2 * u, 3); }\n"
                            "surface s() { float p; float r = piece(u, p); Ci = color(r, p, constant()); paint(); }");
    for (size_t i = 0; i < g.Ci.size(); ++i) {
        const float x = g.u[i];
        float path = 0, r;
        if (x < 0.3f) {
            path = 1;
            r = x * 10;
        } else if (x > 0.7f) {
            path = x > 0.85f ? 3 : 4;
            r = x > 0.85f ? -1 : x + 100;
        } else if (x < 0.45f) {
            path = 2 + 20 + 10;
            r = x - 5;
        } else {
            path = 2 + 40;
            r = 7;
        }
        expectNear(g.Ci[i], Vec3(r, path, x > 0.5f ? 1 : 2), 1e-4f);
        expectNear(g.Oi[i], x < 0.5f ? Vec3(1, 1, 1) : Vec3(x, 2 * x, 3));
    }
}

TEST(FunctionReturn, ReturnOfCallsFromVaryingBranches) {
    // Each branch returns a call whose own body returns early.
    Harness h;
    ShadingGrid g = runLine(h,
                            "float lo(float x) { if (x < 0.1) return -10; return x * 2; }\n"
                            "float hi(float x) { if (x > 0.9) return 10; float y = x * x; return y + lo(x); }\n"
                            "float both(float x) { if (x > 0.5) return hi(x); else return lo(x) + hi(x) * lo(x + 0.05); }\n"
                            "surface s() { Ci = color(both(u), both(1 - u), both(u) - both(1 - u)); }");
    auto lo = [](float x) { return x < 0.1f ? -10.f : x * 2; };
    auto hi = [&](float x) { return x > 0.9f ? 10.f : x * x + lo(x); };
    auto both = [&](float x) { return x > 0.5f ? hi(x) : lo(x) + hi(x) * lo(x + 0.05f); };
    for (size_t i = 0; i < g.Ci.size(); ++i) {
        const float u = g.u[i];
        expectNear(g.Ci[i], Vec3(both(u), both(1 - u), both(u) - both(1 - u)), 1e-4f);
    }
}

TEST(FunctionReturn, ReturnFromInsideLoops) {
    Harness h;
    ShadingGrid g = runLine(h,
                            "float firstFor(float lim) {\n"
                            "  float k, acc = 0;\n"
                            "  for (k = 0; k < 10; k += 1) { acc += k; if (k * 0.1 > lim) return acc; }\n"
                            "  return -acc;\n"
                            "}\n"
                            "float firstWhile(float lim) {\n"
                            "  float k = 0;\n"
                            "  while (k < 8) { k += 1; if (k * 0.125 >= lim) { return k * 10; } }\n"
                            "  return -1;\n"
                            "}\n"
                            "float nested(float lim) {\n"
                            "  float i, j, n = 0;\n"
                            "  for (i = 0; i < 5; i += 1) {\n"
                            "    for (j = 0; j < 5; j += 1) {\n"
                            "      if (j > i) break;\n"
                            "      n += 1;\n"
                            "      if (i + j > lim * 8) return n * 100 + i * 10 + j;\n"
                            "    }\n"
                            "  }\n"
                            "  return n;\n"
                            "}\n"
                            "surface s() { float t = 0, k; for (k = 0; k < 3; k += 1) t += firstFor(u + k * 0.1);\n"
                            "  Ci = color(firstFor(u), firstWhile(u), nested(u)); Oi = t; }");
    auto firstFor = [](float lim) {
        float acc = 0;
        for (float k = 0; k < 10; k += 1) {
            acc += k;
            if (k * 0.1f > lim) return acc;
        }
        return -acc;
    };
    auto firstWhile = [](float lim) {
        float k = 0;
        while (k < 8) {
            k += 1;
            if (k * 0.125f >= lim) return k * 10;
        }
        return -1.f;
    };
    auto nested = [](float lim) {
        float n = 0;
        for (float i = 0; i < 5; i += 1)
            for (float j = 0; j < 5; j += 1) {
                if (j > i) break;
                n += 1;
                if (i + j > lim * 8) return n * 100 + i * 10 + j;
            }
        return n;
    };
    for (size_t i = 0; i < g.Ci.size(); ++i) {
        const float u = g.u[i];
        expectNear(g.Ci[i], Vec3(firstFor(u), firstWhile(u), nested(u)), 1e-4f);
        const float t = firstFor(u) + firstFor(u + 0.1f) + firstFor(u + 0.2f);
        EXPECT_NEAR(g.Oi[i].x, t, 1e-4f) << i;
    }
}

TEST(FunctionReturn, BreakAndContinueInsideFunctionsAndAroundCalls) {
    // A function with levelled break/continue, called inside the caller's
    // own loop, which breaks on the function's result.
    Harness h;
    ShadingGrid g = runLine(h,
                            "float grid(float lim) {\n"
                            "  float i = 0, j, n = 0;\n"
                            "  while (i < 4) {\n"
                            "    i += 1;\n"
                            "    for (j = 0; j < 4; j += 1) {\n"
                            "      if (j == 1) continue;\n"
                            "      if (j > i) continue 2;\n"
                            "      if (i * j > lim * 6) break 2;\n"
                            "      n += 1;\n"
                            "    }\n"
                            "  }\n"
                            "  return n * 10 + i;\n"
                            "}\n"
                            "surface s() {\n"
                            "  float k, sum = 0;\n"
                            "  for (k = 0; k < 6; k += 1) {\n"
                            "    float r = grid(u + k * 0.05);\n"
                            "    if (r > 100) continue;\n"
                            "    sum += r;\n"
                            "    if (sum > 200 * u + 20) break;\n"
                            "  }\n"
                            "  Ci = color(grid(u), sum, k);\n"
                            "}");
    auto grid = [](float lim) {
        float i = 0, n = 0;
        while (i < 4) {
            i += 1;
            bool stop = false;
            for (float j = 0; j < 4; j += 1) {
                if (j == 1) continue;
                if (j > i) break;  // continue 2
                if (i * j > lim * 6) {
                    stop = true;
                    break;
                }
                n += 1;
            }
            if (stop) break;
        }
        return n * 10 + i;
    };
    for (size_t i = 0; i < g.Ci.size(); ++i) {
        const float u = g.u[i];
        float k, sum = 0;
        for (k = 0; k < 6; k += 1) {
            const float r = grid(u + k * 0.05f);
            if (r > 100) continue;
            sum += r;
            if (sum > 200 * u + 20) break;
        }
        expectNear(g.Ci[i], Vec3(grid(u), sum, k), 1e-4f);
    }
}

TEST(FunctionReturn, OutputParametersThroughNestedCalls) {
    Harness h;
    ShadingGrid g = runLine(h,
                            "void split(float x; output float whole; output float frac) { whole = floor(x); frac = x - whole; }\n"
                            "float twice(float x; output color c; output float w) {\n"
                            "  float f;\n"
                            "  split(x * 4, w, f);\n"
                            "  if (f > 0.5) { c = color(f, w, 1); return 1; }\n"
                            "  setcomp(c, 1, w * 2);\n"
                            "  return 0;\n"
                            "}\n"
                            "surface s() {\n"
                            "  color c = color(-1, -2, -3); float w = -5, r = -7;\n"
                            "  if (u > 0.2) r = twice(u * 1.3, c, w);\n"
                            "  Ci = c; Oi = color(w, r, 0);\n"
                            "}");
    for (size_t i = 0; i < g.Ci.size(); ++i) {
        const float u = g.u[i];
        Vec3 c(-1, -2, -3);
        float w = -5, r = -7;
        if (u > 0.2f) {
            const float x = u * 1.3f * 4;
            w = std::floor(x);
            const float f = x - w;
            if (f > 0.5f) {
                c = Vec3(f, w, 1);
                r = 1;
            } else {
                c.y = w * 2;
                r = 0;
            }
        }
        expectNear(g.Ci[i], c, 1e-4f);
        expectNear(g.Oi[i], Vec3(w, r, 0), 1e-4f);
    }
}

TEST(FunctionReturn, NestedFunctionDefinitionsReturnEarlyAndReadTheirEnclosingLocals) {
    Harness h;
    ShadingGrid g = runLine(h,
                            "float outer(float x) {\n"
                            "  float base = x * 3;\n"
                            "  float inner(float y) { extern float base; if (y > base) return y; return base - y; }\n"
                            "  if (x < 0.2) return inner(0.5);\n"
                            "  base += 1;\n"
                            "  return inner(x * 4) + inner(inner(x));\n"
                            "}\n"
                            "surface s() { Ci = color(outer(u), outer(1 - u), 0); }");
    auto outer = [](float x) {
        float base = x * 3;
        auto inner = [&](float y) { return y > base ? y : base - y; };
        if (x < 0.2f) return inner(0.5f);
        base += 1;
        return inner(x * 4) + inner(inner(x));
    };
    for (size_t i = 0; i < g.Ci.size(); ++i) expectNear(g.Ci[i], Vec3(outer(g.u[i]), outer(1 - g.u[i]), 0), 1e-5f);
}

TEST(FunctionReturn, RecursionIsRejectedWithAClearError) {
    // Functions are inlined at each call, so none may reach itself:
    // directly, through another function, or in a function never called.
    struct Case {
        const char* src;
        const char* message;
    };
    const Case cases[] = {
        {"float f(float x) { if (x < 1) return 0; return f(x - 1) + 1; }\nsurface s() { Ci = f(u); }",
         "rec.sl:1:48: error: function 'f' calls itself (recursion is not allowed)"},
        {"float a(float x) { return b(x); }\nfloat b(float x) { return x < 0 ? 0 : a(x - 1); }\nsurface s() { Ci = a(u); }",
         "rec.sl:2:39: error: function 'a' calls itself through 'b' (recursion is not allowed)"},
        {"float c(float x) { return x; }\nfloat a(float x) { return b(c(x)); }\n"
         "float b(float x) { return d(x); }\nfloat d(float x) { return a(x) + c(x); }\nsurface s() { Ci = a(u); }",
         "rec.sl:4:27: error: function 'a' calls itself through 'b', 'd' (recursion is not allowed)"},
        {"float f(float x) { return f(x); }\nsurface s() { Ci = 1; }",
         "rec.sl:1:27: error: function 'f' calls itself (recursion is not allowed)"},
    };
    for (const Case& c : cases) {
        Harness h;
        EXPECT_FALSE(h.sys.compileSource(c.src, "rec.sl")) << c.src;
        EXPECT_NE(h.messages().find(c.message), std::string::npos) << h.messages();
    }
}

namespace {

/// Two lights that reach different points of leaningGrid(): "pt" stands at
/// the origin, in front of the points whose N has z < 0; "sun" shines
/// along (-1, 0, -0.2). Points 0, 1 and 3 see only pt, 2 and 5 only sun,
/// 4 sees both.
const char* kSunLight = "light sun(float k = 0.5) { solar(vector(-1, 0, -0.2), 0) Cl = color(k, 2 * k, 3 * k); }";

struct SeenLight {
    Vec3 L;  // from the surface point to the light, as illuminance sets it
    Vec3 cl;
};

/// What an illuminance(P, axis, PI/2) loop at point i sees, light by light,
/// with the lights in the order {pt, sun} or {sun, pt}.
std::vector<SeenLight> seenAbout(const ShadingGrid& g, size_t i, const Vec3& axis, bool sunFirst = false) {
    std::vector<SeenLight> out;
    const SeenLight pt{-g.P[i], Vec3(1, 0.5f, 0.25f)}, sun{Vec3(1, 0, 0.2f), Vec3(0.5f, 1, 1.5f)};
    for (const SeenLight& l : {sunFirst ? sun : pt, sunFirst ? pt : sun})
        if (dot(l.L, axis) >= 0) out.push_back(l);
    return out;
}

}  // namespace

TEST(FunctionReturn, FunctionsReadClAndLInsideIlluminance) {
    // A helper reads Cl and L; it is called from an illuminance loop that is
    // itself in a function, called under a varying condition.
    Harness h;
    h.svc.spaces["world"] = Mat4::identity();
    auto pt = h.instance(kPointLight);
    auto sun = h.instance(kSunLight);
    ShadingGrid g = leaningGrid();
    h.surface("color one(normal Nn) { float c = normalize(L) . Nn; if (c < 0.6) return Cl * c * 0.5; return Cl * c; }\n"
              "float dist() { return length(L); }\n"
              "color all(normal Nn; output float d) {\n"
              "  color c = 0; d = 0;\n"
              "  illuminance(P, Nn, PI / 2) { c += one(Nn); d += dist(); }\n"
              "  return c;\n"
              "}\n"
              "surface s() { float d = -1; Oi = -1; if (u > 0.3) Oi = all(N, d); Ci = color(d, 0, 0); }",
              g, {pt.get(), sun.get()});
    EXPECT_EQ(seenAbout(g, 0, g.N[0]).size(), 1u);
    EXPECT_EQ(seenAbout(g, 4, g.N[4]).size(), 2u);
    EXPECT_EQ(seenAbout(g, 5, g.N[5]).front().cl.x, 0.5f);
    int early = 0;  // lights seen at less than 0.6 (the helper's early return)
    for (size_t i = 0; i < 6; ++i)
        for (const SeenLight& l : seenAbout(g, i, g.N[i])) early += dot(normalize(l.L), g.N[i]) < 0.6f;
    EXPECT_GT(early, 0);
    EXPECT_LT(early, 7);
    for (size_t i = 0; i < 6; ++i) {
        const float u = g.u[i];
        Vec3 c(0.f);
        float d = 0;
        for (const SeenLight& l : seenAbout(g, i, g.N[i])) {
            const float k = dot(normalize(l.L), g.N[i]);
            c = c + l.cl * k * (k < 0.6f ? 0.5f : 1.f);
            d += length(l.L);
        }
        expectNear(g.Oi[i], u > 0.3f ? c : Vec3(-1, -1, -1), 1e-5f);
        EXPECT_NEAR(g.Ci[i].x, u > 0.3f ? d : -1.f, 1e-5f) << i;
    }
}

TEST(FunctionReturn, ReturnInsideIlluminance) {
    // Each point returns the first light it sees that is brighter than a
    // varying limit; points that see none run on to the end.
    Harness h;
    h.svc.spaces["world"] = Mat4::identity();
    auto pt = h.instance(kPointLight);
    auto sun = h.instance(kSunLight);
    ShadingGrid g = leaningGrid();
    h.surface("color first(float lim) {\n"
              "  float n = 0;\n"
              "  illuminance(P, N, PI / 2) { n += 1; if (comp(Cl, 0) > lim) return Cl * 10 + n; }\n"
              "  return color(-1, n, 0);\n"
              "}\n"
              "surface s() { Ci = first(u * 1.2); color c = 0; illuminance(P, N, PI / 2) { if (u > 0.5) return; c += Cl; } Oi = c; }",
              g, {sun.get(), pt.get()});
    for (size_t i = 0; i < 6; ++i) {
        const float lim = g.u[i] * 1.2f;
        Vec3 expect(-1, 0, 0);
        float n = 0;
        for (const SeenLight& l : seenAbout(g, i, g.N[i], true)) {
            n += 1;
            expect.y = n;
            if (l.cl.x > lim) {
                expect = l.cl * 10 + Vec3(n);
                break;
            }
        }
        expectNear(g.Ci[i], expect, 1e-5f);
        Vec3 c(0.f);
        if (g.u[i] <= 0.5f)
            for (const SeenLight& l : seenAbout(g, i, g.N[i], true)) c = c + l.cl;
        expectNear(g.Oi[i], c, 1e-5f);  // the shader returned before setting Oi where u > 0.5
    }
}

TEST(FunctionReturn, LightShadersCallFunctionsAroundIlluminateAndSolar) {
    // illuminate() and solar() inside functions, which read L and Ps, return
    // early at some points and set Cl through other functions.
    Harness h;
    h.svc.spaces["world"] = Mat4::identity();
    auto spot = h.instance("color atten(float i) { return i * color(1, 0.5, 0.25) / (L . L); }\n"
                           "void emitFrom(point from; float i) {\n"
                           "  illuminate(from) {\n"
                           "    if (xcomp(Ps) > 0.2) { Cl = atten(i) * 3; return; }\n"
                           "    Cl = atten(i);\n"
                           "  }\n"
                           "}\n"
                           "light fnlight(float intensity = 2) { emitFrom(point(0, 0, 0), intensity); }");
    auto sun = h.instance("void boost(float k) { Cl *= k; }\n"
                          "void sunFrom(vector d; float i) { solar(d, 0) { if (u < 0.5) return; Cl = i * color(1, u, zcomp(L)); boost(1 + u); } }\n"
                          "light fnsun() { sunFrom(vector(0, 0, -1), 0.5); }");
    ShadingGrid g = leaningGrid();
    h.surface("surface s() { color a = 0, b = 0; float n = 0;\n"
              "  illuminance(P) { if (n == 0) a = Cl; else b = Cl; n += 1; }\n"
              "  Ci = a; Oi = b; }",
              g, {spot.get(), sun.get()});
    for (size_t i = 0; i < 6; ++i) {
        const Vec3 P = g.P[i];
        const float u = g.u[i];
        expectNear(g.Ci[i], Vec3(1, 0.5f, 0.25f) * (2 / dot(P, P)) * (P.x > 0.2f ? 3.f : 1.f), 1e-5f);
        expectNear(g.Oi[i], u < 0.5f ? Vec3(0.f) : Vec3(0.5f, 0.5f * u, -0.5f) * (1 + u), 1e-5f);
    }
}

TEST(FunctionReturn, IlluminateInAnUncalledFunctionLeavesAnAmbientLight) {
    // A light is ambient when it runs no illuminate() or solar(); one in a
    // function it never calls does not count.
    Harness h;
    auto amb = h.instance("void unused() { illuminate(P) Cl = 5; }\nlight amb(float k = 0.25) { Cl = k; }");
    ShadingGrid g = leaningGrid();
    h.surface("surface s() { Ci = ambient(); }", g, {amb.get()});
    for (size_t i = 0; i < 6; ++i) expectNear(g.Ci[i], Vec3(0.25f), 1e-6f);
}

TEST(FunctionReturn, LightsourceAfterANestedIlluminanceLoop) {
    // lightsource() in an outer loop's body reads the outer loop's light,
    // also after an inner loop over the lights has ended.
    Harness h;
    h.svc.spaces["world"] = Mat4::identity();
    auto a = h.instance("light la(output float tag = 3) { solar(vector(0, 0, 1), 0) Cl = 1; }");
    auto b = h.instance("light lb(output float tag = 7) { solar(vector(0, 0, 1), 0) Cl = 2; }");
    ShadingGrid g = leaningGrid();
    h.surface("float count() { float n = 0; illuminance(P) n += 1; return n; }\n"
              "surface s() { float sum = 0, inner = 0;\n"
              "  illuminance(P) { inner += count(); float t = 0; if (lightsource(\"tag\", t)) sum += t; else sum -= 100; }\n"
              "  Ci = color(sum, inner, 0); }",
              g, {a.get(), b.get()});
    for (size_t i = 0; i < 6; ++i) expectNear(g.Ci[i], Vec3(3 + 7, 4, 0), 1e-6f);
}

TEST(FunctionReturn, ValuesOfVoidCallsAndMissingReturnsAreErrors) {
    // Both would leave the caller reading a register nothing wrote.
    struct Case {
        const char* src;
        const char* message;
    };
    const Case cases[] = {
        {"void paint() { Ci = 1; }\nsurface s() { Oi = paint(); }",
         "bad.sl:2:20: error: 'paint' returns no value (it is void) but its value is used"},
        {"surface s() { color c = 0; float x = 1 + setcomp(c, 0, 1); Ci = x; }",
         "bad.sl:1:42: error: 'setcomp' returns no value (it is void) but its value is used"},
        {"float half(float x) { float y = x / 2; }\nsurface s() { Ci = half(u); }",
         "bad.sl:1:7: error: function 'half' must return a float but has no return statement"},
        {"color never() { Ci = 0; }\nsurface s() { Ci = 1; }",
         "bad.sl:1:7: error: function 'never' must return a color but has no return statement"},
    };
    for (const Case& c : cases) {
        Harness h;
        EXPECT_FALSE(h.sys.compileSource(c.src, "bad.sl")) << c.src;
        EXPECT_NE(h.messages().find(c.message), std::string::npos) << h.messages();
    }
    // As statements, and as a for loop's step, void calls are fine.
    Harness h;
    ShadingGrid g = runLine(h,
                            "void bump(output float k) { k += 1; }\n"
                            "surface s() { float k, n = 0; for (k = 0; k < 3 + u * 5; bump(k)) n += 2; bump(n); printf(\"\"); Ci = n; }");
    EXPECT_EQ(h.diag.errorCount(), 0) << h.messages();
    for (size_t i = 0; i < g.Ci.size(); ++i) EXPECT_NEAR(g.Ci[i].x, 2 * std::ceil(3 + g.u[i] * 5) + 1, 1e-5f) << i;
}
