// Language constructs and built-ins, each run on a small grid and checked
// against values computed here.

#include "shading_test_util.h"

#include <OpenImageIO/imageio.h>

#include <cmath>
#include <filesystem>

using namespace umbra;
using namespace umbra::shading;
using namespace umbra::shading::testing;

namespace {
ShadingGrid line(int n) {
    return makeGrid(n, 1, [](float u, float) { return Vec3(u, 0, 1); });
}
}  // namespace

TEST(Language, ArithmeticOnUAndConstants) {
    Harness h;
    ShadingGrid g = line(5);
    h.surface("surface t() { Ci = color(u * 2 + 1, u - 3, -u / 4); Oi = 1; }", g);
    for (int i = 0; i < 5; ++i) {
        float u = g.u[size_t(i)];
        expectNear(g.Ci[size_t(i)], Vec3(u * 2 + 1, u - 3, -u / 4));
        expectNear(g.Oi[size_t(i)], Vec3(1, 1, 1));
    }
}

namespace {
/// Runs `body` as the inside of a surface shader on a line of n points
/// (P = (u, 0, 1)) and returns Ci.
std::vector<Vec3> runBody(Harness& h, const std::string& body, int n = 6, const std::string& prelude = "") {
    ShadingGrid g = line(n);
    h.surface(prelude + "\nsurface t() {\n" + body + "\n}\n", g);
    return g.Ci;
}
}  // namespace

TEST(Language, VaryingIfElseUnderMask) {
    Harness h;
    auto ci = runBody(h, "if (u < 0.5) Ci = color(1, 0, 0); else if (u < 0.7) Ci = color(0, 1, 0); else Ci = color(0, 0, u);");
    for (int i = 0; i < 6; ++i) {
        float u = float(i) / 5;
        Vec3 expect = u < 0.5f ? Vec3(1, 0, 0) : u < 0.7f ? Vec3(0, 1, 0) : Vec3(0, 0, u);
        expectNear(ci[size_t(i)], expect);
    }
}

TEST(Language, LoopsWithVaryingBreakAndContinue) {
    Harness h;
    // Sum k for k = 0..9 skipping odd k, stopping once k exceeds 10*u.
    auto ci = runBody(h,
                      "float sum = 0, k;\n"
                      "for (k = 0; k < 10; k += 1) {\n"
                      "    if (mod(k, 2) == 1) continue;\n"
                      "    if (k > 10 * u) break;\n"
                      "    sum += k;\n"
                      "}\n"
                      "float w = 0; while (w < u * 4) { w += 1; }\n"
                      "Ci = color(sum, k, w);");
    for (int i = 0; i < 6; ++i) {
        float u = float(i) / 5;
        float sum = 0, k;
        for (k = 0; k < 10; k += 1) {
            if (std::fmod(k, 2.f) == 1) continue;
            if (k > 10 * u) break;
            sum += k;
        }
        float w = 0;
        while (w < u * 4) w += 1;
        expectNear(ci[size_t(i)], Vec3(sum, k, w));
    }
}

TEST(Language, BreakAndContinueWithLevels) {
    Harness h;
    auto ci = runBody(h,
                      "float i, j, count = 0;\n"
                      "for (i = 0; i < 4; i += 1) {\n"
                      "    for (j = 0; j < 4; j += 1) {\n"
                      "        if (j > i) continue 2;\n"
                      "        if (i + j > 5 * u + 1) break 2;\n"
                      "        count += 1;\n"
                      "    }\n"
                      "}\n"
                      "Ci = color(count, i, j);");
    for (int p = 0; p < 6; ++p) {
        float u = float(p) / 5;
        float i, j = 0, count = 0;
        bool stop = false;
        for (i = 0; i < 4 && !stop; i += 1) {
            for (j = 0; j < 4; j += 1) {
                if (j > i) break;  // continue 2
                if (i + j > 5 * u + 1) {
                    stop = true;
                    break;
                }
                count += 1;
            }
            if (stop) break;
        }
        expectNear(ci[size_t(p)], Vec3(count, i, j));
    }
}

TEST(Language, FunctionsWithOutputArgsNestedFunctionsAndEarlyReturn) {
    Harness h;
    std::string prelude =
        "float clampedsquare(float x; output float wasbig) {\n"
        "    wasbig = 0;\n"
        "    if (x > 0.5) { wasbig = 1; return 0.25; }\n"
        "    return x * x;\n"
        "}\n";
    auto ci = runBody(h,
                      "float big;\n"
                      "float scale = 3;\n"
                      "float triple(float y) { extern float scale; return scale * y; }\n"
                      "float sq = clampedsquare(u, big);\n"
                      "Ci = color(sq, big, triple(u));",
                      6, prelude);
    for (int i = 0; i < 6; ++i) {
        float u = float(i) / 5;
        expectNear(ci[size_t(i)], Vec3(u > 0.5f ? 0.25f : u * u, u > 0.5f ? 1.f : 0.f, 3 * u));
    }
}

TEST(Language, PreprocessorMacros) {
    Harness h;
    std::string prelude =
        "#define SQUARE(x) ((x) * (x))\n"
        "#define TWO 2\n"
        "#ifdef TWO\n#define PICK 1\n#else\n#define PICK 0\n#endif\n"
        "#ifndef UNDEFINED_THING\n#define OTHER 5\n#endif\n"
        "#if defined(TWO) && TWO == 2\n#define VIAIF 7\n#else\n#define VIAIF 8\n#endif\n";
    auto ci = runBody(h, "Ci = color(SQUARE(u + 1), PICK * TWO, OTHER + VIAIF);", 4, prelude);
    for (int i = 0; i < 4; ++i) {
        float u = float(i) / 3;
        expectNear(ci[size_t(i)], Vec3((u + 1) * (u + 1), 2, 12));
    }
}

