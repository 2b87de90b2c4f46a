// The texture makers: `umbra txmake` writes the same files as the Make*
// RIB requests (pixel for pixel and tag for tag; shadow maps byte for byte); MakeCubeFaceEnvironment's maps answer environment()
// lookups; errors name the file and leave no output behind.

#include "support/render_harness.h"

#include "umbra/render/make_files.h"
#include "umbra/shading/texture_backend.h"

#include <OpenImageIO/imageio.h>

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <sstream>

using namespace umbra;
using umbra::test::ScratchDir;

namespace {

/// Writes a float TIFF whose pixel (x, y) is `at(x, y)`.
void writeImage(const std::string& path, int w, int h, const std::function<Vec3(int, int)>& at) {
    auto out = OIIO::ImageOutput::create(path);
    ASSERT_TRUE(out);
    OIIO::ImageSpec spec(w, h, 3, OIIO::TypeDesc::FLOAT);
    ASSERT_TRUE(out->open(path, spec));
    std::vector<float> px(size_t(w) * size_t(h) * 3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            Vec3 c = at(x, y);
            float* p = &px[size_t((y * w + x) * 3)];
            p[0] = c.x, p[1] = c.y, p[2] = c.z;
        }
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, px.data()));
    out->close();
}

std::string readBytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

/// Why the textures `a` and `b` differ ("" if they do not): every MIP
/// level's pixels and metadata are compared. (Not their bytes: OpenImageIO
/// 2.4 leaves the padding of the smallest levels' tiles uninitialised.)
std::string textureDifference(const std::string& a, const std::string& b) {
    auto ia = OIIO::ImageInput::open(a), ib = OIIO::ImageInput::open(b);
    if (!ia || !ib) return "cannot open both files";
    for (int level = 0;; ++level) {
        OIIO::ImageSpec sa, sb;
        const bool ha = ia->seek_subimage(0, level, sa), hb = ib->seek_subimage(0, level, sb);
        if (ha != hb) return fmt::format("MIP level {} exists in one file only", level);
        if (!ha) return level > 0 ? "" : "no image";
        if (sa.serialize(OIIO::ImageSpec::SerialText) != sb.serialize(OIIO::ImageSpec::SerialText))
            return fmt::format("level {} metadata:\n{}\nvs\n{}", level, sa.serialize(OIIO::ImageSpec::SerialText),
                               sb.serialize(OIIO::ImageSpec::SerialText));
        std::vector<float> pa(sa.image_pixels() * size_t(sa.nchannels)), pb(pa.size());
        if (!ia->read_image(0, level, 0, sa.nchannels, OIIO::TypeDesc::FLOAT, pa.data()) ||
            !ib->read_image(0, level, 0, sb.nchannels, OIIO::TypeDesc::FLOAT, pb.data()))
            return fmt::format("cannot read level {}", level);
        if (pa != pb) return fmt::format("level {} pixels differ", level);
    }
}

/// Runs `umbra ARGS...`; returns the exit status and sets `messages` to
/// what it printed.
int runUmbra(const std::vector<std::string>& args, const std::string& logPath, std::string* messages = nullptr) {
    const pid_t pid = fork();
    if (pid == 0) {
        const int fd = open(logPath.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fd >= 0) {
            dup2(fd, 1);
            dup2(fd, 2);
        }
        std::vector<char*> argv{const_cast<char*>("umbra")};
        for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
        argv.push_back(nullptr);
        execv(UMBRA_APP, argv.data());
        _exit(127);
    }
    int status = 0;
    if (pid < 0 || waitpid(pid, &status, 0) != pid) return -1;
    if (messages) *messages = readBytes(logPath);
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

/// Renders `rib` (Make* requests only); true when no error was reported.
bool runRib(const std::string& rib) {
    Diagnostics diag;
    diag.setSink([](const Diagnostic&) {});
    int failed = 0;
    test::renderRib(rib, diag, 1, 0, &failed);
    return diag.errorCount() == 0 && failed == 0;
}

/// Six faces of distinct constant colours, px nx py ny pz nz.
const Vec3 kFaceColours[6] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 0}, {0, 1, 1}, {1, 0, 1}};
const char* kFaces[6] = {"px", "nx", "py", "ny", "pz", "nz"};

std::vector<std::string> writeConstantFaces(const ScratchDir& dir, int res) {
    std::vector<std::string> files;
    for (int f = 0; f < 6; ++f) {
        files.push_back(dir.file(std::string(kFaces[f]) + ".tif"));
        writeImage(files.back(), res, res, [&](int, int) { return kFaceColours[f] * 0.5f + Vec3(0.25f); });
    }
    return files;
}

