// What other RenderMan renderers accept, umbra accepts: the RenderMan
// Companion's lights before WorldBegin, `Format x y -1`, display drivers
// umbra does not have. Each frame is rendered (exit status 0: warnings
// allowed) and compared with the same scene written plainly.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>

#include <unistd.h>

using namespace umbra;
using umbra::test::Image;
using umbra::test::maxAbsDiff;
using umbra::test::meanAbsDiff;
using umbra::test::ScratchDir;

namespace {

struct Rendered {
    Image image;
    int errors = 0, warnings = 0, failedFrames = 0;
};

Rendered renderScene(const std::string& rib, const std::string& imagePath) {
    Diagnostics diag;
    diag.setQuiet(true);
    Rendered r;
    r.image = test::renderImage(rib, imagePath, diag, 0, 0, &r.failedFrames);
    r.errors = diag.errorCount();
    r.warnings = diag.warningCount();
    return r;
}

}  // namespace

TEST(Lenient, LightsBeforeWorldBeginShineFromWhereTheyWereGiven) {
    // The Companion's style: the light is declared in camera space, before
    // the camera transform. In camera space the light sits at (-4, 4, -2),
    // up, left and behind the eye; the world is moved 5 away. The plain
    // scene gives the same light in world space: camera (x, y, z) is world
    // (x, y, z - 5).
    ScratchDir dir("pre-world-light");
    const std::string image = dir.file("light.tif");
    constexpr const char* scene = R"(
Format 160 120 1
Display "{}" "file" "rgb"
Projection "perspective" "fov" 40
{}
Translate 0 0 5
WorldBegin
{}
Surface "matte"
Sphere 1 -1 1 360
WorldEnd
)";
    const char* camLight = "LightSource \"pointlight\" 1 \"from\" [-4 4 -2] \"intensity\" [30]";
    const char* worldLight = "LightSource \"pointlight\" 1 \"from\" [-4 4 -7] \"intensity\" [30]";
    Rendered before = renderScene(fmt::format(scene, image, camLight, ""), image);
    EXPECT_EQ(before.errors, 0);
    EXPECT_EQ(before.failedFrames, 0);
    Rendered plain = renderScene(fmt::format(scene, image, "", worldLight), image);
    ASSERT_GT(plain.image.channelSum(0), 100.0);
    EXPECT_LT(meanAbsDiff(before.image, plain.image), 1e-5);
}

TEST(Lenient, NegativeOrZeroFormatValuesMeanTheDefaults) {
    ScratchDir dir("format-defaults");
    const std::string image = dir.file("f.tif");
    constexpr const char* scene = R"(
Format {}
Display "{}" "file" "rgb"
WorldBegin
Surface "constant"
Translate 0 0 5
Sphere 1 -1 1 360
WorldEnd
)";
    // Pixel aspect -1 is the default 1: the same picture as writing 1.
    Rendered negative = renderScene(fmt::format(scene, "64 48 -1", image), image);
    EXPECT_EQ(negative.errors, 0);
    Rendered one = renderScene(fmt::format(scene, "64 48 1", image), image);
    EXPECT_EQ(negative.image.width, 64);
    EXPECT_EQ(meanAbsDiff(negative.image, one.image), 0.0);
    // A resolution of zero or less is the default 640 x 480, with a warning.
    Rendered zero = renderScene(fmt::format(scene, "0 -1 1", image), image);
    EXPECT_EQ(zero.errors, 0);
    EXPECT_GE(zero.warnings, 1);
    EXPECT_EQ(zero.image.width, 640);
    EXPECT_EQ(zero.image.height, 480);
}

