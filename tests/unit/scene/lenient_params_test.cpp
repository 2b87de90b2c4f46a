// Options, attributes and hider settings of other renderers (PRMan, Aqsis,
// Pixie, BMRT): accepted with at most one warning per name, never an
// error; the ones umbra can honour are honoured.

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

TEST(LenientParams, UnknownNamesWarnOncePerNameAndNeverFail) {
    auto r = run(R"(Option "render" "integer minshadowbias" [0.01]
Option "render" "integer minshadowbias" [0.02]
Attribute "shadinggroup" "foo" [1]
Attribute "shadinggroup" "foo" [2]
WorldBegin
Attribute "displacement" "binary" [1]
Attribute "stochastic" "steps" [3]
Attribute "shadows" "casts_shadows" "opaque"
Attribute "stochastic" "steps" [4]
Sphere 1 -1 1 360
WorldEnd
)");
    EXPECT_EQ(r->diag.errorCount(), 0);
    EXPECT_EQ(r->messages(),
              (std::vector<std::string>{
                  "s.rib:1:17: warning: Option \"render\": parameter \"minshadowbias\" (uniform integer) expects "
                  "integers, got 0.01; read as \"uniform float\"",
                  "s.rib:3:26: warning: Attribute \"shadinggroup\": parameter \"foo\" is not declared; read as "
                  "\"uniform float\" (umbra does not use it)",
                  "s.rib:6:26: warning: Attribute \"displacement\": parameter \"binary\" is not declared; read as "
                  "\"uniform float\" (umbra does not use it)",
                  "s.rib:7:24: warning: Attribute \"stochastic\": parameter \"steps\" is not declared; read as "
                  "\"uniform float\" (umbra does not use it)",
                  "s.rib:8:21: warning: Attribute \"shadows\": parameter \"casts_shadows\" is not declared; read as "
                  "\"uniform string\" (umbra does not use it)",
              }));
    ASSERT_EQ(r->sink.worlds.size(), 1u);
    // Kept, as their values say, for attribute()/option() lookups.
    const Attributes& a = *r->sink.worlds[0].primitives.at(0).attributes;
    EXPECT_EQ(a.user.at("stochastic:steps").floats, std::vector<float>{4});
    EXPECT_EQ(a.user.at("shadinggroup:foo").floats, std::vector<float>{2});
    EXPECT_EQ(r->sink.worlds[0].options.user.at("render:minshadowbias").floats, std::vector<float>{0.02f});
}

TEST(LenientParams, OtherRenderersKnownNamesAreSilent) {
    // PRMan's ray-tracing visibility, trace, cull, dice, sides and shade
    // attributes, Pixie's visibility "trace", PRMan hider settings.
    auto r = run(R"(Hider "hidden" "jitter" [1] "mpcache" [1] "mpmemory" [4096] "subpixel" [1] "sigma" [1]
Option "user" "pass" "beauty"
Option "limits" "brickmemory" [10240]
Option "trace" "maxdepth" [4]
WorldBegin
Attribute "user" "float lod" [2]
Attribute "visibility" "diffuse" [1] "specular" [1] "photon" [1] "trace" [1] "indirect" [1]
Attribute "visibility" "transmission" "opaque"
Attribute "trace" "bias" [0.01] "maxdiffusedepth" [1] "maxspeculardepth" [2] "displacements" [1]
Attribute "cull" "hidden" [0] "backfacing" [0]
Attribute "dice" "binary" [1] "rasterorient" [0]
Attribute "sides" "backfacetolerance" [10]
Attribute "shade" "diffusehitmode" "primitive"
Attribute "identifier" "name" "ball" "id" [3]
Attribute "displacementbound" "sphere" [0.5]
Sphere 1 -1 1 360
WorldEnd
)");
    EXPECT_EQ(r->messages(), std::vector<std::string>{});
    ASSERT_EQ(r->sink.worlds.size(), 1u);
    EXPECT_EQ(r->sink.worlds[0].options.user.at("user:pass").stringAt(0), "beauty");
    const Attributes& a = *r->sink.worlds[0].primitives.at(0).attributes;
    EXPECT_EQ(a.name, "ball");
    EXPECT_EQ(a.displacementBound, 0.5f);
    EXPECT_TRUE(a.castsShadows);
    EXPECT_EQ(a.user.at("dice:binary").ints, std::vector<int>{1});
}

TEST(LenientParams, StringTransmissionAndBmrtCastsShadowsAreHonoured) {
    auto r = run(R"(WorldBegin
AttributeBegin
Attribute "visibility" "transmission" "transparent"
Sphere 1 -1 1 360
AttributeEnd
AttributeBegin
Attribute "render" "casts_shadows" "none"
Sphere 1 -1 1 360
AttributeEnd
Attribute "render" "casts_shadows" "Os"
Sphere 1 -1 1 360
WorldEnd
)");
    EXPECT_EQ(r->messages(), std::vector<std::string>{});
    ASSERT_EQ(r->sink.worlds.size(), 1u);
    const auto& prims = r->sink.worlds[0].primitives;
    ASSERT_EQ(prims.size(), 3u);
    EXPECT_FALSE(prims[0].attributes->castsShadows);
    EXPECT_FALSE(prims[1].attributes->castsShadows);
    EXPECT_TRUE(prims[2].attributes->castsShadows);
}

TEST(LenientParams, IdentityColorSamplesAreRgbAndSilent) {
    auto r = run("ColorSamples [1 0 0 0 1 0 0 0 1] [1 0 0 0 1 0 0 0 1]\n"
                 "ColorSamples [0.3 0.3 0.4] [1 1 1]\nWorldBegin WorldEnd\n");
    EXPECT_EQ(r->messages(), std::vector<std::string>{"s.rib:2:1: warning: ColorSamples: only RGB colour is "
                                                      "supported (ignored)"});
}

TEST(LenientParams, ShaderAndGeometryParametersStayStrict) {
    // Leniency is for Option/Attribute/Hider/Display: an undeclared
    // primitive variable is still an error (it would be silently lost).
    auto r = run("WorldBegin\nSphere 1 -1 1 360 \"Kdd\" 0.5\nWorldEnd\n");
    EXPECT_EQ(r->diag.errorCount(), 1);
}

}  // namespace
}  // namespace umbra::scene
