// Procedural primitives (DelayedReadArchive, RunProgram, DynamicLoad) and Geometry
// "teapot", end to end: each expanded procedural must give the pixels of
// the same geometry written inline, in the camera pass and in depth passes;
// a bound the view culls is never read; failing generators warn and the
// rest of the frame renders.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

using namespace umbra;
using umbra::test::Image;
using umbra::test::ScratchDir;

namespace {

void writeFile(const std::string& path, const std::string& text, bool executable = false) {
    std::ofstream(path, std::ios::binary) << text;
    if (executable)
        std::filesystem::permissions(path, std::filesystem::perms::owner_all, std::filesystem::perm_options::add);
}

/// A perspective view of a lit, shadowed scene: a spotlight with an
/// automatic depth map over a ground plane, and `world` on it. Unshadowed
/// (`shadows` false), nothing in it is random, so an expanded procedural
/// must give exactly the pixels of its geometry inline; shadowed, the
/// stochastic shadow samples are seeded by each grid's identity, which for
/// a procedural's pieces comes from the procedural, so the pixels differ
/// by sampling noise only.
std::string shadowedFrame(const std::string& out, const std::string& world, const std::string& options = "",
                          bool shadows = true) {
    return fmt::format(R"(
Display "{}" "openexr" "rgba" "string type" "float"
Format 96 72 1
PixelSamples 3 3
Projection "perspective" "fov" 40
{}
Translate 0 -0.5 8
Rotate -20 1 0 0
WorldBegin
LightSource "shadowspot" 1 "from" [2 5 -3] "to" [0 0 0] "coneangle" 0.8 "intensity" 40 "shadowname" "{}"
LightSource "ambientlight" 2 "intensity" 0.1
Surface "plastic"
AttributeBegin
  Color [0.8 0.8 0.8]
  Polygon "P" [-5 -1 -5  5 -1 -5  5 -1 5  -5 -1 5]
AttributeEnd
{}
WorldEnd
)", out, options, shadows ? "auto" : "", world);
}

/// The geometry the procedurals below stand for: its own attributes,
/// shader and transforms inside an attribute block.
const char* kArchiveBody = R"(
AttributeBegin
  Color [0.2 0.7 0.3]
  Surface "matte"
  Translate 0 0.2 0
  Sphere 0.8 -0.8 0.8 360
AttributeEnd
TransformBegin
  Translate 0.9 -0.5 0
  Cylinder 0.3 -0.5 0.5 360
TransformEnd
)";

nlohmann::json frameStats(const nlohmann::json& stats) { return stats["frames"][0]; }

void expectSamePixels(const Image& a, const Image& b) {
    ASSERT_EQ(a.pixels.size(), b.pixels.size());
    ASSERT_FALSE(a.pixels.empty());
    for (size_t i = 0; i < a.pixels.size(); ++i) ASSERT_EQ(a.pixels[i], b.pixels[i]) << "at float " << i;
}

/// Renders worlds `a` and `b` in unshadowed frames (with `options`; the
/// diagnostics of `a` in `diagA`) and expects the same pixels; returns the
/// statistics of `a`.
nlohmann::json expectSameFrames(const ScratchDir& dir, const std::string& a, const std::string& b, Diagnostics& diagA,
                                int threads = 0, const std::string& options = "") {
    Diagnostics diagB;
    diagB.setQuiet(true);
    auto stats = test::renderRib(shadowedFrame(dir.file("a.exr"), a, options, false), diagA, threads);
    test::renderRib(shadowedFrame(dir.file("b.exr"), b, options, false), diagB, threads);
    Image ia, ib;
    EXPECT_TRUE(test::readImage(dir.file("a.exr"), &ia));
    EXPECT_TRUE(test::readImage(dir.file("b.exr"), &ib));
    expectSamePixels(ia, ib);
    return stats;
}

