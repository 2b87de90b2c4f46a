// Outputs named by a Display (and depth maps, --stats) are written whole
// under a temporary name and renamed into place. A symbolic link is written
// through to its file, as every other program does; a directory, FIFO or
// device is refused with a located error and never replaced.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <filesystem>
#include <sys/stat.h>

using namespace umbra;
using umbra::test::Image;
using umbra::test::ScratchDir;
namespace fs = std::filesystem;

namespace {

std::string sphereTo(const std::string& display, const std::string& driver = "file", const std::string& mode = "rgb") {
    return fmt::format(R"(Format 32 24 1
Display "{}" "{}" "{}"
Projection "perspective" "fov" 40
Translate 0 0 5
WorldBegin
Surface "constant"
Sphere 1 -1 1 360
WorldEnd
)", display, driver, mode);
}

std::vector<std::string> errorsOf(const Diagnostics& d) {
    std::vector<std::string> out;
    for (const Diagnostic& m : d.recorded())
        if (m.severity == Severity::Error) out.push_back(m.str());
    return out;
}

}  // namespace

TEST(OutputFiles, ADisplayOntoASymlinkWritesThroughToItsFile) {
    ScratchDir dir("output-symlink");
    fs::create_directories(dir.file("real"));
    fs::create_symlink("real/picture.tif", dir.file("link.tif"));  // dangling until written
    Diagnostics diag;
    diag.setQuiet(true);
    test::renderRib(sphereTo(dir.file("link.tif")), diag);
    EXPECT_EQ(diag.errorCount(), 0);
    EXPECT_TRUE(fs::is_symlink(dir.file("link.tif")));  // still the user's link
    Image img;
    ASSERT_TRUE(test::readImage(dir.file("real/picture.tif"), &img));
    EXPECT_GT(img.channelSum(0), 10.0);
    // Rendered again: the link's file is replaced, the link kept.
    test::renderRib(sphereTo(dir.file("link.tif")), diag);
    EXPECT_EQ(diag.errorCount(), 0);
    EXPECT_TRUE(fs::is_symlink(dir.file("link.tif")));
}

TEST(OutputFiles, DirectoriesAndFifosAreRefusedAndLeftAlone) {
    ScratchDir dir("output-special");
    fs::create_directories(dir.file("adir"));
    ASSERT_EQ(::mkfifo(dir.file("afifo").c_str(), 0644), 0);
    for (const char* name : {"adir", "afifo"}) {
        for (const char* driver : {"file", "zfile", "shadow"}) {
            Diagnostics diag;
            diag.setQuiet(true);
            diag.setRecord(true);
            int failed = 0;
            test::renderRib(sphereTo(dir.file(name), driver, std::string(driver) == "file" ? "rgb" : "z"), diag, 0,
                            0, &failed);
            std::vector<std::string> errors = errorsOf(diag);
            ASSERT_EQ(errors.size(), 1u) << name << " " << driver;
            EXPECT_NE(errors[0].find("test.rib:2:1: error:"), std::string::npos) << errors[0];
            EXPECT_NE(errors[0].find(std::string(name) == "adir" ? "it is a directory" : "it is a FIFO"),
                      std::string::npos)
                << errors[0];
            EXPECT_EQ(failed, 1) << name << " " << driver;
        }
    }
    EXPECT_TRUE(fs::is_directory(dir.file("adir")));
    EXPECT_TRUE(fs::is_fifo(dir.file("afifo")));
    // Nothing else was left behind: no temporary files.
    int entries = 0;
    for (const auto& e : fs::directory_iterator(dir.file(""))) ++entries, (void)e;
    EXPECT_EQ(entries, 2);
}
