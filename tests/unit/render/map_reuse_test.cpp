// Automatic depth maps reused across frames (docs/shadows.md, "Maps reused
// across frames") and per-frame JSON-lines statistics (docs/statistics.md).
// Sequences run through the `umbra` command in a child process; a reused
// map must leave every pixel as rendering it again would. No test reads a
// clock.

#include "render/map_reuse.h"
#include "support/child_run.h"
#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

using namespace umbra;
using umbra::test::Image;
using umbra::test::ScratchDir;
using umbra::test::writeFile;

namespace {

/// Runs `umbra render --threads 2 ARGS...` in `dir`; its exit status, or -1.
int runUmbra(const ScratchDir& dir, std::vector<std::string> args, std::string* messages = nullptr) {
    args.insert(args.begin(), {"umbra", "render", "--threads", "2"});
    test::ChildRun run = test::runIn(dir, UMBRA_APP, std::move(args));
    if (messages) *messages = run.messages;
    return run.status;
}

/// What one frame of the test sequence shows: a sphere (and perhaps a
/// second) casting into a spotlight's automatic map onto a ground plane
/// that casts nothing.
struct FrameSetup {
    float lightX = 0.5f;
    float sphereX = 0;
    float wobble = 0;          // amplitude of the sphere's displacement; 0: none
    int mapSize = 64;
    bool secondSphere = false;
    float cameraZ = 5;
    const char* groundColor = "1 1 1";
    const char* displacement = "wobble";
};

/// A displacement that moves the surface by a fixed pattern, and one that
/// draws random numbers (so its map depends on the frame's seed).
constexpr const char* kShaders[][2] = {
    {"wobble.sl",
     "displacement wobble(float Km = 0.1;) { P += Km * sin(10 * s) * normalize(N); N = calculatenormal(P); }\n"},
    {"grain.sl",
     "displacement grain(float Km = 0.1;) { P += Km * float random() * normalize(N); N = calculatenormal(P); }\n"},
    {"pulse.sl",
     "displacement pulse(float Km = 0.1;) { float f = 0; option(\"FrameNumber\", f);\n"
     "  P += Km * (1 + mod(f, 2)) * normalize(N); N = calculatenormal(P); }\n"},
    {"anchored.sl",
     "displacement anchored(float Km = 0.1;) { point a = transform(\"anchor\", P);\n"
     "  P += Km * sin(4 * xcomp(a)) * normalize(N); N = calculatenormal(P); }\n"},
};

std::string frameRib(int n, const FrameSetup& f, const std::string& extraOptions = "") {
    const std::string displacement =
        f.wobble > 0 ? fmt::format("Displacement \"{}\" \"Km\" [{}]\n    Attribute \"displacementbound\" \"sphere\" [{}]",
                                   f.displacement, f.wobble, f.wobble)
                     : "";
    const std::string second =
        f.secondSphere ? "AttributeBegin\n    Translate -0.8 0.2 0.4\n    Sphere 0.3 -0.3 0.3 360\n  AttributeEnd" : "";
    return fmt::format(R"(FrameBegin {n}
Display "out.####.tif" "file" "rgba"
Quantize "rgba" 0 0 0 0
Option "umbra" "shadowmapsize" [{size}]
{extra}
Projection "perspective" "fov" 40
Translate 0 0 {camz}
WorldBegin
  LightSource "shadowspot" "key" "from" [{lx} 4 0.3] "to" [0 0 0] "coneangle" [0.9] "intensity" [16] "shadowname" ["auto"]
  Surface "matte"
  AttributeBegin
    Translate {sx} 0.5 0
    {disp}
    Sphere 0.6 -0.6 0.6 360
  AttributeEnd
  {second}
  AttributeBegin
    Attribute "visibility" "transmission" [0]
    Color [{gc}]
    Patch "bilinear" "P" [-3 -0.5 -3  3 -0.5 -3  -3 -0.5 3  3 -0.5 3]
  AttributeEnd
WorldEnd
FrameEnd
)",
                       fmt::arg("n", n), fmt::arg("size", f.mapSize), fmt::arg("extra", extraOptions),
                       fmt::arg("camz", f.cameraZ), fmt::arg("lx", f.lightX), fmt::arg("sx", f.sphereX),
                       fmt::arg("disp", displacement), fmt::arg("second", second), fmt::arg("gc", f.groundColor));
}

