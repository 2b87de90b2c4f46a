// Runs every malformed RIB of tests/rib_errors through the parser and the
// scene builder and compares the diagnostics with name.expected, line by
// line. Files are parsed under their bare names so messages are stable.
// Setting UMBRA_RIB_ERRORS_WRITE=1 writes missing .expected files instead
// (review them by hand before committing).

#include "umbra/ri/parser.h"
#include "umbra/scene/builder.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace umbra {
namespace {

const std::filesystem::path kCorpus = std::filesystem::path(UMBRA_SOURCE_DIR) / "tests" / "rib_errors";

struct Discard : scene::SceneSink {
    void renderWorld(const scene::WorldRecord&) override {}
    void make(const scene::MakeRecord&) override {}
};

std::string readAll(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

std::vector<std::string> diagnosticsFor(const std::filesystem::path& rib) {
    Discard sink;
    Diagnostics diag;
    diag.setRecord(true);
    diag.setSink([](const Diagnostic&) {});
    scene::Builder builder(sink, diag);
    ri::Parser parser(builder, diag);
    std::string bytes = readAll(rib);
    parser.parseString(bytes, rib.filename().string(), kCorpus.string());
    std::vector<std::string> out;
    for (const Diagnostic& d : diag.recorded()) out.push_back(d.str());
    return out;
}

std::vector<std::string> lines(const std::string& text) {
    std::vector<std::string> out;
    std::istringstream in(text);
    for (std::string l; std::getline(in, l);)
        if (!l.empty()) out.push_back(l);
    return out;
}

TEST(RibErrors, EveryCorpusFileGivesItsExpectedDiagnostics) {
    std::vector<std::filesystem::path> ribs;
    for (const auto& e : std::filesystem::directory_iterator(kCorpus))
        if (e.path().extension() == ".rib") ribs.push_back(e.path());
    std::sort(ribs.begin(), ribs.end());
    ASSERT_GE(ribs.size(), 15u);
    bool write = std::getenv("UMBRA_RIB_ERRORS_WRITE") != nullptr;
    for (const auto& rib : ribs) {
        SCOPED_TRACE(rib.filename().string());
        std::vector<std::string> got = diagnosticsFor(rib);
        auto expectedPath = std::filesystem::path(rib).replace_extension(".expected");
        if (write && !std::filesystem::exists(expectedPath)) {
            std::ofstream out(expectedPath);
            for (const auto& l : got) out << l << "\n";
            continue;
        }
        ASSERT_TRUE(std::filesystem::exists(expectedPath)) << "missing " << expectedPath;
        EXPECT_EQ(got, lines(readAll(expectedPath)));
        // Every corpus file is malformed: at least one error, never silence.
        EXPECT_FALSE(got.empty());
    }
}

}  // namespace
}  // namespace umbra