std::string quoted(const std::vector<std::string>& files) {
    std::string out;
    for (const auto& f : files) out += "\"" + f + "\" ";
    return out;
}

}  // namespace

TEST(Txmake, TextureEqualsMakeTexture) {
    ScratchDir dir("txmake-texture");
    writeImage(dir.file("pic.tif"), 40, 24, [](int x, int y) { return Vec3(x / 40.0f, y / 24.0f, (x ^ y) & 1); });
    ASSERT_TRUE(runRib(fmt::format("MakeTexture \"{}\" \"{}\" \"periodic\" \"clamp\" \"box\" 1 1\n",
                                   dir.file("pic.tif"), dir.file("rib.tx"))));
    ASSERT_EQ(runUmbra({"txmake", "--swrap", "periodic", "--twrap", "clamp", "--filter", "box", "--width", "1",
                        dir.file("pic.tif"), dir.file("cmd.tx")},
                       dir.file("log")),
              0)
        << readBytes(dir.file("log"));
    EXPECT_EQ(textureDifference(dir.file("rib.tx"), dir.file("cmd.tx")), "");
}

TEST(Txmake, DefaultsAreBlackGaussianWidthTwo) {
    ScratchDir dir("txmake-defaults");
    writeImage(dir.file("pic.tif"), 16, 16, [](int x, int y) { return Vec3(x / 16.0f, y / 16.0f, 0.5f); });
    ASSERT_TRUE(runRib(fmt::format("MakeTexture \"{}\" \"{}\" \"black\" \"black\" \"gaussian\" 2 2\n",
                                   dir.file("pic.tif"), dir.file("rib.tx"))));
    ASSERT_EQ(runUmbra({"txmake", dir.file("pic.tif"), dir.file("cmd.tx")}, dir.file("log")), 0)
        << readBytes(dir.file("log"));
    EXPECT_EQ(textureDifference(dir.file("rib.tx"), dir.file("cmd.tx")), "");
}

TEST(Txmake, AnUnknownWrapModeMakesABlackWrappedTexture) {
    // RI Spec 3.2 knows periodic, clamp and black; Pixie and Aqsis make a
    // texture of any other ("mirror") and wrap it as black. So does umbra,
    // with a warning, where it made nothing and every lookup read 0.
    ScratchDir dir("txmake-mirror");
    writeImage(dir.file("pic.tif"), 16, 16, [](int x, int y) { return Vec3(x / 16.0f, y / 16.0f, 0.5f); });
    ASSERT_TRUE(runRib(fmt::format("MakeTexture \"{}\" \"{}\" \"mirror\" \"black\" \"gaussian\" 2 2\n",
                                   dir.file("pic.tif"), dir.file("mirror.tx"))));
    ASSERT_TRUE(runRib(fmt::format("MakeTexture \"{}\" \"{}\" \"black\" \"black\" \"gaussian\" 2 2\n",
                                   dir.file("pic.tif"), dir.file("black.tx"))));
    EXPECT_EQ(textureDifference(dir.file("mirror.tx"), dir.file("black.tx")), "");
}

TEST(Txmake, LatLongEqualsMakeLatLongEnvironment) {
    ScratchDir dir("txmake-latlong");
    writeImage(dir.file("env.tif"), 64, 32, [](int x, int y) { return Vec3(x / 64.0f, y / 32.0f, 0.25f); });
    ASSERT_TRUE(runRib(fmt::format("MakeLatLongEnvironment \"{}\" \"{}\" \"gaussian\" 2 2\n", dir.file("env.tif"),
                                   dir.file("rib.env"))));
    ASSERT_EQ(runUmbra({"txmake", "--envlatl", dir.file("env.tif"), dir.file("cmd.env")}, dir.file("log")), 0)
        << readBytes(dir.file("log"));
    EXPECT_EQ(textureDifference(dir.file("rib.env"), dir.file("cmd.env")), "");
}

TEST(Txmake, CubeFacesEqualMakeCubeFaceEnvironment) {
    ScratchDir dir("txmake-cube");
    std::vector<std::string> faces;
    for (int f = 0; f < 6; ++f) {
        faces.push_back(dir.file(std::string(kFaces[f]) + ".tif"));
        writeImage(faces.back(), 16, 16, [&](int x, int y) { return Vec3(f / 6.0f, x / 16.0f, y / 16.0f); });
    }
    ASSERT_TRUE(runRib(fmt::format("MakeCubeFaceEnvironment {} \"{}\" 95 \"box\" 1 1\n", quoted(faces),
                                   dir.file("rib.env"))));
    std::vector<std::string> args{"txmake", "--envcube"};
    args.insert(args.end(), faces.begin(), faces.end());
    args.insert(args.end(), {dir.file("cmd.env"), "--fov", "95", "--filter", "box", "--width", "1"});
    std::string log;
    ASSERT_EQ(runUmbra(args, dir.file("log"), &log), 0) << log;
    EXPECT_EQ(textureDifference(dir.file("rib.env"), dir.file("cmd.env")), "");
}