/// Shadowed frames: the same but for shadow-sampling noise (measured: mean
/// 7e-5 and 1.5e-5, largest 0.05). Without the casters' shadows these
/// frames differ by a mean of 0.004, eight times the bound.
void expectSameButShadowNoise(const Image& a, const Image& b) {
    EXPECT_LT(test::meanAbsDiff(a, b), 5e-4);
    EXPECT_LT(test::maxAbsDiff(a, b, 4), 0.1);
}

/// Renders `a` and `b` (RIB makers taking the output path), shadowed and
/// not, and compares them; returns the statistics of `a` shadowed.
template <typename MakeA, typename MakeB>
nlohmann::json compareWithAndWithoutShadows(const ScratchDir& dir, MakeA a, MakeB b) {
    nlohmann::json stats;
    for (bool shadows : {false, true}) {
        Diagnostics d1, d2;
        auto s = test::renderRib(a(dir.file("a.exr"), shadows), d1);
        if (shadows) stats = s;
        test::renderRib(b(dir.file("b.exr"), shadows), d2);
        EXPECT_EQ(d1.errorCount() + d1.warningCount(), 0);
        EXPECT_EQ(d2.errorCount(), 0);
        Image ia, ib;
        EXPECT_TRUE(test::readImage(dir.file("a.exr"), &ia));
        EXPECT_TRUE(test::readImage(dir.file("b.exr"), &ib));
        if (shadows)
            expectSameButShadowNoise(ia, ib);
        else
            expectSamePixels(ia, ib);
    }
    return stats;
}

}  // namespace

TEST(DelayedReadArchive, SamePixelsAsInlineInCameraAndDepthPasses) {
    // The archive inherits the Procedural's attributes and transform; its
    // sphere and cylinder also cast the spotlight's shadow. The depth pass
    // and the camera pass both need it: it is read once.
    ScratchDir dir("dra_inline");
    writeFile(dir.file("body.rib"), kArchiveBody);
    const std::string placed = "AttributeBegin Translate -0.5 0 0.5 Rotate 30 0 1 0 Color [0.9 0.4 0.1] {} AttributeEnd";
    const std::string procedural =
        fmt::format("Procedural \"DelayedReadArchive\" [\"{}\"] [-1 1.5 -1 1 -1 1]", dir.file("body.rib"));
    auto stats = compareWithAndWithoutShadows(
        dir,
        [&](const std::string& out, bool shadows) {
            return shadowedFrame(out, fmt::format(fmt::runtime(placed), procedural), "", shadows);
        },
        [&](const std::string& out, bool shadows) {
            return shadowedFrame(out, fmt::format(fmt::runtime(placed), kArchiveBody), "", shadows);
        });
    EXPECT_EQ(frameStats(stats)["procedurals"]["archives_read"], 1);
    EXPECT_EQ(frameStats(stats)["procedurals"]["primitives_made"], 2);
}

TEST(DelayedReadArchive, RenderMan19sProcedural2FormDrawsTheSame) {
    // RenderMan for Maya writes its geometry as Procedural2
    // "DelayedReadArchive2" "SimpleBound" "string filename" [...] "float[6]
    // bound" [...]; umbra called it an unknown request. It is the same
    // archive; other Procedural2 kinds are skipped with one warning.
    ScratchDir dir("dra2");
    writeFile(dir.file("body.rib"), kArchiveBody);
    const std::string v2 = fmt::format(
        "Procedural2 \"DelayedReadArchive2\" \"SimpleBound\" \"string filename\" [\"{}\"] "
        "\"float[6] bound\" [-1 1.5 -1 1 -1 1]\nProcedural2 \"DynamicLoad\" \"SimpleBound\" \"string dsoname\" "
        "[\"x.so\"] \"float[6] bound\" [-1 1 -1 1 -1 1]",
        dir.file("body.rib"));
    Diagnostics diag;
    diag.setQuiet(true);
    auto stats = expectSameFrames(dir, v2, kArchiveBody, diag);
    EXPECT_EQ(diag.errorCount(), 0);
    EXPECT_EQ(diag.warningCount(), 1);
    EXPECT_EQ(frameStats(stats)["procedurals"]["archives_read"], 1);
}

