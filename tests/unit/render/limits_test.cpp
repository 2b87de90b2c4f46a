// Inputs past the renderer's limits (docs/rib.md, "Limits") finish with a
// located warning and a sensible image instead of hanging or exhausting
// memory. Renders whose risk is memory run the `umbra` command in a child
// process under a 1 GiB address-space limit (RLIMIT_AS); its exit status,
// messages and image are checked. A CPU-time limit turns a runaway render
// into a failure instead of a stall; no test reads a clock.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <sstream>

using namespace umbra;
using umbra::test::Image;
using umbra::test::ScratchDir;

namespace {

// A sanitized build: g++ says so with __SANITIZE_*__, clang with
// __has_feature. Under a sanitizer the address-space limit cannot hold
// (the shadow memory alone reserves terabytes) and everything runs several
// times slower.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define UMBRA_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
#define UMBRA_SANITIZED 1
#endif
#endif

constexpr rlim_t kAddressSpace = rlim_t(1) << 30;  // 1 GiB
// The CPU limit turns a hang into a failure; it is far beyond any of these
// renders. A sanitized umbra on a loaded CI machine needs many times more
// (one render went past 300 s under ThreadSanitizer).
#ifdef UMBRA_SANITIZED
constexpr rlim_t kCpuSeconds = 3000;
#else
constexpr rlim_t kCpuSeconds = 300;
#endif

/// How a child render ended.
struct ChildRun {
    bool exited = false;  // false: killed by a signal (e.g. SIGXCPU, SIGSEGV)
    int status = -1;      // exit status, or the signal
    std::string messages; // what it printed
    std::string describe() const {
        return fmt::format("{} {}; output:\n{}", exited ? "exit status" : "killed by signal", status, messages);
    }
};

std::string readText(const std::string& path) {
    std::ifstream in(path);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

/// Renders the scene at `ribPath` with `umbra render --threads 2` in a
/// child process limited to 1 GiB of address space.
ChildRun runInChild(const std::string& ribPath, const std::vector<std::string>& options = {}) {
    const std::string logPath = ribPath + ".log";
    const pid_t pid = fork();
    if (pid == 0) {
        rlimit as{kAddressSpace, kAddressSpace};
        rlimit cpu{kCpuSeconds, kCpuSeconds};
        // Sanitizers reserve terabytes of shadow address space, so under
        // them the memory bound is theirs to check (the umbra they run is
        // the sanitized build too); the CPU bound still holds.
#ifndef UMBRA_SANITIZED
        setrlimit(RLIMIT_AS, &as);
#else
        (void)as;
#endif
        setrlimit(RLIMIT_CPU, &cpu);
        const int fd = open(logPath.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fd >= 0) {
            dup2(fd, 1);
            dup2(fd, 2);
        }
        setenv("UMBRA_SHADER_PATH", UMBRA_SOURCE_DIR "/shaders_dsl", 1);
        std::vector<const char*> argv{"umbra", "render", "--threads", "2"};
        for (const std::string& o : options) argv.push_back(o.c_str());
        argv.push_back(ribPath.c_str());
        argv.push_back(nullptr);
        execv(UMBRA_APP, const_cast<char* const*>(argv.data()));
        _exit(127);
    }
    ChildRun run;
    int status = 0;
    if (pid < 0 || waitpid(pid, &status, 0) != pid) return run;
    run.exited = WIFEXITED(status);
    run.status = run.exited ? WEXITSTATUS(status) : WTERMSIG(status);
    run.messages = readText(logPath);
    return run;
}

/// Writes `rib` to dir/name and renders it in a child process (runInChild).
ChildRun renderInChild(const ScratchDir& dir, const std::string& name, const std::string& rib,
                       const std::vector<std::string>& options = {}) {
    const std::string ribPath = dir.file(name);
    {
        std::ofstream out(ribPath);
        out << rib;
    }
    return runInChild(ribPath, options);
}

/// A 64 x 48 perspective frame of `world`, camera 5 units back; its
/// Display writes `out`.
std::string frame(const std::string& out, const std::string& options, const std::string& world) {
    return fmt::format(R"(Display "{}" "openexr" "rgba" "string type" "float"
Format 64 48 1
Projection "perspective" "fov" 40
{}
Translate 0 0 5
WorldBegin
Surface "constant"
{}
WorldEnd
)", out, options, world);
}

/// Sum of the alpha channel: the covered area in pixels.
double coverage(const std::string& path) {
    Image img;
    EXPECT_TRUE(test::readImage(path, &img)) << path;
    return img.pixels.empty() ? 0.0 : img.channelSum(3);
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

/// A 64 x 48 frame of a sphere shaded by `body`, a surface shader written
/// to the scratch folder.
std::string shaderFrame(const ScratchDir& dir, const std::string& body) {
    std::ofstream(dir.file("probe.sl")) << "surface probe() {\n" << body << "\n}\n";
    return fmt::format(R"(Option "searchpath" "shader" ["{}:&"]
Display "{}" "openexr" "rgba" "string type" "float"
Format 64 48 1
Projection "perspective" "fov" 40
Translate 0 0 3
WorldBegin
Surface "probe"
Sphere 1 -1 1 360
WorldEnd
)", dir.file(""), dir.file("out.exr"));
}

}  // namespace

TEST(Limits, ShaderStringsAndFormatsAreBounded) {
    // concat(s, s) forty times would be a terabyte; a format width of a
    // billion pads a gigabyte. Both are cut with one located warning.
    ScratchDir dir("limits-strings");
    const ChildRun concat = renderInChild(
        dir, "concat.rib",
        shaderFrame(dir, "string s = \"ab\"; float i; for (i = 0; i < 40; i += 1) s = concat(s, s);\n"
                         "Ci = match(\"^(ab)+$\", s); Oi = 1;"));
    ASSERT_TRUE(concat.exited && concat.status == 0) << concat.describe();
    EXPECT_TRUE(contains(concat.messages, "probe.sl:2:59: warning: shader 'probe': concat() made a string longer "
                                          "than 1048576 bytes; cut to that length"))
        << concat.messages;
    EXPECT_GT(coverage(dir.file("out.exr")), 100.0);
    const ChildRun format = renderInChild(
        dir, "format.rib",
        shaderFrame(dir, "string s = format(\"%999999999d\", 1); Ci = match(\"1$\", s); Oi = 1;"));
    ASSERT_TRUE(format.exited && format.status == 0) << format.describe();
    EXPECT_TRUE(contains(format.messages, "warning: shader 'probe': a format width or precision above 256 is cut to it"))
        << format.messages;
    // The padded number still ends in 1: match() finds it, Ci = 1.
    Image img;
    ASSERT_TRUE(test::readImage(dir.file("out.exr"), &img));
    EXPECT_GT(img.channelSum(0), 100.0);
}

TEST(Limits, MatchTakesLinearTimeOnPatternsThatBacktrack) {
    // "(a*)*b" against a's without a b backtracks exponentially in engines
    // that backtrack; match() is linear. The CPU limit would kill a hang.
    ScratchDir dir("limits-regex");
    const ChildRun run = renderInChild(
        dir, "regex.rib",
        shaderFrame(dir, "string s = \"aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaac\";\n"
                         "Ci = 1 - match(\"(a*)*b\", s); Oi = 1;"));
    ASSERT_TRUE(run.exited && run.status == 0) << run.describe();
    Image img;
    ASSERT_TRUE(test::readImage(dir.file("out.exr"), &img));
    EXPECT_GT(img.channelSum(0), 100.0);  // no match: Ci = 1 where the sphere is
}

TEST(Limits, ALoopThatNeverEndsIsStoppedPerGridWithOneWarning) {
    ScratchDir dir("limits-loop");
    const ChildRun run =
        renderInChild(dir, "loop.rib", shaderFrame(dir, "float i = 0; while (1) { i += 1; } Ci = 1; Oi = 1;"));
    ASSERT_TRUE(run.exited && run.status == 0) << run.describe();
    EXPECT_TRUE(contains(run.messages, "probe.sl:2:14: warning: shader 'probe': loops ran more than")) << run.messages;
    size_t first = run.messages.find("loops ran more than");
    EXPECT_EQ(run.messages.find("loops ran more than", first + 1), std::string::npos) << "one warning";
    EXPECT_GT(coverage(dir.file("out.exr")), 100.0);
}

TEST(Limits, QuadricSweepsOfAHugeAngleAreClampedToOneTurn) {
    // thetamax 1e30 left u * thetamax no precision, so splitting never made
    // pieces small enough to dice. Clamped, each quadric renders whole.
    ScratchDir dir("limits-sweep");
    const std::string world = R"(AttributeBegin Translate -1.5 0.6 0 Rotate -60 1 0 0 Sphere 0.4 -0.4 0.4 1e30 AttributeEnd
AttributeBegin Translate -0.5 0.6 0 Rotate -60 1 0 0 Cylinder 0.3 -0.3 0.3 -1e30 AttributeEnd
AttributeBegin Translate 0.5 0.6 0 Rotate -60 1 0 0 Cone 0.5 0.3 1e30 AttributeEnd
AttributeBegin Translate 1.5 0.6 0 Rotate -60 1 0 0 Disk 0 0.3 1e30 AttributeEnd
AttributeBegin Translate -1 -0.6 0 Rotate -60 1 0 0 Paraboloid 0.3 0 0.5 1e30 AttributeEnd
AttributeBegin Translate 0 -0.6 0 Rotate -60 1 0 0 Hyperboloid 0.3 0 -0.3 0.3 0 0.3 1e30 AttributeEnd
AttributeBegin Translate 1 -0.6 0 Rotate -60 1 0 0 Torus 0.25 0.1 -1e30 1e30 1e30 AttributeEnd
)";
    const ChildRun run = renderInChild(dir, "sweep.rib", frame(dir.file("out.exr"), "", world));
    ASSERT_TRUE(run.exited && run.status == 0) << run.describe();
    EXPECT_TRUE(contains(run.messages, "sweep.rib:8:54: warning: Sphere: thetamax 1e+30 is outside [-360, 360] "
                                       "degrees; clamped to 360"))
        << run.messages;
    EXPECT_TRUE(contains(run.messages, "sweep.rib:14:52: warning: Torus: phimin -1e+30 is outside")) << run.messages;
    // Seven shapes of a few dozen pixels each.
    EXPECT_GT(coverage(dir.file("out.exr")), 7 * 20.0);
}

TEST(Limits, TinyShadingRateIsClampedAndTheSphereStillRenders) {
    // ShadingRate 1e-6 asked for a million micropolygons a pixel.
    ScratchDir dir("limits-rate");
    const std::string sphere = "Sphere 1 -1 1 360";
    const ChildRun ref = renderInChild(dir, "ref.rib", frame(dir.file("ref.exr"), "", "ShadingRate 1\n" + sphere));
    ASSERT_TRUE(ref.exited && ref.status == 0) << ref.describe();
    const ChildRun run = renderInChild(dir, "tiny.rib", frame(dir.file("tiny.exr"), "", "ShadingRate 1e-6\n" + sphere));
    ASSERT_TRUE(run.exited && run.status == 0) << run.describe();
    EXPECT_TRUE(contains(run.messages, "tiny.rib:8:1: warning: ShadingRate: 1e-06 is below the minimum of 1/64 "
                                       "pixel; clamped to 0.015625"))
        << run.messages;
    const double a = coverage(dir.file("ref.exr")), b = coverage(dir.file("tiny.exr"));
    EXPECT_GT(a, 200.0);
    EXPECT_NEAR(b, a, 0.02 * a);
}

TEST(Limits, InstancesNestedInDefinitionsStopAtTheDefinitionsBudget) {
    // Each object holds four instances of the one before: object 20 would
    // hold 4^19 disks. The definitions stop at 256 MiB, with one error at
    // the first instance refused, and the frame renders (the disks lie
    // behind the eye; the sphere is in view).
    ScratchDir dir("limits-nested-instances");
    std::string world = "ObjectBegin 1 Disk 0 .01 360 ObjectEnd\n";
    for (int k = 2; k <= 20; ++k)
        world += fmt::format("ObjectBegin {} ObjectInstance {} ObjectInstance {} Translate .01 0 0 ObjectInstance {} "
                             "ObjectInstance {} ObjectEnd\n", k, k - 1, k - 1, k - 1, k - 1);
    world += "AttributeBegin Translate 0 0 -100 ObjectInstance 20 AttributeEnd\nSphere 1 -1 1 360\n";
    const ChildRun run = renderInChild(dir, "nested.rib", frame(dir.file("out.exr"), "", world));
    ASSERT_TRUE(run.exited) << run.describe();
    EXPECT_NE(run.status, 0) << run.describe();  // an error was reported
    EXPECT_TRUE(contains(run.messages, "error: ObjectInstance: the object definitions would hold more than 256 MiB "
                                       "(instances nested too deep?); this instance in"))
        << run.messages;
    EXPECT_GT(coverage(dir.file("out.exr")), 200.0);
}

TEST(Limits, HugePixelSamplesAndFilterAreClampedWithinOneGigabyte) {
    // PixelSamples 1000 1000 on a 64 x 48 frame would be 3e9 samples, and a
    // filter 1e6 pixels wide would make every bucket sample the whole
    // frame; together they are the largest sample buffer the limits allow.
    ScratchDir dir("limits-samples");
    const std::string sphere = "Sphere 1 -1 1 360";
    const ChildRun ref = renderInChild(dir, "ref.rib", frame(dir.file("ref.exr"), "", sphere));
    ASSERT_TRUE(ref.exited && ref.status == 0) << ref.describe();
    const ChildRun run = renderInChild(
        dir, "big.rib", frame(dir.file("big.exr"), "PixelSamples 1000 1000\nPixelFilter \"gaussian\" 1e6 1e6", sphere));
    ASSERT_TRUE(run.exited && run.status == 0) << run.describe();
    EXPECT_TRUE(contains(run.messages, "big.rib:4:1: warning: PixelSamples: 1000 1000 exceeds the maximum of 32 "
                                       "samples along each axis of a pixel; clamped to 32 32"))
        << run.messages;
    EXPECT_TRUE(contains(run.messages, "big.rib:5:1: warning: PixelFilter: widths 1000000 1000000 exceed the maximum of "
                                       "16 pixels; clamped to 16 16"))
        << run.messages;
    // A wide filter spreads the sphere, some of it off the frame; but it is
    // there, and nothing is out of range.
    Image img;
    ASSERT_TRUE(test::readImage(dir.file("big.exr"), &img));
    for (float v : img.pixels) ASSERT_TRUE(std::isfinite(v) && v >= -1e-4f && v <= 1.0001f) << v;
    const double a = coverage(dir.file("ref.exr")), b = img.channelSum(3);
    EXPECT_GT(b, 0.3 * a);
    EXPECT_LT(b, 1.05 * a);
}

TEST(Limits, HugeShadingRateDicesBlockyButPresent) {
    // ShadingRate 1000 is a micropolygon 32 pixels on a side: the sphere
    // (about 40 pixels across) used to be diced into a grid whose corners
    // lie on one meridian and covers nothing. It is diced coarsely, into at
    // least 8 x 4 micropolygons, and covers most of its disk.
    ScratchDir dir("limits-coarse");
    Diagnostics diag;
    test::renderRib(frame(dir.file("fine.exr"), "", "ShadingRate 1\nSphere 1 -1 1 360"), diag);
    auto coarseStats = test::renderRib(frame(dir.file("coarse.exr"), "", "ShadingRate 1000\nSphere 1 -1 1 360"), diag);
    ASSERT_EQ(diag.errorCount(), 0);
    const double fine = coverage(dir.file("fine.exr")), coarse = coverage(dir.file("coarse.exr"));
    EXPECT_GT(fine, 200.0);
    EXPECT_GT(coarse, 0.75 * fine);
    EXPECT_LT(coarse, 1.01 * fine);  // the facets lie inside the sphere
    const auto& counts = coarseStats["frames"][0]["passes"][0]["counts"];
    EXPECT_GE(counts["micropolygons"].get<uint64_t>(), 32u);
    EXPECT_LE(counts["micropolygons"].get<uint64_t>(), 64u);  // coarse: far fewer than the ~1000 pixels at rate 1
}

TEST(Limits, SurfacesBeyondFloatPrecisionFinishAndCoverWhatTheyShould) {
    // A split halves a parameter range, and float halves [0, 1] only about
    // 24 times: a surface needing more (a ground plane 10^8 units across,
    // a patch 10^12 wide seen orthographically) once split on into pieces
    // equal to their parent, doubling forever until memory ran out. Such
    // pieces are now diced coarsely, with one warning.
    ScratchDir dir("limits-precision");
    const std::string ortho = R"(Display "{}" "openexr" "rgba" "string type" "float"
Format 64 48 1
WorldBegin
Surface "constant"
{}
WorldEnd
)";
    // The orthographic view is [-4/3, 4/3] x [-1, 1]: the patch covers it all.
    const ChildRun wide = renderInChild(
        dir, "wide.rib",
        fmt::format(fmt::runtime(ortho), dir.file("wide.exr"), "Patch \"bilinear\" \"P\" [-1e12 -1e12 5  1e12 -1e12 5  "
                                                 "-1e12 1e12 5  1e12 1e12 5]"));
    ASSERT_TRUE(wide.exited && wide.status == 0) << wide.describe();
    EXPECT_TRUE(contains(wide.messages, "wide.rib:5:1: warning: Patch: a piece spans more pixels than float "
                                        "precision lets it be split into"))
        << wide.messages;
    EXPECT_NEAR(coverage(dir.file("wide.exr")), 64.0 * 48.0, 1e-3);