std::string sequenceRib(const std::vector<FrameSetup>& frames, const std::string& extraOptions = "") {
    std::string rib = "Format 48 36 1\nPixelSamples 2 2\n";
    for (size_t i = 0; i < frames.size(); ++i) rib += frameRib(int(i) + 1, frames[i], extraOptions);
    return rib;
}

void writeShaders(const ScratchDir& dir) {
    for (const auto& [name, text] : kShaders) writeFile(dir.file(name), text);
}

std::vector<nlohmann::json> readLines(const std::string& path) {
    std::vector<nlohmann::json> lines;
    std::ifstream in(path);
    for (std::string line; std::getline(in, line);) lines.push_back(nlohmann::json::parse(line));
    return lines;
}

Image imageOf(const std::string& path) {
    Image img;
    EXPECT_TRUE(test::readImage(path, &img)) << path;
    return img;
}

/// The sequence of the brief, one change a frame, each kept afterwards.
std::vector<FrameSetup> changesOneAtATime() {
    std::vector<FrameSetup> frames(10);
    for (auto& f : frames) f.wobble = 0.05f;
    auto from = [&](size_t frame, auto change) {
        for (size_t i = frame - 1; i < frames.size(); ++i) change(frames[i]);
    };
    from(3, [](FrameSetup& f) { f.lightX = 0.8f; });         // 3: the light moved
    from(5, [](FrameSetup& f) { f.sphereX = 0.3f; });        // 5: a caster moved
    from(6, [](FrameSetup& f) { f.wobble = 0.08f; });        // 6: its displacement changed
    from(7, [](FrameSetup& f) { f.mapSize = 96; });          // 7: the map size changed
    from(8, [](FrameSetup& f) { f.secondSphere = true; });   // 8: a new caster
    from(9, [](FrameSetup& f) { f.cameraZ = 6; });           // 9: only the camera moved
    frames[9].groundColor = "0.5 0.8 0.2";                   // 10: only a non-caster changed
    return frames;
}

}  // namespace

TEST(MapReuse, DecidedFromContentAndNeverChangesAPixel) {
    const std::vector<FrameSetup> frames = changesOneAtATime();
    const std::vector<std::pair<bool, std::string>> expected = {
        {false, "first frame"},   {true, "same content"},     {false, "light changed"}, {true, "same content"},
        {false, "caster changed"}, {false, "caster changed"}, {false, "map size changed"}, {false, "new caster"},
        {true, "same content"},   {true, "same content"}};
    ScratchDir on("reuse-on"), off("reuse-off"), alone("reuse-alone");
    for (const ScratchDir* dir : {&on, &off, &alone}) {
        writeShaders(*dir);
        writeFile(dir->file("seq.rib"), sequenceRib(frames));
    }
    std::string messages;
    ASSERT_EQ(runUmbra(on, {"seq.rib", "--stats", "run.jsonl"}, &messages), 0) << messages;
    ASSERT_EQ(runUmbra(off, {"seq.rib", "--stats", "run.jsonl", "--no-map-reuse"}, &messages), 0) << messages;
    const auto lines = readLines(on.file("run.jsonl"));
    const auto linesOff = readLines(off.file("run.jsonl"));
    ASSERT_EQ(lines.size(), frames.size());
    ASSERT_EQ(linesOff.size(), frames.size());
    for (size_t i = 0; i < frames.size(); ++i) {
        SCOPED_TRACE(fmt::format("frame {}", i + 1));
        const nlohmann::json& maps = lines[i]["maps"];
        ASSERT_EQ(maps.size(), 1u);
        EXPECT_EQ(maps[0]["reused"].get<bool>(), expected[i].first);
        EXPECT_EQ(maps[0]["reason"].get<std::string>(), expected[i].second);
        // A reused map has no depth pass of its own and reads the earlier file.
        EXPECT_EQ(lines[i]["passes"].size(), expected[i].first ? 1u : 2u);
        if (!expected[i].first) {
            EXPECT_EQ(maps[0]["path"], fmt::format("out.{:04d}.key.shd", i + 1));
        }
        // With reuse off every map is rendered; the decision is still reported.
        EXPECT_FALSE(linesOff[i]["maps"][0]["reused"].get<bool>());
        EXPECT_EQ(linesOff[i]["passes"].size(), 2u);
        const std::string image = fmt::format("out.{:04d}.tif", i + 1);
        EXPECT_EQ(test::maxAbsDiff(imageOf(on.file(image)), imageOf(off.file(image)), 4), 0.0);
    }
    EXPECT_EQ(lines[1]["maps"][0]["path"], "out.0001.key.shd");
    EXPECT_EQ(lines[3]["maps"][0]["path"], "out.0003.key.shd");
    EXPECT_EQ(lines[9]["maps"][0]["path"], "out.0008.key.shd");
    EXPECT_EQ(linesOff[1]["maps"][0]["reason"], "reuse off");
    // The frames that reused a map, each rendered alone, render their own.
    for (int n : {2, 4, 9, 10}) {
        ASSERT_EQ(runUmbra(alone, {"seq.rib", "--frames", std::to_string(n)}, &messages), 0) << messages;
        const std::string image = fmt::format("out.{:04d}.tif", n);
        EXPECT_EQ(test::maxAbsDiff(imageOf(on.file(image)), imageOf(alone.file(image)), 4), 0.0) << image;
    }
}

