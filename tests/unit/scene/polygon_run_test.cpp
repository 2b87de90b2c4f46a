// Consecutive Polygon requests with the same attributes and transform are
// kept as one record (a run), so a scene written as 10^6 separate polygons
// takes the memory of what it holds, not of how it was written.

#include "umbra/ri/parser.h"
#include "umbra/scene/builder.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <unistd.h>

namespace umbra::scene {
namespace {

struct Worlds : SceneSink {
    std::vector<WorldRecord> worlds;
    void renderWorld(const WorldRecord& w) override { worlds.push_back(w); }
    void make(const MakeRecord&) override {}
};

struct Parsed {
    Worlds sink;
    Diagnostics diag;
    std::vector<std::string> messages;
};

std::unique_ptr<Parsed> parse(const std::string& rib) {
    auto r = std::make_unique<Parsed>();
    r->diag.setRecord(true);
    r->diag.setSink([](const Diagnostic&) {});
    Builder builder(r->sink, r->diag);
    ri::Parser parser(builder, r->diag);
    parser.parseString(rib, "run.rib", {});
    for (const auto& d : r->diag.recorded()) r->messages.push_back(d.str());
    return r;
}

std::unique_ptr<Parsed> parseFile(const std::string& path) {
    auto r = std::make_unique<Parsed>();
    r->diag.setRecord(true);
    r->diag.setSink([](const Diagnostic&) {});
    Builder builder(r->sink, r->diag);
    ri::Parser parser(builder, r->diag);
    parser.parseFile(path);
    for (const auto& d : r->diag.recorded()) r->messages.push_back(d.str());
    return r;
}

std::string quad(float x) {
    return "Polygon \"P\" [" + std::to_string(x) + " 0 0 " + std::to_string(x + 1) + " 0 0 " + std::to_string(x + 1) +
           " 1 0 " + std::to_string(x) + " 1 0]\n";
}

TEST(PolygonRun, HundredThousandPolygonsTakeOneRecordOfTheirPoints) {
    const int n = 100000;
    std::string rib = "WorldBegin\nColor 1 0 0\n";
    rib.reserve(size_t(n) * 80);
    for (int k = 0; k < n; ++k) rib += quad(float(k % 1000));
    rib += "WorldEnd\n";
    auto r = parse(rib);
    ASSERT_EQ(r->sink.worlds.size(), 1u);
    const WorldRecord& w = r->sink.worlds[0];
    ASSERT_EQ(w.primitives.size(), 1u);
    const PrimitiveRecord& run = w.primitives[0];
    ASSERT_EQ(run.intArrays.size(), 1u);
    EXPECT_EQ(run.intArrays[0], std::vector<int>(size_t(n), 4));
    const ri::Param* P = run.params.find("P");
    ASSERT_NE(P, nullptr);
    ASSERT_EQ(P->floats.size(), size_t(n) * 12);
    EXPECT_EQ(P->floats[12 * 999 + 3], 1000.0f);  // polygon 999's second corner
    // The record's own storage per polygon: four points and a count (52
    // bytes), where a record each took sizeof(PrimitiveRecord) and a
    // parameter list of its own.
    const size_t bytes = sizeof(PrimitiveRecord) + P->floats.size() * sizeof(float) +
                         run.intArrays[0].size() * sizeof(int);
    EXPECT_LT(double(bytes) / n, 53.0);
    EXPECT_GT(sizeof(PrimitiveRecord), 300u);
    std::set<const Attributes*> states;
    for (const auto& p : w.primitives) states.insert(p.attributes.get());
    EXPECT_EQ(states.size(), 1u);
    EXPECT_EQ(run.loc.str(), "run.rib:3:1");
}

TEST(PolygonRun, ARunEndsWhereTheStateOrTheRequestDiffers) {
    auto r = parse("WorldBegin\n" + quad(0) + quad(1) +     // a run of two
                   "Color 0 1 0\n" + quad(2) +              // new attributes
                   "Translate 0 0 1\n" + quad(3) + quad(4) +  // new transform: a run of two
                   "Polygon \"P\" [0 0 0 1 0 0 1 1 0] \"Cs\" [1 0 0 0 1 0 0 0 1]\n" +  // more than P
                   quad(5) +
                   "AttributeBegin\n" + quad(6) + "AttributeEnd\n" +  // the same state: joins
                   "MotionBegin [0 1]\n" + quad(7) + quad(8) + "MotionEnd\n" +  // deforming: its own
                   quad(9) + "WorldEnd\n");
    ASSERT_EQ(r->sink.worlds.size(), 1u);
    std::vector<size_t> polygons;
    for (const auto& p : r->sink.worlds[0].primitives)
        polygons.push_back(p.intArrays.empty() ? 1 : p.intArrays[0].size());
    EXPECT_EQ(polygons, (std::vector<size_t>{2, 1, 2, 1, 2, 1, 1}));
}

TEST(PolygonRun, AMalformedPolygonKeepsItsOwnRecordAndLocation) {
    auto r = parse("WorldBegin\n" + quad(0) + "Polygon \"P\" [0 0 0 1 0 0]\n" + quad(1) + "WorldEnd\n");
    ASSERT_EQ(r->sink.worlds.size(), 1u);
    const auto& prims = r->sink.worlds[0].primitives;
    ASSERT_EQ(prims.size(), 3u);
    EXPECT_EQ(prims[1].loc.str(), "run.rib:3:1");
    EXPECT_TRUE(prims[0].intArrays.empty());
}

TEST(PolygonRun, TextTheParserGaveBackLeavesLaterRequestsIntact) {
    // Past 17 MB of text the parser gives parsed pages back; an inline
    // archive recorded and read after that, and its message's column, must
    // be as if it had not.
    const std::string path =
        (std::filesystem::temp_directory_path() / ("umbra-large-" + std::to_string(::getpid()) + ".rib")).string();
    const int n = 250000;
    {
        std::ofstream f(path);
        f << "WorldBegin\n";
        for (int k = 0; k < n; ++k) f << quad(float(k % 1000));
        f << "ArchiveBegin \"late\" Sphere 1 \"oops\"\nArchiveEnd\nReadArchive \"late\"\nSphere 2 -2 2 360\nWorldEnd\n";
    }
    ASSERT_GT(std::filesystem::file_size(path), size_t(17) << 20);
    auto r = parseFile(path);
    std::filesystem::remove(path);
    EXPECT_EQ(r->messages, (std::vector<std::string>{
                               path + ":" + std::to_string(n + 2) +
                               ":21: error: Sphere: missing argument zmin (usage: Sphere radius zmin zmax thetamax)"}));
    ASSERT_EQ(r->sink.worlds.size(), 1u);
    const auto& prims = r->sink.worlds[0].primitives;
    ASSERT_EQ(prims.size(), 2u);
    ASSERT_EQ(prims[0].intArrays.at(0).size(), size_t(n));
    const std::vector<float>& P = prims[0].params.find("P")->floats;
    EXPECT_EQ(P[12 * (n - 1)], float((n - 1) % 1000));
    EXPECT_EQ(prims[1].floatArgs.at(0), 2.0f);
}

}  // namespace
}  // namespace umbra::scene