    // Pieces that every halving float allows would leave far larger than
    // the frame are diced coarsely at once: split, they all stayed in view
    // (the wedges around a sphere's pole, the pieces of a ribbon wider than
    // the frame) and multiplied until memory ran out. Each covers the view.
    for (const std::string& shape : {std::string("Sphere 1e12 -1e12 1e12 360"),
                                     std::string("Curves \"linear\" [2] \"nonperiodic\" \"P\" [-1e12 0 5  1e12 0 5] "
                                                 "\"constantwidth\" [1e12]")}) {
        const ChildRun run =
            renderInChild(dir, "huge.rib", fmt::format(fmt::runtime(ortho), dir.file("huge.exr"), shape));
        ASSERT_TRUE(run.exited && run.status == 0) << shape << ": " << run.describe();
        EXPECT_TRUE(contains(run.messages, "float precision")) << run.messages;
        EXPECT_NEAR(coverage(dir.file("huge.exr")), 64.0 * 48.0, 1e-3) << shape;
    }

    // The ground y = -1 from z = 1 to 10^8 under a 40-degree camera at the
    // origin: it reaches from below the frame to the horizon, row 24 (at
    // z = 10^8 it is 10^-7 pixels below it), across the whole width.
    const ChildRun ground = renderInChild(dir, "ground.rib",
                                          frame(dir.file("ground.exr"), "Translate 0 0 -5",
                                                "Patch \"bilinear\" \"P\" [-1e8 -1 1  1e8 -1 1  -1e8 -1 1e8  "
                                                "1e8 -1 1e8]"));
    ASSERT_TRUE(ground.exited && ground.status == 0) << ground.describe();
    EXPECT_NEAR(coverage(dir.file("ground.exr")), 64.0 * 24.0, 0.01 * 64 * 24);

