#include "umbra/scene/builder.h"

#include "umbra/ri/parser.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace umbra::scene {
namespace {

struct Collect : SceneSink {
    std::vector<WorldRecord> worlds;
    std::vector<MakeRecord> makes;
    std::vector<std::string> events;
    void renderWorld(const WorldRecord& w) override {
        worlds.push_back(w);
        events.push_back("world");
    }
    void make(const MakeRecord& m) override {
        makes.push_back(m);
        events.push_back("make " + m.request);
    }
    void frameBegin(int n, const FileLoc&) override { events.push_back(fmt::format("frame {}", n)); }
    void frameEnd(const FileLoc&) override { events.push_back("frameEnd"); }
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
};

std::unique_ptr<Session> run(std::string_view rib, const std::string& dir = {}) {
    auto r = std::make_unique<Session>();
    r->diag.setRecord(true);
    r->diag.setSink([](const Diagnostic&) {});
    r->builder = std::make_unique<Builder>(r->sink, r->diag);
    ri::Parser p(*r->builder, r->diag);
    p.parseString(rib, "s.rib", dir);
    return r;
}

void expectNear(const Vec3& a, const Vec3& b) {
    EXPECT_NEAR(a.x, b.x, 1e-5f);
    EXPECT_NEAR(a.y, b.y, 1e-5f);
    EXPECT_NEAR(a.z, b.z, 1e-5f);
}

TEST(Builder, TranslateThenRotateAppliesRotateFirst) {
    auto r = run("WorldBegin Translate 1 0 0 Rotate 90 0 0 1 Sphere 1 -1 1 360 WorldEnd");
    ASSERT_EQ(r->sink.worlds.size(), 1u);
    const PrimitiveRecord& p = r->sink.worlds[0].primitives.at(0);
    // Rotate (1,0,0) by 90 degrees about z to (0,1,0), then translate by x.
    expectNear(p.worldFromObject.point({1, 0, 0}), {1, 1, 0});
    expectNear(p.worldFromObject.point({0, 0, 2}), {1, 0, 2});
    EXPECT_EQ(p.floatArgs, (std::vector<float>{1, -1, 1, 360}));
}

TEST(Builder, CameraTransformAndProjection) {
    auto r = run("Projection \"perspective\" \"fov\" 40\nScale 1 1 -1\nTranslate 0 0 5\n"
                 "ConcatTransform [1 0 0 0  0 1 0 0  0 0 1 0  0 2 0 1]\nWorldBegin WorldEnd");
    ASSERT_EQ(r->sink.worlds.size(), 1u);
    const Options& o = r->sink.worlds[0].options;
    EXPECT_EQ(o.projection, Projection::Perspective);
    EXPECT_EQ(o.fov, 40.0f);
    // World origin: translated by (0,2,0) (the RIB row-vector matrix), then
    // (0,0,5), then z mirrored.
    expectNear(o.cameraFromWorld.point({0, 0, 0}), {0, 2, -5});
    expectNear(r->sink.worlds[0].coordinateSystems.at("camera").point({0, 2, -5}), {0, 0, 0});
}

TEST(Builder, TransformsBeforeProjectionAreTheScreenTransformation) {
    // RI Spec 3.2: screen = CTM * projection. Scale then Translate compose
    // as transforms do: x' = -2 (x + 0.5), y' = 3 (y + 0.25). The camera
    // transform starts again from the identity after Projection.
    auto r = run("Scale -2 3 1\nTranslate 0.5 0.25 0\nProjection \"perspective\" \"fov\" 40\n"
                 "Translate 0 0 5\nWorldBegin WorldEnd");
    ASSERT_EQ(r->sink.worlds.size(), 1u);
    EXPECT_EQ(r->messages(), std::vector<std::string>{});
    const Options& o = r->sink.worlds[0].options;
    EXPECT_FLOAT_EQ(o.screenLinear[0], -2.0f);
    EXPECT_EQ(o.screenLinear[1], 0.0f);
    EXPECT_EQ(o.screenLinear[2], 0.0f);
    EXPECT_FLOAT_EQ(o.screenLinear[3], 3.0f);
    EXPECT_FLOAT_EQ(o.screenOffset[0], -1.0f);
    EXPECT_FLOAT_EQ(o.screenOffset[1], 0.75f);
    expectNear(o.cameraFromWorld.point({1, 2, 3}), {1, 2, 8});
    // A later Projection takes the transform current then (the identity).
    auto again = run("Scale -1 1 1 Projection \"orthographic\" Projection \"perspective\" WorldBegin WorldEnd");
    EXPECT_EQ(again->sink.worlds.at(0).options.screenLinear[0], 1.0f);
}

TEST(Builder, ScreenRotationIsKeptAndDepthIsWarnedAndDropped) {
    auto r = run("Rotate 90 0 0 1\nScale 2 2 -1\nProjection \"perspective\"\nWorldBegin WorldEnd");
    const std::vector<std::string> m = r->messages();
    ASSERT_EQ(m.size(), 1u);
    EXPECT_EQ(m[0].rfind("s.rib:3:1: warning: Projection: the screen transformation changes depth", 0), 0u) << m[0];
    // A quarter turn of a scale by 2: x' = -2 y, y' = 2 x, the cosines'
    // rounding made exact zeros.
    const Options& o = r->sink.worlds.at(0).options;
    EXPECT_EQ(o.screenLinear[0], 0.0f);
    EXPECT_NEAR(o.screenLinear[1], -2.0f, 1e-6f);
    EXPECT_NEAR(o.screenLinear[2], 2.0f, 1e-6f);
    EXPECT_EQ(o.screenLinear[3], 0.0f);
    EXPECT_EQ(o.screenOffset[0], 0.0f);
}

TEST(Builder, ScreenTransformationIsAGeneralAffineMap) {
    // screen = R(30) * S(2, 1) * T(0.5, 0) applied to projected points:
    // the linear part R(30) diag(2, 1), the offset R(30) (1, 0). No warning.
    auto r = run("Rotate 30 0 0 1 Scale 2 1 1 Translate .5 0 0\nProjection \"perspective\"\nWorldBegin WorldEnd");
    EXPECT_EQ(r->messages(), std::vector<std::string>{});
    const Options& o = r->sink.worlds.at(0).options;
    const float c = std::cos(3.14159265f / 6), s = std::sin(3.14159265f / 6);
    EXPECT_NEAR(o.screenLinear[0], 2 * c, 1e-6f);
    EXPECT_NEAR(o.screenLinear[1], -s, 1e-6f);
    EXPECT_NEAR(o.screenLinear[2], 2 * s, 1e-6f);
    EXPECT_NEAR(o.screenLinear[3], c, 1e-6f);
    EXPECT_NEAR(o.screenOffset[0], c, 1e-6f);
    EXPECT_NEAR(o.screenOffset[1], s, 1e-6f);
    // A shear (a ConcatTransform before Projection) is kept too; one that
    // flattens the image to a line is not.
    auto shear = run("ConcatTransform [1 0 0 0  0.5 1 0 0  0 0 1 0  0 0 0 1]\nProjection \"orthographic\"\n"
                     "WorldBegin WorldEnd");
    EXPECT_EQ(shear->messages(), std::vector<std::string>{});
    const Options& so = shear->sink.worlds.at(0).options;
    // RIB matrices are row-vector: this one maps (x, y) to (x + 0.5 y, y).
    EXPECT_EQ(so.screenLinear[0], 1.0f);
    EXPECT_EQ(so.screenLinear[1], 0.5f);
    EXPECT_EQ(so.screenLinear[2], 0.0f);
    EXPECT_EQ(so.screenLinear[3], 1.0f);
    auto flat = run("ConcatTransform [1 1 0 0  1 1 0 0  0 0 1 0  0 0 0 1]\nProjection \"orthographic\"\n"
                    "WorldBegin WorldEnd");
    ASSERT_EQ(flat->messages().size(), 1u);
    EXPECT_NE(flat->messages()[0].find("scales the image to nothing"), std::string::npos);
    EXPECT_EQ(flat->sink.worlds.at(0).options.screenLinear[0], 1.0f);
    EXPECT_EQ(flat->sink.worlds.at(0).options.screenLinear[1], 0.0f);
}

TEST(Builder, AttributeAndTransformScoping) {
    auto r = run("WorldBegin\nColor 1 0 0\nAttributeBegin Color 0 1 0 Translate 1 0 0 Sphere 1 -1 1 360 AttributeEnd\n"
                 "TransformBegin Color 0 0 1 Translate 0 1 0 Sphere 1 -1 1 360 TransformEnd\n"
                 "Sphere 1 -1 1 360 WorldEnd");
    const auto& prims = r->sink.worlds.at(0).primitives;
    ASSERT_EQ(prims.size(), 3u);
    EXPECT_EQ(prims[0].attributes->color, Color(0, 1, 0));
    expectNear(prims[0].worldFromObject.point({}), {1, 0, 0});
    EXPECT_EQ(prims[1].attributes->color, Color(0, 0, 1));
    expectNear(prims[1].worldFromObject.point({}), {0, 1, 0});
    // TransformEnd restores only the transform.
    EXPECT_EQ(prims[2].attributes->color, Color(0, 0, 1));
    expectNear(prims[2].worldFromObject.point({}), {0, 0, 0});
    // Unchanged attributes are shared, not copied.
    EXPECT_EQ(prims[1].attributes.get(), prims[2].attributes.get());
    EXPECT_TRUE(r->messages().empty());
}

TEST(Builder, UnbalancedBlocksAreReported) {
    auto r = run("WorldBegin AttributeBegin TransformBegin AttributeEnd TransformEnd AttributeEnd AttributeEnd WorldEnd");
    EXPECT_EQ(r->messages(), (std::vector<std::string>{
        "s.rib:1:42: error: AttributeEnd: expected TransformEnd first, to close the TransformBegin at s.rib:1:27 "
        "(ignored)",
        "s.rib:1:81: error: AttributeEnd: no matching AttributeBegin (ignored)"}));
    EXPECT_EQ(r->sink.worlds.size(), 1u);
}

TEST(Builder, InstancesComposeTheInstanceTransform) {
    auto r = run("WorldBegin\nTranslate 0 0 3\nObjectBegin \"thing\" Translate 0 1 0 Sphere 1 -1 1 360 ObjectEnd\n"
                 "Identity Translate 5 0 0 ObjectInstance \"thing\"\nRotate 90 0 0 1 ObjectInstance \"thing\"\n"
                 "ObjectInstance \"nothing\" WorldEnd");
    const auto& prims = r->sink.worlds.at(0).primitives;
    ASSERT_EQ(prims.size(), 2u);
    expectNear(prims[0].worldFromObject.point({0, 0, 0}), {5, 1, 0});
    // Rotation about z maps the object's (0,1,0) offset to (-1,0,0).
    expectNear(prims[1].worldFromObject.point({0, 0, 0}), {4, 0, 0});
    EXPECT_EQ(r->messages(), (std::vector<std::string>{
        "s.rib:6:1: error: ObjectInstance: unknown object \"nothing\" (expected the handle of an ObjectBegin)"}));
}

TEST(Builder, InstancesInsideADefinitionAreItsPieces) {
    // An object made of another's instances (PRMan, Pixie and Aqsis draw
    // it): each piece is placed by the inner instance's transform inside
    // the outer definition, then by the outer instance's; attributes the
    // outer definition sets reach the inner pieces, the instance site's
    // the rest. An object inside its own definition is refused.
    auto r = run("WorldBegin\nObjectBegin 1 Translate 0 1 0 Color 1 0 0 Sphere 1 -1 1 360 Disk 0 1 360 ObjectEnd\n"
                 "ObjectBegin 2 Translate 10 0 0 ObjectInstance 1 Opacity .5 .5 .5 Rotate 90 0 0 1 ObjectInstance 1\n"
                 "ObjectInstance 2 ObjectEnd\n"
                 "Color 0 0 1 Translate 0 0 5 ObjectInstance 2 WorldEnd");
    const auto& prims = r->sink.worlds.at(0).primitives;
    ASSERT_EQ(prims.size(), 4u);
    expectNear(prims[0].worldFromObject.point({0, 0, 0}), {10, 1, 5});
    expectNear(prims[2].worldFromObject.point({0, 0, 0}), {9, 0, 5});  // (0,1,0) turned to (-1,0,0)
    EXPECT_EQ(prims[1].type, "Disk");
    for (const auto& p : prims) EXPECT_EQ(p.attributes->color, Color(1, 0, 0));  // the inner definition's
    EXPECT_EQ(prims[0].attributes->opacity, Color(1, 1, 1));
    EXPECT_EQ(prims[2].attributes->opacity, Color(.5f, .5f, .5f));  // the outer definition's
    EXPECT_EQ(r->messages(), (std::vector<std::string>{
        "s.rib:4:1: error: ObjectInstance: object \"2\" inside its own definition (ignored)"}));
}

TEST(Builder, LightsAndIlluminate) {
    auto r = run("WorldBegin LightSource \"pointlight\" 1 \"intensity\" 2\nLightSource \"distantlight\" \"sun\"\n"
                 "AttributeBegin Illuminate 1 0 Sphere 1 -1 1 360 AttributeEnd\n"
                 "Sphere 1 -1 1 360\nIlluminate \"sun\" 0 Illuminate \"sun\" 1 Illuminate \"sun\" 1 Disk 0 1 360\n"
                 "Illuminate 9 1 WorldEnd");
    const WorldRecord& w = r->sink.worlds.at(0);
    ASSERT_EQ(w.lights.size(), 2u);
    EXPECT_EQ(w.lights[0].shader.name, "pointlight");
    EXPECT_EQ(w.lights[0].handle, "1");
    EXPECT_EQ(w.lights[0].shader.params.getFloat("intensity", 0), 2.0f);
    EXPECT_EQ(w.lights[1].handle, "sun");
    EXPECT_EQ(w.primitives.at(0).attributes->lights, (std::vector<int>{1}));
    EXPECT_EQ(w.primitives.at(1).attributes->lights, (std::vector<int>{0, 1}));
    EXPECT_EQ(w.primitives.at(2).attributes->lights, (std::vector<int>{0, 1}));
    EXPECT_EQ(r->messages(), (std::vector<std::string>{
        "s.rib:6:1: error: Illuminate: unknown light handle \"9\" (expected the handle of a LightSource)"}));
}

TEST(Builder, IlluminateBeforeWorldBeginSwitchesALightGivenThere) {
    // Lights given before WorldBegin start on in the world (as PRMan, Pixie
    // and Aqsis); an Illuminate there turns one off (or on again), as in
    // both peers. It was refused and the light stayed on.
    auto r = run("LightSource \"pointlight\" 1\nLightSource \"distantlight\" \"sun\"\nIlluminate 1 0\n"
                 "Illuminate \"sun\" 0 Illuminate \"sun\" 1\nIlluminate 7 0\nWorldBegin Sphere 1 -1 1 360 WorldEnd");
    const WorldRecord& w = r->sink.worlds.at(0);
    ASSERT_EQ(w.lights.size(), 2u);
    EXPECT_EQ(w.primitives.at(0).attributes->lights, (std::vector<int>{1}));
    EXPECT_EQ(r->messages(), (std::vector<std::string>{
        "s.rib:5:1: error: Illuminate: unknown light handle \"7\" (expected the handle of a LightSource given before "
        "it)"}));
}

TEST(Builder, FrameEndRestoresOptions) {
    auto r = run("Format 100 50 1\nFrameBegin 7 Format 320 240 1 Display \"a.tif\" \"tiff\" \"rgba\"\n"
                 "Display \"+a.z\" \"zfile\" \"z\" WorldBegin WorldEnd FrameEnd\nFrameBegin 8 WorldBegin WorldEnd FrameEnd");
    ASSERT_EQ(r->sink.worlds.size(), 2u);
    const Options& o7 = r->sink.worlds[0].options;
    EXPECT_EQ(r->sink.worlds[0].frameNumber, 7);
    EXPECT_EQ(o7.xResolution, 320);
    ASSERT_EQ(o7.displays.size(), 2u);
    EXPECT_EQ(o7.displays[1].name, "a.z");
    EXPECT_EQ(o7.displays[1].mode, "z");
    const Options& o8 = r->sink.worlds[1].options;
    EXPECT_EQ(o8.xResolution, 100);
    // Frame 8 names no display: the default one, as PRMan and Aqsis write.
    ASSERT_EQ(o8.displays.size(), 1u);
    EXPECT_EQ(o8.displays[0].name, "ri.pic");
    EXPECT_TRUE(o8.displays[0].implicitDefault);
    EXPECT_FALSE(o7.displays[0].implicitDefault);
    EXPECT_EQ(r->sink.events,
              (std::vector<std::string>{"frame 7", "world", "frameEnd", "frame 8", "world", "frameEnd"}));
}

TEST(Builder, SearchPathsExpandAmpersandAndAt) {
    auto r = std::make_unique<Session>();
    r->builder = std::make_unique<Builder>(r->sink, r->diag);
    r->builder->setDefaultSearchPath("shader", "/usr/share/umbra/shaders");
    ri::Parser p(*r->builder, r->diag);
    p.parseString("Option \"searchpath\" \"shader\" \"/a:/b\"\nOption \"searchpath\" \"shader\" \"/c:&:@\"\n"
                  "Option \"searchpath\" \"archive\" \"/x::/y\"", "s.rib");
    EXPECT_EQ(r->builder->options().searchPaths.at("shader"), "/c:/a:/b:/usr/share/umbra/shaders");
    EXPECT_EQ(r->builder->archiveSearchPath(), (std::vector<std::string>{"/x", "/y"}));
}

TEST(Builder, FirstAmpersandIsTheDefault) {
    // Before any Option "searchpath", '&' is the built-in default, for
    // every kind: shader, texture, archive, procedural, display.
    auto r = std::make_unique<Session>();
    r->builder = std::make_unique<Builder>(r->sink, r->diag);
    for (const char* kind : {"shader", "texture", "archive", "procedural", "display"})
        r->builder->setDefaultSearchPath(kind, std::string("/std/") + kind);
    ri::Parser p(*r->builder, r->diag);
    p.parseString("Option \"searchpath\" \"shader\" \"/mine:&\" \"texture\" \"&:/maps\"\n"
                  "Option \"searchpath\" \"archive\" \"@\" \"procedural\" \"/p:&\" \"display\" \"/d\"\n"
                  "Option \"searchpath\" \"display\" \"&:@\"",
                  "s.rib");
    const auto& sp = r->builder->options().searchPaths;
    EXPECT_EQ(sp.at("shader"), "/mine:/std/shader");
    EXPECT_EQ(sp.at("texture"), "/std/texture:/maps");
    EXPECT_EQ(sp.at("archive"), "/std/archive");
    EXPECT_EQ(sp.at("procedural"), "/p:/std/procedural");
    EXPECT_EQ(sp.at("display"), "/d:/std/display");
    EXPECT_EQ(r->diag.errorCount(), 0);
}

TEST(Builder, SetSearchPathSeedsWhatAmpersandStandsFor) {
    auto r = std::make_unique<Session>();
    r->builder = std::make_unique<Builder>(r->sink, r->diag);
    r->builder->setDefaultSearchPath("shader", "/std");
    r->builder->setSearchPath("shader", ".:/scenes:@");
    ri::Parser p(*r->builder, r->diag);
    p.parseString("Option \"searchpath\" \"shader\" \"/mine:&\"", "s.rib");
    EXPECT_EQ(r->builder->options().searchPaths.at("shader"), "/mine:.:/scenes:/std");
}

TEST(Builder, ReadArchiveUsesTheArchiveSearchPath) {
    auto dir = std::filesystem::path(UMBRA_BINARY_DIR) / "test_scene_tmp" / "lib";
    std::filesystem::create_directories(dir);
    std::ofstream(dir / "ball.rib") << "Sphere 2 -2 2 360\n";
    auto r = run(fmt::format("Option \"searchpath\" \"archive\" \"{}\"\nWorldBegin ReadArchive \"ball.rib\" WorldEnd",
                             dir.string()));
    ASSERT_EQ(r->sink.worlds.size(), 1u);
    ASSERT_EQ(r->sink.worlds[0].primitives.size(), 1u);
    EXPECT_EQ(r->sink.worlds[0].primitives[0].floatArgs[0], 2.0f);
    EXPECT_EQ(r->sink.worlds[0].primitives[0].loc.str(), (dir / "ball.rib").string() + ":1:1");
}

TEST(Builder, OrientationAgainstHandedness) {
    auto r = run("WorldBegin Sphere 1 -1 1 360\nAttributeBegin Scale -1 1 1 Sphere 1 -1 1 360 AttributeEnd\n"
                 "AttributeBegin ReverseOrientation Sphere 1 -1 1 360 AttributeEnd\n"
                 "AttributeBegin Scale -1 1 1 Orientation \"outside\" Sphere 1 -1 1 360 AttributeEnd\n"
                 "AttributeBegin Orientation \"rh\" Sphere 1 -1 1 360 AttributeEnd\n"
                 "AttributeBegin Orientation \"inside\" Sphere 1 -1 1 360 AttributeEnd WorldEnd");
    const auto& p = r->sink.worlds.at(0).primitives;
    ASSERT_EQ(p.size(), 6u);
    // RI spec 3.2 §4.2: the orientation flips with every mirroring transform,
    // so a mirror alone never turns a primitive inside out.
    EXPECT_FALSE(p[0].attributes->insideOut);
    EXPECT_FALSE(p[1].attributes->insideOut);  // mirrored: orientation and handedness flip together
    EXPECT_TRUE(p[2].attributes->insideOut);   // ReverseOrientation
    EXPECT_FALSE(p[3].attributes->insideOut);  // "outside" matches the mirrored space
    EXPECT_TRUE(p[4].attributes->insideOut);   // rh in a left-handed world
    EXPECT_TRUE(p[5].attributes->insideOut);
}

TEST(Builder, OptionsAttributesAndBasis) {
    auto r = run("PixelSamples 3 2.5 PixelFilter \"catmull-rom\" 3 3 Exposure 2 2.2 Quantize \"z\" 0 0 0 0\n"
                 "Hider \"hidden\" \"jitter\" [0] \"depthfilter\" \"midpoint\"\n"
                 "Option \"limits\" \"bucketsize\" [32 8] \"gridsize\" 64 Option \"statistics\" \"endofframe\" 1\n"
                 "Option \"user\" \"float quality\" 3\nWorldBegin\n"
                 "Basis \"b-spline\" 1 [1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16] 2\n"
                 "Attribute \"displacementbound\" \"sphere\" 0.5 \"coordinatesystem\" \"shader\"\n"
                 "Attribute \"identifier\" \"name\" \"ball\" Attribute \"visibility\" \"transmission\" 0\n"
                 "Attribute \"user\" \"color tint\" [1 2 3]\nSurface \"plastic\" \"Kd\" 0.3 Sides 1 ShadingRate 4\n"
                 "Polygon \"P\" [0 0 0 1 0 0 1 1 0] WorldEnd");
    EXPECT_TRUE(r->messages().empty()) << fmt::format("{}", fmt::join(r->messages(), "\n"));
    const WorldRecord& w = r->sink.worlds.at(0);
    const Options& o = w.options;
    EXPECT_EQ(o.pixelSamples[0], 3);
    EXPECT_EQ(o.pixelSamples[1], 3);
    EXPECT_EQ(o.pixelFilter, "catmull-rom");
    EXPECT_EQ(o.exposureGamma, 2.2f);
    EXPECT_FALSE(o.jitter);
    EXPECT_EQ(o.depthFilter, "midpoint");
    EXPECT_EQ(o.bucketSize[0], 32);
    EXPECT_EQ(o.bucketSize[1], 8);
    EXPECT_EQ(o.gridSize, 64);
    EXPECT_EQ(o.statisticsEndOfFrame, 1);
    EXPECT_EQ(o.user.at("user:quality").floats, (std::vector<float>{3}));
    const Attributes& a = *w.primitives.at(0).attributes;
    EXPECT_EQ(a.uBasis.m[2][1], Basis::bspline().m[2][1]);
    EXPECT_EQ(a.uBasis.step, 1);
    EXPECT_EQ(a.vBasis.m[1][2], 7.0f);  // row 1, column 2 of the matrix as written
    EXPECT_EQ(a.vBasis.step, 2);
    EXPECT_EQ(a.displacementBound, 0.5f);
    EXPECT_EQ(a.displacementBoundSpace, "shader");
    EXPECT_EQ(a.name, "ball");
    EXPECT_FALSE(a.castsShadows);
    EXPECT_EQ(a.user.at("user:tint").floats, (std::vector<float>{1, 2, 3}));
    ASSERT_TRUE(a.surface);
    EXPECT_EQ(a.surface->params.getFloat("Kd", 0), 0.3f);
    EXPECT_EQ(a.sides, 1);
    EXPECT_EQ(a.shadingRate, 4.0f);
}

TEST(Builder, SkewTurnsTheFirstVectorTowardsTheSecond) {
    auto r = run("WorldBegin Skew 45 1 0 0 0 1 0 Sphere 1 -1 1 360 WorldEnd");
    const Mat4& m = r->sink.worlds.at(0).primitives.at(0).worldFromObject;
    expectNear(m.point({1, 0, 0}), {1, 1, 0});
    expectNear(m.point({0, 1, 0}), {0, 1, 0});
    expectNear(m.point({0, 0, 1}), {0, 0, 1});
}

TEST(Builder, MakeRecordsInRequestOrder) {
    auto r = run("MakeTexture \"a.tif\" \"a.tx\" \"periodic\" \"clamp\" \"gaussian\" 2 2\n"
                 "MakeShadow \"d.z\" \"d.shd\" WorldBegin WorldEnd\n"
                 "MakeCubeFaceEnvironment \"px\" \"nx\" \"py\" \"ny\" \"pz\" \"nz\" \"e.env\" 95 \"box\" 1 1");
    EXPECT_EQ(r->sink.events, (std::vector<std::string>{"make MakeTexture", "make MakeShadow", "world",
                                                         "make MakeCubeFaceEnvironment"}));
    EXPECT_EQ(r->sink.makes[0].stringArgs, (std::vector<std::string>{"periodic", "clamp", "gaussian"}));
    EXPECT_EQ(r->sink.makes[2].inputs.size(), 6u);
    EXPECT_EQ(r->sink.makes[2].floatArgs, (std::vector<float>{95, 1, 1}));
}

TEST(Builder, CoordinateSystems) {
    auto r = run("Translate 0 0 10 CoordinateSystem \"cam10\" WorldBegin Translate 1 0 0 CoordinateSystem \"here\"\n"
                 "Identity CoordSysTransform \"here\" Sphere 1 -1 1 360 CoordSysTransform \"cam10\" Disk 0 1 360 "
                 "CoordSysTransform \"nowhere\" WorldEnd");
    const WorldRecord& w = r->sink.worlds.at(0);
    expectNear(w.coordinateSystems.at("here").point({}), {1, 0, 0});
    expectNear(w.primitives.at(0).worldFromObject.point({}), {1, 0, 0});
    // cam10 was named before WorldBegin where the camera transform was the same.
    expectNear(w.primitives.at(1).worldFromObject.point({}), {0, 0, 0});
    ASSERT_EQ(r->messages().size(), 1u);
}

TEST(Builder, ScopedCoordinateSystemNamesACoordinateSystemUntilAttributeEnd) {
    // PRMan's ScopedCoordinateSystem, as RenderMan for Maya writes it: the
    // name holds inside its attribute block, then its earlier meaning (here
    // none) is back. umbra kept it for the whole frame.
    auto r = run("WorldBegin AttributeBegin Translate 2 0 0 ScopedCoordinateSystem \"proj\"\n"
                 "AttributeBegin CoordSysTransform \"proj\" Sphere 1 -1 1 360 AttributeEnd AttributeEnd\n"
                 "CoordSysTransform \"proj\" Sphere 1 -1 1 360 WorldEnd");
    const WorldRecord& w = r->sink.worlds.at(0);
    expectNear(w.primitives.at(0).worldFromObject.point({}), {2, 0, 0});
    expectNear(w.primitives.at(1).worldFromObject.point({}), {0, 0, 0});
    EXPECT_EQ(r->messages(), (std::vector<std::string>{
        "s.rib:3:1: error: CoordSysTransform: unknown coordinate system \"proj\" (expected \"world\", \"camera\" or a "
        "name given to CoordinateSystem)"}));
}

TEST(Builder, UnsupportedRequestsWarnOnce) {
    auto r = run("WorldBegin Sphere 1 -1 1 360\n\nClippingPlane 0 0 1 0 0 -1 ClippingPlane 0 0 1 0 0 -1 WorldEnd");
    EXPECT_EQ(r->messages(), (std::vector<std::string>{
        "s.rib:3:1: warning: ClippingPlane: not supported (ignored)"}));
    ASSERT_EQ(r->sink.worlds.at(0).primitives.size(), 1u);
}

TEST(Builder, GeometricApproximationTypesOfOtherRenderersWarnOnce) {
    auto r = run("WorldBegin GeometricApproximation \"flatness\" 0.5\n"
                 "GeometricApproximation \"tesselation\" 4 GeometricApproximation \"tesselation\" 64\n"
                 "GeometricApproximation \"motionfactor\" 1 Sphere 1 -1 1 360 WorldEnd");
    EXPECT_EQ(r->messages(), (std::vector<std::string>{
        "s.rib:2:1: warning: GeometricApproximation \"tesselation\": not a type umbra knows (it knows "
        "\"flatness\" and \"motionfactor\"); ignored"}));
    ASSERT_EQ(r->sink.worlds.at(0).primitives.size(), 1u);
}

TEST(Builder, ProceduralsAreRecordedWithTheirBoundAndStrings) {
    auto r = run("WorldBegin Translate 1 0 0 Color [1 0 0]\n"
                 "Procedural \"DelayedReadArchive\" [\"a.rib\"] [-1 1 -2 2 -3 3]\n"
                 "Procedural \"RunProgram\" [\"gen.py -v\" \"0.5\"] [0 1 0 1 0 1]\n"
                 "Geometry \"teapot\" WorldEnd");
    EXPECT_TRUE(r->messages().empty());
    const auto& prims = r->sink.worlds.at(0).primitives;
    ASSERT_EQ(prims.size(), 3u);
    EXPECT_EQ(prims[0].type, "Procedural");
    EXPECT_EQ(prims[0].stringArgs, (std::vector<std::string>{"DelayedReadArchive", "a.rib"}));
    EXPECT_EQ(prims[0].floatArgs, (std::vector<float>{-1, 1, -2, 2, -3, 3}));
    expectNear(prims[0].worldFromObject.point({}), {1, 0, 0});
    EXPECT_EQ(prims[0].attributes->color.y, 0.0f);
    EXPECT_EQ(prims[1].stringArgs, (std::vector<std::string>{"RunProgram", "gen.py -v", "0.5"}));
    EXPECT_EQ(prims[2].type, "Geometry");
}

TEST(Builder, MalformedProceduralsAndUnknownGeometryAreReportedAtTheRequest) {
    auto r = run("WorldBegin\n"
                 "Procedural \"Teleport\" [\"x\"] [0 1 0 1 0 1]\n"
                 "Procedural \"DelayedReadArchive\" [] [0 1 0 1 0 1]\n"
                 "Procedural \"DelayedReadArchive\" [\"a.rib\"] [0 1 0 1]\n"
                 "Procedural \"DelayedReadArchive\" [\"a.rib\"] [1 0 0 1 0 1]\n"
                 "Geometry \"bunny\" Geometry \"bunny\"\n"
                 "Geometry \"kettle\"\n"
                 "WorldEnd");
    EXPECT_EQ(r->messages(), (std::vector<std::string>{
        "s.rib:2:1: error: Procedural: unknown procedural \"Teleport\" (expected \"DelayedReadArchive\", "
        "\"RunProgram\" or \"DynamicLoad\"; skipped)",
        "s.rib:3:1: error: Procedural \"DelayedReadArchive\": expected the arguments [\"archive.rib\"], got 0 strings "
        "(skipped)",
        "s.rib:4:1: error: Procedural: expected a bound of 6 floats [xmin xmax ymin ymax zmin zmax], got 4 (skipped)",
        "s.rib:5:1: warning: Procedural: the bound's x range [1 0] is written max first (expected min <= max; read "
        "as [0 1])",
        "s.rib:6:1: warning: Geometry \"bunny\": drawn by some other renderers; umbra draws only \"teapot\" (skipped)",
        "s.rib:7:1: warning: Geometry \"kettle\": unknown; umbra draws only \"teapot\" (skipped)"}));
    // The bound written max first is read as the range it spans (Pixie and
    // Aqsis draw it); the others are skipped.
    const auto& p = r->sink.worlds.at(0).primitives;
    ASSERT_EQ(p.size(), 1u);
    EXPECT_EQ(p[0].floatArgs, (std::vector<float>{0, 1, 0, 1, 0, 1}));
}

TEST(Builder, MotionBlocksAroundTransformsMoveTheCurrentTransform) {
    auto r = run("Shutter 0 1 WorldBegin MotionBegin [0 1] Translate 1 0 0 Translate 2 0 0 MotionEnd\n"
                 "MotionBegin [0 1] Translate 0 1 0 Translate 0 2 0 MotionEnd Translate 0 0 3 Sphere 1 -1 1 360\n"
                 "WorldEnd");
    EXPECT_TRUE(r->messages().empty()) << r->messages()[0];
    const auto& p = r->sink.worlds.at(0).primitives;
    ASSERT_EQ(p.size(), 1u);
    ASSERT_TRUE(p[0].worldFromObjectMotion);
    EXPECT_TRUE(p[0].moving());
    expectNear(p[0].worldFromObject.point({}), {1, 1, 3});  // at the shutter's opening
    expectNear(p[0].worldFromObjectMotion->at(0.5f).point({}), {1.5f, 1.5f, 3});
    expectNear(p[0].worldFromObjectMotion->at(1).point({}), {2, 2, 3});
    EXPECT_EQ(p[0].worldFromObjectMotion->keyTimes(), (std::vector<float>{0, 1}));
}

TEST(Builder, MotionBlocksAroundPrimitivesAreShapes) {
    auto r = run("WorldBegin MotionBegin [0 0.5 1] Sphere 1 -1 1 360 Sphere 2 -2 2 360 Sphere 3 -3 3 360 MotionEnd\n"
                 "Sphere 1 -1 1 360 WorldEnd");
    EXPECT_TRUE(r->messages().empty());
    const auto& p = r->sink.worlds.at(0).primitives;
    ASSERT_EQ(p.size(), 2u);
    EXPECT_EQ(p[0].shapeTimes, (std::vector<float>{0, 0.5f, 1}));
    ASSERT_EQ(p[0].shapes.size(), 2u);
    EXPECT_EQ(p[0].floatArgs[0], 1.0f);
    EXPECT_EQ(p[0].shapes[1].floatArgs[0], 3.0f);
    EXPECT_FALSE(p[1].moving());
}

TEST(Builder, MalformedMotionBlocksAreReported) {
    auto r = run("WorldBegin\nMotionBegin [0 1] Translate 1 0 0 MotionEnd\n"
                 "MotionBegin [0 1] Sphere 1 -1 1 360 Disk 0 1 360 MotionEnd\n"
                 "MotionBegin [1 0] Translate 1 0 0 Translate 2 0 0 MotionEnd\n"
                 "MotionBegin [0 1] MotionBegin [0 1] MotionEnd\nWorldEnd");
    const auto m = r->messages();
    ASSERT_GE(m.size(), 4u);
    EXPECT_EQ(m[0].rfind("s.rib:2:35: error: MotionEnd: the block begun at s.rib:2:1 has 2 times but 1 transforms", 0), 0u)
        << m[0];
    EXPECT_EQ(m[1].rfind("s.rib:3:37: error: Disk: a motion block's primitives must have the same type", 0), 0u) << m[1];
    EXPECT_EQ(m[2].rfind("s.rib:4:1: error: MotionBegin: expected one or more times in increasing order", 0), 0u)
        << m[2];
    EXPECT_EQ(m[3].rfind("s.rib:5:19: error: MotionBegin: already inside the motion block begun at s.rib:5:1", 0), 0u)
        << m[3];
    // The malformed shapes render unblurred.
    const auto& p = r->sink.worlds.at(0).primitives;
    ASSERT_EQ(p.size(), 1u);
    EXPECT_TRUE(p[0].shapes.empty());
}

TEST(Builder, MotionBlocksSayWhatTheyDoNotBlur) {
    // Transforms of different kinds blend their matrices (RI spec: one
    // kind a block), a Color is not blurred (the first is used), and a
    // Polygon whose keys have different vertex counts is not a deformation.
    auto r = run("WorldBegin\nMotionBegin [0 1] Translate 1 0 0 Rotate 90 0 0 1 MotionEnd\n"
                 "MotionBegin [0 1] Color 1 0 0 Color 0 1 0 MotionEnd\n"
                 "MotionBegin [0 1] Polygon \"P\" [0 0 0 1 0 0 1 1 0 0 1 0] Polygon \"P\" [0 0 0 1 0 0 1 1 0] MotionEnd\n"
                 "MotionBegin [0 1] Polygon \"P\" [0 0 0 1 0 0 1 1 0] \"Cs\" [1 0 0 1 0 0 1 0 0] "
                 "Polygon \"P\" [0 0 1 1 0 1 1 1 1] \"Cs\" [0 1 0 0 1 0 0 1 0] MotionEnd\n"
                 "WorldEnd");
    EXPECT_EQ(r->messages(), (std::vector<std::string>{
        "s.rib:2:1: warning: MotionBegin: the block's transforms are not all the same request (RI spec: one kind a "
        "block); blurred between their matrices",
        "s.rib:3:31: warning: Color: not blurred in a motion block (umbra blurs transforms and primitives); the "
        "block's first request is used",
        "s.rib:4:57: error: Polygon: a motion block's primitives must have the same type and topology as its first "
        "(Polygon at s.rib:4:19); the block renders the first, unblurred",
        "s.rib:5:76: warning: Polygon: \"Cs\" differs between the motion block's keys; the first key's is used "
        "(umbra shades once, at the shutter's opening)"}));
    const auto& p = r->sink.worlds.at(0).primitives;
    ASSERT_EQ(p.size(), 2u);
    EXPECT_TRUE(p[0].shapes.empty());
    EXPECT_EQ(p[0].attributes->color, Color(1, 0, 0));
    EXPECT_EQ(p[1].shapes.size(), 1u);  // the deformation is blurred
}

TEST(Builder, AMotionBlockLeftOpenIsClosedWithItsWorld) {
    // Found by the RIB fuzzer: the MotionEnd after WorldEnd used to hand the
    // dead world's shapes to a world that no longer existed.
    auto r = run("WorldBegin\nMotionBegin [0 1] Sphere 1 -1 1 360 Sphere 2 -2 2 360\nWorldEnd\nMotionEnd\n"
                 "WorldBegin\nSphere 3 -3 3 360\nWorldEnd\n");
    const auto m = r->messages();
    ASSERT_EQ(m.size(), 2u);
    EXPECT_NE(m[0].find("MotionBegin"), std::string::npos) << m[0];
    EXPECT_EQ(m[1].rfind("s.rib:4:1: error: MotionEnd: no matching MotionBegin", 0), 0u) << m[1];
    ASSERT_EQ(r->sink.worlds.size(), 2u);
    const auto& second = r->sink.worlds[1].primitives;
    ASSERT_EQ(second.size(), 1u);
    EXPECT_EQ(second[0].floatArgs[0], 3.0f);
    EXPECT_FALSE(second[0].moving());
}

TEST(Builder, CameraMotionAndDepthOfFieldAreOptions) {
    auto r = run("Shutter 0.5 1.5 Option \"shutter\" \"offset\" [1] DepthOfField 2.8 0.05 4\n"
                 "MotionBegin [1.5 2.5] Translate 0 0 5 Translate 1 0 5 MotionEnd WorldBegin WorldEnd\n"
                 "DepthOfField 0 1 1 DepthOfField");
    const Options& o = r->sink.worlds.at(0).options;
    EXPECT_EQ(o.shutterOffset, 1.0f);
    EXPECT_EQ(o.fstop, 2.8f);
    EXPECT_EQ(o.focalLength, 0.05f);
    EXPECT_EQ(o.focalDistance, 4.0f);
    ASSERT_TRUE(o.cameraMotion);
    expectNear(o.cameraMotion->at(2.0f).point({}), {0.5f, 0, 5});
    expectNear(o.cameraFromWorld.point({}), {0, 0, 5});  // at the opening, 0.5 + 1
    const auto m = r->messages();
    ASSERT_EQ(m.size(), 1u);
    EXPECT_EQ(m[0].rfind("s.rib:3:1: error: DepthOfField: expected fstop, focallength and focaldistance > 0", 0), 0u)
        << m[0];
}

TEST(Builder, ShutterOpeningTakesBothSpellings) {
    // Aqsis/umbra's Option and PRMan's Camera parameter shape the same
    // shutter; a bad pair is an error naming its request.
    auto r = run("Option \"shutter\" \"opening\" [0.25 0.75] WorldBegin WorldEnd\n"
                 "Camera \"world\" \"float[2] shutteropening\" [0.1 0.6] WorldBegin WorldEnd\n"
                 "Camera \"world\" \"float[2] shutteropening\" [0.7 0.2] WorldBegin WorldEnd");
    ASSERT_EQ(r->sink.worlds.size(), 3u);
    EXPECT_EQ(r->sink.worlds[0].options.shutterOpening[0], 0.25f);
    EXPECT_EQ(r->sink.worlds[0].options.shutterOpening[1], 0.75f);
    EXPECT_EQ(r->sink.worlds[1].options.shutterOpening[0], 0.1f);
    EXPECT_EQ(r->sink.worlds[1].options.shutterOpening[1], 0.6f);
    EXPECT_EQ(r->sink.worlds[2].options.shutterOpening[0], 0.1f);  // unchanged
    const auto m = r->messages();
    ASSERT_EQ(m.size(), 1u) << m.at(0) << "\n" << m.at(1);
    EXPECT_NE(m[0].find("s.rib:3:"), std::string::npos) << m[0];
    EXPECT_NE(m[0].find("Camera \"shutteropening\" expects two fractions"), std::string::npos) << m[0];
}

TEST(Builder, TrimCurveAppliesUntilAttributeEnd) {
    // Two loops: a square of one linear curve, a second of two curves.
    auto r = run(
        "WorldBegin AttributeBegin "
        "TrimCurve [1 2] [2 2 2] [0 0 1 2 3 4 4  0 0 1 1  0 0 1 1] [0 0 0] [4 1 1] [5 2 2] "
        "[0 1 1 0 0  0 1  1 0] [0 0 1 1 0  0 0  0 1] [1 1 1 1 1  1 1  1 1] "
        "NuPatch 2 2 [0 0 1 1] 0 1 2 2 [0 0 1 1] 0 1 \"P\" [0 0 0 1 0 0 0 1 0 1 1 0] "
        "AttributeEnd "
        "NuPatch 2 2 [0 0 1 1] 0 1 2 2 [0 0 1 1] 0 1 \"P\" [0 0 0 1 0 0 0 1 0 1 1 0] WorldEnd");
    EXPECT_TRUE(r->messages().empty()) << r->messages().at(0);
    ASSERT_EQ(r->sink.worlds.size(), 1u);
    const auto& prims = r->sink.worlds[0].primitives;
    ASSERT_EQ(prims.size(), 2u);
    const auto& trim = prims[0].attributes->trimCurves;
    ASSERT_TRUE(trim);
    EXPECT_EQ(trim->ncurves, (std::vector<int>{1, 2}));
    EXPECT_EQ(trim->order, (std::vector<int>{2, 2, 2}));
    EXPECT_EQ(trim->n, (std::vector<int>{5, 2, 2}));
    EXPECT_EQ(trim->knot.size(), 15u);
    EXPECT_EQ(trim->max, (std::vector<float>{4, 1, 1}));
    EXPECT_EQ(trim->u.size(), 9u);
    EXPECT_EQ(trim->w.size(), 9u);
    EXPECT_EQ(trim->v[2], 1.0f);
    EXPECT_FALSE(prims[1].attributes->trimCurves);
}

TEST(Builder, MalformedTrimCurvesAreReportedAndLeaveTheTrimAsItWas) {
    auto r = run("WorldBegin TrimCurve [1] [2] [0 0 1] [0] [1] [2] [0 1] [0 1] [1 1] "  // a knot short
                 "TrimCurve [1] [3] [0 0 0 1 1] [0] [1] [2] [0 1] [0 1] [1 1] "       // n < order
                 "Sphere 1 -1 1 360 WorldEnd");
    const auto msgs = r->messages();
    ASSERT_EQ(msgs.size(), 2u);
    EXPECT_NE(msgs[0].find("TrimCurve: expected 12 floats"), std::string::npos) << msgs[0];
    EXPECT_NE(msgs[1].find("order 3 and n 2"), std::string::npos) << msgs[1];
    EXPECT_FALSE(r->sink.worlds.at(0).primitives.at(0).attributes->trimCurves);
}

}  // namespace
}  // namespace umbra::scene