TEST(Language, ArraysTernaryAndComponents) {
    Harness h;
    auto ci = runBody(h,
                      "float a[4] = {10, 20, 30, 40};\n"
                      "a[1] = u;\n"
                      "float idx = floor(u * 3.999);\n"
                      "color c = color(1, 2, 3);\n"
                      "setcomp(c, 1, u);\n"
                      "point p = point(4, 5, 6);\n"
                      "setxcomp(p, comp(c, 2));\n"
                      "Ci = color(a[idx], u > 0.5 ? xcomp(p) : comp(c, 1), a[1] + zcomp(p));");
    for (int i = 0; i < 6; ++i) {
        float u = float(i) / 5;
        float a[4] = {10, u, 30, 40};
        int idx = int(std::floor(u * 3.999f));
        expectNear(ci[size_t(i)], Vec3(a[idx], u > 0.5f ? 3.f : u, u + 6));
    }
}

TEST(Language, MathBuiltins) {
    Harness h;
    auto ci = runBody(h,
                      "Ci = color(sin(u) + cos(u) * tan(u * 0.5), pow(u + 1, 2.5) + exp(u) - log(u + 2, 3), "
                      "atan(u, 1 - u) + sqrt(u) + inversesqrt(u + 1) + sign(u - 0.5));\n"
                      "Oi = color(clamp(u * 3, 0.5, 2) + mix(1, 3, u), smoothstep(0.2, 0.8, u) + step(0.5, u) + mod(-u * 7, 3), "
                      "min(u, 0.3, 0.5) + max(u, 0.6) + abs(-u) + floor(u * 2.5) + ceil(u * 2.5) + round(u * 2.5) + degrees(radians(u)));");
    ShadingGrid g = line(6);
    h.surface("surface t() {\n"
              "Ci = color(sin(u) + cos(u) * tan(u * 0.5), pow(u + 1, 2.5) + exp(u) - log(u + 2, 3), "
              "atan(u, 1 - u) + sqrt(u) + inversesqrt(u + 1) + sign(u - 0.5));\n"
              "Oi = color(clamp(u * 3, 0.5, 2) + mix(1, 3, u), smoothstep(0.2, 0.8, u) + step(0.5, u) + mod(-u * 7, 3), "
              "min(u, 0.3, 0.5) + max(u, 0.6) + abs(-u) + floor(u * 2.5) + ceil(u * 2.5) + round(u * 2.5) + degrees(radians(u)));\n}",
              g);
    for (int i = 0; i < 6; ++i) {
        float u = float(i) / 5;
        auto sstep = [](float a, float b, float x) {
            float t = std::clamp((x - a) / (b - a), 0.f, 1.f);
            return t * t * (3 - 2 * t);
        };
        float m = -u * 7;
        m = m - 3 * std::floor(m / 3);
        float sg = u > 0.5f ? 1.f : u < 0.5f ? -1.f : 0.f;
        expectNear(g.Ci[size_t(i)], Vec3(std::sin(u) + std::cos(u) * std::tan(u * 0.5f),
                                         std::pow(u + 1, 2.5f) + std::exp(u) - std::log(u + 2) / std::log(3.f),
                                         std::atan2(u, 1 - u) + std::sqrt(u) + 1 / std::sqrt(u + 1) + sg),
                    1e-4f);
        expectNear(g.Oi[size_t(i)], Vec3(std::clamp(u * 3, 0.5f, 2.f) + 1 + 2 * u, sstep(0.2f, 0.8f, u) + (u < 0.5f ? 0.f : 1.f) + m,
                                         std::min({u, 0.3f, 0.5f}) + std::max(u, 0.6f) + u + std::floor(u * 2.5f) +
                                             std::ceil(u * 2.5f) + std::round(u * 2.5f) + u),
                    1e-4f);
    }
}

TEST(Language, RuntimeFaultsGiveZeroNotCrashes) {
    Harness h;
    auto ci = runBody(h, "float z = u - u; Ci = color(1 / z, sqrt(-1 - u), log(z)); Oi = color(1, 2, 3) / z;");
    for (auto& c : ci) expectNear(c, Vec3(0, 0, 0));
}

TEST(Language, SplineCatmullRomAndBases) {
    Harness h;
    auto ci = runBody(h,
                      "float k[6] = {0, 1, 4, 9, 16, 25};\n"
                      "Ci = color(spline(u, 0, 1, 4, 9, 16, 25), spline(\"linear\", u, 0, 1, 2, 3, 4), spline(\"bezier\", u, k[0], k[1], k[2], k[3]));");
    for (int i = 0; i < 6; ++i) {
        float u = float(i) / 5;
        // Catmull-Rom through 1,4,9,16 over 3 segments: the curve x^2 is
        // reproduced exactly (CR reproduces quadratics).
        float x = 1 + 3 * u;
        // linear: interior knots 1..3 over 2 segments
        float lin = 1 + 2 * u;
        // Bezier with control values 0,1,4,9.
        float b = std::pow(1 - u, 3.f) * 0 + 3 * u * std::pow(1 - u, 2.f) * 1 + 3 * u * u * (1 - u) * 4 + u * u * u * 9;
        expectNear(ci[size_t(i)], Vec3(x * x, lin, b), 1e-4f);
    }
}