    // A Catmull-Clark cube, half of its corners thrown out to 10^21 ..
    // 10^31 (a mutation the render fuzzer made): a limit-surface step's
    // length squared its coordinates and overflowed, so every piece kept
    // the whole face's bound and splitting never shrank it.
    const ChildRun cube = renderInChild(
        dir, "cube.rib",
        fmt::format(fmt::runtime(ortho), dir.file("cube.exr"),
                    "SubdivisionMesh \"catmull-clark\" [4 4 4 4 4 4] "
                    "[0 1 3 2 2 3 5 4 4 5 7 6 6 7 1 0 1 7 5 3 6 0 2 4] [] [] [] []\n"
                    "  \"P\" [-1 -1 1  1 -1 1  -1 1 1  1 1 1  4.5e21 1.8e31 -1.4e8  7.5e28 8.2e30 0  "
                    "1.1e27 -1.5e8 0  7.2e22 1.1e27 1.1e21]"));
    ASSERT_TRUE(cube.exited && cube.status == 0) << cube.describe();
}

TEST(Limits, ASurfaceWhosePiecesPileUpInViewStopsAtItsSplitBudget) {
    // A NuPatch with one control point thrown out to (0.3, 2.4e8, 4.5e30)
    // (a mutation the render fuzzer made), seen orthographically: all of
    // the patch but slivers along two edges, within 10^-8 of them in v,
    // lies far off the frame, but those slivers sweep across every row of
    // it. Pieces along them stay in view down to float precision, and they
    // multiplied until memory ran out (4 GB in 18 seconds; Aqsis 1.8.4
    // does not finish it either). A primitive's pieces may now need 64
    // times what it needs between them, its need no more than its bound
    // holds in the frame: 66 x 50 pixels (64 x 48 and the filter's margin
    // of 1) and a 16-pixel strip along each side, at most
    // 64 x (66 x 50 + 16 x 2 x (66 + 50) + 16) pixels, 1,757 grids' worth.
    // The sphere beside it has a budget of its own and renders whole.
    ScratchDir dir("limits-budget");
    const std::string scene = R"(Display "{}" "openexr" "rgba" "string type" "float"
Format 64 48 1
WorldBegin
Surface "constant"
AttributeBegin
  Translate -0.7 0 5
  Sphere 0.5 -0.5 0.5 360
AttributeEnd
{}
WorldEnd
)";
    const std::string patch = R"(AttributeBegin
  Translate 1 0 5
  NuPatch 4 4 [0 0 0 0 1 1 1 1] 0 1 4 4 [0 0 0 0 1 1 1 1] 0 1 "Pw" [
    -1 -1 0 1  -0.3 -1 0 1  0.3 -1 0 1  1 -1 0 1
    -1 -0.3 0 1  -0.3 -0.3 1 1  0.3 -0.3 1 1  1 -0.3 0 1
    -1 0.3 0 1  -0.3 0.3 1 1  0.3 {} 1  1 0.3 0 1
    -1 1 0 1  -0.3 1 0 1  0.3 1 0 1  1 1 0 1]
