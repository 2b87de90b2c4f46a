// Frame selection and farm restarts through the `umbra` command:
// `--frames SPEC`, `--resume`, failed frames among good ones, and frame
// patterns in RIB and Display names (docs/frames.md). Each run is a child
// process; no test reads a clock.

#include "support/child_run.h"
#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <sys/stat.h>

#include <cstring>
#include <filesystem>
#include <fstream>

using namespace umbra;
using umbra::test::Image;
using umbra::test::readFile;
using umbra::test::ScratchDir;
using umbra::test::writeFile;
using UmbraRun = umbra::test::ChildRun;
namespace fs = std::filesystem;

namespace {

/// Runs `umbra render --threads 2 ARGS...` in `dir` (its working directory).
UmbraRun runUmbra(const ScratchDir& dir, std::vector<std::string> args) {
    args.insert(args.begin(), {"umbra", "render", "--threads", "2"});
    return test::runIn(dir, UMBRA_APP, std::move(args));
}

/// One frame: a sphere lit by a spotlight with an automatic depth map (so
/// the frame has a first pass), moved by its number, written to `display`.
std::string frameBody(int n, const std::string& display, const std::string& options = "") {
    return fmt::format(R"(Display "{}" "file" "rgba"
{}
Projection "perspective" "fov" 40
Translate 0 0 5
WorldBegin
  LightSource "shadowspot" 1 "from" [0.5 4 0.3] "to" [0 0 0] "coneangle" [0.9] "intensity" [16] "shadowname" ["auto"]
  Surface "matte"
  AttributeBegin
    Translate {} 0.5 0
    Sphere 0.6 -0.6 0.6 360
  AttributeEnd
  Patch "bilinear" "P" [-3 -0.5 -3  3 -0.5 -3  -3 -0.5 3  3 -0.5 3]
WorldEnd
)",
                       display, options, 0.2 * (n - 3));
}

/// A sequence of FrameBegin 1..count, all writing out.####.tif.
std::string sequence(int count) {
    std::string rib = "Format 32 24 1\nPixelSamples 2 2\n";
    for (int n = 1; n <= count; ++n) rib += fmt::format("FrameBegin {}\n{}FrameEnd\n", n, frameBody(n, "out.####.tif"));
    return rib;
}

bool exists(const ScratchDir& dir, const std::string& name) { return fs::exists(dir.file(name)); }

Image imageOf(const std::string& path) {
    Image img;
    EXPECT_TRUE(test::readImage(path, &img)) << path;
    return img;
}

}  // namespace

TEST(Frames, OnlySelectedFramesAreRendered) {
    ScratchDir dir("frames-select");
    writeFile(dir.file("seq.rib"), sequence(6));
    UmbraRun run = runUmbra(dir, {"seq.rib", "--frames", "2-6x2"});
    ASSERT_EQ(run.status, 0) << run.messages;
    for (int n = 1; n <= 6; ++n) EXPECT_EQ(exists(dir, fmt::format("out.{:04d}.tif", n)), n % 2 == 0) << n;
    // An unselected frame has no first pass either: one depth map a frame rendered.
    int maps = 0;
    for (const auto& e : fs::directory_iterator(dir.file(""))) maps += e.path().extension() == ".shd";
    EXPECT_EQ(maps, 3);
}

TEST(Frames, UnselectedFramesKeepOptionsScoped) {
    // Frame 1 (not rendered) changes Format inside its block; frame 2 must
    // still have the Format given before both frames.
    ScratchDir dir("frames-scope");
    std::string rib = "Format 32 24 1\n";
    rib += "FrameBegin 1\nFormat 16 8 1\n" + frameBody(1, "a.####.tif") + "FrameEnd\n";
    rib += "FrameBegin 2\n" + frameBody(2, "a.####.tif") + "FrameEnd\n";
    writeFile(dir.file("scope.rib"), rib);
    UmbraRun run = runUmbra(dir, {"scope.rib", "--frames", "2"});
    ASSERT_EQ(run.status, 0) << run.messages;
    EXPECT_FALSE(exists(dir, "a.0001.tif"));
    Image img = imageOf(dir.file("a.0002.tif"));
    EXPECT_EQ(img.width, 32);
    EXPECT_EQ(img.height, 24);
}

