// `--progress` through the `umbra` command: the share of the work it
// reports comes from the buckets' estimated work, so a frame whose top
// third is empty does not claim a third done once its empty buckets are.
// The test reads the plain progress lines (stderr is not a terminal); it
// reads no clock and asserts nothing about the times printed.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <regex>
#include <sstream>

using umbra::test::ScratchDir;

TEST(Progress, ShareFollowsWorkNotBuckets) {
    ScratchDir dir("progress-sky");
    {
        // 384x216 in 16-pixel buckets: 24 x 14. An orthographic view of a
        // plane covering the lower two thirds; above it, nothing.
        std::ofstream rib(dir.file("sky.rib"));
        rib << "Format 384 216 1\nPixelSamples 1 1\nDisplay \"sky.tif\" \"file\" \"rgba\"\n"
               "Projection \"orthographic\"\nWorldBegin\nSurface \"constant\"\n"
               "Patch \"bilinear\" \"P\" [-2 0.3333 5  2 0.3333 5  -2 -1.1 5  2 -1.1 5]\nWorldEnd\n";
    }
    const std::string log = dir.file("run.log");
    const pid_t pid = fork();
    if (pid == 0) {
        if (chdir(dir.file("").c_str()) != 0) _exit(126);
        const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fd >= 0) dup2(fd, 2);
        setenv("UMBRA_SHADER_PATH", UMBRA_SOURCE_DIR "/shaders_dsl", 1);
        execl(UMBRA_APP, "umbra", "render", "--threads", "1", "--progress", "--quiet", "sky.rib", nullptr);
        _exit(127);
    }
    int status = 0;
    ASSERT_EQ(waitpid(pid, &status, 0), pid);
    std::ifstream in(log);
    std::stringstream text;
    text << in.rdbuf();
    ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << text.str();

    // "image: 40% (201/336 buckets), 0.0s elapsed, ETA 0.0s"
    const std::regex line(R"(image: (\d+)% \((\d+)/(\d+) buckets\))");
    int lastPercent = -1, lines = 0;
    double bucketsAtTenPercent = -1;
    std::string s = text.str();
    for (std::sregex_iterator it(s.begin(), s.end(), line), end; it != end; ++it) {
        const int percent = std::stoi((*it)[1]);
        const double buckets = std::stod((*it)[2]) / std::stod((*it)[3]);
        EXPECT_GT(percent, lastPercent) << it->str();  // never back, a line per new tenth
        lastPercent = percent;
        if (percent >= 10 && bucketsAtTenPercent < 0) bucketsAtTenPercent = buckets;
        ++lines;
    }
    ASSERT_GT(lines, 2) << s;
    EXPECT_EQ(lastPercent, 100);
    // The empty third (a tenth of a covered pixel's work per pixel) is
    // about 5% of the frame: 10% is reached only past it.
    EXPECT_GT(bucketsAtTenPercent, 1.0 / 3.0) << s;
}