AttributeEnd)";
    auto render = [&](const std::string& name, const std::string& world, std::vector<std::string> options = {}) {
        const ChildRun run = renderInChild(dir, name + ".rib",
                                           fmt::format(fmt::runtime(scene), dir.file(name + ".exr"), world), options);
        EXPECT_TRUE(run.exited && run.status == 0) << name << ": " << run.describe();
        return run;
    };
    const std::string stats = dir.file("corrupt.json");
    const ChildRun corrupt =
        render("corrupt", fmt::format(fmt::runtime(patch), "2.4e8 4.5e30"), {"--stats", stats});
    EXPECT_TRUE(contains(corrupt.messages, "corrupt.rib:11:3: warning: NuPatch: its pieces would cover the frame "
                                           "many times over"))
        << corrupt.messages;
    const auto counts = nlohmann::json::parse(readText(stats))["frames"][0]["passes"][0]["counts"];
    EXPECT_LE(counts["grids"].get<uint64_t>(), 64u * (66u * 50u + 16u * 2u * (66u + 50u) + 16u) / 256u + 8u);

    // The slivers cover what the healthy patch covers, the frame's right
    // third (x from 0 to 4/3 of [-4/3, 4/3]); the sphere beside it is whole.
    render("sphere", "");
    render("healthy", fmt::format(fmt::runtime(patch), "0.3 0"));
    const double withCorrupt = coverage(dir.file("corrupt.exr")), sphereOnly = coverage(dir.file("sphere.exr")),
                 withHealthy = coverage(dir.file("healthy.exr"));
    const double disc = kPi * 0.5 * 0.5 * 24 * 24;  // 24 pixels a unit
    EXPECT_NEAR(sphereOnly, disc, 0.03 * disc);
    EXPECT_NEAR(withHealthy, sphereOnly + 32 * 48, 0.01 * 32 * 48);
    EXPECT_NEAR(withCorrupt, withHealthy, 0.01 * 32 * 48);
}

