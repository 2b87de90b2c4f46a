// Golden-image tests: every folder of tests/golden/ holding a scene.rib is
// one case. The scene is rendered in a scratch directory and its out.exr
// compared with the folder's reference.exr under the folder's tolerance.txt:
//
//   max  0.05    largest allowed per-channel difference of a pixel...
//   fraction 0.001  ...except for at most this fraction of the pixels
//   mean 0.002   largest allowed mean absolute difference over all channels
//
// Stochastic sampling is deterministic, so tolerances only absorb float
// differences between compilers and sanitizer builds.

#include "support/render_harness.h"

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>

namespace fs = std::filesystem;
using namespace umbra;

namespace {

std::vector<std::string> goldenCases() {
    std::vector<std::string> cases;
    for (const auto& entry : fs::directory_iterator(fs::path(UMBRA_SOURCE_DIR) / "tests" / "golden"))
        if (entry.is_directory() && fs::exists(entry.path() / "scene.rib")) cases.push_back(entry.path().filename().string());
    std::sort(cases.begin(), cases.end());
    return cases;
}

std::map<std::string, double> readTolerance(const fs::path& file) {
    std::map<std::string, double> t = {{"max", 0.05}, {"fraction", 0.001}, {"mean", 0.002}};
    std::ifstream in(file);
    std::string key;
    double value;
    while (in >> key >> value) t[key] = value;
    return t;
}

class Golden : public ::testing::TestWithParam<std::string> {};

TEST_P(Golden, MatchesReference) {
    const fs::path dir = fs::path(UMBRA_SOURCE_DIR) / "tests" / "golden" / GetParam();
    test::ScratchDir scratch("golden-" + GetParam());
    const fs::path work = fs::path(scratch.file(""));
    // The scene names its outputs relative to the working directory.
    fs::path previous = fs::current_path();
    fs::current_path(work);
    Diagnostics diag;
    std::ifstream in(dir / "scene.rib");
    std::string rib((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    test::renderRib(rib, diag);
    fs::current_path(previous);
    ASSERT_EQ(diag.errorCount(), 0);
    const fs::path out = work / "out.exr";
    ASSERT_TRUE(fs::exists(out));

    const fs::path reference = dir / "reference.exr";
    if (std::getenv("UMBRA_GOLDEN_UPDATE")) {
        fs::copy_file(out, reference, fs::copy_options::overwrite_existing);
        std::printf("reference rewritten: %s\n", reference.c_str());
        return;
    }
    ASSERT_TRUE(fs::exists(reference)) << "no reference image; run with UMBRA_GOLDEN_UPDATE=1";
    OIIO::ImageBuf a(out.string()), b(reference.string());
    ASSERT_TRUE(a.read() && b.read());
    ASSERT_EQ(a.spec().width, b.spec().width);
    ASSERT_EQ(a.spec().height, b.spec().height);
    ASSERT_EQ(a.spec().nchannels, b.spec().nchannels);
    auto tol = readTolerance(dir / "tolerance.txt");
    auto cmp = OIIO::ImageBufAlgo::compare(a, b, float(tol["max"]), float(tol["max"]));
    double pixels = double(a.spec().width) * a.spec().height;
    EXPECT_LE(double(cmp.nfail) / pixels, tol["fraction"]) << cmp.nfail << " pixels differ by more than " << tol["max"];
    EXPECT_LE(cmp.meanerror, tol["mean"]);
}

INSTANTIATE_TEST_SUITE_P(Cases, Golden, ::testing::ValuesIn(goldenCases()),
                         [](const auto& info) { return info.param; });

}  // namespace