TEST(Lenient, AViewerDisplayStillWritesTheFrame) {
    // `Display "name" "it"` (PRMan's viewer), "x11", "framebuffer": one
    // warning, and the image written as the "file" driver would.
    ScratchDir dir("viewer-display");
    for (const char* driver : {"it", "x11", "framebuffer", "xpm"}) {
        const std::string name = dir.file(fmt::format("view-{}", driver));
        std::string rib = fmt::format(R"(
Format 32 24 1
Display "{}" "{}" "rgb"
WorldBegin
Surface "constant"
Translate 0 0 5
Sphere 1 -1 1 360
WorldEnd
)",
                                      name, driver);
        Rendered viewer = renderScene(rib, name + ".tif");
        EXPECT_EQ(viewer.errors, 0) << driver;
        EXPECT_EQ(viewer.failedFrames, 0) << driver;
        EXPECT_EQ(viewer.warnings, 1) << driver;
        EXPECT_GT(viewer.image.channelSum(0), 10.0) << driver;
    }
}

TEST(Lenient, AViewerShowingTheFilesImageDoesNotOverwriteIt) {
    // Exporters and examples pair a file with a window on the same name:
    // `Display "out.tif" "file" "rgba"` then `Display "+out.tif"
    // "framebuffer" "rgb"`. Without a window, the viewer's stand-in file
    // must not replace the file asked for: out.tif keeps its alpha and is
    // the image of the scene without the viewer.
    ScratchDir dir("viewer-same-name");
    const std::string name = dir.file("out.tif");
    auto scene = [&](const std::string& viewer) {
        return fmt::format(R"(
Format 32 24 1
Display "{0}" "file" "rgba"
{1}
WorldBegin
Surface "constant"
Translate 0 0 5
Sphere 1 -1 1 360
WorldEnd
)",
                           name, viewer);
    };
    Rendered plain = renderScene(scene(""), name);
    Rendered both = renderScene(scene(fmt::format("Display \"+{}\" \"framebuffer\" \"rgb\"", name)), name);
    EXPECT_EQ(both.errors, 0);
    EXPECT_EQ(both.warnings, 1);
    ASSERT_EQ(both.image.channels, 4);
    EXPECT_EQ(maxAbsDiff(both.image, plain.image, 4), 0.0);
}

TEST(Lenient, ASearchPathMarkerInsideAnEntryStillReachesTheStandardShaders) {
    // Houdini's BMRT-era output writes ".:../&" for ".:..:&". The standard
    // light and surface must still be found: the same picture as the scene
    // with no searchpath at all, with no error.
    ScratchDir dir("searchpath-marker");
    constexpr const char* scene = R"(
{}
Format 64 48 1
Display "{}" "file" "rgb"
Projection "perspective" "fov" 40
Translate 0 0 5
WorldBegin
LightSource "ambientlight" 1 "intensity" [0.2]
LightSource "distantlight" 2 "from" [1 1 -1] "to" [0 0 0]
Color [0.9 0.5 0.2]
Surface "matte"
Sphere 1 -1 1 360
WorldEnd
)";
    const std::string marked = dir.file("marked.tif"), plain = dir.file("plain.tif");
    Rendered a = renderScene(fmt::format(scene, R"(Option "searchpath" "shader" [".:../&"])", marked), marked);
    Rendered b = renderScene(fmt::format(scene, "", plain), plain);
    EXPECT_EQ(a.errors, 0);
    EXPECT_EQ(b.errors, 0);
    EXPECT_GT(b.image.channelSum(0), 100.0);
    EXPECT_EQ(maxAbsDiff(a.image, b.image, 3), 0.0);
}