TEST(MapReuse, CubeAndDistantMapsToo) {
    // A point light's six faces and a distant light's map fitted to the
    // casters' bound are reused alike, with the same pixels.
    std::string rib = "Format 48 36 1\nPixelSamples 2 2\n";
    for (int n = 1; n <= 3; ++n) {
        std::string frame = frameRib(n, FrameSetup{});
        const std::string spot = frame.substr(frame.find("  LightSource"), frame.find("\n", frame.find("  LightSource")) -
                                                                                frame.find("  LightSource") + 1);
        frame.replace(frame.find(spot), spot.size(),
                      fmt::format("  LightSource \"shadowpoint\" \"bulb\" \"from\" [0.5 2.5 0.3] \"intensity\" [6] "
                                  "\"shadowname\" [\"auto\"]\n"
                                  "  LightSource \"shadowdistant\" \"sun\" \"from\" [0 0 0] \"to\" [{} -1 0.2] "
                                  "\"intensity\" [0.5] \"shadowname\" [\"auto\"]\n",
                                  n == 3 ? 0.4 : 0.3));
        rib += frame;
    }
    ScratchDir on("reuse-cube-on"), off("reuse-cube-off");
    std::string messages;
    for (const ScratchDir* dir : {&on, &off}) writeFile(dir->file("seq.rib"), rib);
    ASSERT_EQ(runUmbra(on, {"seq.rib", "--stats", "run.jsonl"}, &messages), 0) << messages;
    ASSERT_EQ(runUmbra(off, {"seq.rib", "--no-map-reuse"}, &messages), 0) << messages;
    const auto lines = readLines(on.file("run.jsonl"));
    ASSERT_EQ(lines.size(), 3u);
    ASSERT_EQ(lines[1]["maps"].size(), 2u);
    EXPECT_EQ(lines[1]["maps"][0]["reused"], true);  // the cube map
    EXPECT_EQ(lines[1]["maps"][1]["reused"], true);
    EXPECT_EQ(lines[1]["passes"].size(), 1u);
    EXPECT_EQ(lines[2]["maps"][0]["reused"], true);
    EXPECT_EQ(lines[2]["maps"][1]["reason"], "light changed");
    for (int n = 1; n <= 3; ++n) {
        const std::string image = fmt::format("out.{:04d}.tif", n);
        EXPECT_EQ(test::maxAbsDiff(imageOf(on.file(image)), imageOf(off.file(image)), 4), 0.0) << image;
    }
}

TEST(MapReuse, OptionTurnsItOff) {
    ScratchDir dir("reuse-option");
    writeShaders(dir);
    writeFile(dir.file("seq.rib"), sequenceRib(std::vector<FrameSetup>(2), "Option \"umbra\" \"reusemaps\" [0]"));
    std::string messages;
    ASSERT_EQ(runUmbra(dir, {"seq.rib", "--stats", "run.jsonl"}, &messages), 0) << messages;
    EXPECT_EQ(messages.find("reusemaps"), std::string::npos) << messages;  // a declared option
    const auto lines = readLines(dir.file("run.jsonl"));
    ASSERT_EQ(lines.size(), 2u);
    EXPECT_EQ(lines[1]["maps"][0]["reused"], false);
    EXPECT_EQ(lines[1]["maps"][0]["reason"], "reuse off");
    EXPECT_EQ(lines[1]["maps"][0]["path"], "out.0002.key.shd");
}