TEST(DelayedReadArchive, UnderADetailItsOwnAttributesAreChosenLikeTheWorlds) {
    // Pixar's level-of-detail set-up: Detail, then a DelayedReadArchive
    // whose archive sets its own Color before its sphere. The archive's
    // attribute set, made while a pass ran, had no level of detail chosen:
    // one thread aborted (map::at), two hung for ever. RI Spec 3.2's
    // default detail range draws it at every detail.
    ScratchDir dir("dra_detail");
    writeFile(dir.file("cs.rib"), "Color [1 0 0]\nSphere 0.8 -0.8 0.8 360\n");
    const std::string viaDetail = fmt::format(
        "Detail [-1 1 -1 1 -1 1]\nProcedural \"DelayedReadArchive\" [\"{}\"] [-1 1 -1 1 -1 1]", dir.file("cs.rib"));
    const std::string inlined = "AttributeBegin Color [1 0 0] Sphere 0.8 -0.8 0.8 360 AttributeEnd";
    for (int threads : {1, 2}) {
        Diagnostics diag;
        expectSameFrames(dir, viaDetail, inlined, diag, threads);
        EXPECT_EQ(diag.errorCount(), 0);
    }
}

TEST(DelayedReadArchive, BoundOffScreenIsNeverRead) {
    // Not RIB at all: reading it would report errors. Its bound lies
    // beside the view and behind the camera (and out of the light's view),
    // so no pass may open it; the one on screen is read.
    ScratchDir dir("dra_offscreen");
    writeFile(dir.file("garbage.rib"), "{ this is not RIB ]]]\n\"unterminated\n");
    writeFile(dir.file("body.rib"), kArchiveBody);
    const std::string world = fmt::format(R"(
        AttributeBegin Translate 40 0 0 Procedural "DelayedReadArchive" ["{0}"] [-1 1 -1 1 -1 1] AttributeEnd
        AttributeBegin Translate 0 0 -30 Procedural "DelayedReadArchive" ["{0}"] [-1 1 -1 1 -1 1] AttributeEnd
        Procedural "DelayedReadArchive" ["{1}"] [-1 1.5 -1 1 -1 1]
    )", dir.file("garbage.rib"), dir.file("body.rib"));
    Diagnostics diag;
    auto stats = test::renderRib(shadowedFrame(dir.file("out.exr"), world), diag);
    EXPECT_EQ(diag.errorCount(), 0);
    EXPECT_EQ(frameStats(stats)["procedurals"]["archives_read"], 1);
    EXPECT_EQ(frameStats(stats)["procedurals"]["expanded"], 1);
}