TEST(Frames, UnselectedFramesReadNoArchives) {
    // Frame 1 reads an archive that does not exist, frame 2 one that does:
    // with --frames 2, frame 1's archive is not even looked for (no error,
    // exit 0) and frame 2 is the same picture as rendered in sequence with
    // the missing archive written out. Selecting frame 1 reports it.
    ScratchDir dir("frames-archives");
    writeFile(dir.file("ball.rib"), "AttributeBegin Translate 0 0.5 0 Sphere 0.6 -0.6 0.6 360 AttributeEnd\n");
    auto frame = [](int n, const std::string& archive) {
        return fmt::format(R"(FrameBegin {}
Display "b.####.tif" "file" "rgba"
Projection "perspective" "fov" 40
Translate 0 0 5
WorldBegin
  LightSource "distantlight" 1
  Surface "matte"
  ReadArchive "{}"
WorldEnd
FrameEnd
)",
                           n, archive);
    };
    writeFile(dir.file("seq.rib"), "Format 32 24 1\n" + frame(1, "missing.rib") + frame(2, "ball.rib"));
    UmbraRun run = runUmbra(dir, {"seq.rib", "--frames", "2"});
    ASSERT_EQ(run.status, 0) << run.messages;
    EXPECT_EQ(run.messages.find("missing.rib"), std::string::npos) << run.messages;
    EXPECT_FALSE(exists(dir, "b.0001.tif"));
    const Image alone = imageOf(dir.file("b.0002.tif"));
    fs::rename(dir.file("b.0002.tif"), dir.file("alone.tif"));
    writeFile(dir.file("both.rib"), "Format 32 24 1\n" + frame(1, "ball.rib") + frame(2, "ball.rib"));
    ASSERT_EQ(runUmbra(dir, {"both.rib"}).status, 0);
    EXPECT_EQ(test::meanAbsDiff(alone, imageOf(dir.file("b.0002.tif"))), 0.0);
    EXPECT_GT(alone.at(16, 9, 3), 0.99f);  // the ball is there
    // Frame 1 selected: its archive is looked for, and missing.
    UmbraRun one = runUmbra(dir, {"seq.rib", "--frames", "1"});
    EXPECT_NE(one.status, 0);
    EXPECT_NE(one.messages.find("cannot find archive \"missing.rib\""), std::string::npos) << one.messages;
}

TEST(Frames, BadSpecSaysWhatWasExpected) {
    ScratchDir dir("frames-bad");
    writeFile(dir.file("seq.rib"), sequence(1));
    UmbraRun run = runUmbra(dir, {"seq.rib", "--frames", "9-3"});
    EXPECT_NE(run.status, 0);
    EXPECT_NE(run.messages.find("runs backwards"), std::string::npos) << run.messages;
    EXPECT_NE(run.messages.find("expected"), std::string::npos) << run.messages;
    EXPECT_FALSE(exists(dir, "out.0001.tif"));
}

TEST(Frames, FrameAloneEqualsFrameInSequence) {
    ScratchDir all("frames-all"), alone("frames-alone");
    writeFile(all.file("seq.rib"), sequence(4));
    writeFile(alone.file("seq.rib"), sequence(4));
    ASSERT_EQ(runUmbra(all, {"seq.rib"}).status, 0);
    UmbraRun run = runUmbra(alone, {"seq.rib", "--frames", "3"});
    ASSERT_EQ(run.status, 0) << run.messages;
    Image a = imageOf(all.file("out.0003.tif")), b = imageOf(alone.file("out.0003.tif"));
    ASSERT_EQ(a.width, b.width);
    ASSERT_EQ(a.channels, b.channels);
    ASSERT_EQ(a.pixels.size(), b.pixels.size());
    EXPECT_EQ(0, std::memcmp(a.pixels.data(), b.pixels.data(), a.pixels.size() * sizeof(float)))
        << "frame 3 differs when rendered alone";
    EXPECT_GT(a.channelSum(0), 0.0);
}

TEST(Frames, ResumeSkipsCompleteFramesAndRedoesTruncatedOnes) {
    ScratchDir dir("frames-resume");
    writeFile(dir.file("seq.rib"), sequence(3));
    ASSERT_EQ(runUmbra(dir, {"seq.rib"}).status, 0);
    const std::string one = dir.file("out.0001.tif"), two = dir.file("out.0002.tif"), three = dir.file("out.0003.tif");
    const std::string bytesOne = readFile(one), bytesTwo = readFile(two);
    struct stat before {};
    ASSERT_EQ(stat(one.c_str(), &before), 0);
    // Frame 2 as a killed copy left it; frame 3 gone.
    fs::resize_file(two, bytesTwo.size() / 2);
    fs::remove(three);

    UmbraRun run = runUmbra(dir, {"seq.rib", "--resume"});
    ASSERT_EQ(run.status, 0) << run.messages;
    struct stat after {};
    ASSERT_EQ(stat(one.c_str(), &after), 0);
    EXPECT_EQ(readFile(one), bytesOne);
    EXPECT_EQ(after.st_mtim.tv_sec, before.st_mtim.tv_sec);
    EXPECT_EQ(after.st_mtim.tv_nsec, before.st_mtim.tv_nsec);
    EXPECT_NE(run.messages.find("frame 1 is complete, skipped"), std::string::npos) << run.messages;
    EXPECT_NE(run.messages.find("not a complete image"), std::string::npos) << run.messages;
    // Rendered again, whole.
    Image img = imageOf(two);
    EXPECT_EQ(img.width, 32);
    EXPECT_TRUE(exists(dir, "out.0003.tif"));

    // --skip-existing is the same flag: now every frame is skipped.
    run = runUmbra(dir, {"seq.rib", "--skip-existing"});
    ASSERT_EQ(run.status, 0) << run.messages;
    EXPECT_NE(run.messages.find("frame 2 is complete, skipped"), std::string::npos) << run.messages;
}