TEST(Limits, SurfacesThatTileTheImageNeverSpendTheirSplitBudget) {
    // Ordinary surfaces whose pieces' bounds overlap heavily: a ground
    // plane 2,000 units wide running from under the camera to the horizon
    // (every wedge's bound reaches the horizon; slivers along it need more
    // micropolygons than their area), the same plane crossing the frame
    // under motion blur, and a sphere filling the frame. The first split
    // budget, shared by the pieces' bound areas, ran out on the plane and
    // diced parts of it coarsely with the budget's warning. Measured on the
    // surface, none of them comes near it; each covers what it should.
    const std::string ground = R"(Patch "bilinear" "P" [-1000 0 0.1  1000 0 0.1  -1000 0 2000  1000 0 2000])";
    // The camera is a unit above the ground, 3.1 units from its near edge
    // and 2,003 from its far one, turned 10 degrees up; the ground covers
    // the rows between those edges' depression angles (each seen 10
    // degrees further below the centre), across the whole width.
    const auto row = [](double depression) { return 120.0 * std::tan(depression + 10 * kPi / 180) / std::tan(kPi / 6); };
    const double groundShare = (row(std::atan(1 / 3.1)) - row(std::atan(1 / 2003.0))) / 240.0;
    struct Case {
        const char* name;
        std::string options, world;
        double coverage;  // share of the frame
    };
    const std::vector<Case> cases = {
        {"ground", "Rotate 10 1 0 0\nTranslate 0 -1 0", ground, groundShare},
        {"moving ground", "Shutter 0 1\nRotate 10 1 0 0\nTranslate 0 -1 0",
         "MotionBegin [0 1]\nTranslate -3 0 0\nTranslate 3 0 0\nMotionEnd\n" + ground, groundShare},
        {"sphere", "", "Sphere 3 -3 3 360", 1.0},
    };
    for (const Case& c : cases) {
        ScratchDir dir("limits-tiling");
        const std::string out = dir.file("out.exr");
        Diagnostics diag;
        diag.setRecord(true);
        diag.setSink([](const Diagnostic&) {});
        test::renderRib(fmt::format(R"(Display "{}" "openexr" "rgba" "string type" "float"
Format 320 240 1
Projection "perspective" "fov" 60
{}
Translate 0 0 3
WorldBegin
Surface "constant"
{}
WorldEnd
)", out, c.options, c.world), diag);
        for (const Diagnostic& m : diag.recorded())
            EXPECT_EQ(m.message.find("would cover the frame"), std::string::npos) << c.name << ": " << m.message;
        Image img;
        ASSERT_TRUE(test::readImage(out, &img)) << c.name;
        EXPECT_NEAR(img.channelSum(3) / (320.0 * 240.0), c.coverage, 0.002) << c.name;  // half a row
    }
}

TEST(Limits, SigtermStopsTheRenderWritesNoImageAndLeavesNoTemporaries) {
    // A frame far longer than the test: the signal is sent once the render
    // reports progress, so the handlers are in place; how soon the render
    // stops is the renderer's (the scheduler checks between buckets), and
    // the CPU limit would catch one that never stops.
    ScratchDir dir("limits-sigterm");
    const std::string rib = dir.file("long.rib");
    std::ofstream(rib) << fmt::format(R"(Format 2000 1500 1
PixelSamples 8 8
Display "{}" "file" "rgb"
Projection "perspective" "fov" 40
Translate 0 0 4
WorldBegin
Surface "plastic"
Displacement "bumpy" "Km" [0.01]
Sphere 1 -1 1 360
WorldEnd
)",
                                      dir.file("long.tif"));
    const std::string logPath = dir.file("long.log");
    const pid_t pid = fork();
    if (pid == 0) {
        rlimit cpu{kCpuSeconds, kCpuSeconds};
        setrlimit(RLIMIT_CPU, &cpu);
        const int fd = open(logPath.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fd >= 0) {
            dup2(fd, 1);
            dup2(fd, 2);
        }
        setenv("UMBRA_SHADER_PATH", UMBRA_SOURCE_DIR "/shaders_dsl", 1);
        execl(UMBRA_APP, "umbra", "render", "--progress", "--threads", "2", rib.c_str(), static_cast<char*>(nullptr));
        _exit(127);
    }
    ASSERT_GT(pid, 0);
    // Wait (in 20 ms steps, 6000 at most) for the first progress line.
    bool started = false;
    for (int k = 0; k < 6000 && !started; ++k) {
        started = contains(readText(logPath), "buckets");
        if (!started) usleep(20000);
    }
    ASSERT_TRUE(started) << readText(logPath);
    kill(pid, SIGTERM);
    int status = 0;
    ASSERT_EQ(waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(WIFEXITED(status)) << "killed by signal " << WTERMSIG(status);
    EXPECT_EQ(WEXITSTATUS(status), 128 + SIGTERM);
    EXPECT_TRUE(contains(readText(logPath), "interrupted by signal 15; its images were not written")) << readText(logPath);
    // No image, no temporary: only the scene and the log are left.
    std::vector<std::string> left;
    for (const auto& e : std::filesystem::directory_iterator(dir.file(""))) left.push_back(e.path().filename().string());
    std::sort(left.begin(), left.end());
    EXPECT_EQ(left, (std::vector<std::string>{"long.log", "long.rib"}));
}

TEST(ExitStatus, ZeroWhenRenderedAsAskedNonZeroWhenSomethingAskedForWasNotDone) {
    // docs/compatibility.md, "Exit status": warnings keep 0, an unfound
    // shader (drawn with the default surface) does not.
    ScratchDir dir("exit-status");
    const ChildRun lenient = renderInChild(
        dir, "lenient.rib",
        frame(dir.file("a.exr"), "Option \"render\" \"integer minshadowbias\" [0.01]",
              "Attribute \"identifier\" \"shadinggroup\" [\"g\"] Sphere 1 -1 1 360"));
    ASSERT_TRUE(lenient.exited) << lenient.describe();
    EXPECT_EQ(lenient.status, 0) << lenient.describe();
    EXPECT_TRUE(contains(lenient.messages, "warning")) << lenient.messages;
    const ChildRun missing =
        renderInChild(dir, "missing.rib", frame(dir.file("b.exr"), "", "Surface \"nosuchshader\" Sphere 1 -1 1 360"));
    ASSERT_TRUE(missing.exited) << missing.describe();
    EXPECT_EQ(missing.status, 1) << missing.describe();
    EXPECT_TRUE(contains(missing.messages, "cannot find shader 'nosuchshader'")) << missing.messages;
    EXPECT_GT(coverage(dir.file("b.exr")), 100.0);  // still drawn, with the default surface
}

namespace {

/// Deflates `in` into the gzip stream `zs` and ends with a full flush:
/// what follows refers to nothing before it.
std::string deflateFlushed(z_stream& zs, std::string_view in) {
    std::string out;
    zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data()));
    zs.avail_in = static_cast<uInt>(in.size());
    do {
        char buf[1 << 16];
        zs.next_out = reinterpret_cast<Bytef*>(buf);
        zs.avail_out = sizeof buf;
        EXPECT_EQ(deflate(&zs, Z_FULL_FLUSH), Z_OK);
        out.append(buf, sizeof buf - zs.avail_out);
    } while (zs.avail_out == 0);
    return out;
}