TEST(MapReuse, RandomDisplacementFollowsTheFrameSeed) {
    // A displacement drawing random numbers draws others in every frame:
    // its map is never the same content, though nothing in the RIB changed.
    ScratchDir dir("reuse-random");
    writeShaders(dir);
    FrameSetup grainy;
    grainy.wobble = 0.05f;
    grainy.displacement = "grain";
    writeFile(dir.file("seq.rib"), sequenceRib({grainy, grainy}));
    std::string messages;
    ASSERT_EQ(runUmbra(dir, {"seq.rib", "--stats", "run.jsonl"}, &messages), 0) << messages;
    const auto lines = readLines(dir.file("run.jsonl"));
    ASSERT_EQ(lines.size(), 2u);
    EXPECT_EQ(lines[1]["maps"][0]["reused"], false);
    EXPECT_EQ(lines[1]["maps"][0]["reason"], "frame seed changed");
}

TEST(MapReuse, DisplacementReadingTheFrameOrACoordinateSystem) {
    // A displacement reading the frame number (option()) is this frame's
    // alone; one placed in a named coordinate system follows it.
    ScratchDir dir("reuse-frame-state");
    writeShaders(dir);
    FrameSetup pulsing;
    pulsing.wobble = 0.05f;
    pulsing.displacement = "pulse";
    FrameSetup anchored = pulsing;
    anchored.displacement = "anchored";
    std::string rib = "Format 48 36 1\nPixelSamples 2 2\n" + frameRib(1, pulsing) + frameRib(2, pulsing);
    auto withAnchor = [&](int n, float x) {
        std::string text = frameRib(n, anchored);
        const std::string at = "WorldBegin\n";
        return text.insert(text.find(at) + at.size(),
                           fmt::format("  TransformBegin\n    Translate {} 0 0\n    CoordinateSystem \"anchor\"\n  TransformEnd\n", x));
    };
    rib += withAnchor(3, 0) + withAnchor(4, 0) + withAnchor(5, 0.5f);
    writeFile(dir.file("seq.rib"), rib);
    std::string messages;
    ASSERT_EQ(runUmbra(dir, {"seq.rib", "--stats", "run.jsonl"}, &messages), 0) << messages;
    const auto lines = readLines(dir.file("run.jsonl"));
    ASSERT_EQ(lines.size(), 5u);
    EXPECT_EQ(lines[1]["maps"][0]["reason"], "frame seed changed");
    EXPECT_EQ(lines[3]["maps"][0]["reason"], "same content");
    EXPECT_EQ(lines[4]["maps"][0]["reason"], "caster changed");
}

TEST(MapReuse, CasterDigestFollowsWhatADepthPassReads) {
    scene::PrimitiveRecord sphere;
    sphere.type = "Sphere";
    sphere.floatArgs = {1, -1, 1, 360};
    auto attributes = std::make_shared<scene::Attributes>();
    sphere.attributes = attributes;
    const render::Digest base = render::casterDigest(sphere);
    EXPECT_EQ(render::casterDigest(sphere), base);

    // Surface colour and shader never reach a depth map.
    auto coloured = std::make_shared<scene::Attributes>(*attributes);
    coloured->color = {0.2f, 0.3f, 0.4f};
    coloured->surface = std::make_shared<scene::ShaderRecord>(scene::ShaderRecord{"plastic", {}, {}, {}});
    scene::PrimitiveRecord r = sphere;
    r.attributes = coloured;
    EXPECT_EQ(render::casterDigest(r), base);

    // Geometry, transform, sides, displacement and its parameters do.
    r = sphere;
    r.floatArgs[0] = 1.5f;
    EXPECT_NE(render::casterDigest(r), base);
    r = sphere;
    r.worldFromObject.m[3][0] = 0.25f;
    EXPECT_NE(render::casterDigest(r), base);
    auto oneSided = std::make_shared<scene::Attributes>(*attributes);
    oneSided->sides = 1;
    r = sphere;
    r.attributes = oneSided;
    EXPECT_NE(render::casterDigest(r), base);
    auto displaced = std::make_shared<scene::Attributes>(*attributes);
    auto shader = std::make_shared<scene::ShaderRecord>();
    shader->name = "wobble";
    ri::Param km;
    km.decl.name = "Km";
    km.floats = {0.1f};
    shader->params.add(km);
    displaced->displacement = shader;
    r = sphere;
    r.attributes = displaced;
    const render::Digest withDisplacement = render::casterDigest(r);
    EXPECT_NE(withDisplacement, base);
    auto stronger = std::make_shared<scene::ShaderRecord>(*shader);
    ri::ParamList params;
    km.floats = {0.2f};
    params.add(km);
    stronger->params = params;
    auto displacedMore = std::make_shared<scene::Attributes>(*displaced);
    displacedMore->displacement = stronger;
    r.attributes = displacedMore;
    EXPECT_NE(render::casterDigest(r), withDisplacement);
}