TEST(Lenient, ALightShadersPIsWhereTheLightWasPlaced) {
    // The Companion's listing 12.5 writes its spotlight as
    // `illuminate(P)`: P of a light that is not an area light is the light
    // itself, the origin of its shader space. The same light written with
    // that point spelled out must draw the same picture, and light it.
    ScratchDir dir("light-p");
    std::ofstream(dir.file("fromp.sl")) << "light fromp(float intensity = 1) { illuminate(P) Cl = intensity; }\n";
    std::ofstream(dir.file("fromorigin.sl"))
        << "light fromorigin(float intensity = 1) { illuminate(point \"shader\" (0, 0, 0)) Cl = intensity; }\n";
    constexpr const char* scene = R"(Option "searchpath" "shader" ["{}:&"]
Format 64 64 1
Display "{}" "file" "rgb"
Projection "perspective" "fov" 60
Translate 0 0 3
WorldBegin
TransformBegin
Translate 1 1 -2
LightSource "{}" 1 "intensity" [0.8]
TransformEnd
Surface "matte"
Polygon "P" [-1 -1 0  -1 1 0  1 1 0  1 -1 0]
WorldEnd
)";
    const std::string a = dir.file("p.tif"), b = dir.file("origin.tif");
    Rendered fromP = renderScene(fmt::format(scene, dir.file(""), a, "fromp"), a);
    Rendered fromOrigin = renderScene(fmt::format(scene, dir.file(""), b, "fromorigin"), b);
    EXPECT_EQ(fromP.errors, 0);
    EXPECT_EQ(fromOrigin.errors, 0);
    EXPECT_GT(fromOrigin.image.channelSum(0), 100.0);
    EXPECT_EQ(maxAbsDiff(fromP.image, fromOrigin.image, 3), 0.0);
}

TEST(Lenient, LightShadersReadTheSurfacesNormalAsNs) {
    // Ns in a light shader is the shaded point's normal (PRMan, Pixie and
    // Aqsis give it): a light making Cl from it equals the surface doing so.
    ScratchDir dir("ns-light");
    std::ofstream(dir.file("nslight.sl")) << "light nslight() { solar(vector(0, 0, 1), 0) { Cl = abs(xcomp(normalize(Ns))); } }\n";
    std::ofstream(dir.file("sumcl.sl")) << "surface sumcl() { Ci = 0; illuminance(P) { Ci += Cl; } Oi = 1; }\n";
    std::ofstream(dir.file("nx.sl")) << "surface nx() { Ci = abs(xcomp(normalize(N))); Oi = 1; }\n";
    const std::string image = dir.file("ns.tif");
    constexpr const char* scene = R"(
Option "searchpath" "shader" ["{}:&"]
Format 64 48 1
Display "{}" "file" "rgb"
Projection "perspective" "fov" 40
Translate 0 0 5
WorldBegin
LightSource "nslight" 1
Surface "{}"
Sphere 1 -1 1 360
WorldEnd
)";
    Rendered fromLight = renderScene(fmt::format(scene, dir.file(""), image, "sumcl"), image);
    EXPECT_EQ(fromLight.errors, 0);
    Rendered fromSurface = renderScene(fmt::format(scene, dir.file(""), image, "nx"), image);
    ASSERT_GT(fromSurface.image.channelSum(0), 50.0);
    EXPECT_LT(meanAbsDiff(fromLight.image, fromSurface.image), 1e-6);
}

TEST(Lenient, EveryRenderManPixelFilterRenders) {
    // PRMan's filter names (mitchell, separable-catmull-rom, blackman-harris,
    // lanczos, disk, bessel, as well as the spec's five). The builder used
    // to accept mitchell and blackman-harris that the film then refused. A
    // normalised filter leaves a flat region flat: the middle of a constant
    // white disc stays 1 under every filter, and the corner stays black.
    ScratchDir dir("pixel-filters");
    const std::string image = dir.file("f.tif");
    for (const char* filter : {"box 1 1", "gaussian 2 2", "mitchell 4 4", "separable-catmull-rom 4 4",
                               "blackman-harris 3 3", "lanczos 4 4", "disk 2 2", "bessel 6.49 6.49",
                               "catmull-rom 4 4", "sinc 4 4", "triangle 2 2"}) {
        std::string rib = fmt::format(R"(
Format 48 48 1
PixelFilter "{}
Display "{}" "file" "rgb"
Quantize "rgba" 0 0 0 0
Projection "orthographic"
WorldBegin
Surface "constant"
Translate 0 0 5
Disk 0 0.8 360
WorldEnd
)",
                                      std::string(filter).insert(std::string(filter).find(' '), "\""), image);
        Rendered r = renderScene(rib, image);
        EXPECT_EQ(r.errors, 0) << filter;
        EXPECT_EQ(r.warnings, 0) << filter;
        EXPECT_EQ(r.failedFrames, 0) << filter;
        ASSERT_EQ(r.image.width, 48) << filter;
        EXPECT_NEAR(r.image.at(24, 24, 0), 1.0f, 1e-4f) << filter;
        EXPECT_NEAR(r.image.at(1, 1, 0), 0.0f, 1e-4f) << filter;
    }
}