/// Writes a gzip file of `head`, `count` copies of `chunk`, then `tail`,
/// deflating the chunk once: after a full flush its compressed block
/// stands alone, so writing it `count` times makes `count` chunks of
/// text. A MiB of one repeated byte compresses to about 1 KiB.
void writeGzipBomb(const std::string& path, const std::string& head, const std::string& chunk, int count,
                   const std::string& tail) {
    z_stream zs{};
    ASSERT_EQ(deflateInit2(&zs, 9, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY), Z_OK);
    std::ofstream out(path, std::ios::binary);
    out << deflateFlushed(zs, head);
    const std::string block = deflateFlushed(zs, chunk);
    for (int k = 0; k < count; ++k) out << block;
    out << deflateFlushed(zs, tail);
    deflateEnd(&zs);
    // The trailer: an empty final block, then the CRC and length of the
    // whole text (modulo 2^32), as the member would have ended.
    const uLong chunkCrc = crc32(0, reinterpret_cast<const Bytef*>(chunk.data()), uInt(chunk.size()));
    uLong crc = crc32(0, reinterpret_cast<const Bytef*>(head.data()), uInt(head.size()));
    for (int k = 0; k < count; ++k) crc = crc32_combine(crc, chunkCrc, z_off_t(chunk.size()));
    crc = crc32(crc, reinterpret_cast<const Bytef*>(tail.data()), uInt(tail.size()));
    const uint64_t length = head.size() + uint64_t(count) * chunk.size() + tail.size();
    unsigned char trailer[10] = {0x03, 0x00};
    for (int k = 0; k < 4; ++k) {
        trailer[2 + k] = static_cast<unsigned char>(crc >> (8 * k));
        trailer[6 + k] = static_cast<unsigned char>(length >> (8 * k));
    }
    out.write(reinterpret_cast<const char*>(trailer), sizeof trailer);
}