TEST(DelayedReadArchive, NestedArchivesAndThreadsGiveTheInlinePixels) {
    // An archive whose contents are two more delayed archives, each moved:
    // the same pixels as the geometry inline, whatever the thread count and
    // bucket size (expansion happens in whichever bucket asks first).
    ScratchDir dir("dra_nested");
    writeFile(dir.file("body.rib"), kArchiveBody);
    writeFile(dir.file("outer.rib"), fmt::format(R"(
        AttributeBegin Translate -1.2 0 0 Procedural "DelayedReadArchive" ["{0}"] [-1 1.5 -1 1 -1 1] AttributeEnd
        AttributeBegin Translate 1.2 0 0 Opacity [0.5 0.5 0.5]
          Procedural "DelayedReadArchive" ["{0}"] [-1 1.5 -1 1 -1 1] AttributeEnd
    )", dir.file("body.rib")));
    const std::string inlined = fmt::format(R"(
        AttributeBegin Translate -1.2 0 0 {0} AttributeEnd
        AttributeBegin Translate 1.2 0 0 Opacity [0.5 0.5 0.5] {0} AttributeEnd
    )", kArchiveBody);
    Diagnostics d1, d2, d3;
    auto stats = test::renderRib(
        shadowedFrame(dir.file("a.exr"),
                      fmt::format("Procedural \"DelayedReadArchive\" [\"{}\"] [-3 3 -1 1 -1 1]", dir.file("outer.rib"))),
        d1, 1, 16);
    test::renderRib(
        shadowedFrame(dir.file("b.exr"),
                      fmt::format("Procedural \"DelayedReadArchive\" [\"{}\"] [-3 3 -1 1 -1 1]", dir.file("outer.rib"))),
        d2, 2, 7);
    test::renderRib(shadowedFrame(dir.file("c.exr"), inlined), d3, 2, 7);
    ASSERT_EQ(d1.errorCount() + d2.errorCount() + d3.errorCount(), 0);
    EXPECT_EQ(frameStats(stats)["procedurals"]["archives_read"], 3);
    Image a, b, c;
    ASSERT_TRUE(test::readImage(dir.file("a.exr"), &a));
    ASSERT_TRUE(test::readImage(dir.file("b.exr"), &b));
    ASSERT_TRUE(test::readImage(dir.file("c.exr"), &c));
    expectSamePixels(a, b);
    expectSameButShadowNoise(a, c);
}

TEST(DelayedReadArchive, MissingFileAndSelfReferenceAreLocatedErrors) {
    ScratchDir dir("dra_errors");
    writeFile(dir.file("self.rib"),
              fmt::format("Procedural \"DelayedReadArchive\" [\"{}\"] [-1 1 -1 1 -1 1]\n", dir.file("self.rib")));
    Diagnostics diag;
    diag.setRecord(true);
    diag.setSink([](const Diagnostic&) {});
    test::renderRib(shadowedFrame(dir.file("out.exr"),
                                  fmt::format("Procedural \"DelayedReadArchive\" [\"{0}\"] [-1 1 -1 1 -1 1]\n"
                                              "Procedural \"DelayedReadArchive\" [\"{1}\"] [-1 1 -1 1 -1 1]\n"
                                              "Procedural \"DelayedReadArchive\" [\"{1}\"] [-1 1 -1 1 -1 1]",
                                              dir.file("missing.rib"), dir.file("self.rib"))),
                    diag);
    bool missing = false;
    int nested = 0;  // once for self.rib's request, however many chains reach the limit there
    for (const Diagnostic& d : diag.recorded()) {
        if (d.message.find("cannot find") != std::string::npos) {
            missing = true;
            EXPECT_EQ(d.loc.line, 17);  // the Procedural's own line in the frame
        }
        nested += d.message.find("nested more than") != std::string::npos;
    }
    EXPECT_TRUE(missing);
    EXPECT_EQ(nested, 1);
}

namespace {

/// A RunProgram generator in plain sh: answers each request "detail
/// radius" with a sphere of that radius, and notes each start and each
/// detail it is given in `log`.
std::string sphereGenerator(const std::string& log) {
    return fmt::format(R"(#!/bin/sh
echo start >> "{0}"
while read detail radius; do
  echo "detail $detail" >> "{0}"
  printf 'AttributeBegin Color [0.2 0.4 0.9] Sphere %s -%s %s 360 AttributeEnd\n\377' "$radius" "$radius" "$radius"
done
)", log);
}

std::vector<std::string> lines(const std::string& path) {
    std::ifstream in(path);
    std::vector<std::string> out;
    for (std::string l; std::getline(in, l);) out.push_back(l);
    return out;
}

}  // namespace

TEST(RunProgram, SamePixelsAsInlineAndOneProcessPerProgram) {
    ScratchDir dir("runprogram");
    writeFile(dir.file("gen.sh"), sphereGenerator(dir.file("log.txt")), true);
    const std::string world = fmt::format(R"(
        AttributeBegin Translate -1 0 0 Procedural "RunProgram" ["{0}" "0.7"] [-0.7 0.7 -0.7 0.7 -0.7 0.7] AttributeEnd
        AttributeBegin Translate 1 0 0 Procedural "RunProgram" ["{0}" "0.5"] [-0.5 0.5 -0.5 0.5 -0.5 0.5] AttributeEnd
    )", dir.file("gen.sh"));
    const std::string inlined = R"(
        AttributeBegin Translate -1 0 0 AttributeBegin Color [0.2 0.4 0.9] Sphere 0.7 -0.7 0.7 360 AttributeEnd AttributeEnd
        AttributeBegin Translate 1 0 0 AttributeBegin Color [0.2 0.4 0.9] Sphere 0.5 -0.5 0.5 360 AttributeEnd AttributeEnd
    )";
    auto stats = compareWithAndWithoutShadows(
        dir, [&](const std::string& out, bool shadows) { return shadowedFrame(out, world, "", shadows); },
        [&](const std::string& out, bool shadows) { return shadowedFrame(out, inlined, "", shadows); });
    EXPECT_EQ(frameStats(stats)["procedurals"]["program_requests"], 2);
    // Each frame started the program once and kept it for its second
    // request: two frames, two starts, four requests.
    const std::vector<std::string> log = lines(dir.file("log.txt"));
    ASSERT_EQ(log.size(), 6u);
    EXPECT_EQ(std::count(log.begin(), log.end(), "start"), 2);
    EXPECT_EQ(log[0], "start");
    EXPECT_EQ(log[3], "start");
}