TEST(Language, DerivativesMatchDifferencesOfKnownP) {
    Harness h;
    // P = (u^2, v^3, u v) on a 5 x 4 grid; Du/Dv are central differences
    // inside and one-sided at the edges, divided by du/dv.
    ShadingGrid g = makeGrid(5, 4, [](float u, float v) { return Vec3(u * u, v * v * v, u * v); });
    h.surface("surface t() { Ci = color Du(P); Oi = color Dv(P); }", g);
    float du = 0.25f, dv = 1.0f / 3;
    auto f = [](float u, float v) { return Vec3(u * u, v * v * v, u * v); };
    for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 5; ++i) {
            float u = float(i) * du, v = float(j) * dv;
            Vec3 eu = i == 0 ? (f(u + du, v) - f(u, v)) / du : i == 4 ? (f(u, v) - f(u - du, v)) / du : (f(u + du, v) - f(u - du, v)) / (2 * du);
            Vec3 ev = j == 0 ? (f(u, v + dv) - f(u, v)) / dv : j == 3 ? (f(u, v) - f(u, v - dv)) / dv : (f(u, v + dv) - f(u, v - dv)) / (2 * dv);
            expectNear(g.Ci[size_t(j * 5 + i)], eu, 1e-4f);
            expectNear(g.Oi[size_t(j * 5 + i)], ev, 1e-4f);
        }
    // Inside, central differences of u^2 are exactly 2u.
    EXPECT_NEAR(g.Ci[size_t(1 * 5 + 2)].x, 2 * 0.5f, 1e-5f);
}

TEST(Language, AreaAndCalculateNormalOnAPlane) {
    Harness h;
    ShadingGrid g = makeGrid(3, 3, [](float u, float v) { return Vec3(2 * u, 3 * v, 1); });
    h.surface("surface t() { Ci = color calculatenormal(P); Oi = color(area(P), Deriv(P, u) . vector(1, 0, 0), 0); }", g);
    for (int i = 0; i < 9; ++i) {
        expectNear(g.Ci[size_t(i)], Vec3(0, 0, 6));  // (2,0,0) x (0,3,0)
        EXPECT_NEAR(g.Oi[size_t(i)].x, (2 * 0.5f) * (3 * 0.5f), 1e-5f);
        EXPECT_NEAR(g.Oi[size_t(i)].y, 2, 1e-5f);
    }
}

TEST(Language, TransformsBetweenNamedSpaces) {
    Harness h;
    Mat4 currentFromWorld = Mat4::translate(Vec3(1, 2, 3)) * Mat4::rotate(90, Vec3(0, 0, 1));
    h.svc.spaces["world"] = currentFromWorld;
    h.svc.spaces["myspace"] = Mat4::scale(Vec3(2, 2, 2));
    ShadingGrid g = line(3);
    h.surface("surface t() {\n"
              "  point pw = transform(\"world\", P);\n"
              "  vector vw = vtransform(\"world\", vector(1, 0, 0));\n"
              "  point back = point \"world\" (1, 0, 0);\n"
              "  Ci = color(xcomp(pw), ycomp(pw), zcomp(pw));\n"
              "  Oi = color(xcomp(vw) + 10 * ycomp(vw), xcomp(back) + 10 * ycomp(back), zcomp(transform(\"myspace\", \"world\", point(1, 1, 1))));\n"
              "}",
              g);
    Mat4 worldFromCurrent = currentFromWorld.inverse();
    for (int i = 0; i < 3; ++i) {
        expectNear(g.Ci[size_t(i)], worldFromCurrent.point(g.P[size_t(i)]), 1e-5f);
        Vec3 vw = worldFromCurrent.vector(Vec3(1, 0, 0));
        Vec3 back = currentFromWorld.point(Vec3(1, 0, 0));
        Vec3 ms = worldFromCurrent.point(Mat4::scale(Vec3(2, 2, 2)).point(Vec3(1, 1, 1)));
        expectNear(g.Oi[size_t(i)], Vec3(vw.x + 10 * vw.y, back.x + 10 * back.y, ms.z), 1e-5f);
    }
}

TEST(Language, ColorSpacesAndMatrices) {
    Harness h;
    ShadingGrid g = line(2);
    h.surface("surface t() {\n"
              "  color c = color \"hsv\" (0.5, 1, 1);\n"  // cyan
              "  color back = ctransform(\"hsv\", color(1, 0, 0));\n"
              "  matrix m = matrix(2, 0, 0, 0,  0, 3, 0, 0,  0, 0, 4, 0,  1, 1, 1, 1);\n"
              "  matrix t2 = translate(matrix 1, vector(1, 2, 3));\n"
              "  Ci = c + color(0, 0, determinant(m));\n"
              "  Oi = color(xcomp(transform(m, point(1, 1, 1))), comp(t2, 3, 1), comp(back, 0) + comp(back, 1) + comp(back, 2) + comp(m / m, 0, 0));\n"
              "}",
              g);
    expectNear(g.Ci[0], Vec3(0, 1, 1 + 24));
    expectNear(g.Oi[0], Vec3(3, 2, 0 + 1 + 1 + 1), 1e-5f);
}

TEST(Language, StringsFormatPrintfAndMatch) {
    Harness h;
    ShadingGrid g = line(2);
    h.surface("surface t() {\n"
              "  string s = concat(\"ab\", \"cd\");\n"
              "  string f = format(\"%s=%.2f %d\", s, 1.5, 7);\n"
              "  printf(\"%s|%c\\n\", f, color(1, 0, 0));\n"
              "  Ci = color(match(\"b.d\", s), match(\"^x\", s), f == \"abcd=1.50 7\");\n"
              "  Oi = color(format(\"[%5s][%-5s][%.2s][%s]\", \"ab\", \"ab\", \"abcd\", \"xyz\") == \"[   ab][ab   ][ab][xyz]\", 1, 1);\n"
              "}",
              g);
    expectNear(g.Ci[0], Vec3(1, 0, 1));
    expectNear(g.Oi[0], Vec3(1, 1, 1));  // %s takes C's width and precision
    EXPECT_EQ(h.svc.printed, "abcd=1.50 7|1.000000 0.000000 0.000000\n");
}