TEST(Lenient, BinaryDicingDrawsTheSamePicture) {
    // Attribute "dice" "binary" [1] changes only how grids are counted:
    // the lit sphere matches the plain one to within dicing noise, with no
    // message.
    ScratchDir dir("binary-dice");
    const std::string image = dir.file("b.tif");
    constexpr const char* scene = R"(
Format 64 48 1
Display "{}" "file" "rgb"
Projection "perspective" "fov" 40
WorldBegin
LightSource "distantlight" 1 "from" [-1 1 -1] "to" [0 0 0]
{}
Surface "matte"
Translate 0 0 5
Sphere 1 -1 1 360
WorldEnd
)";
    Rendered binary = renderScene(fmt::format(scene, image, "Attribute \"dice\" \"binary\" [1]"), image);
    EXPECT_EQ(binary.errors, 0);
    EXPECT_EQ(binary.warnings, 0);
    Rendered plain = renderScene(fmt::format(scene, image, ""), image);
    ASSERT_GT(plain.image.channelSum(0), 50.0);
    EXPECT_LT(meanAbsDiff(binary.image, plain.image), 2e-3);
}

TEST(Lenient, BinaryEncodedRibDrawsWhatItsAsciiFormDraws) {
    // RIB writers' binary mode (RI Spec 3.2, appendix C), as a compact
    // writer uses it: each request defined once and then sent as its code,
    // repeated strings as defined tokens, integers in fixed point, other
    // numbers as floats, float arrays as counted runs.
    ScratchDir dir("binary-rib");
    const std::string image = dir.file("b.tif");
    std::string bin;
    std::map<std::string, int> requests, strings;
    auto bytes = [&](std::initializer_list<int> b) {
        for (int x : b) bin.push_back(char(x));
    };
    auto request = [&](const std::string& name) {
        if (!requests.count(name)) {
            const int code = int(requests.size());
            requests[name] = code;
            bytes({0314, code, 0220 + int(name.size())});
            bin += name;
        }
        bytes({0246, requests[name]});
    };
    auto string = [&](const std::string& v) {
        if (!strings.count(v)) {
            const int token = int(strings.size());
            strings[v] = token;
            bytes({0315, token, 0240, int(v.size())});
            bin += v;
        }
        bytes({0317, strings[v]});
    };
    auto floatBits = [&](float f) {
        uint32_t u;
        std::memcpy(&u, &f, 4);
        bytes({int(u >> 24) & 255, int(u >> 16) & 255, int(u >> 8) & 255, int(u) & 255});
    };
    auto integer = [&](int v) { bytes({0201, (v >> 8) & 255, v & 255}); };
    auto real = [&](float f) {
        bytes({0244});
        floatBits(f);
    };
    auto floats = [&](std::initializer_list<float> v) {
        bytes({0310, int(v.size())});
        for (float f : v) floatBits(f);
    };
    request("Format"), integer(64), integer(48), integer(1);
    request("Display"), string(image), string("file"), string("rgb");
    request("Projection"), string("perspective"), string("fov"), real(40);
    request("WorldBegin");
    request("LightSource"), string("distantlight"), integer(1), string("from"), floats({-1, 1, -1}), string("to"),
        floats({0, 0, 0});
    request("Surface"), string("plastic"), string("roughness"), real(0.2f);
    request("Translate"), integer(0), real(-0.25f), integer(5);
    request("Sphere"), integer(1), integer(-1), integer(1), integer(360);
    request("WorldEnd");
    Rendered binary = renderScene(bin, image);
    EXPECT_EQ(binary.errors, 0);
    EXPECT_EQ(binary.warnings, 0);
    Rendered plain = renderScene(fmt::format(R"(
Format 64 48 1
Display "{}" "file" "rgb"
Projection "perspective" "fov" 40
WorldBegin
LightSource "distantlight" 1 "from" [-1 1 -1] "to" [0 0 0]
Surface "plastic" "roughness" 0.2
Translate 0 -0.25 5
Sphere 1 -1 1 360
WorldEnd
)", image), image);
    ASSERT_GT(plain.image.channelSum(0), 50.0);
    EXPECT_EQ(maxAbsDiff(binary.image, plain.image, 3), 0.0);
}

TEST(Lenient, RenderMan13RequestsDrawWhatThePlainSceneDraws) {
    // An inline archive read twice, a conditional on Option "user", a
    // Resource restore and PRMan's other requests: the same picture as the
    // two spheres written out plainly, with only System's warning.
    ScratchDir dir("ri13");
    const std::string image = dir.file("r.tif");
    const std::string rich = fmt::format(R"rib(
Option "user" "string pass" "beauty"
Format 64 48 1
Display "{}" "file" "rgb"
Projection "perspective" "fov" 40
Hider "raytrace" "integrationmode" "path"
Camera "main"
System "date"
ArchiveBegin "ball"
  Sphere 0.8 -0.8 0.8 360
ArchiveEnd
WorldBegin
LightSource "distantlight" 1 "from" [-1 1 -1] "to" [0 0 0]
Surface "matte"
Color 1 0 0
Resource "red" "attributes" "string operation" "save"
IfBegin "$user:pass == 'shadow'"
  Color 0 0 1
Else
  Color 0 1 0
IfEnd
AttributeBegin Translate -1 0 5 ReadArchive "ball" AttributeEnd
Resource "red" "attributes" "string operation" "restore"
AttributeBegin Translate 1 0 5 ReadArchive "ball" AttributeEnd
WorldEnd
)rib",
                                         image);
    const std::string plain = fmt::format(R"rib(
Format 64 48 1
Display "{}" "file" "rgb"
Projection "perspective" "fov" 40
WorldBegin
LightSource "distantlight" 1 "from" [-1 1 -1] "to" [0 0 0]
Surface "matte"
AttributeBegin Color 0 1 0 Translate -1 0 5 Sphere 0.8 -0.8 0.8 360 AttributeEnd
AttributeBegin Color 1 0 0 Translate 1 0 5 Sphere 0.8 -0.8 0.8 360 AttributeEnd
WorldEnd
)rib",
                                          image);
    Diagnostics diag;
    diag.setRecord(true);
    diag.setSink([](const Diagnostic&) {});
    int failed = 0;
    test::renderRib(rich, diag, 0, 0, &failed);
    EXPECT_EQ(failed, 0);
    EXPECT_EQ(diag.errorCount(), 0);
    std::vector<std::string> messages;
    for (const Diagnostic& d : diag.recorded()) messages.push_back(d.str());
    EXPECT_EQ(messages, (std::vector<std::string>{
                            "test.rib:6:1: warning: Hider: \"raytrace\" is not supported; \"hidden\" is used",
                            "test.rib:8:1: warning: System: running commands is not supported (ignored)"}));
    Image richImage;
    ASSERT_TRUE(test::readImage(image, &richImage));
    Rendered p = renderScene(plain, image);
    EXPECT_EQ(p.errors, 0);
    ASSERT_GT(p.image.channelSum(0), 20.0);
    ASSERT_GT(p.image.channelSum(1), 20.0);
    EXPECT_EQ(meanAbsDiff(richImage, p.image), 0.0);
}