TEST(RunProgram, DetailIsTheRasterAreaOfTheBound) {
    // Orthographic, 4 world units over 256 pixels: a 2 x 1 bound facing
    // the camera covers 128 x 64 pixels, whatever its depth extent.
    ScratchDir dir("runprogram_detail");
    writeFile(dir.file("gen.sh"), sphereGenerator(dir.file("log.txt")), true);
    const std::string rib = fmt::format(R"(
Display "{}" "openexr" "rgba"
Format 256 256 1
ScreenWindow -2 2 -2 2
Projection "orthographic"
Translate 0 0 5
WorldBegin
Procedural "RunProgram" ["{}" "0.5"] [-1 1 -0.5 0.5 -3 1]
WorldEnd
)", dir.file("out.exr"), dir.file("gen.sh"));
    Diagnostics diag;
    test::renderRib(rib, diag);
    ASSERT_EQ(diag.errorCount(), 0);
    const std::vector<std::string> log = lines(dir.file("log.txt"));
    ASSERT_EQ(log.size(), 2u);
    EXPECT_EQ(log[1], "detail 8192");
}

TEST(RunProgram, FailingProgramsAreErrorsAndTheRestRenders) {
    // A program that exits at once, one that does not exist and one that
    // never answers (within the 1 s budget) are errors at their Procedural:
    // geometry the scene asked for was not made, so the exit status says so,
    // as for a missing texture or archive. One that answers garbage is the
    // generator's fault: warnings in its output. The frame is still that of
    // the inline sphere alone.
    ScratchDir dir("runprogram_fail");
    writeFile(dir.file("dies.sh"), "#!/bin/sh\nexit 3\n", true);
    writeFile(dir.file("garbage.sh"), "#!/bin/sh\nwhile read l; do printf 'Sphere oops [ 1\\n\\377'; done\n", true);
    writeFile(dir.file("silent.sh"), "#!/bin/sh\nwhile read l; do :; done\n", true);
    const std::string sphere = "Sphere 0.6 -0.6 0.6 360";
    const std::string world = fmt::format(R"(
        Procedural "RunProgram" ["{0}" ""] [-1 1 -1 1 -1 1]
        Procedural "RunProgram" ["{1}" ""] [-1 1 -1 1 -1 1]
        Procedural "RunProgram" ["{2}" ""] [-1 1 -1 1 -1 1]
        Procedural "RunProgram" ["{3}" ""] [-1 1 -1 1 -1 1]
        {4}
    )", dir.file("dies.sh"), dir.file("no-such-program"), dir.file("garbage.sh"), dir.file("silent.sh"), sphere);
    const std::string budget = "Option \"limits\" \"float proceduraltime\" [1]";
    Diagnostics d1, d2;
    d1.setRecord(true);
    d1.setSink([](const Diagnostic&) {});
    int failed = 0;
    auto stats = test::renderRib(shadowedFrame(dir.file("a.exr"), world, budget, false), d1, 0, 0, &failed);
    test::renderRib(shadowedFrame(dir.file("b.exr"), sphere, budget, false), d2);
    EXPECT_EQ(failed, 0);
    int located = 0, errors = 0;
    bool statusSaid = false;
    for (const Diagnostic& d : d1.recorded()) {
        if (d.message.find("RunProgram") == std::string::npos) continue;
        if (d.severity == Severity::Error) ++errors;
        if (d.loc.line >= 17) ++located;
        // Before or after its request reached it, as the two processes race.
        statusSaid = statusSaid || d.message.find("\" exited with status 3 before ") != std::string::npos;
    }
    EXPECT_TRUE(statusSaid);  // the exit status, not just "no byte 0xFF"
    EXPECT_EQ(errors, 3);
    EXPECT_EQ(d1.errorCount(), 3);
    EXPECT_GE(d1.warningCount(), 1);  // the garbage
    EXPECT_GE(located, 3);
    EXPECT_GE(frameStats(stats)["procedurals"]["failed"], 3);
    Image a, b;
    ASSERT_TRUE(test::readImage(dir.file("a.exr"), &a));
    ASSERT_TRUE(test::readImage(dir.file("b.exr"), &b));
    expectSamePixels(a, b);
}