TEST(Language, NoiseRangesPeriodicityAndDeterminism) {
    Harness h;
    ShadingGrid g = makeGrid(16, 16, [](float u, float v) { return Vec3(u * 7.3f, v * 5.1f, 0.37f); });
    h.surface("surface t() {\n"
              "  Ci = color(noise(P), pnoise(xcomp(P), 4) - pnoise(xcomp(P) + 4, 4), cellnoise(floor(P)) - cellnoise(P));\n"
              "  Oi = color(random(), noise(s * 3, t * 3), noise(xcomp(P)));\n"
              "}",
              g);
    std::vector<Vec3> first = g.Oi;
    float lo = 1, hi = 0;
    for (int i = 0; i < g.size(); ++i) {
        Vec3 c = g.Ci[size_t(i)];
        EXPECT_GE(c.x, 0);
        EXPECT_LE(c.x, 1);
        lo = std::min(lo, c.x);
        hi = std::max(hi, c.x);
        EXPECT_NEAR(c.y, 0, 1e-5f);  // period 4
        EXPECT_EQ(c.z, 0);           // constant within a cell
        EXPECT_GE(g.Oi[size_t(i)].x, 0);
        EXPECT_LT(g.Oi[size_t(i)].x, 1);
    }
    EXPECT_GT(hi - lo, 0.2f);  // not constant
    // Same grid seed, same random numbers.
    ShadingGrid g2 = makeGrid(16, 16, [](float u, float v) { return Vec3(u * 7.3f, v * 5.1f, 0.37f); });
    h.surface("surface t() {\n"
              "  Ci = color(noise(P), pnoise(xcomp(P), 4) - pnoise(xcomp(P) + 4, 4), cellnoise(floor(P)) - cellnoise(P));\n"
              "  Oi = color(random(), noise(s * 3, t * 3), noise(xcomp(P)));\n"
              "}",
              g2);
    for (int i = 0; i < g.size(); ++i) EXPECT_EQ(g2.Oi[size_t(i)], first[size_t(i)]);
    // Integer lattice points of gradient noise are exactly 0.5.
    ShadingGrid g3 = makeGrid(3, 1, [](float u, float) { return Vec3(2 * u, 1, 3); });
    h.surface("surface t() { Ci = color(noise(P), noise(xcomp(P)), noise(xcomp(P), 1)); }", g3);
    for (auto& c : g3.Ci) expectNear(c, Vec3(0.5f, 0.5f, 0.5f));
}

// noise(), pnoise(), cellnoise() and random() return the type their context
// asks for (RI Spec 3.2): a colour or point context takes three channels, as
// Pixie and Aqsis give. umbra promoted the float version: grey "colour"
// noise, and `P + noise(P)` moved points only along (1, 1, 1). Where the
// peers disagree (a float operand first, `noise(P) * Cs`) umbra keeps
// Aqsis's float.
TEST(Language, NoiseTakesTheTypeItsContextAsksFor) {
    Harness h;
    auto grid = [] { return makeGrid(16, 16, [](float u, float v) { return Vec3(u * 7.3f, v * 5.1f, 0.37f); }); };
    // The largest difference between two channels over the grid, and the
    // range of the first.
    auto spread = [](const std::vector<Vec3>& c, float* range) {
        float most = 0, lo = 1e9f, hi = -1e9f;
        for (const Vec3& v : c) {
            most = std::max({most, std::abs(v.x - v.y), std::abs(v.y - v.z)});
            lo = std::min(lo, v.x), hi = std::max(hi, v.x);
        }
        if (range) *range = hi - lo;
        return most;
    };
    for (const char* body : {"Ci = color noise(P);", "color c = noise(P); Ci = c;", "Ci = noise(P);",
                             "Ci = color(1, 1, 1) * noise(P);", "Ci = color pnoise(P, point(4, 4, 4));",
                             "Ci = color cellnoise(P);", "Ci = color random();",
                             "point q = P + noise(P); Ci = color(q - P);", "Ci = color noise(s * 3, t * 3);"}) {
        ShadingGrid g = grid();
        h.surface(fmt::format("surface t() {{ {} }}", body), g);
        float range = 0;
        EXPECT_GT(spread(g.Ci, &range), 0.1f) << body;
        EXPECT_GT(range, 0.2f) << body;
        for (const Vec3& c : g.Ci) {
            EXPECT_GE(std::min({c.x, c.y, c.z}), 0.0f) << body;
            EXPECT_LE(std::max({c.x, c.y, c.z}), 1.0f) << body;
        }
    }
    for (const char* body : {"float f = noise(P); Ci = f;", "Ci = noise(P) * color(1, 1, 1);",
                             "Ci = 0.5 + noise(P);", "Ci = mix(color(0), color(1), noise(P));"}) {
        ShadingGrid g = grid();
        h.surface(fmt::format("surface t() {{ {} }}", body), g);
        EXPECT_EQ(spread(g.Ci, nullptr), 0.0f) << body;
    }
}