TEST(Frames, ResumeChecksDepthMapOutputs) {
    ScratchDir dir("frames-resume-z");
    std::string rib = "Format 32 24 1\n";
    for (int n = 1; n <= 2; ++n)
        rib += fmt::format("FrameBegin {}\nDisplay \"d.####.z\" \"zfile\" \"z\"\nProjection \"perspective\" \"fov\" 40\n"
                           "Translate 0 0 5\nWorldBegin\nSphere 1 -1 1 360\nWorldEnd\nFrameEnd\n",
                           n);
    writeFile(dir.file("z.rib"), rib);
    ASSERT_EQ(runUmbra(dir, {"z.rib"}).status, 0);
    const std::string z1 = dir.file("d.0001.z"), z2 = dir.file("d.0002.z");
    const std::string bytes = readFile(z2);
    fs::resize_file(z1, 200);
    UmbraRun run = runUmbra(dir, {"z.rib", "--resume"});
    ASSERT_EQ(run.status, 0) << run.messages;
    EXPECT_NE(run.messages.find("frame 2 is complete, skipped"), std::string::npos) << run.messages;
    EXPECT_EQ(readFile(z1).size(), bytes.size());  // rendered again
}

TEST(Frames, FailedFrameIsReportedAndTheOthersWritten) {
    ScratchDir dir("frames-fail");
    writeFile(dir.file("blocker"), "a file, not a directory");
    std::string rib = "Format 32 24 1\n";
    rib += "FrameBegin 1\n" + frameBody(1, "ok.####.tif") + "FrameEnd\n";
    rib += "FrameBegin 2\n" + frameBody(2, "blocker/bad.####.tif") + "FrameEnd\n";
    rib += "FrameBegin 3\n" + frameBody(3, "ok.####.tif") + "FrameEnd\n";
    writeFile(dir.file("fail.rib"), rib);
    UmbraRun run = runUmbra(dir, {"fail.rib"});
    EXPECT_NE(run.status, 0) << run.messages;
    EXPECT_TRUE(exists(dir, "ok.0001.tif"));
    EXPECT_TRUE(exists(dir, "ok.0003.tif"));
    EXPECT_NE(run.messages.find("umbra: 1 frame failed: 2\n"), std::string::npos) << run.messages;
}

TEST(Frames, OneRibPerFrameFromAPattern) {
    ScratchDir dir("frames-pattern");
    // No FrameBegin in the files: each file's world is the frame it is named by.
    for (int n = 1; n <= 3; ++n)
        writeFile(dir.file(fmt::format("shot.{:04d}.rib", n)), "Format 32 24 1\n" + frameBody(n, "img.%04d.tif"));
    UmbraRun run = runUmbra(dir, {"shot.%04d.rib", "--frames", "1-3"});
    ASSERT_EQ(run.status, 0) << run.messages;
    for (int n = 1; n <= 3; ++n) EXPECT_TRUE(exists(dir, fmt::format("img.{:04d}.tif", n))) << n;

    // A missing file fails its frame only.
    fs::remove(dir.file("img.0002.tif"));
    run = runUmbra(dir, {"shot.####.rib", "--frames", "2,4"});
    EXPECT_NE(run.status, 0);
    EXPECT_TRUE(exists(dir, "img.0002.tif"));
    EXPECT_NE(run.messages.find("umbra: 1 frame failed: 4\n"), std::string::npos) << run.messages;

    // A pattern needs --frames.
    run = runUmbra(dir, {"shot.####.rib"});
    EXPECT_NE(run.status, 0);
    EXPECT_NE(run.messages.find("--frames"), std::string::npos) << run.messages;
}

