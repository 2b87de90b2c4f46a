// Where a render looks for shaders: the current directory, then the RIB
// file's directory, then the defaults ('@'), with '&' in Option
// "searchpath" standing for the path so far.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>

using namespace umbra;
using umbra::test::Image;
using umbra::test::ScratchDir;

namespace {

struct Collect : scene::SceneSink {
    void renderWorld(const scene::WorldRecord&) override {}
    void make(const scene::MakeRecord&) override {}
};

/// A scene whose one sphere fills the centre with `shader`, into `image`.
std::string sphereScene(const std::string& image, const std::string& shader, const std::string& searchpath = "") {
    return fmt::format(R"({}
Format 16 16 1
Display "{}" "openexr" "rgba" "string type" "float"
Projection "perspective" "fov" 40
WorldBegin
  Translate 0 0 5
  Surface "{}"
  Sphere 1 -1 1 360
WorldEnd
)", searchpath, image, shader);
}

/// Changes the current directory for one scope.
class ScopedCwd {
public:
    explicit ScopedCwd(const std::string& dir) : m_old(std::filesystem::current_path()) {
        std::filesystem::current_path(dir);
    }
    ~ScopedCwd() { std::filesystem::current_path(m_old); }

private:
    std::filesystem::path m_old;
};

void writeFile(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

/// Renders `rib` (written to `ribPath`) as `umbra render` does; the centre
/// pixel's colour.
Vec3 renderCentre(const std::string& ribPath, const std::string& rib, const std::string& image, int* errors) {
    writeFile(ribPath, rib);
    Diagnostics diag;
    diag.setSink([](const Diagnostic&) {});
    render::RenderSettings settings;
    settings.quiet = true;
    settings.threads = 1;
    render::renderFiles({ribPath}, settings, "", diag);
    *errors = diag.errorCount();
    Image img;
    if (!test::readImage(image, &img)) return Vec3(-1);
    return Vec3(img.at(8, 8, 0), img.at(8, 8, 1), img.at(8, 8, 2));
}

}  // namespace

TEST(SearchPath, PrepareSeedsCurrentDirRibDirThenDefault) {
    Diagnostics diag;
    render::RenderSettings settings;
    settings.shaderPath = {"/std/a", "/std/b"};
    settings.texturePath = {"/tex"};
    render::Renderer renderer(settings, diag);
    Collect sink;
    scene::Builder builder(sink, diag);
    renderer.prepare(builder, "/scenes/shot/scene.rib");
    EXPECT_EQ(builder.options().searchPaths.at("shader"), ".:/scenes/shot:/std/a:/std/b");
    EXPECT_EQ(builder.options().searchPaths.at("texture"), ".:/scenes/shot:/tex");
    ri::Parser p(builder, diag);
    p.parseString("Option \"searchpath\" \"shader\" \"/mine:&\"\nOption \"searchpath\" \"texture\" \"@:/late\"",
                  "/scenes/shot/scene.rib");
    EXPECT_EQ(builder.options().searchPaths.at("shader"), "/mine:.:/scenes/shot:/std/a:/std/b");
    // '@' holds the current directory, as Aqsis's and Pixie's defaults do.
    EXPECT_EQ(builder.options().searchPaths.at("texture"), ".:/tex:/late");

    scene::Builder relative(sink, diag);
    renderer.prepare(relative, "scene.rib");
    EXPECT_EQ(relative.options().searchPaths.at("shader"), ".:/std/a:/std/b");
}

TEST(SearchPath, ShaderBesideTheRibFileIsFoundFromElsewhere) {
    ScratchDir dir("searchpath-ribdir");
    std::filesystem::create_directories(dir.file("scene"));
    std::filesystem::create_directories(dir.file("elsewhere"));
    writeFile(dir.file("scene/red.sl"), "surface red() { Ci = color(1, 0, 0); Oi = 1; }\n");
    ScopedCwd cwd(dir.file("elsewhere"));
    int errors = 0;
    Vec3 c = renderCentre(dir.file("scene/s.rib"), sphereScene(dir.file("out.exr"), "red"), dir.file("out.exr"),
                          &errors);
    EXPECT_EQ(errors, 0);
    EXPECT_NEAR(c.x, 1, 1e-4f);
    EXPECT_NEAR(c.y, 0, 1e-4f);
}

TEST(SearchPath, CurrentDirectoryComesBeforeTheRibDirAndTheDefault) {
    // A "constant" shader in the current directory hides the standard one
    // and one beside the RIB file, as in Aqsis and Pixie.
    ScratchDir dir("searchpath-cwd");
    std::filesystem::create_directories(dir.file("scene"));
    std::filesystem::create_directories(dir.file("work"));
    writeFile(dir.file("work/constant.sl"), "surface constant() { Ci = color(0, 1, 0); Oi = 1; }\n");
    writeFile(dir.file("scene/constant.sl"), "surface constant() { Ci = color(0, 0, 1); Oi = 1; }\n");
    ScopedCwd cwd(dir.file("work"));
    int errors = 0;
    Vec3 c = renderCentre(dir.file("scene/s.rib"), sphereScene(dir.file("out.exr"), "constant"), dir.file("out.exr"),
                          &errors);
    EXPECT_EQ(errors, 0);
    EXPECT_NEAR(c.y, 1, 1e-4f);
    EXPECT_NEAR(c.z, 0, 1e-4f);
}

TEST(SearchPath, AtAloneFindsOnlyTheStandardShaders) {
    // "@" drops the current directory and the RIB's: the standard
    // constant shader (Ci = Cs, white) wins over the one beside the RIB.
    ScratchDir dir("searchpath-at");
    writeFile(dir.file("constant.sl"), "surface constant() { Ci = color(0, 0, 1); Oi = 1; }\n");
    int errors = 0;
    Vec3 c = renderCentre(dir.file("s.rib"),
                          sphereScene(dir.file("out.exr"), "constant", "Option \"searchpath\" \"shader\" \"@\""),
                          dir.file("out.exr"), &errors);
    EXPECT_EQ(errors, 0);
    EXPECT_NEAR(c.x, 1, 1e-4f);
    EXPECT_NEAR(c.z, 1, 1e-4f);
}

TEST(SearchPath, WithoutAmpersandTheStandardShadersAreNotSearched) {
    ScratchDir dir("searchpath-replace");
    std::filesystem::create_directories(dir.file("mine"));
    int errors = 0;
    renderCentre(dir.file("s.rib"),
                 sphereScene(dir.file("out.exr"), "plastic",
                             fmt::format("Option \"searchpath\" \"shader\" \"{}\"", dir.file("mine"))),
                 dir.file("out.exr"), &errors);
    EXPECT_GE(errors, 1);
}
