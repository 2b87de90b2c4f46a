// Outputs named by a Display (and depth maps, --stats) are written whole
// under a temporary name and renamed into place. A symbolic link is written
// through to its file, as every other program does; a directory, FIFO or
// device is refused with a located error and never replaced.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <OpenImageIO/imageio.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <thread>
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

namespace {

std::string bytesOf(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

/// A sphere written as TIFF, OpenEXR and PNG into `dir`, in-process.
void renderThreeFormats(const ScratchDir& dir) {
    const std::string rib = fmt::format(R"(Format 32 24 1
Display "{0}/a.tif" "file" "rgba"
Display "+{0}/a.exr" "openexr" "rgba"
Display "+{0}/a.png" "png" "rgba"
Projection "perspective" "fov" 40
Translate 0 0 5
WorldBegin
Surface "constant"
Sphere 1 -1 1 360
WorldEnd
)", dir.file(""));
    Diagnostics diag;
    diag.setQuiet(true);
    test::renderRib(rib, diag);
    EXPECT_EQ(diag.errorCount(), 0);
}

}  // namespace

TEST(OutputFiles, SourceDateEpochMakesFilesReproducible) {
    // The reproducible-builds convention: with SOURCE_DATE_EPOCH set, the
    // date images carry is that time (UTC) and no render time is written,
    // so two renders a second apart write the same bytes.
    ScratchDir first("output-sde-1"), second("output-sde-2");
    ::setenv("SOURCE_DATE_EPOCH", "1700000000", 1);  // 2023-11-14 22:13:20 UTC
    renderThreeFormats(first);
    std::this_thread::sleep_for(std::chrono::milliseconds(1100));  // another second on the clock
    renderThreeFormats(second);
    ::unsetenv("SOURCE_DATE_EPOCH");
    for (const char* name : {"a.tif", "a.exr", "a.png"}) {
        SCOPED_TRACE(name);
        const std::string a = bytesOf(first.file(name)), b = bytesOf(second.file(name));
        ASSERT_FALSE(a.empty());
        EXPECT_TRUE(a == b) << "the two renders' files differ";
        auto in = OIIO::ImageInput::open(first.file(name));
        ASSERT_TRUE(in);
        EXPECT_EQ(in->spec().get_string_attribute("DateTime"), "2023:11:14 22:13:20");
        EXPECT_EQ(in->spec().find_attribute("umbra:rendertime"), nullptr);
    }
    // Unset, the files carry the render's own time again.
    ScratchDir third("output-sde-3");
    renderThreeFormats(third);
    auto in = OIIO::ImageInput::open(third.file("a.exr"));
    ASSERT_TRUE(in);
    EXPECT_NE(in->spec().find_attribute("umbra:rendertime"), nullptr);
}