// Ray marches of tens of thousands of steps (Advanced RenderMan's
// cellclouds: 20,000) run to their end, as in Pixie and Aqsis, whatever the
// grid's size: the loop budget was 2^21 point-iterations a grid, 8,192
// iterations on 256 points, and cut the march into grid-shaped pieces.
TEST(Language, LongLoopsRunToTheirEndOnAnyGrid) {
    for (int side : {4, 16, 32}) {
        Harness h;
        ShadingGrid g = makeGrid(side, side, [](float u, float v) { return Vec3(u, v, 1); });
        // Three loops of 30,000: 90,000 iterations in all (they were cut at 65,536).
        h.surface("surface t(float n = 30000) { float i, a = 0, b = 0, c = 0;\n"
                  "  for (i = 0; i < n; i += 1) a += 1 / n;\n"
                  "  for (i = 0; i < n; i += 1) b += 1 / n;\n"
                  "  for (i = 0; i < n; i += 1) c += 1 / n;\n"
                  "  Ci = color(a, b, c); }", g);
        for (const Vec3& c : g.Ci) expectNear(c, Vec3(1, 1, 1), 2e-3f);
        EXPECT_EQ(h.messages().find("loops ran more than"), std::string::npos) << h.messages();
    }
}

// pnoise(u, v, uperiod, vperiod) and pnoise(P, t, Pperiod, tperiod) take
// their positions first, then the periods (RI Spec 3.2): umbra read
// (u, uperiod, v, vperiod), so 2D and 4D periodic noise was not periodic in
// the periods given (|f(x) - f(x + period)| 0.146; Pixie and Aqsis 0).
TEST(Language, PeriodicNoiseOfTwoAndFourDimensionsRepeatsWithItsPeriods) {
    Harness h;
    ShadingGrid g = makeGrid(16, 16, [](float u, float v) { return Vec3(u * 7.3f, v * 5.1f, 0.37f); });
    h.surface("surface t() {\n"
              "  float a = pnoise(s * 8, t * 8, 4, 2) - pnoise(s * 8 + 4, t * 8 - 2, 4, 2);\n"
              "  float b = pnoise(P, s * 5, point(3, 2, 1), 2) - pnoise(P + vector(3, -2, 1), s * 5 + 2, point(3, 2, 1), 2);\n"
              "  float c = pnoise(s * 8, t * 8, 4, 2) - pnoise(s * 8 + 2, t * 8, 4, 2);\n"
              "  Ci = color(a, b, c);\n"
              "}",
              g);
    float notPeriodic = 0;
    for (const Vec3& c : g.Ci) {
        EXPECT_NEAR(c.x, 0, 1e-5f);
        EXPECT_NEAR(c.y, 0, 1e-5f);
        notPeriodic = std::max(notPeriodic, std::abs(c.z));
    }
    EXPECT_GT(notPeriodic, 0.05f);  // half a period away: a different value
}

TEST(Language, UniformInferenceAndListing) {
    Harness h;
    auto sh = h.sys.compileSource("surface t(float k = 2) { float a = k * 3; float b = a + u; Ci = b; }", "t.sl");
    ASSERT_TRUE(sh) << h.messages();
    std::string l = sh->listing();
    EXPECT_NE(l.find("reg a uniform float"), std::string::npos) << l;
    EXPECT_NE(l.find("reg b varying float"), std::string::npos) << l;
}

TEST(Language, ShadowCallsTheServiceWithFootprintAndParams) {
    Harness h;
    ShadingGrid g = makeGrid(3, 2, [](float u, float v) { return Vec3(u, 2 * v, 1); });
    h.svc.shadowFn = [](const ShadowQuery& q, float* r) {
        for (int k = 0; k < q.count; ++k) r[k] = q.P[k].x;
        return true;
    };
    h.surface("surface t() { if (u > 0.2) Ci = shadow(\"map.shd\", P, \"samples\", 4, \"bias\", 0.5, \"filter\", \"box\"); }", g);
    ASSERT_EQ(h.svc.shadowQueries.size(), 1u);
    const ShadowQuery& q = h.svc.shadowQueries[0];
    EXPECT_EQ(q.mapName, "map.shd");
    EXPECT_EQ(q.count, 4);  // u = 0.5, 1 on both rows
    ASSERT_EQ(q.params.size(), 3u);
    EXPECT_EQ(q.params[0].name, "samples");
    EXPECT_EQ(q.params[0].floatOr(0), 4);
    EXPECT_EQ(q.params[2].strings.at(0), "box");
    for (int i = 0; i < g.size(); ++i) EXPECT_NEAR(g.Ci[size_t(i)].x, g.u[size_t(i)] > 0.2f ? g.u[size_t(i)] : 0.f, 1e-6f);
    h.svc.shadowQueries.clear();
    // The footprint is Du(P)*du and Dv(P)*dv: (0.5, 0, 0) and (0, 2, 0) here.
    h.svc.shadowFn = [](const ShadowQuery& q, float* r) {
        for (int k = 0; k < q.count; ++k) r[k] = q.dPdu[k].x * 10 + q.dPdv[k].y;
        return true;
    };
    h.surface("surface t() { Ci = shadow(\"m\", P); }", g);
    for (int i = 0; i < g.size(); ++i) EXPECT_NEAR(g.Ci[size_t(i)].x, 10 * 0.5f + 2, 1e-5f);
    // A service without the map: shadow() is 0.
    h.svc.shadowFn = nullptr;
    h.surface("surface t() { Ci = 1 - shadow(\"missing\", P); }", g);
    for (auto& c : g.Ci) expectNear(c, Vec3(1, 1, 1));
}