TEST(Txmake, ShadowEqualsMakeShadow) {
    ScratchDir dir("txmake-shadow");
    Diagnostics diag;
    test::renderRib(fmt::format(R"(Display "{}" "zfile" "z"
Format 32 32 1
Projection "perspective" "fov" 40
WorldBegin
  Translate 0 0 5
  Sphere 1 -1 1 360
WorldEnd
MakeShadow "{}" "{}"
)", dir.file("d.z"), dir.file("d.z"), dir.file("rib.shd")),
                    diag);
    ASSERT_EQ(diag.errorCount(), 0);
    ASSERT_EQ(runUmbra({"txmake", "--shadow", dir.file("d.z"), dir.file("cmd.shd")}, dir.file("log")), 0)
        << readBytes(dir.file("log"));
    const std::string rib = readBytes(dir.file("rib.shd"));
    ASSERT_GT(rib.size(), 100u);
    EXPECT_TRUE(rib == readBytes(dir.file("cmd.shd")));
}

TEST(Txmake, ShadowFromADepthTiffEqualsShadowFromAZfile) {
    // The RenderMan books render the depth for MakeShadow as `Display
    // "zbuffer.tiff" "file" "z"`; MakeShadow takes that TIFF (RI Spec 3.2:
    // "a file containing a depth image"; Pixie does too) and makes the map
    // the zfile of the same frame makes, byte for byte. It refused it.
    ScratchDir dir("makeshadow-tiff");
    Diagnostics diag;
    diag.setRecord(true);
    test::renderRib(fmt::format(R"(Display "{}" "zfile" "z"
Display "+{}" "file" "z"
Format 40 30 1
Projection "perspective" "fov" 40
WorldBegin
  Translate 0 0 5
  Sphere 1 -1 1 360
  Translate 0.5 0.3 2
  Cylinder 0.7 -1 1 300
WorldEnd
MakeShadow "{}" "{}"
MakeShadow "{}" "{}"
)", dir.file("d.z"), dir.file("d.tif"), dir.file("d.z"), dir.file("z.shd"), dir.file("d.tif"), dir.file("tif.shd")),
                    diag);
    ASSERT_EQ(diag.errorCount(), 0) << (diag.recorded().empty() ? "" : diag.recorded()[0].message);
    const std::string fromZ = readBytes(dir.file("z.shd"));
    ASSERT_GT(fromZ.size(), 100u);
    EXPECT_TRUE(fromZ == readBytes(dir.file("tif.shd")));
}

TEST(Txmake, ErrorsNameTheFileAndWriteNothing) {
    ScratchDir dir("txmake-errors");
    std::string log;
    EXPECT_EQ(runUmbra({"txmake", dir.file("absent.tif"), dir.file("out.tx")}, dir.file("log"), &log), 1);
    EXPECT_NE(log.find("cannot open \"" + dir.file("absent.tif") + "\""), std::string::npos) << log;
    EXPECT_FALSE(std::filesystem::exists(dir.file("out.tx")));

    writeImage(dir.file("pic.tif"), 8, 8, [](int, int) { return Vec3(1); });
    EXPECT_EQ(runUmbra({"txmake", "--filter", "blurry", dir.file("pic.tif"), dir.file("out.tx")}, dir.file("log"),
                       &log),
              1);
    EXPECT_NE(log.find("unknown filter \"blurry\" (expected one of box,"), std::string::npos) << log;
    EXPECT_FALSE(std::filesystem::exists(dir.file("out.tx")));

    // Not an image at all.
    std::ofstream(dir.file("junk.tif")) << "not a picture";
    EXPECT_EQ(runUmbra({"txmake", dir.file("junk.tif"), dir.file("out.tx")}, dir.file("log"), &log), 1);
    EXPECT_NE(log.find(dir.file("junk.tif")), std::string::npos) << log;
    EXPECT_FALSE(std::filesystem::exists(dir.file("out.tx")));

    // A cube face of the wrong size, named with its role.
    std::vector<std::string> faces = writeConstantFaces(dir, 8);
    writeImage(faces[3], 8, 4, [](int, int) { return Vec3(1); });
    std::vector<std::string> args{"txmake", "--envcube"};
    args.insert(args.end(), faces.begin(), faces.end());
    args.push_back(dir.file("out.env"));
    EXPECT_EQ(runUmbra(args, dir.file("log"), &log), 1);
    EXPECT_NE(log.find("the ny face \"" + faces[3] + "\" is 8x4 pixels"), std::string::npos) << log;
    EXPECT_FALSE(std::filesystem::exists(dir.file("out.env")));

    // Six faces are needed.
    EXPECT_EQ(runUmbra({"txmake", "--envcube", faces[0], faces[1], dir.file("out.env")}, dir.file("log"), &log), 1);
    EXPECT_NE(log.find("expected six cube faces (px nx py ny pz nz) and an output file, got 3 file names"),
              std::string::npos)
        << log;

    // Nothing half-written is left beside the output either.
    for (const auto& e : std::filesystem::directory_iterator(dir.file("")))
        EXPECT_EQ(e.path().string().find("umbra-tmp"), std::string::npos) << e.path();
}

