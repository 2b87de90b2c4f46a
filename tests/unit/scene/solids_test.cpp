// SolidBegin trees and level-of-detail attributes as the builder records them.

#include "umbra/ri/parser.h"
#include "umbra/scene/builder.h"

#include <gtest/gtest.h>

#include <cmath>

namespace umbra::scene {
namespace {

struct Collect : SceneSink {
    std::vector<WorldRecord> worlds;
    void renderWorld(const WorldRecord& w) override { worlds.push_back(w); }
    void make(const MakeRecord&) override {}
};

WorldRecord build(std::string_view rib, Diagnostics& diag) {
    Collect sink;
    diag.setRecord(true);
    diag.setSink([](const Diagnostic&) {});
    Builder builder(sink, diag);
    ri::Parser(builder, diag).parseString(rib, "s.rib", {});
    EXPECT_EQ(sink.worlds.size(), 1u);
    return sink.worlds.empty() ? WorldRecord() : sink.worlds[0];
}

}  // namespace

TEST(Solids, TreesRecordOperationsParentsAndLeaves) {
    Diagnostics diag;
    const WorldRecord w = build(R"(WorldBegin
        SolidBegin "primitive" Sphere 1 -1 1 360 SolidEnd
        SolidBegin "difference"
          SolidBegin "union"
            SolidBegin "primitive" Sphere 1 -1 1 360 Disk 0 1 360 SolidEnd
            Sphere 2 -2 2 360
          SolidEnd
          SolidBegin "primitive" Sphere 0.5 -0.5 0.5 360 SolidEnd
        SolidEnd
        Sphere 3 -3 3 360
        WorldEnd)",
                                diag);
    EXPECT_EQ(diag.errorCount(), 0);
    EXPECT_EQ(diag.warningCount(), 0);
    // 0 difference, 1 union, 2 primitive, 3 the bare sphere's own leaf, 4 primitive.
    ASSERT_EQ(w.solids.size(), 5u);
    const std::pair<const char*, int> expected[] = {
        {"difference", -1}, {"union", 0}, {"primitive", 1}, {"primitive", 1}, {"primitive", 0}};
    for (size_t k = 0; k < 5; ++k) {
        EXPECT_EQ(w.solids[k].operation, expected[k].first) << k;
        EXPECT_EQ(w.solids[k].parent, expected[k].second) << k;
    }
    ASSERT_EQ(w.primitives.size(), 6u);
    const int leaves[] = {-1, 2, 2, 3, 4, -1};  // a top-level primitive solid is ordinary geometry
    for (size_t k = 0; k < 6; ++k) EXPECT_EQ(w.primitives[k].solid, leaves[k]) << k;
}

TEST(Solids, AnInstanceIsOneLeaf) {
    Diagnostics diag;
    const WorldRecord w = build(R"(ObjectBegin 1 Sphere 1 -1 1 360 Disk 0 1 360 ObjectEnd
        WorldBegin
        SolidBegin "intersection" ObjectInstance 1 Sphere 1 -1 1 360 SolidEnd
        WorldEnd)",
                                diag);
    ASSERT_EQ(w.solids.size(), 3u);
    ASSERT_EQ(w.primitives.size(), 3u);
    EXPECT_EQ(w.primitives[0].solid, 1);
    EXPECT_EQ(w.primitives[1].solid, 1);
    EXPECT_EQ(w.primitives[2].solid, 2);
}

TEST(Solids, UnknownOperationIsALocatedError) {
    Diagnostics diag;
    const WorldRecord w = build("WorldBegin\nSolidBegin \"xor\" Sphere 1 -1 1 360 SolidEnd WorldEnd", diag);
    ASSERT_EQ(diag.errorCount(), 1);
    EXPECT_NE(diag.recorded().front().str().find("s.rib:2:1: error: SolidBegin: unknown operation \"xor\""),
              std::string::npos)
        << diag.recorded().front().str();
    EXPECT_TRUE(w.solids.empty());
    EXPECT_EQ(w.primitives.at(0).solid, -1);
}

TEST(Solids, NestingIsBounded) {
    std::string rib = "WorldBegin\n";
    for (int k = 0; k < 300; ++k) rib += "SolidBegin \"union\"\n";
    rib += "Sphere 1 -1 1 360\n";
    for (int k = 0; k < 300; ++k) rib += "SolidEnd\n";
    rib += "WorldEnd\n";
    Diagnostics diag;
    const WorldRecord w = build(rib, diag);
    EXPECT_EQ(diag.errorCount(), 44);
    EXPECT_NE(diag.recorded().front().str().find("s.rib:258:1: error: SolidBegin: CSG nested deeper than 256"),
              std::string::npos)
        << diag.recorded().front().str();
    ASSERT_EQ(w.solids.size(), 257u);  // 256 unions and the sphere's own leaf
    EXPECT_EQ(w.primitives.at(0).solid, 256);
}

TEST(LevelOfDetailAttributes, DetailBoxIsKeptInWorldSpace) {
    Diagnostics diag;
    const WorldRecord w = build(R"(RelativeDetail 0.5
        WorldBegin
        Translate 0 0 10 Scale 2 2 2
        Detail [-1 1 -1 1 -1 1]
        DetailRange [1 2 3 4]
        Sphere 1 -1 1 360
        WorldEnd)",
                                diag);
    EXPECT_EQ(diag.errorCount(), 0);
    EXPECT_EQ(w.options.relativeDetail, 0.5f);
    const Attributes& a = *w.primitives.at(0).attributes;
    ASSERT_TRUE(a.hasDetail);
    EXPECT_EQ(a.detailCorners[0], Vec3(-2, -2, 8));
    EXPECT_EQ(a.detailCorners[7], Vec3(2, 2, 12));
    EXPECT_EQ(a.detailRange, (std::array<float, 4>{1, 2, 3, 4}));
}

}  // namespace umbra::scene