TEST(Language, ShadowFootprintsOfSomePointsAreTheirGridDifferences) {
    // Only some points call shadow(), scattered over rows and edges: each
    // one's footprint is its own central difference along u and v (one-sided
    // at the grid's edges), computed here from the grid.
    Harness h;
    const int nu = 5, nv = 4;
    ShadingGrid g = makeGrid(nu, nv, [](float u, float v) { return Vec3(u * u, v * v * v + u, 1 + u * v); });
    // The query's arrays live only during the call.
    std::vector<int> indices;
    std::vector<Vec3> dPdu, dPdv;
    h.svc.shadowFn = [&](const ShadowQuery& q, float* r) {
        indices.assign(q.indices, q.indices + q.count);
        dPdu.assign(q.dPdu, q.dPdu + q.count);
        dPdv.assign(q.dPdv, q.dPdv + q.count);
        std::fill_n(r, q.count, 0.0f);
        return true;
    };
    h.surface("surface t() { if (u > 0.3 || v > 0.9) Ci = shadow(\"m\", P); }", g);
    ASSERT_EQ(h.svc.shadowQueries.size(), 1u);
    auto diff = [&](int i, int step, int pos, int count) {
        if (pos == 0) return g.P[size_t(i + step)] - g.P[size_t(i)];
        if (pos == count - 1) return g.P[size_t(i)] - g.P[size_t(i - step)];
        return (g.P[size_t(i + step)] - g.P[size_t(i - step)]) * 0.5f;
    };
    int expected = 0;
    for (int i = 0; i < g.size(); ++i) expected += g.u[size_t(i)] > 0.3f || g.v[size_t(i)] > 0.9f;
    ASSERT_EQ(int(indices.size()), expected);
    for (size_t k = 0; k < indices.size(); ++k) {
        const int i = indices[k], iu = i % nu, iv = i / nu;
        const Vec3 du = diff(i, 1, iu, nu), dv = diff(i, nu, iv, nv);
        EXPECT_EQ(dPdu[k].x, du.x) << i;
        EXPECT_EQ(dPdu[k].y, du.y) << i;
        EXPECT_EQ(dPdu[k].z, du.z) << i;
        EXPECT_EQ(dPdv[k].x, dv.x) << i;
        EXPECT_EQ(dPdv[k].y, dv.y) << i;
        EXPECT_EQ(dPdv[k].z, dv.z) << i;
    }
}

TEST(Language, IlluminanceWithTestLightCategoriesAndMessagePassing) {
    Harness h;
    h.svc.spaces["world"] = Mat4::identity();
    auto light = h.instance("light keylight(float intensity = 2; string __category = \"key,rim\"; output float spec = 0.25) {\n"
                            "  illuminate(point(0, 0, 0)) Cl = intensity;\n"
                            "}");
    auto fill = h.instance("light filllight(float intensity = 0.5) { solar(vector(0, 0, 1), 0) Cl = intensity; }");
    ShadingGrid g = makeGrid(3, 1, [](float u, float) { return Vec3(u - 0.5f, 0, 1); });
    h.surface("surface t() {\n"
              "  color key = 0, all = 0; float n = 0, sp = 0;\n"
              "  illuminance(\"key\", P) { key += Cl; float x; if (lightsource(\"spec\", x)) sp += x; }\n"
              "  illuminance(P, N, PI / 2) { all += Cl * (normalize(L) . normalize(N)); n += 1; }\n"
              "  Ci = color(comp(key, 0), comp(all, 0), n); Oi = color(sp, 0, 0);\n"
              "}",
              g, {light.get(), fill.get()});
    for (int i = 0; i < 3; ++i) {
        Vec3 P = g.P[size_t(i)];
        float cosKey = dot(normalize(-P), Vec3(0, 0, -1));
        expectNear(g.Ci[size_t(i)], Vec3(2, 2 * cosKey + 0.5f * 1, 2), 1e-5f);
        EXPECT_NEAR(g.Oi[size_t(i)].x, 0.25f, 1e-6f);
    }
}

// A varying output of another shader reaches each point with its own
// value. The variable receiving it was inferred uniform and took the
// grid's first point's value: grid-sized blocks wherever a surface read a
// displacement's output (layered exporter shaders) or a volume a surface's.
TEST(Language, MessagePassingGivesEachPointItsOwnValue) {
    Harness h;
    auto disp = h.instance("displacement d(output varying color dcol = 0) { dcol = color(s, t, 0.5); }");
    auto surf = h.instance("surface t() { color c = color(1, 0, 1); float ok = displacement(\"dcol\", c); "
                           "Ci = c; Oi = ok; }");
    ASSERT_TRUE(disp && surf);
    ShadingGrid g = makeGrid(4, 3, [](float u, float v) { return Vec3(u, v, 1); });
    ShadeRequest req;
    req.displacement = disp.get();
    req.surface = surf.get();
    h.sys.shade(g, req, h.svc);
    for (int i = 0; i < g.size(); ++i) {
        expectNear(g.Ci[size_t(i)], Vec3(g.s[size_t(i)], g.t[size_t(i)], 0.5f));
        EXPECT_EQ(g.Oi[size_t(i)].x, 1.0f);
    }
}

// A light asks the surface it lights for a parameter (RI Spec 3.2 message
// passing; RIBMosaic's lights scale their shadow by the surface's
// ShadowAlpha). The surface was not yet known while its own illuminance
// loop ran the light: surface() found nothing, and no object cast a shadow.
TEST(Language, LightsReadTheSurfacesParameters) {
    Harness h;
    auto light = h.instance("light l() { float k = -1; float f = surface(\"Kd\", k); "
                            "illuminate(point(0, 0, 0)) Cl = color(f, k, 0); }");
    ShadingGrid g = makeGrid(3, 1, [](float u, float) { return Vec3(u, 0, 1); });
    h.surface("surface t(float Kd = 0.6) { color c = 0; illuminance(P) c += Cl; Ci = c; }", g, {light.get()});
    for (const Vec3& c : g.Ci) expectNear(c, Vec3(1, 0.6f, 0));
}