TEST(RunProgram, AnAnswerEndedByExitingIsTakenAndOneWithoutTheEndByteIsNamed) {
    // A generator that writes its RIB and exits without the byte 0xFF
    // (Pixie draws its answer, Aqsis nothing): its RIB is the answer, with a
    // warning. One that writes RIB and waits without the 0xFF is an error
    // that says it answered, not that it "did not answer".
    ScratchDir dir("runprogram_noend");
    const std::string sphere = "Sphere 0.6 -0.6 0.6 360";
    writeFile(dir.file("exits.sh"), "#!/bin/sh\nread l\nprintf '" + sphere + "\\n'\n", true);
    writeFile(dir.file("waits.sh"), "#!/bin/sh\nread l\nprintf 'Sphere 0.3 -0.3 0.3 360\\n'\nwhile read l; do :; done\n", true);
    const std::string budget = "Option \"limits\" \"float proceduraltime\" [2]";
    Diagnostics d1;
    d1.setRecord(true);
    d1.setSink([](const Diagnostic&) {});
    const std::string world = fmt::format(R"(
        Procedural "RunProgram" ["{0}" ""] [-1 1 -1 1 -1 1]
        Procedural "RunProgram" ["{1}" ""] [-1 1 -1 1 -1 1]
    )", dir.file("exits.sh"), dir.file("waits.sh"));
    expectSameFrames(dir, world, sphere, d1, 0, budget);
    EXPECT_EQ(d1.errorCount(), 1);
    EXPECT_EQ(d1.warningCount(), 1);
    bool said = false;
    for (const Diagnostic& d : d1.recorded())
        said = said || (d.severity == Severity::Error && d.message.find("bytes of RIB but not") != std::string::npos);
    EXPECT_TRUE(said);
}

TEST(DynamicLoad, SamePixelsAsInline) {
    // tests/unit/render/dso/sphere_dso.cpp makes, through the C binding,
    // the sphere the RunProgram generator above writes as RIB.
    ScratchDir dir("dynamicload");
    const std::string world = fmt::format(R"(
        AttributeBegin Translate -1 0 0 Procedural "DynamicLoad" ["{0}" "0.7"] [-0.7 0.7 -0.7 0.7 -0.7 0.7] AttributeEnd
        AttributeBegin Translate 1 0 0 Procedural "DynamicLoad" ["{0}" "0.5"] [-0.5 0.5 -0.5 0.5 -0.5 0.5] AttributeEnd
    )", UMBRA_TEST_SPHERE_DSO);
    const std::string inlined = R"(
        AttributeBegin Translate -1 0 0 AttributeBegin Color [0.2 0.4 0.9] Sphere 0.7 -0.7 0.7 360 AttributeEnd AttributeEnd
        AttributeBegin Translate 1 0 0 AttributeBegin Color [0.2 0.4 0.9] Sphere 0.5 -0.5 0.5 360 AttributeEnd AttributeEnd
    )";
    auto stats = compareWithAndWithoutShadows(
        dir, [&](const std::string& out, bool shadows) { return shadowedFrame(out, world, "", shadows); },
        [&](const std::string& out, bool shadows) { return shadowedFrame(out, inlined, "", shadows); });
    EXPECT_EQ(frameStats(stats)["procedurals"]["expanded"], 2);
    EXPECT_EQ(frameStats(stats)["procedurals"]["primitives_made"], 2);
}