TEST(Frames, AutomaticMapNamesCarryTheFrameNumberOnce) {
    ScratchDir dir("frames-mapnames");
    std::string rib = "Format 32 24 1\n";
    rib += "FrameBegin 1\n" + frameBody(1, "out.####.tif") + "FrameEnd\n";
    rib += "FrameBegin 5\n" + frameBody(5, "still.tif") + "FrameEnd\n";
    writeFile(dir.file("names.rib"), rib);
    UmbraRun run = runUmbra(dir, {"names.rib"});
    ASSERT_EQ(run.status, 0) << run.messages;
    // The Display's pattern already numbers the image: the map is named after it.
    EXPECT_TRUE(exists(dir, "out.0001.1.shd"));
    EXPECT_FALSE(exists(dir, "out.0001.0001.1.shd"));
    // A name without a pattern gets the frame number, so frames keep their own maps.
    EXPECT_TRUE(exists(dir, "still.0005.1.shd"));
}

TEST(Frames, MessagesNameWorldsOutsideFramesWithoutMinusOne) {
    ScratchDir dir("frames-unnumbered");
    writeFile(dir.file("still.rib"),
              "Format 32 24 1\n" + frameBody(0, "still.tif", "Option \"statistics\" \"endofframe\" [1]"));
    UmbraRun run = runUmbra(dir, {"still.rib", "--progress"});
    ASSERT_EQ(run.status, 0) << run.messages;
    EXPECT_EQ(run.messages.find("frame -1"), std::string::npos) << run.messages;
    EXPECT_NE(run.messages.find("statistics of the world at still.rib"), std::string::npos) << run.messages;
    EXPECT_TRUE(exists(dir, "still.1.shd"));
    run = runUmbra(dir, {"still.rib", "--resume"});
    ASSERT_EQ(run.status, 0) << run.messages;
    EXPECT_EQ(run.messages.find("frame -1"), std::string::npos) << run.messages;
    EXPECT_NE(run.messages.find("the world at still.rib"), std::string::npos) << run.messages;
    EXPECT_NE(run.messages.find("is complete, skipped"), std::string::npos) << run.messages;
}

TEST(Frames, EndOfFrameStatisticsLevelsPrintMoreAndMore) {
    // Option "statistics" "endofframe": 1 a summary, 2 also each pass, map
    // and the lookups' counters, 3 also the whole statistics record; each
    // checked against the --stats document of the same run.
    ScratchDir dir("frames-endofframe");
    for (int level : {0, 1, 2, 3, 7}) {
        SCOPED_TRACE(fmt::format("level {}", level));
        writeFile(dir.file("still.rib"),
                  "Format 32 24 1\nFrameBegin 1\n" +
                      frameBody(1, "still.tif", fmt::format("Option \"statistics\" \"endofframe\" [{}]", level)) +
                      "FrameEnd\n");
        UmbraRun run = runUmbra(dir, {"still.rib", "--stats", "run.json"});
        ASSERT_EQ(run.status, 0) << run.messages;
        const std::string& m = run.messages;
        const nlohmann::json frame = nlohmann::json::parse(readFile(dir.file("run.json")))["frames"][0];
        EXPECT_EQ(m.find("statistics of frame 1") != std::string::npos, level >= 1) << m;
        // Level 2: a line per pass with its micropolygons, the map's fate,
        // and the shadow lookups.
        for (const auto& pass : frame["passes"]) {
            const std::string name = pass["name"].get<std::string>();
            const size_t at = m.find("    " + name + " ");
            EXPECT_EQ(at != std::string::npos, level >= 2) << name << "\n" << m;
            if (at == std::string::npos) continue;
            const std::string line = m.substr(at, m.find('\n', at) - at);
            EXPECT_NE(line.find(fmt::format(" {} micropolygons", pass["counts"]["micropolygons"].get<uint64_t>())),
                      std::string::npos)
                << line;
        }
        EXPECT_EQ(m.find("    1                    rendered (first frame) still.0001.1.shd") != std::string::npos,
                  level >= 2)
            << m;
        EXPECT_EQ(m.find(fmt::format("  lookups     {} points", frame["shadow"]["points"].get<uint64_t>())) !=
                      std::string::npos,
                  level >= 2)
            << m;
        // The film: streamed (a TIFF frame) and its rows held at most.
        EXPECT_EQ(m.find(fmt::format("  film        streamed to its TIFFs while rendering, {} rows held at most",
                                     frame["film_rows_held_peak"].get<int>())) != std::string::npos,
                  level >= 2)
            << m;
        // Level 3: the frame's record itself.
        const size_t record = m.find("  record      ");
        ASSERT_EQ(record != std::string::npos, level >= 3) << m;
        if (record != std::string::npos) {
            const std::string text = m.substr(record + 14, m.rfind('}') - record - 13);
            EXPECT_EQ(nlohmann::json::parse(text), frame);
        }
    }
}