namespace {
/// Six points at z = 1 around the origin, where the test lights stand;
/// even points face the origin (N = (0,0,-1)), odd points face away.
ShadingGrid facingAndAway() {
    ShadingGrid g = makeGrid(6, 1, [](float u, float) { return Vec3(u - 0.5f, 0, 1); });
    for (size_t i = 1; i < 6; i += 2) g.N[i] = g.Ng[i] = Vec3(0, 0, 1);
    return g;
}
/// A light at the origin whose every point calls shadow(): the points it
/// was run at are the points the service was asked about.
const char* kShadowedLight = "light probe() { illuminate(point(0, 0, 0)) Cl = 1 - shadow(\"m\", Ps); }";
}  // namespace

TEST(Language, LightsRunOnlyWhereTheSurfacesConeCanUseThem) {
    Harness h;
    h.svc.spaces["world"] = Mat4::identity();
    auto light = h.instance(kShadowedLight);
    std::vector<int> asked;
    h.svc.shadowFn = [&](const ShadowQuery& q, float* r) {
        for (int k = 0; k < q.count; ++k) {
            asked.push_back(q.indices[k]);
            r[k] = 0.25f;
        }
        return true;
    };
    // diffuse(), specular() and an illuminance loop about N share one cone:
    // the light runs once, at the three points facing it.
    ShadingGrid g = facingAndAway();
    h.surface("surface t() { color c = 0; illuminance(P, N, PI / 2) c += Cl;\n"
              "  Ci = diffuse(N) + specular(N, -I, 0.1) * 0 + c * 100; }",
              g, {light.get()});
    EXPECT_EQ(asked, (std::vector<int>{0, 2, 4}));
    for (size_t i = 0; i < 6; ++i) {
        const Vec3 P = g.P[i], toLight = normalize(-P);
        const float expect = i % 2 ? 0.0f : 0.75f * dot(toLight, Vec3(0, 0, -1)) + 75.0f;
        EXPECT_NEAR(g.Ci[i].x, expect, 1e-4f) << i;
    }
    // A later loop that takes every direction runs the light again at every
    // point, and sees it where the first loop did not.
    asked.clear();
    g = facingAndAway();
    h.surface("surface t() { Ci = diffuse(N); float n = 0; illuminance(P) n += 1; Oi = n; }", g, {light.get()});
    EXPECT_EQ(asked, (std::vector<int>{0, 2, 4, 0, 1, 2, 3, 4, 5}));
    for (size_t i = 0; i < 6; ++i) EXPECT_EQ(g.Oi[i].x, 1.0f) << i;
    // So does a loop about another axis: -N accepts the odd points.
    asked.clear();
    g = facingAndAway();
    h.surface("surface t() { Ci = diffuse(N); color c = 0; illuminance(P, -N, PI / 2) c += Cl; Oi = c; }", g,
              {light.get()});
    EXPECT_EQ(asked.size(), 3u + 6u);
    for (size_t i = 0; i < 6; ++i) EXPECT_NEAR(g.Oi[i].x, i % 2 ? 0.75f : 0.0f, 1e-6f) << i;
    // An ambient() first runs no directional light at all.
    asked.clear();
    g = facingAndAway();
    h.surface("surface t() { Ci = ambient(); }", g, {light.get()});
    EXPECT_TRUE(asked.empty());
}

TEST(Language, OutputParametersAreReadableAsAovs) {
    Harness h;
    auto inst = h.instance("surface t(output varying float mask = 0; output color tint = color(1, 2, 3)) { mask = u; Ci = 0; }");
    ShadingGrid g = line(4);
    ShadeRequest req;
    req.surface = inst.get();
    req.outputs = {"mask", "tint"};
    h.sys.shade(g, req, h.svc);
    std::vector<float> v;
    int per = 0;
    ASSERT_TRUE(g.output("mask", &v, &per));
    EXPECT_EQ(per, 1);
    for (int i = 0; i < 4; ++i) EXPECT_NEAR(v[size_t(i)], g.u[size_t(i)], 1e-6f);
    ASSERT_TRUE(g.output("tint", &v, &per));
    EXPECT_EQ(per, 3);
    EXPECT_EQ(v[9], 1);
    EXPECT_EQ(v[11], 3);
    EXPECT_FALSE(g.output("nope", &v, &per));
}

TEST(Language, EndlessLoopIsStoppedWithAWarning) {
    Harness h;
    auto ci = runBody(h, "float k = 0; while (1) { k += 1; } Ci = k;", 2);
    EXPECT_EQ(ci[0].x, float(1 << 18));  // the budget: 2^18 iterations a grid
    EXPECT_EQ(h.diag.warningCount(), 1) << h.messages();
}

TEST(Language, TextureThroughOpenImageIO) {
    namespace fs = std::filesystem;
    fs::path dir = fs::temp_directory_path() / "umbra_shading_texture_test";
    fs::create_directories(dir);
    // A 4 x 4 constant image: every filtered lookup returns its colour.
    std::string file = (dir / "flat.tif").string();
    {
        auto out = OIIO::ImageOutput::create(file);
        ASSERT_TRUE(out);
        OIIO::ImageSpec spec(4, 4, 3, OIIO::TypeDesc::FLOAT);
        spec.attribute("wrapmodes", "periodic,periodic");  // as MakeTexture writes it
        std::vector<float> px(4 * 4 * 3);
        for (size_t i = 0; i < px.size(); i += 3) {
            px[i] = 0.25f;
            px[i + 1] = 0.5f;
            px[i + 2] = 0.75f;
        }
        ASSERT_TRUE(out->open(file, spec));
        ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, px.data()));
        out->close();
    }
    Harness h;
    h.sys.setTextureSearchPath({dir.string()});
    ShadingGrid g = line(3);
    h.surface("surface t() { Ci = color texture(\"flat.tif\"); Oi = color(float texture(\"flat.tif\"[1], s, t), "
              "float texture(\"missing.tif\"), 0); }",
              g);
    for (int i = 0; i < 3; ++i) {
        expectNear(g.Ci[size_t(i)], Vec3(0.25f, 0.5f, 0.75f), 1e-4f);
        expectNear(g.Oi[size_t(i)], Vec3(0.5f, 0, 0), 1e-4f);
    }
    // The missing texture: one error (the rule of unreadable maps), once.
    EXPECT_EQ(h.diag.errorCount(), 1) << h.messages();
    EXPECT_EQ(h.diag.warningCount(), 0) << h.messages();
    fs::remove_all(dir);
}

