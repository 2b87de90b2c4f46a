#pragma once
// The frame driver: turns each finished world (WorldBegin..WorldEnd) into
// images. For every world it runs the depth passes the lights need, then
// the camera pass, through the same REYES core (hider/bucket_scheduler.h),
// writes the displays and records statistics.

#include "umbra/scene/builder.h"
#include "umbra/scene/scene.h"
#include "umbra/util/error.h"
#include "umbra/util/frame_set.h"

#include <nlohmann/json.hpp>

#include <functional>
#include <memory>
#include <optional>
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
    /// Automatic maps of an earlier frame stand in for a frame's own when
    /// their content would be the same (`--no-map-reuse` turns it off).
    bool reuseMaps = true;
    /// `--map-cache DIR`: automatic maps shared between processes (a
    /// farm's tasks) by their content digest: a map whose digest names a
    /// file in DIR is read from there instead of rendered; a rendered one
    /// is copied there (temporary name, then rename). Empty: none.
    std::string mapCache;
    /// `--resume`: frames whose every Display file is a complete image
    /// (film::imageFileComplete) are not rendered again.
    bool resume = false;
    /// Streams the camera pass's film to its displays as strips of rows
    /// complete, freeing the rows, when every display is a TIFF and no
    /// imager needs the whole film (film::Film::openStream). False
    /// (`--no-film-stream`): the whole film is kept and written at the end.
    /// The files are the same bytes either way.
    bool filmStream = true;
    /// `--frames`: the FrameBegin numbers to render; unset: all. Worlds
    /// outside FrameBegin/FrameEnd have no number and are always rendered
    /// (docs/frames.md).
    std::optional<FrameSet> frames;
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
    void frameBegin(int frameNumber, const FileLoc& loc) override;
    void frameEnd(const FileLoc& loc) override;
    bool frameWanted(int frameNumber) const override { return selected(frameNumber); }

    /// Whether a world of frame `frameNumber` (-1: outside any frame) is to
    /// be rendered under the settings' `frames`.
    bool selected(int frameNumber) const;
    /// Records that frame `frameNumber` failed without reaching the
    /// renderer (e.g. its RIB file of a `#` pattern could not be read).
    void addFailedFrame(int frameNumber);
    /// While `frame` >= 0, the RIB being read is that frame's own file (a
    /// `#` pattern's): all its worlds and Make requests belong to it and are
    /// rendered whatever their FrameBegin numbers.
    void setFileFrame(int frame) { m_fileFrame = frame; }

    /// Statistics of every frame rendered so far (docs/statistics.md).
    nlohmann::json statistics() const;
    /// Called with each frame's statistics as the frame ends (rendered or
    /// skipped), e.g. to append them to a JSON-lines file.
    void onFrameStatistics(std::function<void(const nlohmann::json&)> sink);
    /// Number of worlds that failed to render (a non-zero exit).
    int failedFrames() const { return m_failed; }
    /// The numbers of the frames that failed, in render order, each once
    /// (-1: a world outside any frame; a failed Make request counts as a
    /// failure of the frame it is in).
    const std::vector<int>& failedFrameNumbers() const { return m_failedNumbers; }

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
    int m_failed = 0;
    std::vector<int> m_failedNumbers;
    int m_frame = -1;      // the open FrameBegin's number; -1 outside frames
    int m_fileFrame = -1;  // setFileFrame
    /// Noted on the failure list of `frame` when m_failed went past `before`.
    void noteFailure(int frame, int before);
};

/// Parses and renders RIB files in order, as `umbra render` does. A file
/// name with a frame pattern (`shot.####.rib`, `shot.%04d.rib`) stands for
/// one file per frame of `settings.frames`, which it then requires. A failed
/// frame does not stop the others; a summary line names the failed frames.
/// Returns the process exit code: 0 on success, 1 on any error.
/// The version of the statistics' layout, in every line of a `--stats
/// FILE.jsonl`: raised when a field changes meaning or is removed.
inline constexpr int kStatisticsSchema = 1;

int renderFiles(const std::vector<std::string>& files, const RenderSettings& settings,
                const std::string& statsPath, Diagnostics& diag);

}  // namespace umbra::render