TEST(Lenient, AFrameWithoutADisplayWritesRiPic) {
    // Modellers' exports (Wings 3D's writes nothing but the world block)
    // carry no Display, and umbra rendered them to nothing at all, exit 0.
    // PRMan and Aqsis write "ri.pic", a TIFF, into the working directory.
    // The rest are the spec's defaults: 640x480, an orthographic camera
    // whose screen window is [-4/3, 4/3] x [-1, 1], so the unit square seen
    // here covers 240 x 240 pixels.
    ScratchDir dir("no-display");
    const std::string rib = R"(# Exported from a modeller
WorldBegin
AttributeBegin
Surface "constant"
Polygon "P" [-0.5 -0.5 2  -0.5 0.5 2  0.5 0.5 2  0.5 -0.5 2]
AttributeEnd
WorldEnd
)";
    char cwd[4096];
    ASSERT_NE(getcwd(cwd, sizeof cwd), nullptr);
    ASSERT_EQ(chdir(dir.file("").c_str()), 0);
    Rendered r = renderScene(rib, dir.file("ri.pic"));
    ASSERT_EQ(chdir(cwd), 0);
    EXPECT_EQ(r.errors, 0);
    EXPECT_EQ(r.warnings, 1);
    ASSERT_EQ(r.image.width, 640);
    ASSERT_EQ(r.image.height, 480);
    EXPECT_NEAR(r.image.channelSum(0), 240.0 * 240.0, 240.0 * 4);  // a pixel's width of edge either way
}

