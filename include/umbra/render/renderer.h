#pragma once
// The frame driver: turns each finished world (WorldBegin..WorldEnd) into
// images. For every world it runs the depth passes the lights need, then
// the camera pass, through the same REYES core (hider/bucket_scheduler.h),
// writes the displays and records statistics.

#include "umbra/scene/builder.h"
#include "umbra/scene/scene.h"
#include "umbra/util/error.h"

#include <nlohmann/json.hpp>

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace umbra::render {

/// Command-line settings that override or complement the RIB's options.
struct RenderSettings {
    int threads = 0;            // 0: all cores
    int bucketSize = 0;         // 0: from Option "limits" "bucketsize" (default 16)
    bool progress = false;      // live progress on stderr
    bool quiet = false;         // no statistics summary
    bool noShadows = false;     // every shadow() lookup and depth pass off (Reeves' Table 1 baseline)
    bool skipExisting = false;  // frames whose outputs all exist are not rendered
    /// The default shader and texture directories, what '@' stands for in
    /// RIB search paths. Empty: $UMBRA_SHADER_PATH / $UMBRA_TEXTURE_PATH, or
    /// the standard shaders (umbra/util/search_path.h).
    std::vector<std::string> shaderPath;
    std::vector<std::string> texturePath;
};

/// Renders worlds as the scene builder finishes them (a scene::SceneSink).
class Renderer : public scene::SceneSink {
public:
    Renderer(const RenderSettings& settings, Diagnostics& diag);
    ~Renderer() override;

    /// Gives a builder about to read `ribFile` the search paths' defaults:
    /// '@' is the settings' path; before any Option "searchpath", the
    /// shader and texture paths are ".:<ribFile's directory>:@".
    void prepare(scene::Builder& builder, const std::string& ribFile) const;

    void renderWorld(const scene::WorldRecord& world) override;
    void make(const scene::MakeRecord& make) override;

    /// Statistics of every frame rendered so far (docs/statistics.md).
    nlohmann::json statistics() const;
    /// Number of worlds that failed to render (a non-zero exit).
    int failedFrames() const { return m_failed; }

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
    int m_failed = 0;
};

/// Parses and renders RIB files in order, as `umbra render` does. Returns
/// the process exit code: 0 on success, 1 on any error.
int renderFiles(const std::vector<std::string>& files, const RenderSettings& settings,
                const std::string& statsPath, Diagnostics& diag);

}  // namespace umbra::render
