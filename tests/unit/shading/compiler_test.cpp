// Compiler diagnostics (the malformed-shader corpus in errors/), golden
// bytecode listings (golden/), and third-party-style shaders.

#include "shading_test_util.h"

#include <filesystem>
#include <fstream>
#include <sstream>

using namespace umbra;
using namespace umbra::shading;
using namespace umbra::shading::testing;

namespace {

namespace fs = std::filesystem;

std::string readText(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

fs::path testDir() { return fs::path(UMBRA_SOURCE_DIR) / "tests" / "unit" / "shading"; }

}  // namespace

// Each errors/NAME.sl must fail to compile with exactly the diagnostics in
// errors/NAME.expected (file named NAME.sl, as given to compileSource).
TEST(Compiler, MalformedShaderCorpus) {
    int cases = 0;
    for (const auto& entry : fs::directory_iterator(testDir() / "errors")) {
        if (entry.path().extension() != ".sl") continue;
        ++cases;
        Harness h;
        std::string name = entry.path().filename().string();
        auto sh = h.sys.compileSource(readText(entry.path()), name);
        EXPECT_FALSE(sh) << name;
        fs::path expectedPath = entry.path();
        expectedPath.replace_extension(".expected");
        ASSERT_TRUE(fs::exists(expectedPath)) << expectedPath;
        EXPECT_EQ(h.messages(), readText(expectedPath)) << name;
    }
    EXPECT_GE(cases, 10);
}

// Each golden/NAME.sl compiles to exactly the listing in golden/NAME.listing.
TEST(Compiler, GoldenListings) {
    int cases = 0;
    for (const auto& entry : fs::directory_iterator(testDir() / "golden")) {
        if (entry.path().extension() != ".sl") continue;
        ++cases;
        Harness h;
        auto sh = h.sys.compileSource(readText(entry.path()), entry.path().filename().string());
        ASSERT_TRUE(sh) << h.messages();
        fs::path expectedPath = entry.path();
        expectedPath.replace_extension(".listing");
        EXPECT_EQ(sh->listing(), readText(expectedPath)) << entry.path();
    }
    EXPECT_GE(cases, 2);
}

TEST(Compiler, ErrorMessageQuotesTheLineWithACaret) {
    Harness h;
    EXPECT_FALSE(h.sys.compileSource("surface x()\n{\n    Ci = foo * Cs;\n}\n", "shaders/x.sl"));
    // The source line is quoted as written, indented by four spaces.
    EXPECT_EQ(h.messages(), "shaders/x.sl:3:10: error: undefined variable 'foo'\n        Ci = foo * Cs;\n             ^\n");
}

TEST(Compiler, CompileFileAndIncludes) {
    fs::path dir = fs::temp_directory_path() / "umbra_shading_include_test";
    fs::create_directories(dir);
    {
        std::ofstream(dir / "common.h") << "#define KD 0.25\nfloat halve(float x) { return x / 2; }\n";
        std::ofstream(dir / "inc.sl") << "#include \"common.h\"\nsurface inc() { Ci = halve(KD) * Cs; }\n";
    }
    Diagnostics diag;
    diag.setSink([](const Diagnostic&) {});
    std::string listing;
    EXPECT_TRUE(compileFile((dir / "inc.sl").string(), {}, diag, &listing));
    EXPECT_EQ(diag.errorCount(), 0);
    EXPECT_NE(listing.find("surface inc"), std::string::npos);
    // halve(0.25) is constant-folded... or computed at run time: run it.
    Harness h;
    auto sh = h.sys.compile((dir / "inc.sl").string());
    ASSERT_TRUE(sh) << h.messages();
    EXPECT_EQ(h.sys.compile((dir / "inc.sl").string()), sh);  // cached
    scene::ShaderRecord rec;
    auto inst = h.sys.instantiate(sh, rec);
    ShadingGrid g = makeGrid(2, 1, [](float u, float) { return Vec3(u, 0, 1); });
    ShadeRequest req;
    req.surface = inst.get();
    h.sys.shade(g, req, h.svc);
    expectNear(g.Ci[0], Vec3(0.125f));
    EXPECT_FALSE(compileFile((dir / "missing.sl").string(), {}, diag, nullptr));
    fs::remove_all(dir);
}

// cpp's token pasting and stringizing, as 3Delight's XSI shader library
// writes each colour's alpha (`n##_a`); umbra refused `#` in a body.
TEST(Compiler, MacrosPasteAndStringizeTheirArguments) {
    Harness h;
    ShadingGrid g = makeGrid(2, 1, [](float u, float) { return Vec3(u, 0, 1); });
    h.surface("#define RGBA(n, r) color n = color(r, 0, 0); float n##_a = 0.5\n"
              "#define STR(x) #x\n"
              "#define GLUE(a, b) a ## b\n"
              "#define TWICE(x) (2 * x)\n"
              "surface t() {\n"
              "  RGBA(c1, 0.5);\n"
              "  string s = STR(hello);\n"
              "  float GLUE(k, 2) = GLUE(1, 5);\n"           /* k2 = 15 */
              "  float xy = 3; float e = TWICE(GLUE(x, y));\n"  /* TWICE(xy) = 6 */
              "  Ci = color(comp(c1, 0) * c1_a, s == \"hello\", k2 + e);\n"
              "}",
              g);
    expectNear(g.Ci[0], Vec3(0.25f, 1, 21));  // k2 + e = 15 + 6
}

// cpp rescans an expansion together with what follows it: a pasted or
// forwarded name of a function-like macro takes the arguments written after
// the expansion. umbra left the name unexpanded (then "undefined function").
// A macro's own name in its expansion is not expanded again (F below).
TEST(Compiler, ExpansionIsRescannedWithTheTokensAfterIt) {
    Harness h;
    ShadingGrid g = makeGrid(2, 1, [](float u, float) { return Vec3(u, 0, 1); });
    h.surface("float F(float y) { return y * 10; }\n"
              "#define GLUE(a, b) a ## b\n"
              "#define TWICE(x) (2 * (x))\n"
              "#define PICK TWICE\n"
              "#define ID(m) m\n"
              "#define F(x) x + F\n"
              "surface t() {\n"
              "  float a = GLUE(TW, ICE)(3);\n"    /* 6 */
              "  float b = PICK(4);\n"             /* 8 */
              "  float c = ID(TWICE)(5);\n"        /* 10 */
              "  float d = F(1)(2);\n"             /* 1 + F(2): the function, 21 */
              "  Ci = color(a, b + c, d);\n"
              "}",
              g);
    expectNear(g.Ci[0], Vec3(6, 18, 21));
}

// A user function returning a string (RI Spec 3.2 ch. 14: functions of any
// type) compiled, but its return copied the string as floats and crashed
// the render. Plain, with arguments, with two returns and nested.
TEST(Compiler, FunctionsReturnStrings) {
    Harness h;
    ShadingGrid g = makeGrid(2, 1, [](float u, float) { return Vec3(u, 0, 1); });
    h.surface("string f() { return \"a\"; }\n"
              "string pick(float k; string x, y) { if (k > 0) return x; return y; }\n"
              "surface t() {\n"
              "  string inner(string p) { return concat(p, \"!\"); }\n"
              "  string q = f(), r = pick(1, \"yes\", \"no\"), w = pick(0, \"yes\", \"no\");\n"
              "  Ci = color(q == \"a\", r == \"yes\" && w == \"no\", inner(q) == \"a!\");\n"
              "}",
              g);
    expectNear(g.Ci[0], Vec3(1, 1, 1));
}

// #if takes C's integer constant expressions: arithmetic, shifts, bitwise
// operators and ?: besides comparisons and logic, macros expanded first and
// names left over 0. umbra knew only comparisons and logic and refused the
// rest as a "malformed #if expression" (`#if TWO * 2 == 4` with TWO
// defined as (ONE + ONE)); cpp, Pixie and Aqsis evaluate them.
TEST(Compiler, IfEvaluatesCIntegerConstantExpressions) {
    const std::pair<const char*, bool> cases[] = {
        {"TWO * 2 == 4", true},
        {"2 + 3 * 4 == 14", true},
        {"1 - 1 - 1 == -1", true},
        {"7 / 2 == 3 && -7 / 2 == -3", true},
        {"10 % 3 == 1 && -7 % 3 == -1", true},
        {"(1 << 2) == 4 && (-16 >> 2) == -4 && 1 << 2 + 1 == 8", true},
        {"1 ? 2 : 0", true},
        {"0 ? 1 : 0 ? 1 : 0", false},
        {"~0 == -1 && (6 & 3) == 2 && (6 | 3) == 7 && (6 ^ 3) == 5", true},
        {"(5 & 2) || 0", false},
        {"defined TWO && defined(ONE) && !defined UNDEFINED && -+-1 == 1", true},
        {"UNDEFINED_NAME == 0 && UNDEFINED_NAME + 1", true},
        {"0 && 1 / 0 || (1 ? 1 : 1 % 0)", true},  // unevaluated: no division by zero
        {"0x1F == 31 && 010 == 8 && 10u == 10 && 1L == 1", true},
        {"-1 > 0u && -1 < 0", true},  // unsigned arithmetic if either side is
        {"2 * 3 < 5", false},
    };
    for (const auto& [expr, truth] : cases) {
        SCOPED_TRACE(expr);
        Harness h;
        ShadingGrid g = makeGrid(2, 1, [](float u, float) { return Vec3(u, 0, 1); });
        h.surface(fmt::format("#define ONE 1\n#define TWO (ONE + ONE)\n"
                              "#if {}\n#define RES 0.4\n#else\n#define RES 0.8\n#endif\n"
                              "surface t() {{ Ci = RES; }}\n",
                              expr),
                  g);
        expectNear(g.Ci[0], Vec3(truth ? 0.4f : 0.8f));
    }
    Harness h;
    ShadingGrid g = makeGrid(2, 1, [](float u, float) { return Vec3(u, 0, 1); });
    h.surface("#if 0\n#define RES 0.1\n#elif 2 * 3 > 5\n#define RES 0.2\n#endif\nsurface t() { Ci = RES; }\n", g);
    expectNear(g.Ci[0], Vec3(0.2f));
    // Errors name their place; garbage is refused without overflowing the stack.
    h.expectRefused("#if 1 / (2 - 2)\n#endif\nsurface t() { Ci = 1; }\n",
                    "t.sl:1:7: error: division by zero in #if expression");
    h.expectRefused("#if 1.5 > 1\n#endif\nsurface t() { Ci = 1; }\n", "t.sl:1:5: error: floating constant '1.5'");
    h.expectRefused("#if (1 + 2\n#endif\nsurface t() { Ci = 1; }\n", "t.sl:1:10: error: expected ')'");
    h.expectRefused("#if 1 +\n#endif\nsurface t() { Ci = 1; }\n", "t.sl:1:7: error: missing operand");
    for (const std::string& garbage : {std::string(5000, '('), std::string(5000, '-'), [] {
             std::string s;
             for (int i = 0; i < 2000; ++i) s += "1 ? 1 : ";
             return s;
         }()})
        h.expectRefused("#if " + garbage + "1\n#endif\nsurface t() { Ci = 1; }\n", "#if expression nested too deeply");
}

// cpp looks only for directives in a skipped #if group, so notes holding
// `@`, `$`, a backtick, an apostrophe or a lone quote may sit there, and an
// unused macro may hold them too. umbra lexed the skipped text as shading
// language and refused it ("unexpected character '@'"); cpp, Pixie and
// Aqsis compile it (with the apostrophe gcc only warns and Aqsis accepts).
TEST(Compiler, SkippedGroupsAreOnlyScannedForDirectives) {
    Harness h;
    ShadingGrid g = makeGrid(2, 1, [](float u, float) { return Vec3(u, 0, 1); });
    h.surface("#if 0\n"
              "  old version by joe@studio, cost $5, see `notes`\n"
              "  this doesn't work, nor does \"this\n"
              "#if 1\n"
              "  @\n"
              "#endif\n"
              "#elif 0\n"
              "  $\n"
              "#else\n"
              "#define RES 0.5\n"
              "#endif\n"
              "#define UNUSED @ $\n"
              "surface t() { Ci = RES; }\n",
              g);
    expectNear(g.Ci[0], Vec3(0.5f));
    // In the shader's text they are errors where they stand.
    h.expectRefused("#define AT @\nsurface t() {\n  Ci = 1; $\n  string s = \"open;\n  Ci = AT;\n}\n",
                    "t.sl:3:11: error: unexpected character '$'");
    EXPECT_NE(h.messages().find("t.sl:4:14: error: unterminated string"), std::string::npos) << h.messages();
    EXPECT_NE(h.messages().find("t.sl:5:8: error: unexpected character '@'"), std::string::npos) << h.messages();
}

// cpp predefines __LINE__ (the line of its use; inside a macro, of the
// macro's use) and __FILE__ (the file's name as a string literal). umbra
// had neither ("undefined variable '__LINE__'"); cpp, Pixie and Aqsis have
// both.
TEST(Compiler, LineAndFileArePredefinedMacros) {
    Harness h;
    ShadingGrid g = makeGrid(2, 1, [](float u, float) { return Vec3(u, 0, 1); });
    h.surface("#define HERE __LINE__\n"
              "surface t() {\n"
              "  float a = __LINE__;\n"
              "  float b = HERE;\n"
              "  float c = __FILE__ == \"test.sl\";\n"
              "#if __LINE__ == 6 && defined(__FILE__) && defined __LINE__\n"
              "  Ci = color(a, b, c);\n"
              "#endif\n"
              "}\n",
              g);
    expectNear(g.Ci[0], Vec3(3, 4, 1));
}

// C splices lines (drops each backslash-newline) before it recognises
// comments, so a // comment ending in a backslash swallows the next line,
// and a token may go on over a splice. umbra ended the comment at the line
// and ran `Ci = 0.9` silently; cpp and Aqsis give 0.3 (gcc warns of a
// multi-line comment), Pixie 0.9 as umbra did.
TEST(Compiler, LinesAreSplicedBeforeCommentsAreRecognised) {
    Harness h;
    ShadingGrid g = makeGrid(2, 1, [](float u, float) { return Vec3(u, 0, 1); });
    h.surface("surface t() {\n"
              "  Ci = 0.3; // a comment ending in a backslash \\\n"
              "  Ci = 0.9;\n"
              "  float ten = 1\\\n"
              "0; float line = __LINE__;\n"
              "  Ci = color(comp(Ci, 0), ten, line);\n"
              "}\n",
              g);
    expectNear(g.Ci[0], Vec3(0.3f, 10, 5));
    // Errors after splices and comments keep the lines and columns as written.
    h.expectRefused("surface t() {\n  // \\\n  Ci = 1;\n  Ci = foo\\\nbar; /*\n */ Ci = baz;\n}\n",
                    "t.sl:4:8: error: undefined variable 'foobar'");
    EXPECT_NE(h.messages().find("t.sl:6:10: error: undefined variable 'baz'"), std::string::npos) << h.messages();
}

// for (float i = 0; ...): a declaration in the loop's first clause, as
// student shaders write it (Aqsis takes it; Pixie does not). umbra said
// "the left side of an assignment must be a variable". The loop's `i` is
// its own: an outer `i` keeps its value.
TEST(Compiler, ForLoopDeclaresItsCounter) {
    Harness h;
    ShadingGrid g = makeGrid(2, 1, [](float u, float) { return Vec3(u, 0, 1); });
    h.surface("surface t() {\n"
              "  float n = 0, i = 7;\n"
              "  for (float i = 0, k = 2; i < 4; i += 1) n += 0.25 * k;\n"
              "  for (uniform float j = 0; j < 3; j += 1) n += 1;\n"
              "  Ci = color(n, i, 0);\n"
              "}",
              g);
    expectNear(g.Ci[0], Vec3(5, 7, 0));
}

// A shader in the style found in the wild: macros with arguments, nested
// functions with output parameters, illuminance with categories, output
// parameters, arrays, and the RI spec 3.2 idioms.
TEST(Compiler, ThirdPartyStyleShaderCompilesAndRuns) {
    Harness h;
    h.svc.spaces["world"] = Mat4::identity();
    const char* src = R"(
#define SNOISE(p) (2 * noise(p) - 1)
#define LUMINANCE(c) (.299 * comp(c, 0) + .587 * comp(c, 1) + .114 * comp(c, 2))
#ifndef PI_2
#define PI_2 (PI / 2)
#endif

color blinnphong(normal Nn; vector V; float rough; string cat; output float nlights) {
    color C = 0;
    nlights = 0;
    illuminance(cat, P, Nn, PI_2) {
        extern vector L;
        vector H = normalize(normalize(L) + V);
        C += Cl * pow(max(0, Nn . H), 1 / rough);
        nlights += 1;
    }
    return C;
}

surface fancy(float Kd = .6, Ks = .4, roughness = .2;
              color stripes[2] = {color(1, 0, 0), color(0, 0, 1)};
              output varying float aov_lum = 0; output varying float aov_n = 0;)
{
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    float which = mod(floor(s * 4), 2);
    color base = stripes[which];
    float wobble = SNOISE(P * 3) * 0.05;
    void tint(output color c; float amount) {
        c = mix(c, color(1, 1, 1), amount);
    }
    tint(base, clamp(wobble, 0, 1));
    float n;
    Ci = Os * (base * Kd * diffuse(Nf) + Ks * blinnphong(Nf, V, roughness, "key", n));
    Oi = Os;
    aov_lum = LUMINANCE(Ci);
    aov_n = n;
}
)";
    auto surf = h.instance(src);
    ASSERT_TRUE(surf) << h.messages();
    auto key = h.instance("light k(string __category = \"key\") { solar(vector(0, 0, 1), 0) Cl = 1; }");
    auto fill = h.instance("light f(string __category = \"fill\") { solar(vector(0, 0, 1), 0) Cl = 0.5; }");
    ShadingGrid g = makeGrid(8, 2, [](float u, float v) { return Vec3(u - 0.5f, v - 0.5f, 3); });
    ShadeRequest req;
    req.surface = surf.get();
    req.lights = {key.get(), fill.get()};
    req.outputs = {"aov_lum", "aov_n"};
    h.sys.shade(g, req, h.svc);
    std::vector<float> lum, n;
    int per;
    ASSERT_TRUE(g.output("aov_lum", &lum, &per));
    ASSERT_TRUE(g.output("aov_n", &n, &per));
    for (int i = 0; i < g.size(); ++i) {
        const Vec3& c = g.Ci[size_t(i)];
        EXPECT_NEAR(lum[size_t(i)], .299f * c.x + .587f * c.y + .114f * c.z, 1e-5f);
        EXPECT_EQ(n[size_t(i)], 1);  // only the "key" light matches the category
        // The stripe colour dominates: red stripes have more red than blue.
        bool red = int(std::floor(g.s[size_t(i)] * 4)) % 2 == 0;
        EXPECT_EQ(red, c.x > c.z) << i;
    }
}