TEST(Language, ReflectRefractFresnelAndFaceforward) {
    Harness h;
    ShadingGrid g = line(2);
    h.surface("surface t() {\n"
              "  vector In = normalize(vector(1, 0, 1)); normal Nn = normal(0, 0, -1);\n"
              "  float kr, kt; vector R, T;\n"
              "  fresnel(In, Nn, 1 / 1.5, kr, kt, R, T);\n"
              "  vector Rf = reflect(In, Nn); vector Tr = refract(In, Nn, 1 / 1.5);\n"
              "  Ci = color(kr, kt, xcomp(R) - xcomp(Rf) + zcomp(Rf));\n"
              "  Oi = color(xcomp(Tr), zcomp(Tr), zcomp(faceforward(Nn, -In)));\n"
              "  if (u > 0.5) return;\n"
              "  Oi = Oi * 2;\n"
              "}",
              g);
    float eta = 1 / 1.5f;
    Vec3 I = normalize(Vec3(1, 0, 1)), N(0, 0, -1);
    float ci = -dot(I, N);
    float ct = std::sqrt(1 - eta * eta * (1 - ci * ci));
    float rs = (eta * ci - ct) / (eta * ci + ct), rp = (ci - eta * ct) / (ci + eta * ct);
    float kr = 0.5f * (rs * rs + rp * rp);
    Vec3 T = I * eta - N * (eta * dot(I, N) + std::sqrt(1 - eta * eta * (1 - dot(I, N) * dot(I, N))));
    expectNear(g.Ci[0], Vec3(kr, 1 - kr, -I.z), 1e-5f);  // reflect flips z
    expectNear(g.Oi[1], Vec3(T.x, T.z, 1), 1e-5f);     // faceforward(N, -I) flips N to +z
    expectNear(g.Oi[0], Vec3(2 * T.x, 2 * T.z, 2), 1e-5f);  // u = 0 did not return early
}

TEST(ShadingGridBind, FromADicedGrid) {
    geometry::Grid grid;
    grid.nu = 2;
    grid.nv = 1;
    grid.du = 0.5f;
    grid.dv = 1;
    for (int j = 0; j <= 1; ++j)
        for (int i = 0; i <= 2; ++i) {
            grid.P.push_back(Vec3(float(i), 2 * float(j), 4));
            grid.u.push_back(0.5f * float(i));
            grid.v.push_back(float(j));
        }
    geometry::GridVar cs;
    cs.name = "Cs";
    cs.type = ri::ParamType::Color;
    cs.components = 3;
    cs.perVertex = false;
    cs.data = {0.1f, 0.2f, 0.3f};
    grid.vars.push_back(cs);
    ShadingGrid g;
    g.bind(grid, Color(1, 1, 1), Color(0.5f, 0.5f, 0.5f), true);
    ASSERT_EQ(g.size(), 6);
    for (int k = 0; k < 6; ++k) {
        expectNear(g.dPdu[size_t(k)], Vec3(2, 0, 0));  // dP/du: 1 per 0.5 of u
        expectNear(g.dPdv[size_t(k)], Vec3(0, 2, 0));
        expectNear(g.Ng[size_t(k)], Vec3(0, 0, 4));
        expectNear(g.N[size_t(k)], g.Ng[size_t(k)]);
        expectNear(g.I[size_t(k)], g.P[size_t(k)]);
        expectNear(g.Cs[size_t(k)], Vec3(0.1f, 0.2f, 0.3f));
        expectNear(g.Os[size_t(k)], Vec3(0.5f));
        EXPECT_EQ(g.s[size_t(k)], g.u[size_t(k)]);
        // Black and opaque until a shader says otherwise (RI 3.2, 12.1.1).
        expectNear(g.Ci[size_t(k)], Vec3(0.f));
        expectNear(g.Oi[size_t(k)], Vec3(1.f));
    }
    EXPECT_EQ(g.primvars, &grid.vars);
    // A surface that sets only Ci keeps the opaque default.
    Harness h;
    h.surface("surface t() { Ci = color(s, 0, 0); }", g);
    for (int k = 0; k < 6; ++k) {
        expectNear(g.Ci[size_t(k)], Vec3(g.s[size_t(k)], 0, 0));
        expectNear(g.Oi[size_t(k)], Vec3(1.f));
    }
}

TEST(Language, AttributeOptionAndRendererInfo) {
    Harness h;
    ShadeValue id;
    id.type = ValueType::Float;
    id.floats = {42};
    h.svc.attributes["user:id"] = id;
    ShadingGrid g = line(2);
    h.surface("surface t() {\n"
              "  float v = -1, w = -1; string r = \"\";\n"
              "  float ok1 = attribute(\"user:id\", v), ok2 = attribute(\"user:none\", w), ok3 = rendererinfo(\"renderer\", r);\n"
              "  Ci = color(v + 10 * ok1, w + 10 * ok2, (r == \"umbra\") + 10 * ok3);\n"
              "  Oi = option(\"nope\", v);\n"
              "}",
              g);
    expectNear(g.Ci[0], Vec3(52, -1, 11));
    expectNear(g.Oi[0], Vec3(0, 0, 0));
}