TEST(Lenient, ShadowMapsAreFoundOnTheTextureSearchPath) {
    // BlenderMan's frames set Option "searchpath" "texture" to the folder
    // MakeShadow wrote into and name the map alone; PRMan, Pixie and Aqsis
    // search that path for shadow() as for texture(). The picture must be
    // the one with the map named by its full path.
    ScratchDir dir("shadow-searchpath");
    const std::string maps = dir.file("maps");
    ASSERT_EQ(std::system(fmt::format("mkdir -p '{}'", maps).c_str()), 0);
    const std::string image = dir.file("lit.tif");
    auto scene = [&](const std::string& searchPath, const std::string& mapName) {
        return fmt::format(R"(
FrameBegin 0
Format 64 64 1
Projection "perspective" "fov" 50
Translate 0 0 6
Display "{0}/l.z" "zfile" "z"
WorldBegin
Translate 0 0 -3
Sphere 0.5 -0.5 0.5 360
Translate 0 0 3
Patch "bilinear" "P" [-3 -3 1  3 -3 1  -3 3 1  3 3 1]
WorldEnd
MakeShadow "{0}/l.z" "{0}/l.tx"
FrameEnd
FrameBegin 1
{1}
Display "{2}" "file" "rgb"
Format 48 48 1
Projection "perspective" "fov" 50
Translate 0 0 6
WorldBegin
LightSource "shadowspot" 1 "from" [0 0 -6] "to" [0 0 0] "coneangle" 0.6 "intensity" 40 "shadowname" "{3}"
Surface "matte"
Translate 0 0 -3
Sphere 0.5 -0.5 0.5 360
Translate 0 0 3
Patch "bilinear" "P" [-3 -3 1  3 -3 1  -3 3 1  3 3 1]
WorldEnd
FrameEnd
)",
                           maps, searchPath, image, mapName);
    };
    Rendered byPath = renderScene(scene("", maps + "/l.tx"), image);
    ASSERT_EQ(byPath.errors, 0);
    Rendered bySearch = renderScene(scene(fmt::format("Option \"searchpath\" \"texture\" [\"{}:&\"]", maps), "l.tx"), image);
    EXPECT_EQ(bySearch.errors, 0);
    EXPECT_EQ(bySearch.failedFrames, 0);
    EXPECT_EQ(maxAbsDiff(bySearch.image, byPath.image, 3), 0.0);
    // The map shadows something: the sphere's shadow on the floor is dark
    // where the picture without a map is lit.
    Rendered noMap = renderScene(scene("", ""), image);
    EXPECT_GT(maxAbsDiff(byPath.image, noMap.image, 3), 0.2);
}

