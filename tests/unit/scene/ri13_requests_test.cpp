// RenderMan 13+ requests: inline archives, conditional RIB, Resource,
// Camera, System, GeometricRepresentation, named Quantize.

#include "umbra/ri/parser.h"
#include "umbra/scene/builder.h"

#include <gtest/gtest.h>

namespace umbra::scene {
namespace {

struct Collect : SceneSink {
    std::vector<WorldRecord> worlds;
    void renderWorld(const WorldRecord& w) override { worlds.push_back(w); }
    void make(const MakeRecord&) override {}
};

struct Session {
    Collect sink;
    Diagnostics diag;
    std::unique_ptr<Builder> builder;
    std::vector<std::string> messages() const {
        std::vector<std::string> out;
        for (auto& d : diag.recorded()) out.push_back(d.str());
        return out;
    }
    /// The first float argument (the radius) of each primitive of world 0.
    std::vector<float> radii() const {
        std::vector<float> out;
        if (sink.worlds.empty()) return out;
        for (const PrimitiveRecord& p : sink.worlds[0].primitives) out.push_back(p.floatArgs.at(0));
        return out;
    }
};

std::unique_ptr<Session> run(std::string_view rib) {
    auto r = std::make_unique<Session>();
    r->diag.setRecord(true);
    r->diag.setSink([](const Diagnostic&) {});
    r->builder = std::make_unique<Builder>(r->sink, r->diag);
    ri::Parser p(*r->builder, r->diag);
    p.parseString(rib, "s.rib");
    return r;
}

using Strings = std::vector<std::string>;

TEST(InlineArchive, RecordedThenReplayedByReadArchive) {
    auto r = run(R"rib(ArchiveBegin "ball"
  Sphere 2 -2 2 360
  ArchiveBegin "inner" Sphere 9 -9 9 360 ArchiveEnd
ArchiveEnd
WorldBegin
ReadArchive "ball"
Translate 1 0 0
ReadArchive "ball"
ReadArchive "inner"
WorldEnd
)rib");
    EXPECT_EQ(r->messages(), Strings{});
    // Nothing drawn while recording; the inner archive exists once the
    // outer one has been read.
    EXPECT_EQ(r->radii(), (std::vector<float>{2, 2, 9}));
    EXPECT_EQ(r->sink.worlds[0].primitives[1].worldFromObject.point({0, 0, 0}).x, 1.0f);
}

TEST(InlineArchive, MessagesInsideGiveTheBodysLines) {
    auto r = run("ArchiveBegin \"bad\" Sphere 1 -1 1 360\nSphere 1 \"oops\"\nArchiveEnd\n"
                 "WorldBegin ReadArchive \"bad\" WorldEnd\nArchiveEnd\nArchiveBegin \"open\"\n");
    EXPECT_EQ(r->messages(),
              (Strings{"s.rib:2:1: error: Sphere: missing argument zmin (usage: Sphere radius zmin zmax thetamax)",
                       "s.rib:5:1: error: ArchiveEnd: no matching ArchiveBegin (ignored)",
                       "s.rib:6:1: error: ArchiveBegin: no matching ArchiveEnd before the end of s.rib (archive "
                       "\"open\" is not recorded)"}));
    EXPECT_EQ(r->radii(), (std::vector<float>{1}));
}

TEST(Conditional, BranchesFollowUserOptionsAndAttributes) {
    auto r = run(R"rib(Option "user" "string pass" "shadow"
WorldBegin
IfBegin "$user:pass == 'shadow'"
  Sphere 1 -1 1 360
ElseIf "$user:pass == 'beauty'"
  Sphere 2 -2 2 360
Else
  Sphere 3 -3 3 360
IfEnd
IfBegin "$user:pass == 'beauty'"
  Sphere 4 -4 4 360
  IfBegin "1" Sphere 5 -5 5 360 Else Sphere 6 -6 6 360 IfEnd
  Bogus 1 2 3
Else
  Attribute "user" "float lod" [2]
  IfBegin "$lod >= 2 && !defined($Attribute:user:missing)" Sphere 7 -7 7 360 IfEnd
IfEnd
IfBegin "$Option:user:pass != 'shadow'" Sphere 8 -8 8 360 ElseIf "1" Sphere 9 -9 9 360 ElseIf "1" Sphere 10 -10 10 360 IfEnd
WorldEnd
)rib");
    EXPECT_EQ(r->messages(), Strings{});
    EXPECT_EQ(r->radii(), (std::vector<float>{1, 7, 9}));
}

TEST(Conditional, StructureErrorsAndUndefinedNames) {
    auto r = run("WorldBegin\nIfBegin \"$user:nope == 'x'\" Sphere 1 -1 1 360 IfEnd\nElse\nIfEnd\n"
                 "IfBegin \"pass ==\" Sphere 2 -2 2 360 Else Sphere 3 -3 3 360 Else IfEnd\n"
                 "IfBegin \"1\"\nWorldEnd\n");
    EXPECT_EQ(r->messages(),
              (Strings{"s.rib:2:1: warning: IfBegin: \"$user:nope\" is not defined (taken as the empty string)",
                       "s.rib:3:1: error: Else: no matching IfBegin (ignored)",
                       "s.rib:4:1: error: IfEnd: no matching IfBegin (ignored)",
                       "s.rib:5:1: error: IfBegin: bad condition \"pass ==\": unknown word \"pass\" (strings are "
                       "quoted: 'pass') (taken as false)",
                       "s.rib:5:60: error: Else: after the Else at s.rib:5:37 of the IfBegin at s.rib:5:1 (ignored)",
                       "s.rib:6:1: error: IfBegin: no matching IfEnd before the end of s.rib"}));
    EXPECT_EQ(r->radii(), (std::vector<float>{3}));
}

TEST(Resource, SavesAndRestoresAttributesAndTransform) {
    auto r = run(R"rib(WorldBegin
Color 1 0 0
Translate 1 0 0
Resource "red" "attributes" "string operation" "save"
Color 0 1 0
Translate 0 5 0
Sphere 1 -1 1 360
Resource "red" "attributes" "string operation" "restore"
Sphere 2 -2 2 360
Color 0 0 1
Surface "plastic"
Resource "red" "attributes" "string operation" "restore" "string subset" "shading"
Sphere 3 -3 3 360
ResourceBegin
Resource "inner" "attributes" "string operation" "save"
ResourceEnd
Resource "inner" "attributes" "string operation" "restore"
WorldEnd
)rib");
    EXPECT_EQ(r->messages(), (Strings{"s.rib:17:1: error: Resource: no attributes saved as \"inner\" (expected a "
                                      "Resource \"inner\" \"attributes\" \"operation\" \"save\" first; ignored)"}));
    const auto& prims = r->sink.worlds.at(0).primitives;
    ASSERT_EQ(prims.size(), 3u);
    EXPECT_EQ(prims[0].attributes->color.y, 1.0f);
    EXPECT_EQ(prims[1].attributes->color.x, 1.0f);
    EXPECT_EQ(prims[1].worldFromObject.point({0, 0, 0}).y, 0.0f);
    // "shading" brings back colour and surface, not the transform.
    EXPECT_EQ(prims[2].attributes->color.x, 1.0f);
    EXPECT_EQ(prims[2].attributes->color.z, 0.0f);
    EXPECT_EQ(prims[2].attributes->surface, nullptr);
}

TEST(Camera, NamesTheCameraSpace) {
    auto r = run("Projection \"perspective\" Translate 0 0 5 Rotate 30 0 1 0 Camera \"main\" "
                 "WorldBegin WorldEnd");
    EXPECT_EQ(r->messages(), Strings{});
    const auto& spaces = r->sink.worlds.at(0).coordinateSystems;
    const Mat4& named = spaces.at("main");
    const Mat4& camera = spaces.at("camera");
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) EXPECT_NEAR(named.m[i][j], camera.m[i][j], 1e-5f) << i << j;
}

TEST(OtherRequests, SystemGeometricRepresentationAndNamedQuantize) {
    auto r = run(R"rib(Quantize "Cs" 65535 0 65535 0.5
Exposure 1.5 2.2
Imager "background" "color background" [0 0 1]
System "rm -rf /"
WorldBegin
GeometricRepresentation "primitive"
GeometricRepresentation "lines"
GeometricRepresentation "lines"
Sphere 1 -1 1 360
WorldEnd
)rib");
    EXPECT_EQ(r->messages(), (Strings{"s.rib:4:1: warning: System: running commands is not supported (ignored)",
                                      "s.rib:7:1: warning: GeometricRepresentation: \"lines\" is not supported; "
                                      "surfaces are drawn as primitives"}));
    const Options& o = r->sink.worlds.at(0).options;
    EXPECT_EQ(o.namedQuantize.at("Cs"), (std::array<float, 4>{65535, 0, 65535, 0.5f}));
    EXPECT_EQ(o.exposureGain, 1.5f);
    EXPECT_EQ(o.quantizeOne, 255.0f);  // rgba untouched
}

}  // namespace
}  // namespace umbra::scene