TEST(MapReuse, ReasonNamesTheFirstDifference) {
    render::Hasher h;
    render::MapContent a;
    a.size = 256;
    a.settings = h.str("settings").value();
    a.view = h.str("view").value();
    a.casters = {render::Hasher().str("ball").value(), render::Hasher().str("lamp").value()};
    EXPECT_EQ(render::reuseReason(nullptr, a), "first frame");
    EXPECT_EQ(render::reuseReason(&a, a), render::kSameContent);
    render::MapContent b = a;
    b.size = 512;
    EXPECT_EQ(render::reuseReason(&a, b), "map size changed");
    b = a;
    b.settings = render::Hasher().str("other").value();
    EXPECT_EQ(render::reuseReason(&a, b), "map settings changed");
    b = a;
    b.casters.push_back(render::Hasher().str("cube").value());
    EXPECT_EQ(render::reuseReason(&a, b), "new caster");
    EXPECT_EQ(render::reuseReason(&b, a), "caster removed");
    b = a;
    b.casters[1] = render::Hasher().str("lamp moved").value();
    EXPECT_EQ(render::reuseReason(&a, b), "caster changed");
    b = a;
    b.view = render::Hasher().str("view moved").value();
    EXPECT_EQ(render::reuseReason(&a, b), "light changed");
    b = a;
    b.seed = 7;
    EXPECT_EQ(render::reuseReason(&a, b), "frame seed changed");
}