TEST(Lenient, AnAreaLightLightsFromItsShaderSpaceAsThePeersDo) {
    // RI Spec 3.2's AreaLightSource, as the Companion and exporters write
    // it: the light, then its primitive, in an attribute block, then
    // Illuminate to keep it on. Pixie and Aqsis light from the shader
    // alone (P = the shader space's origin) and draw the primitive; umbra
    // turned the light off, leaving the floor black. The plain scene: the
    // same light given by LightSource at the same place.
    ScratchDir dir("area-light");
    const std::string image = dir.file("area.tif");
    constexpr const char* scene = R"(
Format 96 96 1
Display "{}" "file" "rgb"
Projection "perspective" "fov" 50
Translate 0 0 6
WorldBegin
AttributeBegin
  Translate 0 1.5 -1
  {} "pointlight" "key" "intensity" 4
  Surface "constant"
  Sphere 0.2 -0.2 0.2 360
AttributeEnd
Illuminate "key" 1
Surface "matte"
Polygon "P" [-2 -2 0  2 -2 0  2 2 0  -2 2 0]
WorldEnd
)";
    Rendered area = renderScene(fmt::format(scene, image, "AreaLightSource"), image);
    EXPECT_EQ(area.errors, 0);
    EXPECT_EQ(area.warnings, 1);  // lit as an ordinary light, said once
    EXPECT_EQ(area.failedFrames, 0);
    Rendered plain = renderScene(fmt::format(scene, image, "LightSource"), image);
    EXPECT_EQ(plain.warnings, 0);
    // The floor below the sphere: 4 / d^2 with d^2 = 1.5^2 + 1, times the
    // cosine 1 / d: about 0.53 straight under the light.
    ASSERT_GT(plain.image.channelSum(0), 0.1 * 96 * 96);
    EXPECT_EQ(maxAbsDiff(area.image, plain.image, 3), 0.0);
}

TEST(Lenient, TheDefaultSearchPathHoldsTheCurrentDirectory) {
    // Course scenes write Option "searchpath" "shader" ["./bin:@"] for
    // shaders compiled beside the RIB; in Aqsis and Pixie '@' (the default)
    // holds the current directory. umbra's '@' held only the standard
    // shaders: "cannot find shader", the default surface drawn.
    ScratchDir dir("searchpath-at");
    std::ofstream(dir.file("greenish.sl")) << "surface greenish() { Ci = color(0, 1, 0); Oi = 1; }\n";
    const std::string rib = fmt::format(R"(Option "searchpath" "shader" ["./bin:@"]
Format 16 16 1
Display "{}" "file" "rgb"
Projection "orthographic"
WorldBegin
Surface "greenish"
Polygon "P" [-2 -2 1  2 -2 1  2 2 1  -2 2 1]
WorldEnd
)",
                                        dir.file("at.tif"));
    char cwd[4096];
    ASSERT_NE(getcwd(cwd, sizeof cwd), nullptr);
    ASSERT_EQ(chdir(dir.file("").c_str()), 0);
    Rendered r = renderScene(rib, dir.file("at.tif"));
    ASSERT_EQ(chdir(cwd), 0);
    EXPECT_EQ(r.errors, 0);
    EXPECT_EQ(r.image.channelSum(0), 0.0);
    EXPECT_EQ(r.image.channelSum(1), 16.0 * 16.0);
}