/// One MiB of comment lines.
std::string commentMiB() {
    std::string s(size_t(1) << 20, 'c');
    s.front() = '#';
    s.back() = '\n';
    return s;
}

}  // namespace

TEST(GzipBomb, MoreTextThanTheAddressSpaceIsReadAsAStreamAndRenders) {
    // 1.1 GiB of comments (1.2 MB of gzip) between the options and the
    // world: held whole, the text alone would not fit in the child's 1 GiB.
    ScratchDir dir("gzip-bomb-within");
    const std::string rib = frame(dir.file("out.exr"), "", "Sphere 1 -1 1 360");
    const size_t world = rib.find("WorldBegin");
    const std::string path = dir.file("bomb.rib.gz");
    writeGzipBomb(path, rib.substr(0, world), commentMiB(), 1100, rib.substr(world));
    ASSERT_LT(std::filesystem::file_size(path), size_t(2) << 20);
    const ChildRun run = runInChild(path);
    ASSERT_TRUE(run.exited) << run.describe();
    EXPECT_EQ(run.status, 0) << run.describe();
    EXPECT_GT(coverage(dir.file("out.exr")), 100.0);
}

TEST(GzipBomb, PastTheDecompressedBudgetStopsWithALocatedError) {
    // 8 GiB of comments (8.5 MB of gzip) after a budget of 64 MiB: the
    // error stands on the line where the budget runs out, and nothing is
    // rendered (the frame was never finished). The Option takes effect
    // once the next request name ends its parameter list.
    ScratchDir dir("gzip-bomb-past");
    const std::string head = "Option \"limits\" \"decompressedmb\" [64]\nIdentity\n";
    const std::string path = dir.file("bomb.rib.gz");
    writeGzipBomb(path, head, commentMiB(), 8192, frame(dir.file("out.exr"), "", "Sphere 1 -1 1 360"));
    const ChildRun run = runInChild(path);
    ASSERT_TRUE(run.exited) << run.describe();
    EXPECT_EQ(run.status, 1) << run.describe();
    // Byte 64 MiB lies 1 MiB - head bytes + 1 into the 64th comment line.
    const size_t column = (size_t(1) << 20) - head.size() + 1;
    EXPECT_TRUE(contains(run.messages, fmt::format("{}:66:{}: error: RIB: the decompressed RIB is larger than 64 MiB "
                                                   "(Option \"limits\" \"decompressedmb\"); the rest of it is not "
                                                   "read", path, column)))
        << run.messages;
    EXPECT_FALSE(std::filesystem::exists(dir.file("out.exr")));
}