TEST(MapCache, SharedBetweenProcessesByContent) {
    // A farm's tasks: three processes each render one frame of a shot whose
    // camera moves and whose light and casters do not, sharing one cache.
    // The first renders the map and adds it; the others read it, and every
    // image is the one a single process rendering the whole shot makes.
    // A fourth frame whose light moved is not served by the cache.
    std::vector<FrameSetup> frames(4);
    for (auto& f : frames) f.wobble = 0.05f;
    frames[1].cameraZ = 5.5f;
    frames[2].cameraZ = 6;
    frames[3].lightX = 0.8f;
    ScratchDir farm("map-cache-farm"), single("map-cache-single");
    for (const ScratchDir* dir : {&farm, &single}) {
        writeShaders(*dir);
        writeFile(dir->file("seq.rib"), sequenceRib(frames));
    }
    std::string messages;
    ASSERT_EQ(runUmbra(single, {"seq.rib"}, &messages), 0) << messages;
    std::vector<nlohmann::json> tasks;
    for (int n = 1; n <= 4; ++n) {
        const std::string stats = fmt::format("task{}.jsonl", n);
        ASSERT_EQ(runUmbra(farm, {"seq.rib", "--frames", std::to_string(n), "--map-cache", "maps", "--stats", stats},
                           &messages),
                  0)
            << messages;
        const auto lines = readLines(farm.file(stats));
        ASSERT_EQ(lines.size(), 1u);
        ASSERT_EQ(lines[0]["maps"].size(), 1u);
        tasks.push_back(lines[0]);
    }
    std::vector<std::string> cached;
    for (const auto& entry : std::filesystem::directory_iterator(farm.file("maps")))
        cached.push_back(entry.path().filename().string());
    std::sort(cached.begin(), cached.end());
    // Two maps (the still light's and the moved light's), no temporary left.
    ASSERT_EQ(cached.size(), 2u) << fmt::format("{}", fmt::join(cached, " "));
    for (const std::string& name : cached) EXPECT_EQ(name.size(), 32u + 4u) << name;  // <128-bit hex>.shd

    EXPECT_EQ(tasks[0]["maps"][0]["reused"], false);
    EXPECT_EQ(tasks[0]["maps"][0]["reason"], "first frame");
    EXPECT_EQ(tasks[0]["passes"].size(), 2u);
    const std::string shared = tasks[1]["maps"][0]["path"].get<std::string>();
    EXPECT_EQ(shared.rfind("maps/", 0), 0u) << shared;
    for (int t : {1, 2}) {
        SCOPED_TRACE(fmt::format("task {}", t + 1));
        EXPECT_EQ(tasks[t]["maps"][0]["reused"], true);
        EXPECT_EQ(tasks[t]["maps"][0]["reason"], "map cache");
        EXPECT_EQ(tasks[t]["maps"][0]["path"], shared);
        EXPECT_EQ(tasks[t]["passes"].size(), 1u) << "no depth pass";
    }
    EXPECT_EQ(tasks[3]["maps"][0]["reused"], false);
    EXPECT_EQ(tasks[3]["maps"][0]["reason"], "first frame");
    for (int n = 1; n <= 4; ++n) {
        const std::string image = fmt::format("out.{:04d}.tif", n);
        EXPECT_EQ(test::maxAbsDiff(imageOf(farm.file(image)), imageOf(single.file(image)), 4), 0.0) << image;
    }

    // Within one process the cached map is reused as its own: frames 2-3
    // rendered together read the cache once, then reuse it from memory.
    ASSERT_EQ(runUmbra(farm, {"seq.rib", "--frames", "2-3", "--map-cache", "maps", "--stats", "both.jsonl"}, &messages),
              0)
        << messages;
    const auto both = readLines(farm.file("both.jsonl"));
    ASSERT_EQ(both.size(), 2u);
    EXPECT_EQ(both[0]["maps"][0]["reason"], "map cache");
    EXPECT_EQ(both[1]["maps"][0]["reason"], "same content");
    EXPECT_EQ(both[1]["maps"][0]["path"], shared);
}

TEST(MapCache, ConcurrentProcessesShareOneCacheSafely) {
    // Three processes start at once on frames of one shot with an empty
    // cache: each may render the map or read it (whichever comes first),
    // but none fails, none reads part of a map, no temporary name is left,
    // and every image is the single process's.
    std::vector<FrameSetup> frames(3);
    for (size_t i = 0; i < frames.size(); ++i) frames[i].cameraZ = 5 + 0.5f * float(i);
    ScratchDir farm("map-cache-concurrent"), single("map-cache-concurrent-single");
    for (const ScratchDir* dir : {&farm, &single}) writeFile(dir->file("seq.rib"), sequenceRib(frames));
    std::string messages;
    ASSERT_EQ(runUmbra(single, {"seq.rib"}, &messages), 0) << messages;
    std::vector<pid_t> children;
    for (int n = 1; n <= 3; ++n)
        children.push_back(test::startIn(farm, UMBRA_APP,
                                         {"umbra", "render", "--threads", "1", "--frames", std::to_string(n),
                                          "--map-cache", "maps", "--stats", fmt::format("task{}.jsonl", n), "seq.rib"},
                                         {}, fmt::format("run{}.log", n)));
    for (size_t i = 0; i < children.size(); ++i) {
        const test::ChildRun run = test::finish(farm, children[i], fmt::format("run{}.log", i + 1));
        EXPECT_EQ(run.status, 0) << run.messages;
    }
    std::vector<std::string> cached;
    for (const auto& entry : std::filesystem::directory_iterator(farm.file("maps")))
        cached.push_back(entry.path().filename().string());
    ASSERT_EQ(cached.size(), 1u) << fmt::format("{}", fmt::join(cached, " "));
    for (int n = 1; n <= 3; ++n) {
        const auto lines = readLines(farm.file(fmt::format("task{}.jsonl", n)));
        ASSERT_EQ(lines.size(), 1u);
        const std::string reason = lines[0]["maps"][0]["reason"].get<std::string>();
        EXPECT_TRUE(reason == "first frame" || reason == "map cache") << reason;
        const std::string image = fmt::format("out.{:04d}.tif", n);
        EXPECT_EQ(test::maxAbsDiff(imageOf(farm.file(image)), imageOf(single.file(image)), 4), 0.0) << image;
    }
}