TEST(MakeCubeFaceEnvironment, AxisLookupsReturnEachFaceColour) {
    // Six constant faces: environment() along +x, -x, +y, -y, +z, -z must
    // return exactly the colour of the face that axis looks through.
    ScratchDir dir("cube-lookup");
    for (float fov : {90.0f, 100.0f}) {
        std::vector<std::string> faces = writeConstantFaces(dir, 16);
        scene::MakeRecord make;
        make.request = "MakeCubeFaceEnvironment";
        make.inputs = faces;
        make.output = dir.file(fmt::format("cube{}.env", fov));
        make.stringArgs = {"gaussian"};
        make.floatArgs = {fov, 2, 2};
        Diagnostics diag;
        ASSERT_TRUE(render::makeFile(make, diag));
        std::string error;
        shading::TextureBackend* ts = shading::textureBackend(&error);
        ASSERT_TRUE(ts) << error;
        const Vec3 axes[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
        for (int f = 0; f < 6; ++f) {
            float out[3] = {-1, -1, -1};
            ASSERT_TRUE(ts->environment(make.output, shading::TextureOptions{}, axes[f], Vec3(0), Vec3(0), 3, out));
            const Vec3 want = kFaceColours[f] * 0.5f + Vec3(0.25f);
            EXPECT_NEAR(out[0], want.x, 1e-5f) << kFaces[f] << " fov " << fov;
            EXPECT_NEAR(out[1], want.y, 1e-5f) << kFaces[f] << " fov " << fov;
            EXPECT_NEAR(out[2], want.z, 1e-5f) << kFaces[f] << " fov " << fov;
        }
    }
}

TEST(MakeCubeFaceEnvironment, FacesAreTheViewsAlongEachAxis) {
    // Each face is what a camera at the centre sees looking along its axis
    // (RenderMan's left-handed views: px looks along +x with +y up, so its
    // image's right is -z; py has -z up; nz has -x to the right). A face
    // whose colour is its own (s, t) shows where a direction lands in it.
    ScratchDir dir("cube-orientation");
    const int res = 64;
    std::vector<std::string> faces = writeConstantFaces(dir, res);
    for (int f : {0, 2, 5})
        writeImage(faces[size_t(f)], res, res,
                   [&](int x, int y) { return Vec3((x + 0.5f) / res, (y + 0.5f) / res, 0); });
    scene::MakeRecord make;
    make.request = "MakeCubeFaceEnvironment";
    make.inputs = faces;
    make.output = dir.file("cube.env");
    make.stringArgs = {"box"};
    make.floatArgs = {90, 1, 1};
    Diagnostics diag;
    ASSERT_TRUE(render::makeFile(make, diag));
    std::string error;
    shading::TextureBackend* ts = shading::textureBackend(&error);
    ASSERT_TRUE(ts) << error;
    struct Case {
        Vec3 dir;
        float s, t;  // where it lands on its face
    };
    // s = (1 + right.d / forward.d) / 2, t = (1 - up.d / forward.d) / 2.
    const Case cases[] = {
        {{1, 0.3f, -0.2f}, 0.6f, 0.35f},  // px: right -z, up +y
        {{0.2f, 1, 0.3f}, 0.6f, 0.65f},   // py: right +x, up -z
        {{0.2f, 0.3f, -1}, 0.4f, 0.35f},  // nz: right -x, up +y
    };
    for (const Case& c : cases) {
        float out[3] = {-1, -1, -1};
        ASSERT_TRUE(ts->environment(make.output, shading::TextureOptions{}, c.dir, Vec3(0), Vec3(0), 3, out));
        EXPECT_NEAR(out[0], c.s, 0.01f) << c.dir.x << " " << c.dir.y << " " << c.dir.z;
        EXPECT_NEAR(out[1], c.t, 0.01f) << c.dir.x << " " << c.dir.y << " " << c.dir.z;
    }
}
