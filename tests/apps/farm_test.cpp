// `umbra farm submit`: the scripts and sbatch commands it makes (--dry-run),
// and the scripts themselves run by bash as Slurm would run them (a stand-in
// `sbatch` on PATH records the commands and hands out job ids), so the
// maps job, the array tasks sharing its map through the map cache, the
// retries and the report job are checked without a cluster. The real
// cluster is tests/apps/slurm_test.sh. Every run is a child process; no
// test reads a clock.

#include "support/child_run.h"
#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>

using umbra::test::Image;
using umbra::test::ChildRun;
using umbra::test::readFile;
using umbra::test::runIn;
using umbra::test::ScratchDir;
using umbra::test::writeFile;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

ChildRun runUmbra(const ScratchDir& dir, std::vector<std::string> args, const std::vector<std::string>& env = {}) {
    args.insert(args.begin(), "umbra");
    return runIn(dir, UMBRA_APP, std::move(args), env);
}

/// Five 48 x 36 frames: the camera moves, the spotlight and the sphere do
/// not, so every frame's automatic map has the same content. Frame `bad`
/// (if any) displays onto a directory, which fails every time.
std::string fiveFrames(int bad = 0) {
    std::string rib = "Format 48 36 1\nPixelSamples 2 2\n";
    for (int n = 1; n <= 5; ++n)
        rib += fmt::format(R"(FrameBegin {}
Display "{}" "file" "rgba"
Projection "perspective" "fov" 40
Translate {} 0 5
WorldBegin
  LightSource "shadowspot" "key" "from" [0.5 4 0.3] "to" [0 0 0] "coneangle" [0.9] "intensity" [16] "shadowname" ["auto"]
  Surface "matte"
  AttributeBegin
    Translate 0 0.5 0
    Sphere 0.6 -0.6 0.6 360
  AttributeEnd
  Patch "bilinear" "P" [-3 -0.5 -3  3 -0.5 -3  -3 -0.5 3  3 -0.5 3]
WorldEnd
FrameEnd
)",
                           n, n == bad ? std::string("adir") : std::string("out.####.tif"), 0.1 * (n - 3));
    return rib;
}

/// A stand-in for sbatch: appends its arguments to sbatch.log and prints
/// job ids 101, 102, ... as `sbatch --parsable` does ("id;cluster").
void writeFakeSbatch(const ScratchDir& dir, bool fail = false) {
    fs::create_directories(dir.file("bin"));
    writeFile(dir.file("bin/sbatch"),
              fail ? "#!/bin/sh\necho 'sbatch: error: Batch job submission failed: Invalid partition name specified' >&2\n"
                     "exit 1\n"
                   : "#!/bin/sh\necho \"$*\" >> \"$(dirname \"$0\")/../sbatch.log\"\n"
                     "n=$(wc -l < \"$(dirname \"$0\")/../sbatch.log\")\necho \"$((100 + n));cluster\"\n");
    fs::permissions(dir.file("bin/sbatch"), fs::perms::owner_all);
}

std::string pathWith(const ScratchDir& dir) {
    const char* path = std::getenv("PATH");
    return "PATH=" + dir.file("bin") + ":" + (path ? path : "/usr/bin:/bin");
}

std::vector<json> readLines(const std::string& path) {
    std::vector<json> lines;
    std::ifstream in(path);
    for (std::string line; std::getline(in, line);)
        if (!line.empty()) lines.push_back(json::parse(line));
    return lines;
}

}  // namespace