TEST(LargePolygon, AHundredThousandVerticesRenderAsTheSameShapeWrittenAsTriangles) {
    // A star of 10^5 vertices (radii alternating 1 and 0.6) as one Polygon,
    // triangulated by the renderer's sweep, against the same star written
    // plainly as a fan of triangles about its centre. Ear clipping took
    // over a minute for this polygon.
    const int n = 100000;
    std::string points, fanPoints = "0 0 0 ", fanSizes, fanIndices;
    for (int k = 0; k < n; ++k) {
        const double a = 2 * M_PI * k / n, r = k % 2 ? 0.6 : 1.0;
        const std::string p = fmt::format("{} {} 0 ", r * std::cos(a), r * std::sin(a));
        points += p;
        fanPoints += p;
        fanSizes += "3 ";
        fanIndices += fmt::format("0 {} {} ", k + 1, (k + 1) % n + 1);
    }
    ScratchDir dir("large-polygon");
    const ChildRun one = renderInChild(dir, "star.rib", frame(dir.file("star.exr"), "",
                                                              "Polygon \"P\" [" + points + "]"));
    ASSERT_TRUE(one.exited) << one.describe();
    EXPECT_EQ(one.status, 0) << one.describe();
    EXPECT_FALSE(contains(one.messages, "warning")) << one.messages;
    const ChildRun fan = renderInChild(
        dir, "fan.rib",
        frame(dir.file("fan.exr"), "",
              fmt::format("PointsPolygons [{}] [{}] \"P\" [{}]", fanSizes, fanIndices, fanPoints)));
    ASSERT_TRUE(fan.exited) << fan.describe();
    const double star = coverage(dir.file("star.exr")), reference = coverage(dir.file("fan.exr"));
    EXPECT_GT(reference, 200.0);
    EXPECT_NEAR(star, reference, 0.002 * reference);
}

TEST(OutOfMemory, NamesWhatWasBeingAllocatedAndForWhichRequest) {
#ifdef UMBRA_SANITIZED
    // Without the address-space limit these allocations would succeed and
    // a 60000 x 60000 frame would render.
    GTEST_SKIP() << "needs RLIMIT_AS, which sanitizers cannot run under";
#endif
    // A 60000 x 60000 film (58 GB: rgba, no display reads z) under a 1 GiB address space: the error
    // names the film, its size and the frame's WorldBegin.
    ScratchDir dir("out-of-memory");
    const ChildRun film = renderInChild(dir, "film.rib", R"(Display "big.exr" "openexr" "rgba"
Format 60000 60000 1
PixelSamples 4 4
Projection "perspective" "fov" 40
Translate 0 0 5
WorldBegin
Sphere 1 -1 1 360
WorldEnd
)");
    ASSERT_TRUE(film.exited) << film.describe();
    EXPECT_EQ(film.status, 1) << film.describe();
    EXPECT_TRUE(contains(film.messages, dir.file("film.rib") + ":6:1: error: out of memory allocating the 60000x60000 "
                                        "film with 16 samples per pixel (57600000000 bytes)"))
        << film.messages;
    EXPECT_FALSE(std::filesystem::exists(dir.file("big.exr")));

    // 1.5 x 10^8 numbers in one Polygon (300 MB of text from 0.3 MB of
    // gzip): parsed as doubles they outgrow the address space while the
    // parser reads them, and the error names the request.
    const std::string path = dir.file("values.rib.gz");
    std::string zeros;
    for (size_t k = 0; k < (size_t(1) << 19); ++k) zeros += "0 ";
    writeGzipBomb(path, "WorldBegin\nPolygon \"P\" [", zeros, 300, "]\nWorldEnd\n");
    const ChildRun values = runInChild(path);
    ASSERT_TRUE(values.exited) << values.describe();
    EXPECT_EQ(values.status, 1) << values.describe();
    EXPECT_TRUE(contains(values.messages, path + ":2:1: error: out of memory allocating the values of a Polygon "
                                          "request ("))
        << values.messages;
}
