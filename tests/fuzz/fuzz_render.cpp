// libFuzzer entry point for the whole pipeline: any bytes, parsed as RIB
// and rendered (first pass, camera pass, output) on a tiny budget, so
// everything past the parser is within the fuzzer's reach: dicing, the
// shading language, depth maps and lookups, the film and its writers.
// Must never crash, hang or leak.
//
// The budget (applied to each world before it is rendered): at most a
// 32 x 24 frame, 2 x 2 samples, 64^2 maps, 32 primitives, 4 lights, a
// shading rate of at least 1, six eye splits, one thread. Outputs are written in a scratch
// directory the fuzzer works in; MakeTexture and the like are dropped, as
// are RunProgram and DynamicLoad procedurals.

#include "umbra/render/renderer.h"
#include "umbra/ri/parser.h"
#include "umbra/scene/builder.h"

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string_view>
#include <unistd.h>
#include <vector>

namespace {

using namespace umbra;

class Budgeted : public scene::SceneSink {
public:
    explicit Budgeted(render::Renderer& r) : m_renderer(r) {}
    void renderWorld(const scene::WorldRecord& in) override {
        scene::WorldRecord w = in;
        scene::Options& o = w.options;
        o.xResolution = std::clamp(o.xResolution, 1, 32);
        o.yResolution = std::clamp(o.yResolution, 1, 24);
        o.pixelSamples[0] = std::clamp(o.pixelSamples[0], 1, 2);
        o.pixelSamples[1] = std::clamp(o.pixelSamples[1], 1, 2);
        // At most 2^6 pieces of a primitive across an eye plane: a fuzzed
        // caster moving across a point light's six planes was split into
        // 2^10 pieces on several faces, each bounded over the shutter, 17 s
        // under the sanitizers (0.6 s in a Release build), past the timeout.
        o.eyeSplits = std::clamp(o.eyeSplits, 0, 6);
        if (auto it = o.user.find("umbra:shadowmapsize"); it != o.user.end()) o.user.erase(it);
        ri::Param size;
        size.decl.name = "shadowmapsize";
        size.decl.type = ri::ParamType::Integer;
        size.ints = {64};
        o.user["umbra:shadowmapsize"] = size;
        // Outputs stay in the scratch directory, whatever they are named.
        int k = 0;
        for (scene::DisplayRecord& d : o.displays)
            d.name = "out" + std::to_string(k++) + std::filesystem::path(d.name).extension().string();
        // Fuzzed RunProgram and DynamicLoad procedurals would run any
        // program or library on the machine: dropped, as MakeTexture is.
        std::erase_if(w.primitives, [](const scene::PrimitiveRecord& p) {
            return p.type == "Procedural" && !p.stringArgs.empty() && p.stringArgs[0] != "DelayedReadArchive";
        });
        if (w.primitives.size() > 32) w.primitives.resize(32);
        for (scene::PrimitiveRecord& p : w.primitives)
            if (p.type == "Polygon" && p.intArrays.size() == 1 && p.intArrays[0].size() > 32) {
                // A run of Polygons (scene.h) counts as its polygons.
                std::vector<int>& nverts = p.intArrays[0];
                nverts.resize(32);
                size_t points = 0;
                for (int n : nverts) points += size_t(n);
                p.params.findMutable("P")->floats.resize(3 * points);
            }
        if (w.lights.size() > 4) w.lights.resize(4);
        std::map<const scene::Attributes*, std::shared_ptr<const scene::Attributes>> coarse;
        for (scene::PrimitiveRecord& p : w.primitives) {
            if (!p.attributes || p.attributes->shadingRate >= 1) continue;
            auto& a = coarse[p.attributes.get()];
            if (!a) {
                auto c = std::make_shared<scene::Attributes>(*p.attributes);
                c->shadingRate = 1;
                a = c;
            }
            p.attributes = a;
        }
        for (scene::LightRecord& l : w.lights)
            if (l.attributes && l.attributes->user.count("umbra:shadowmapsize")) {
                auto c = std::make_shared<scene::Attributes>(*l.attributes);
                c->user.erase("umbra:shadowmapsize");  // the frame's 64 applies
                l.attributes = c;
            }
        m_renderer.renderWorld(w);
    }
    void make(const scene::MakeRecord&) override {}

private:
    render::Renderer& m_renderer;
};

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    // Work in a scratch directory of our own: outputs, automatic maps.
    char dir[] = "/tmp/umbra-fuzz-render-XXXXXX";
    if (!mkdtemp(dir) || chdir(dir) != 0) std::abort();
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    Diagnostics diag;
    diag.setSink([](const Diagnostic&) {});
    render::RenderSettings settings;
    settings.threads = 1;
    settings.quiet = true;
    render::Renderer renderer(settings, diag);
    Budgeted sink(renderer);
    scene::Builder builder(sink, diag);
    renderer.prepare(builder, "fuzz.rib");
    ri::Parser parser(builder, diag);
    parser.parseString(std::string_view(reinterpret_cast<const char*>(data), size), "fuzz.rib", ".");
    return 0;
}
