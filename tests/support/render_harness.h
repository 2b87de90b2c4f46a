#pragma once
// Test support: render RIB text end to end (parser, builder, renderer) into
// a scratch directory and read the images back with OpenImageIO.

#include "umbra/render/renderer.h"
#include "umbra/ri/parser.h"
#include "umbra/scene/builder.h"

#include <OpenImageIO/imageio.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

namespace umbra::test {

/// A float image read back from a file.
struct Image {
    int width = 0, height = 0, channels = 0;
    std::vector<float> pixels;
    float at(int x, int y, int c) const { return pixels[(size_t(y) * width + x) * channels + c]; }
    double channelSum(int c) const {
        double s = 0;
        for (int y = 0; y < height; ++y)
            for (int x = 0; x < width; ++x) s += at(x, y, c);
        return s;
    }
};

/// Mean |a - b| over every channel of every pixel; huge when the sizes
/// differ, so a comparison of mismatched images cannot pass.
inline double meanAbsDiff(const Image& a, const Image& b) {
    if (a.pixels.size() != b.pixels.size() || a.pixels.empty()) return 1e9;
    double d = 0;
    for (size_t i = 0; i < a.pixels.size(); ++i) d += std::fabs(double(a.pixels[i]) - double(b.pixels[i]));
    return d / double(a.pixels.size());
}

/// Largest |a - b| over the first `channels` channels.
inline double maxAbsDiff(const Image& a, const Image& b, int channels) {
    if (a.width != b.width || a.height != b.height) return 1e9;
    double d = 0;
    for (int y = 0; y < a.height; ++y)
        for (int x = 0; x < a.width; ++x)
            for (int c = 0; c < channels; ++c) d = std::max(d, std::fabs(double(a.at(x, y, c)) - double(b.at(x, y, c))));
    return d;
}

inline bool readImage(const std::string& path, Image* out) {
    auto in = OIIO::ImageInput::open(path);
    if (!in) return false;
    const OIIO::ImageSpec& spec = in->spec();
    out->width = spec.width;
    out->height = spec.height;
    out->channels = spec.nchannels;
    out->pixels.resize(size_t(spec.width) * spec.height * spec.nchannels);
    bool ok = in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, out->pixels.data());
    in->close();
    return ok;
}

/// A scratch directory for one test, removed afterwards.
class ScratchDir {
public:
    explicit ScratchDir(const std::string& name) {
        m_path = std::filesystem::temp_directory_path() / ("umbra-test-" + name + "-" + std::to_string(::getpid()));
        std::filesystem::remove_all(m_path);
        std::filesystem::create_directories(m_path);
    }
    ~ScratchDir() { std::filesystem::remove_all(m_path); }
    std::string file(const std::string& name) const { return (m_path / name).string(); }

private:
    std::filesystem::path m_path;
};

/// Renders RIB text; returns the renderer's statistics. Errors are recorded
/// in `diag` (pass one with setRecord(true) to inspect them); `failedFrames`,
/// if given, receives the number of frames that failed. The settings are
/// the caller's, made quiet and given the project's shaders.
inline nlohmann::json renderRib(const std::string& rib, Diagnostics& diag, render::RenderSettings settings,
                                int* failedFrames = nullptr) {
    settings.quiet = true;
    settings.shaderPath = {std::string(UMBRA_SOURCE_DIR) + "/shaders_dsl"};
    render::Renderer renderer(settings, diag);
    scene::Builder builder(renderer, diag);
    renderer.prepare(builder, "test.rib");
    ri::parseString(rib, "test.rib", builder, diag);
    if (failedFrames) *failedFrames = renderer.failedFrames();
    return renderer.statistics();
}

inline nlohmann::json renderRib(const std::string& rib, Diagnostics& diag, int threads = 0, int bucketSize = 0,
                                int* failedFrames = nullptr) {
    render::RenderSettings settings;
    settings.threads = threads;
    settings.bucketSize = bucketSize;
    return renderRib(rib, diag, settings, failedFrames);
}

/// Renders RIB text whose Display writes `imagePath` and reads that image
/// back (an empty image, with a test failure, if there is none).
inline Image renderImage(const std::string& rib, const std::string& imagePath, Diagnostics& diag, int threads = 0,
                         int bucketSize = 0, int* failedFrames = nullptr) {
    renderRib(rib, diag, threads, bucketSize, failedFrames);
    Image img;
    EXPECT_TRUE(readImage(imagePath, &img)) << imagePath;
    return img;
}

}  // namespace umbra::test