TEST(DynamicLoad, MissingDsoIsAnErrorAndTheRestRenders) {
    ScratchDir dir("dynamicload_missing");
    writeFile(dir.file("not-a-dso.so"), "not an ELF file");
    const std::string sphere = "Sphere 0.6 -0.6 0.6 360";
    const std::string world = fmt::format(R"(
        Procedural "DynamicLoad" ["{}" ""] [-1 1 -1 1 -1 1]
        Procedural "DynamicLoad" ["{}" ""] [-1 1 -1 1 -1 1]
        {}
    )", dir.file("missing"), dir.file("not-a-dso.so"), sphere);
    Diagnostics d1, d2;
    d1.setSink([](const Diagnostic&) {});
    test::renderRib(shadowedFrame(dir.file("a.exr"), world, "", false), d1);
    test::renderRib(shadowedFrame(dir.file("b.exr"), sphere, "", false), d2);
    EXPECT_EQ(d1.errorCount(), 2);
    EXPECT_EQ(d1.warningCount(), 0);
    Image a, b;
    ASSERT_TRUE(test::readImage(dir.file("a.exr"), &a));
    ASSERT_TRUE(test::readImage(dir.file("b.exr"), &b));
    expectSamePixels(a, b);
}

TEST(Teapot, SilhouetteIsSymmetricAboutTheSpoutPlaneAndSpansTheData) {
    // Seen from above (orthographic, 1/32 unit pixels), the teapot's
    // outline is symmetric about y = 0, the plane of its spout and handle,
    // and spans the handle's outer edge (x = -3: its outer curve's ends sit
    // there and bulge no further) and the body's widest circle (radius 2:
    // the body patches' silhouette control points lie on it).
    ScratchDir dir("teapot");
    const std::string rib = fmt::format(R"(
Display "{}" "openexr" "rgba" "string type" "float"
Format 256 160 1
ScreenWindow -4 4 -2.5 2.5
Projection "orthographic"
PixelSamples 4 4
PixelFilter "box" 1 1
Translate 0 0 10
WorldBegin
Surface "constant"
Geometry "teapot"
WorldEnd
)", dir.file("top.exr"));
    Diagnostics diag;
    Image img = test::renderImage(rib, dir.file("top.exr"), diag);
    ASSERT_EQ(diag.errorCount(), 0);
    ASSERT_EQ(img.height, 160);
    // Raster y runs down the image, world y up: row r and row 159 - r are
    // mirror images about y = 0.
    double asymmetry = 0, covered = 0;
    int xmin = img.width, xmax = -1, ymin = img.height, ymax = -1;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            const float a = img.at(x, y, 3);
            asymmetry += std::fabs(a - img.at(x, img.height - 1 - y, 3));
            covered += a;
            if (a > 0.5f) {
                xmin = std::min(xmin, x);
                xmax = std::max(xmax, x);
                ymin = std::min(ymin, y);
                ymax = std::max(ymax, y);
            }
        }
    EXPECT_GT(covered, 1000);
    EXPECT_LT(asymmetry / covered, 0.01);
    // Pixel centres: world x = -4 + (x + 0.5) / 32.
    EXPECT_NEAR(-4 + (xmin + 0.5) / 32.0, -3.0, 1.0 / 32);
    EXPECT_NEAR(2.5 - (ymin + 0.5) / 32.0, 2.0, 1.0 / 32);
    EXPECT_NEAR(2.5 - (ymax + 0.5) / 32.0, -2.0, 1.0 / 32);
}