TEST(MapCache, FrameSeededMapsAreNeverShared) {
    ScratchDir dir("map-cache-seeded");
    writeShaders(dir);
    FrameSetup grainy;
    grainy.wobble = 0.05f;
    grainy.displacement = "grain";
    writeFile(dir.file("seq.rib"), sequenceRib({grainy, grainy}));
    std::string messages;
    for (int n = 1; n <= 2; ++n) {
        ASSERT_EQ(runUmbra(dir, {"seq.rib", "--frames", std::to_string(n), "--map-cache", "maps", "--stats", "run.jsonl"},
                           &messages),
                  0)
            << messages;
    }
    const auto lines = readLines(dir.file("run.jsonl"));
    ASSERT_EQ(lines.size(), 2u);
    for (const auto& line : lines) {
        EXPECT_EQ(line["maps"][0]["reused"], false);
        EXPECT_EQ(line["maps"][0]["reason"], "first frame");
    }
    EXPECT_TRUE(std::filesystem::is_empty(dir.file("maps")));
}

TEST(MapCache, AnUnusableDirectoryIsAnError) {
    ScratchDir dir("map-cache-bad");
    writeShaders(dir);
    writeFile(dir.file("seq.rib"), sequenceRib(std::vector<FrameSetup>(1)));
    writeFile(dir.file("afile"), "not a directory");
    std::string messages;
    EXPECT_EQ(runUmbra(dir, {"seq.rib", "--map-cache", "afile/maps"}, &messages), 1);
    EXPECT_NE(messages.find("--map-cache: cannot use \"afile/maps\""), std::string::npos) << messages;
    EXPECT_FALSE(std::filesystem::exists(dir.file("out.0001.tif")));
}

TEST(FrameStatistics, JsonLinesHaveALinePerFrame) {
    ScratchDir dir("stats-lines");
    writeShaders(dir);
    writeFile(dir.file("seq.rib"), sequenceRib(std::vector<FrameSetup>(3)));
    std::string messages;
    ASSERT_EQ(runUmbra(dir, {"seq.rib", "--stats", "run.jsonl"}, &messages), 0) << messages;
    std::ifstream in(dir.file("run.jsonl"));
    std::vector<std::string> lines;
    for (std::string line; std::getline(in, line);) lines.push_back(line);
    ASSERT_EQ(lines.size(), 3u);
    for (size_t i = 0; i < lines.size(); ++i) {
        SCOPED_TRACE(lines[i]);
        ASSERT_TRUE(nlohmann::json::accept(lines[i]));
        const nlohmann::json f = nlohmann::json::parse(lines[i]);
        EXPECT_EQ(f["schema"], 1);
        EXPECT_EQ(f["frame"], int(i) + 1);
        EXPECT_TRUE(f["first_pass"]["wall_seconds"].is_number());
        EXPECT_EQ(f["passes"].back()["name"], "camera");
        for (const auto& pass : f["passes"]) EXPECT_TRUE(pass["wall_seconds"].is_number());
        ASSERT_EQ(f["maps"].size(), 1u);
        EXPECT_EQ(f["maps"][0]["light"], "key");
        EXPECT_EQ(f["maps"][0]["reused"], i > 0);
        EXPECT_EQ(f["maps"][0]["reason"], i > 0 ? "same content" : "first frame");
    }
    // Another run appends (farm tasks may share the file); a .json name
    // still gets one document.
    ASSERT_EQ(runUmbra(dir, {"seq.rib", "--frames", "2", "--stats", "run.jsonl"}, &messages), 0) << messages;
    EXPECT_EQ(readLines(dir.file("run.jsonl")).size(), 4u);
    ASSERT_EQ(runUmbra(dir, {"seq.rib", "--stats", "run.json"}, &messages), 0) << messages;
    std::ifstream doc(dir.file("run.json"));
    const nlohmann::json all = nlohmann::json::parse(doc);
    EXPECT_EQ(all["frames"].size(), 3u);
    EXPECT_EQ(all["schema"], 1);
}