TEST(Farm, DryRunPrintsTheScriptsAndCommandsAndWritesNothing) {
    ScratchDir dir("farm-dry");
    writeFile(dir.file("seq.rib"), fiveFrames());
    const ChildRun run = runUmbra(dir, {"farm", "submit", "--dry-run", "--frames", "2-5", "--chunk", "2", "--cpus",
                                        "2", "--partition", "render", "seq.rib", "-o", "farm"});
    ASSERT_EQ(run.status, 0) << run.messages;
    const std::string& out = run.messages;
    const std::string farm = fs::weakly_canonical(dir.file("farm")).string();
    const std::string umbra = fs::canonical(UMBRA_APP).string();
    // The maps job renders the first selected frame into the map cache.
    EXPECT_NE(out.find("frames=2\n"), std::string::npos) << out;
    EXPECT_NE(out.find("'" + umbra + "' render --threads 2 --frames \"$frames\" --map-cache '" + farm + "/maps'"),
              std::string::npos)
        << out;
    // The other frames in chunks of two, one per array task.
    EXPECT_NE(out.find("chunks=('3,4' '5')"), std::string::npos) << out;
    EXPECT_NE(out.find("stats='" + farm + "/stats'/task.$SLURM_ARRAY_TASK_ID.jsonl"), std::string::npos) << out;
    EXPECT_NE(out.find("#SBATCH --output=" + farm + "/logs/task.%a.log"), std::string::npos) << out;
    EXPECT_NE(out.find("#SBATCH --partition=render"), std::string::npos) << out;
    EXPECT_NE(out.find("#SBATCH --cpus-per-task=2"), std::string::npos) << out;
    EXPECT_NE(out.find("if [ \"$attempt\" -gt 2 ]"), std::string::npos) << out;  // --retries 2 by default
    // The commands: afterany dependencies, the array requeued.
    EXPECT_NE(out.find("MAPS_JOB=$(sbatch --parsable " + farm + "/scripts/maps.sh)"), std::string::npos) << out;
    EXPECT_NE(out.find("FRAMES_JOB=$(sbatch --parsable --requeue --dependency=afterany:$MAPS_JOB --array=0-1 " + farm +
                       "/scripts/frames.sh)"),
              std::string::npos)
        << out;
    EXPECT_NE(out.find("REPORT_JOB=$(sbatch --parsable --dependency=afterany:$FRAMES_JOB " + farm +
                       "/scripts/report.sh)"),
              std::string::npos)
        << out;
    EXPECT_FALSE(fs::exists(dir.file("farm")));
}

TEST(Farm, SubmittedScriptsRenderTheFramesAsOneProcessWould) {
    ScratchDir dir("farm-fake"), local("farm-local");
    writeFile(dir.file("seq.rib"), fiveFrames());
    writeFile(local.file("seq.rib"), fiveFrames());
    writeFakeSbatch(dir);
    ChildRun run = runUmbra(dir, {"farm", "submit", "--chunk", "2", "seq.rib", "-o", "farm"}, {pathWith(dir)});
    ASSERT_EQ(run.status, 0) << run.messages;
    const std::string farm = fs::canonical(dir.file("farm")).string();
    const std::string log = readFile(dir.file("sbatch.log"));
    EXPECT_EQ(log, fmt::format("--parsable {0}/scripts/maps.sh\n"
                               "--parsable --requeue --dependency=afterany:101 --array=0-1 {0}/scripts/frames.sh\n"
                               "--parsable --dependency=afterany:102 {0}/scripts/report.sh\n",
                               farm));
    const json jobs = json::parse(readFile(farm + "/jobs.json"));
    EXPECT_EQ(jobs["maps"], "101");
    EXPECT_EQ(jobs["frames_array"], "102");
    EXPECT_EQ(jobs["report"], "103");
    EXPECT_EQ(jobs["frames"], json({1, 2, 3, 4, 5}));
    EXPECT_EQ(jobs["chunks"], json({"2,3", "4,5"}));

    // Run the jobs in the order their dependencies give, as Slurm would.
    run = runIn(dir, "bash", {"bash", farm + "/scripts/maps.sh"});
    ASSERT_EQ(run.status, 0) << run.messages;
    for (int task : {0, 1}) {
        run = runIn(dir, "bash", {"bash", farm + "/scripts/frames.sh"}, {fmt::format("SLURM_ARRAY_TASK_ID={}", task)});
        ASSERT_EQ(run.status, 0) << run.messages;
    }
    run = runIn(dir, "bash", {"bash", farm + "/scripts/report.sh"});
    ASSERT_EQ(run.status, 0) << run.messages;
    EXPECT_EQ(readFile(farm + "/report/missing.txt"), "");
    const std::string md = readFile(farm + "/report/report.md");
    EXPECT_NE(md.find("Table 1"), std::string::npos) << md;

    // The array tasks read the maps job's map from the cache.
    const auto maps = readLines(farm + "/stats/maps.jsonl");
    ASSERT_EQ(maps.size(), 1u);
    EXPECT_EQ(maps[0]["frame"], 1);
    EXPECT_EQ(maps[0]["maps"][0]["reused"], false);
    for (int task : {0, 1}) {
        const auto lines = readLines(fmt::format("{}/stats/task.{}.jsonl", farm, task));
        ASSERT_EQ(lines.size(), 2u);
        EXPECT_EQ(lines[0]["frame"], 2 + 2 * task);
        EXPECT_EQ(lines[0]["maps"][0]["reason"], "map cache");
        EXPECT_EQ(lines[1]["maps"][0]["reason"], "same content");
    }
    run = runUmbra(local, {"render", "seq.rib"});
    ASSERT_EQ(run.status, 0) << run.messages;
    for (int n = 1; n <= 5; ++n) {
        const std::string image = fmt::format("out.{:04d}.tif", n);
        Image a, b;
        ASSERT_TRUE(umbra::test::readImage(dir.file(image), &a)) << image;
        ASSERT_TRUE(umbra::test::readImage(local.file(image), &b)) << image;
        EXPECT_EQ(umbra::test::maxAbsDiff(a, b, 4), 0.0) << image;
    }
}

