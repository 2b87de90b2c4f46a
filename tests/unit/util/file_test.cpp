#include "umbra/util/file.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

using namespace umbra;
namespace fs = std::filesystem;

namespace {

std::string readAll(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

}  // namespace

TEST(MoveIntoPlace, ReplacesAnExistingFileAndCreatesAMissingOne) {
    const fs::path dir = fs::temp_directory_path() / "umbra_move_into_place";
    fs::remove_all(dir);
    fs::create_directories(dir);
    const fs::path target = dir / "image.tif", tmp = dir / ".image.tif.tmp";
    std::ofstream(tmp) << "first";
    ASSERT_TRUE(moveIntoPlace(tmp.string(), target.string()));
    EXPECT_EQ(readAll(target), "first");
    EXPECT_FALSE(fs::exists(tmp));
    std::ofstream(tmp) << "second, longer";
    ASSERT_TRUE(moveIntoPlace(tmp.string(), target.string()));
    EXPECT_EQ(readAll(target), "second, longer");
    EXPECT_FALSE(fs::exists(tmp));
    fs::remove_all(dir);
}

TEST(MoveIntoPlace, FailsOntoADirectoryAndKeepsTheFinishedFile) {
    const fs::path dir = fs::temp_directory_path() / "umbra_move_into_place_dir";
    fs::remove_all(dir);
    fs::create_directories(dir / "target" / "inside");
    const fs::path tmp = dir / "finished.tmp";
    std::ofstream(tmp) << "pixels";
    EXPECT_FALSE(moveIntoPlace(tmp.string(), (dir / "target").string()));
    EXPECT_EQ(readAll(tmp), "pixels");
    EXPECT_TRUE(fs::is_directory(dir / "target" / "inside"));
    fs::remove_all(dir);
}