TEST(Compiler, PathologicalInputsAreRejectedNotCrashing) {
    Harness h;
    std::string longSum = "surface t() { Ci = s";
    for (int i = 0; i < 5000; ++i) longSum += " + s";
    longSum += "; }";
    EXPECT_FALSE(h.sys.compileSource(longSum, "long.sl"));
    std::string deep = "surface t() { Ci = " + std::string(1000, '(') + "s" + std::string(1000, ')') + "; }";
    EXPECT_FALSE(h.sys.compileSource(deep, "deep.sl"));
    // Exponential macro expansion is cut off.
    std::string bomb = "#define A0 s\n";
    for (int i = 1; i < 40; ++i) bomb += fmt::format("#define A{} A{} + A{}\n", i, i - 1, i - 1);
    bomb += "surface t() { Ci = A39; }\n";
    EXPECT_FALSE(h.sys.compileSource(bomb, "bomb.sl"));
    // Self-referencing macros stop expanding at themselves.
    EXPECT_FALSE(h.sys.compileSource("#define X X + 1\nsurface t() { Ci = X; }\n", "self.sl"));
    std::string msgs = h.messages();
    EXPECT_NE(msgs.find("long.sl:1:"), std::string::npos) << msgs;
    EXPECT_NE(msgs.find("expression too long"), std::string::npos);
    EXPECT_NE(msgs.find("nested too deeply"), std::string::npos);
    EXPECT_NE(msgs.find("macro expansion too large"), std::string::npos);
    EXPECT_NE(msgs.find("self.sl:2:20: error: undefined variable 'X'"), std::string::npos) << msgs;
}