TEST(Farm, AFailingChunkIsRetriedAndTheReportNamesIt) {
    ScratchDir dir("farm-retry");
    writeFile(dir.file("seq.rib"), fiveFrames(5));
    fs::create_directories(dir.file("adir"));
    writeFakeSbatch(dir);
    ChildRun run = runUmbra(dir, {"farm", "submit", "--chunk", "2", "--retries", "1", "seq.rib", "-o", "farm"},
                            {pathWith(dir)});
    ASSERT_EQ(run.status, 0) << run.messages;
    const std::string farm = fs::canonical(dir.file("farm")).string();
    run = runIn(dir, "bash", {"bash", farm + "/scripts/frames.sh"}, {"SLURM_ARRAY_TASK_ID=1"});
    EXPECT_NE(run.status, 0);
    EXPECT_NE(run.messages.find("frames 4,5 failed (exit status 1); attempt 2 of 2"), std::string::npos)
        << run.messages;
    EXPECT_NE(run.messages.find("frames 4,5 failed 2 times"), std::string::npos) << run.messages;
    // The maps job and task 0 never ran: the report names them and fails.
    run = runIn(dir, "bash", {"bash", farm + "/scripts/report.sh"});
    EXPECT_NE(run.status, 0);
    EXPECT_EQ(readFile(farm + "/report/missing.txt"), "maps (frames 1)\ntask.0 (frames 2,3)\n");
    EXPECT_EQ(readFile(farm + "/report/failed.txt"), "task.1 (frames 4,5)\n");
    EXPECT_NE(run.messages.find("no statistics from: maps (frames 1) task.0 (frames 2,3)"), std::string::npos)
        << run.messages;
    // The frame that rendered in the failed chunk left its statistics.
    EXPECT_GE(readLines(farm + "/stats/task.1.jsonl").size(), 1u);
}

TEST(Farm, ErrorsAreClearMessages) {
    ScratchDir dir("farm-errors");
    writeFile(dir.file("seq.rib"), fiveFrames());
    writeFile(dir.file("afile"), "not a directory");
    ChildRun run = runUmbra(dir, {"farm", "submit", "--dry-run", "--frames", "3-x", "seq.rib", "-o", "farm"});
    EXPECT_NE(run.status, 0);
    EXPECT_NE(run.messages.find("--frames \"3-x\""), std::string::npos) << run.messages;
    run = runUmbra(dir, {"farm", "submit", "--dry-run", "--frames", "7-9", "seq.rib", "-o", "farm"});
    EXPECT_NE(run.status, 0);
    EXPECT_NE(run.messages.find("none of the scene's frames (1,2,3,4,5) is selected"), std::string::npos)
        << run.messages;
    run = runUmbra(dir, {"farm", "submit", "seq.rib", "-o", "farm"}, {"PATH=" + dir.file("nowhere")});
    EXPECT_NE(run.status, 0);
    EXPECT_NE(run.messages.find("sbatch is not on PATH"), std::string::npos) << run.messages;
    writeFakeSbatch(dir);
    run = runUmbra(dir, {"farm", "submit", "seq.rib", "-o", "afile/farm"}, {pathWith(dir)});
    EXPECT_NE(run.status, 0);
    EXPECT_NE(run.messages.find("cannot use"), std::string::npos) << run.messages;
    EXPECT_FALSE(fs::exists(dir.file("sbatch.log")));
    writeFakeSbatch(dir, true);
    run = runUmbra(dir, {"farm", "submit", "seq.rib", "-o", "farm"}, {pathWith(dir)});
    EXPECT_NE(run.status, 0);
    EXPECT_NE(run.messages.find("Invalid partition name specified"), std::string::npos) << run.messages;
}