namespace umbra::scene {
namespace {

TEST(Limits, ShadingRatePixelSamplesAndFilterWidthAreClampedWithAWarning) {
    auto r = run("PixelSamples 1000 3\nPixelFilter \"gaussian\" 1e6 4\nWorldBegin\nShadingRate 1e-6\nSphere 1 -1 1 360\n"
                 "ShadingRate 1e-5\nSphere 1 -1 1 360\nWorldEnd");
    EXPECT_EQ(r->diag.errorCount(), 0);
    EXPECT_EQ(r->messages(), (std::vector<std::string>{
        "s.rib:1:1: warning: PixelSamples: 1000 3 exceeds the maximum of 32 samples along each axis of a pixel; "
        "clamped to 32 3",
        "s.rib:2:1: warning: PixelFilter: widths 1000000 4 exceed the maximum of 16 pixels; clamped to 16 4",
        // An attribute may be set per object: one warning for them all.
        "s.rib:4:1: warning: ShadingRate: 1e-06 is below the minimum of 1/64 pixel; clamped to 0.015625"}));
    ASSERT_EQ(r->sink.worlds.size(), 1u);
    const Options& o = r->sink.worlds[0].options;
    EXPECT_EQ(o.pixelSamples[0], kMaxPixelSamples);
    EXPECT_EQ(o.pixelSamples[1], 3);
    EXPECT_EQ(o.filterWidth[0], kMaxFilterWidth);
    EXPECT_EQ(o.filterWidth[1], 4.0f);
    for (const PrimitiveRecord& p : r->sink.worlds[0].primitives) EXPECT_EQ(p.attributes->shadingRate, kMinShadingRate);
    // At the limits themselves: no warning.
    auto ok = run("PixelSamples 32 32 PixelFilter \"box\" 16 16 WorldBegin ShadingRate 0.015625 WorldEnd");
    EXPECT_TRUE(ok->messages().empty());
}

TEST(Limits, AHundredThousandUnclosedBlocksGiveAFewLines) {
    // Ten blocks named, innermost first, then one line for the rest.
    std::string rib = "FrameBegin 1\nWorldBegin\n";
    for (int i = 0; i < 100000; ++i) rib += "AttributeBegin\n";
    auto r = run(rib);
    std::vector<std::string> m = r->messages();
    ASSERT_EQ(m.size(), size_t(kMaxListedOpenBlocks) + 1);
    EXPECT_EQ(m[0], "s.rib:100002:1: error: AttributeBegin: no matching AttributeEnd before the end of the input");
    EXPECT_EQ(m[9], "s.rib:99993:1: error: AttributeBegin: no matching AttributeEnd before the end of the input");
    EXPECT_EQ(m[10], "s.rib:1:1: error: FrameBegin: ... and 99992 more blocks with no matching end before the end of "
                     "the input (the outermost is this one)");
    // WorldEnd closing them: the same cap.
    rib += "WorldEnd\n";
    r = run(rib);
    m = r->messages();
    ASSERT_EQ(m.size(), size_t(kMaxListedOpenBlocks) + 2);
    EXPECT_EQ(m[0], "s.rib:100003:1: error: WorldEnd: the AttributeBegin at s.rib:100002:1 is still open (closed here)");
    EXPECT_EQ(m[10], "s.rib:100003:1: error: WorldEnd: ... and 99990 more open blocks, closed here (the outermost "
                     "is the AttributeBegin at s.rib:3:1)");
    EXPECT_EQ(m[11], "s.rib:1:1: error: FrameBegin: no matching FrameEnd before the end of the input");
    EXPECT_EQ(r->sink.worlds.size(), 1u);
}

/// Writes archives a01.rib .. aNN.rib into `dir`, each reading the next
/// twice; the last holds one sphere.
void writeFanOut(const std::filesystem::path& dir, int depth) {
    std::filesystem::create_directories(dir);
    for (int k = 1; k <= depth; ++k) {
        std::ofstream out(dir / fmt::format("a{:02}.rib", k));
        if (k == depth)
            out << "Sphere 1 -1 1 360\n";
        else
            out << fmt::format("ReadArchive \"a{0:02}.rib\"\nReadArchive \"a{0:02}.rib\"\n", k + 1);
    }
}

TEST(Limits, ArchivesThatFanOutStopAtTheFramesReadBudget) {
    // 30 archives deep, each reading the next twice, would read 2^30 files
    // within the nesting limit. The frame's budget of reads stops them with
    // one located error.
    const auto dir = std::filesystem::temp_directory_path() / fmt::format("umbra-fanout-{}", ::getpid());
    writeFanOut(dir, 30);
    auto r = run("WorldBegin\nReadArchive \"a01.rib\"\nWorldEnd\n", dir.string());
    std::vector<std::string> m = r->messages();
    ASSERT_EQ(m.size(), 1u);
    EXPECT_NE(m[0].find(": error: ReadArchive: more than 10000 archive reads in one frame; this and the frame's "
                        "further ReadArchive requests are skipped (raise Option \"limits\" \"archivereads\" if the "
                        "scene needs more)"),
              std::string::npos)
        << m[0];
    EXPECT_EQ(m[0].find("a"), 0u);  // located in one of the archives
    ASSERT_EQ(r->sink.worlds.size(), 1u);
    // Depth-first: the reads reach the bottom, whose spheres are kept.
    EXPECT_GT(r->sink.worlds[0].primitives.size(), 1000u);

    // Option "limits" "archivereads" sets the budget, per frame: each
    // frame reads its own 40.
    r = run("Option \"limits\" \"archivereads\" 40\n"
            "FrameBegin 1 WorldBegin ReadArchive \"a01.rib\" WorldEnd FrameEnd\n"
            "FrameBegin 2 WorldBegin ReadArchive \"a01.rib\" WorldEnd FrameEnd\n",
            dir.string());
    m = r->messages();
    ASSERT_EQ(m.size(), 2u);
    EXPECT_NE(m[0].find("more than 40 archive reads in one frame"), std::string::npos) << m[0];
    ASSERT_EQ(r->sink.worlds.size(), 2u);
    EXPECT_EQ(r->sink.worlds[0].primitives.size(), r->sink.worlds[1].primitives.size());
    EXPECT_EQ(r->sink.worlds[0].primitives.size(), 7u);  // 40 reads: 30 down to a sphere, 10 on the way back

    r = run("Option \"limits\" \"archivereads\" -1", dir.string());
    EXPECT_EQ(r->messages(), (std::vector<std::string>{
        "s.rib:1:17: error: Option: limits \"archivereads\" expects an integer of 0 or more, got -1"}));
    std::filesystem::remove_all(dir);
}

TEST(Builder, AWorldInsideAnAttributeOrTransformBlockIsRenderedWithAWarning) {
    // Blocks must nest (RI Spec 3.2); Pixie and Aqsis refuse such a world.
    // The intent is plain: umbra renders it and says where the block opened.
    auto r = run("TransformBegin\nWorldBegin\nSphere 1 -1 1 360\nWorldEnd\nTransformEnd\n"
                 "FrameBegin 2\nWorldBegin\nWorldEnd\nFrameEnd\n");
    ASSERT_EQ(r->sink.worlds.size(), 2u);
    EXPECT_EQ(r->sink.worlds[0].primitives.size(), 1u);
    EXPECT_EQ(r->messages(), (std::vector<std::string>{
        "s.rib:2:1: warning: WorldBegin: inside the TransformBegin block opened at s.rib:1:1 (blocks must nest; "
        "Pixie and Aqsis refuse this world, umbra renders it)"}));
}

TEST(Builder, APrimitivesDataAfterAnAttributeIsWarnedNotKept) {
    // The LEGO brick exporter writes "P", "N" and a facevarying "uv0" after
    // Attribute "identifier", its primitive request lost: umbra kept them as
    // user attributes without a word (Pixie and Aqsis warn).
    auto r = run("WorldBegin\nAttribute \"identifier\" \"name\" [\"brick\"]\n  \"P\" [0 0 0 1 0 0 1 1 0]\n"
                 "  \"facevarying float[2] uv0\" [0 0 1 0 1 1]\nAttribute \"user\" \"float k\" [2]\nSphere 1 -1 1 360\nWorldEnd\n");
    ASSERT_EQ(r->sink.worlds.size(), 1u);
    const Attributes& a = *r->sink.worlds[0].primitives.at(0).attributes;
    EXPECT_EQ(a.name, "brick");
    EXPECT_EQ(a.user.count("identifier:P"), 0u);
    EXPECT_EQ(a.user.count("user:k"), 1u);
    EXPECT_EQ(r->messages(), (std::vector<std::string>{
        "s.rib:3:3: warning: Attribute \"identifier\": \"P\" is a primitive's data, not an attribute (ignored; is a "
        "primitive request missing before it?)",
        "s.rib:4:3: warning: Attribute \"identifier\": \"uv0\" is a primitive's data, not an attribute (ignored; is a "
        "primitive request missing before it?)"}));
}

}  // namespace
}  // namespace umbra::scene
