// Bias-free shadows on scenes written as users write them: a light-view RIB
// with `Hider "hidden" "depthfilter"`, `Display "...shd" "shadow" "z"`,
// casters `Sides 1`, the ground an ordinary two-sided bilinear Patch, an
// orthographic camera straight down, bias 0, 256^2 maps and nothing else
// set; and the same with automatic maps, and with mirrored cameras.
//
// Scored against shadows known in closed form (ray-sphere and ray-box
// tests written here), away from a 3-pixel band around the exact shadow
// edges: acne = a lit point the lookup darkens by more than half, leak =
// a shadowed point it lights by more than half.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>

using namespace umbra;
using umbra::test::Image;
using umbra::test::ScratchDir;

namespace {

constexpr int kImage = 192;     // camera pixels across the floor
constexpr float kHalf = 3.0f;   // the floor is [-3, 3]^2 at y = 0
constexpr int kMap = 256;

struct Box {
    Vec3 lo, hi;
};

/// A scene: casters, the direction towards the distant light.
struct Scene {
    const char* name;
    Vec3 towardLight;
    std::optional<std::array<float, 4>> sphere;  // centre x y z, radius
    std::vector<Box> boxes;
    /// A capped cylinder lying on the floor along z: centre x, radius, z0, z1.
    std::optional<std::array<float, 4>> cylinder = std::nullopt;
    /// Score the floor only: the term shader lights every side, so a
    /// solid's far side near its terminator is the map's to shadow, and
    /// a second-depth map stores that side itself (Wang & Molnar leave it
    /// to the illumination model).
    bool floorOnly = false;
};

Scene sphereScene() {
    return {"sphere", normalize(Vec3(0.35f, 1.0f, 0.2f)), std::array<float, 4>{0, 1, 0, 1}, {}};
}

Scene boxesScene() {
    // Light 16 degrees above the floor. Four thin legs standing on it, a
    // thin slab floating above, a cube resting on it.
    const float e = 16.0f * 3.14159265f / 180;
    Scene s{"boxes", normalize(Vec3(std::cos(e) * 0.8f, std::sin(e), std::cos(e) * 0.6f)), std::nullopt, {}};
    for (float x : {-2.2f, -1.6f})
        for (float z : {1.0f, 1.6f}) s.boxes.push_back({{x, 0, z}, {x + 0.08f, 0.6f, z + 0.08f}});
    s.boxes.push_back({{-0.5f, 0.5f, -2.4f}, {0.9f, 0.56f, -1.6f}});  // the slab
    s.boxes.push_back({{0.6f, 0, 0.6f}, {1.2f, 0.6f, 1.2f}});         // the cube
    return s;
}

Scene cylinderScene() {
    // One quadric whose rim, seen from the light, lies inside its grids:
    // a second-depth map must store the far side there, not the floor.
    Scene s{"cylinder", normalize(Vec3(0.7f, 0.8f, 0.45f)), std::nullopt, {}};
    s.cylinder = std::array<float, 4>{0.6f, 0.8f, -1.8f, 1.8f};
    s.floorOnly = true;
    return s;
}

/// Ray (o + t d, t > eps) against a box: the nearest t, or a negative value.
float hitBox(const Box& b, const Vec3& o, const Vec3& d) {
    float t0 = 1e-4f, t1 = 1e30f;
    for (int k = 0; k < 3; ++k) {
        float ok = k == 0 ? o.x : (k == 1 ? o.y : o.z), dk = k == 0 ? d.x : (k == 1 ? d.y : d.z);
        float lo = k == 0 ? b.lo.x : (k == 1 ? b.lo.y : b.lo.z), hi = k == 0 ? b.hi.x : (k == 1 ? b.hi.y : b.hi.z);
        if (std::fabs(dk) < 1e-12f) {
            if (ok < lo || ok > hi) return -1;
            continue;
        }
        float a = (lo - ok) / dk, c = (hi - ok) / dk;
        if (a > c) std::swap(a, c);
        t0 = std::max(t0, a);
        t1 = std::min(t1, c);
        if (t0 > t1) return -1;
    }
    return t0;
}

float hitSphere(const std::array<float, 4>& s, const Vec3& o, const Vec3& d) {
    Vec3 c(s[0], s[1], s[2]);
    Vec3 oc = o - c;
    float b = dot(oc, d), cc = dot(oc, oc) - s[3] * s[3];
    float disc = b * b - cc;
    if (disc < 0) return -1;
    float t = -b - std::sqrt(disc);
    if (t > 1e-4f) return t;
    t = -b + std::sqrt(disc);
    return t > 1e-4f ? t : -1;
}

/// The capped cylinder (axis along z through (cx, r)): the nearest t and
/// the normal there, or a negative t.
float hitCylinder(const std::array<float, 4>& c, const Vec3& o, const Vec3& d, Vec3* normal) {
    const float cx = c[0], r = c[1], z0 = c[2], z1 = c[3];
    float best = -1;
    auto take = [&](float t, Vec3 n) {
        if (t > 1e-4f && (best < 0 || t < best)) {
            best = t;
            *normal = n;
        }
    };
    const float ox = o.x - cx, oy = o.y - r;
    const float a = d.x * d.x + d.y * d.y, b = ox * d.x + oy * d.y, cc = ox * ox + oy * oy - r * r;
    if (a > 1e-12f && b * b - a * cc >= 0)
        for (float sign : {-1.0f, 1.0f}) {
            const float t = (-b + sign * std::sqrt(b * b - a * cc)) / a;
            const Vec3 p = o + d * t;
            if (p.z >= z0 && p.z <= z1) take(t, normalize(Vec3(p.x - cx, p.y - r, 0)));
        }
    if (std::fabs(d.z) > 1e-12f)
        for (float zc : {z0, z1}) {
            const float t = (zc - o.z) / d.z;
            const Vec3 p = o + d * t;
            if ((p.x - cx) * (p.x - cx) + (p.y - r) * (p.y - r) <= r * r) take(t, Vec3(0, 0, zc == z0 ? -1.0f : 1.0f));
        }
    return best;
}

/// What the camera straight down sees at floor coordinates (x, z), and
/// whether it is lit: 0 floor, 1 + k caster k; lit in closed form.
struct Truth {
    int surface = 0;
    bool lit = true;
};

Truth truthAt(const Scene& s, float x, float z) {
    const Vec3 down(0, -1, 0), from(x, 100, z);
    float best = 100.0f;  // the floor, at t = 100
    int surface = 0;
    Vec3 n(0, 1, 0);
    if (s.sphere) {
        float t = hitSphere(*s.sphere, from, down);
        if (t > 0 && t < best) {
            best = t;
            surface = 1;
            Vec3 p = from + down * t;
            n = normalize(p - Vec3((*s.sphere)[0], (*s.sphere)[1], (*s.sphere)[2]));
        }
    }
    if (s.cylinder) {
        Vec3 cn;
        float t = hitCylinder(*s.cylinder, from, down, &cn);
        if (t > 0 && t < best) {
            best = t;
            surface = 1;
            n = cn;
        }
    }
    for (size_t k = 0; k < s.boxes.size(); ++k) {
        float t = hitBox(s.boxes[k], from, down);
        if (t > 0 && t < best) {
            best = t;
            surface = int(k) + 2;
            n = Vec3(0, 1, 0);  // seen from above: a top face
        }
    }
    Vec3 p = from + down * best;
    Truth out;
    out.surface = surface;
    if (dot(n, s.towardLight) <= 0) {
        out.lit = false;
        return out;
    }
    Vec3 q = p + n * 1e-4f;
    if (s.sphere && hitSphere(*s.sphere, q, s.towardLight) > 0) out.lit = false;
    for (const Box& b : s.boxes)
        if (hitBox(b, q, s.towardLight) > 0) out.lit = false;
    Vec3 unused;
    if (s.cylinder && hitCylinder(*s.cylinder, q, s.towardLight, &unused) > 0) out.lit = false;
    return out;
}

std::string casters(const Scene& s) {
    std::string out = "Sides 1\n";
    if (s.sphere)
        out += fmt::format("AttributeBegin Translate {} {} {} Sphere {} {} {} 360 AttributeEnd\n", (*s.sphere)[0],
                           (*s.sphere)[1], (*s.sphere)[2], (*s.sphere)[3], -(*s.sphere)[3], (*s.sphere)[3]);
    if (s.cylinder) {
        const auto& c = *s.cylinder;
        out += fmt::format("AttributeBegin Translate {0} {1} {2} Cylinder {1} 0 {3} 360 "
                           "AttributeBegin Translate 0 0 {3} Disk 0 {1} 360 AttributeEnd "
                           "Rotate 180 1 0 0 Disk 0 {1} 360 AttributeEnd\n",
                           c[0], c[1], c[2], c[3] - c[2]);
    }
    for (const Box& b : s.boxes) {
        // Six faces, each wound clockwise seen from outside (RenderMan's
        // outward normal in a left-handed world).
        const float x0 = b.lo.x, y0 = b.lo.y, z0 = b.lo.z, x1 = b.hi.x, y1 = b.hi.y, z1 = b.hi.z;
        out += fmt::format(
            "PointsPolygons [4 4 4 4 4 4] [0 1 2 3  7 6 5 4  0 4 5 1  1 5 6 2  2 6 7 3  3 7 4 0] \"P\" "
            "[{0} {1} {2}  {0} {4} {2}  {3} {4} {2}  {3} {1} {2}  {0} {1} {5}  {0} {4} {5}  {3} {4} {5}  {3} {1} {5}]\n",
            x0, y0, z0, x1, y1, z1);
    }
    return out;
}

const char* kFloor = "Sides 2\nPatch \"bilinear\" \"P\" [-3 0 -3  3 0 -3  -3 0 3  3 0 3]\n";

/// The light's camera: orthographic, looking along -towardLight from 20
/// away, covering the floor; a rotation with rows X, Y, Z (camera axes in
/// world space, X = Y x Z so it keeps handedness).
std::string lightCamera(const Scene& s, bool mirrored) {
    const Vec3 Z = -s.towardLight;
    const Vec3 X = normalize(cross(Vec3(0, 0, 1), Z));
    const Vec3 Y = cross(Z, X);
    // RIB matrices are written for row vectors: the rotation's transpose.
    return fmt::format("Projection \"orthographic\"\nScreenWindow -4.5 4.5 -4.5 4.5\n{}Translate 0 0 20\n"
                       "ConcatTransform [{} {} {} 0  {} {} {} 0  {} {} {} 0  0 0 0 1]\n",
                       mirrored ? "Scale -1 1 1\n" : "", X.x, Y.x, Z.x, X.y, Y.y, Z.y, X.z, Y.z, Z.z);
}

std::string downCamera(bool mirrored) {
    // Camera +z is world -y; camera +y is world +z; x stays x (or flops).
    return fmt::format("Projection \"orthographic\"\nScreenWindow -3 3 -3 3\n{}Rotate -90 1 0 0\nTranslate 0 -10 0\n",
                       mirrored ? "Scale -1 1 1\n" : "");
}

const char* kDistantShader = R"(
light qdist(point from = point "shader" (0, 0, 0); point to = point "shader" (0, 0, 1);
           string shadowname = ""; float samples = 16, bias = 0;)
{
    solar(to - from, 0.0) {
        Cl = 1;
        if (shadowname != "")
            Cl = 1 - shadow(shadowname, Ps, "samples", samples, "bias", bias);
    }
}
)";
const char* kTermShader = "surface term() { Ci = 0; illuminance(P) { Ci += Cl; } Oi = 1; }\n";

struct Score {
    double acne = 0, leak = 0;
    int scored = 0;
};

/// Renders the scene's camera view with a shadow map (two-pass: `map` is
/// the .shd written by a light-view RIB; automatic: map "auto"), and
/// scores it against the closed form.
Score renderAndScore(const ScratchDir& dir, const Scene& s, const std::string& filter, bool twoPass,
                     bool mirroredCamera, bool mirroredLight, float bias = 0) {
    std::ofstream(dir.file("qdist.sl")) << kDistantShader;
    std::ofstream(dir.file("term.sl")) << kTermShader;
    const std::string search = fmt::format("Option \"searchpath\" \"shader\" [\"{}:&\"]\n", dir.file(""));
    std::string map = "auto";
    Diagnostics diag;
    diag.setQuiet(true);
    if (twoPass) {
        map = dir.file(fmt::format("{}-{}.shd", s.name, filter));
        std::string lightRib = search + fmt::format("Format {0} {0} 1\nHider \"hidden\" \"depthfilter\" \"{1}\"\n"
                                                    "Display \"{2}\" \"shadow\" \"z\"\n{3}WorldBegin\n{4}{5}WorldEnd\n",
                                                    kMap, filter, map, lightCamera(s, mirroredLight), casters(s),
                                                    kFloor);
        test::renderRib(lightRib, diag);
    }
    const std::string image = dir.file("camera.tif");
    std::string autoOptions = twoPass ? std::string()
                                      : fmt::format("Option \"umbra\" \"shadowmapsize\" [{}]\nOption \"umbra\" "
                                                    "\"depthfilter\" [\"{}\"]\n",
                                                    kMap, filter);
    std::string rib = search + autoOptions +
                      fmt::format("Format {0} {0} 1\nPixelSamples 2 2\nPixelFilter \"box\" 1 1\n"
                                  "Display \"{1}\" \"file\" \"rgb\"\n{2}WorldBegin\n"
                                  "LightSource \"qdist\" 1 \"from\" [{3} {4} {5}] \"to\" [0 0 0] \"shadowname\" [\"{6}\"] "
                                  "\"bias\" [{9}]\n"
                                  "Surface \"term\"\n{7}{8}WorldEnd\n",
                                  kImage, image, downCamera(mirroredCamera), s.towardLight.x, s.towardLight.y,
                                  s.towardLight.z, map, casters(s), kFloor, bias);
    test::renderRib(rib, diag);
    EXPECT_EQ(diag.errorCount(), 0);
    Image img;
    EXPECT_TRUE(test::readImage(image, &img));
    Score score;
    if (img.width != kImage) return score;

    // Closed form at every pixel centre; a pixel is scored when all within
    // 3 pixels agree on the surface and on lit-or-not.
    std::vector<Truth> truth(size_t(kImage) * kImage);
    auto world = [](int px, int py, float* x, float* z) {
        *x = -kHalf + (px + 0.5f) * (2 * kHalf / kImage);
        *z = kHalf - (py + 0.5f) * (2 * kHalf / kImage);
    };
    for (int py = 0; py < kImage; ++py)
        for (int px = 0; px < kImage; ++px) {
            float x, z;
            world(px, py, &x, &z);
            truth[size_t(py) * kImage + px] = truthAt(s, x, z);
        }
    int acne = 0, leak = 0;
    for (int py = 3; py < kImage - 3; ++py)
        for (int px = 3; px < kImage - 3; ++px) {
            const Truth& t = truth[size_t(py) * kImage + px];
            bool uniform = true;
            for (int dy = -3; dy <= 3 && uniform; ++dy)
                for (int dx = -3; dx <= 3 && uniform; ++dx) {
                    const Truth& u = truth[size_t(py + dy) * kImage + px + dx];
                    uniform = u.surface == t.surface && u.lit == t.lit;
                }
            if (!uniform || (s.floorOnly && t.surface != 0)) continue;
            ++score.scored;
            // The mirrored camera flops the picture.
            float v = img.at(mirroredCamera ? kImage - 1 - px : px, py, 0);
            if (t.lit && v < 0.5f) ++acne;
            if (!t.lit && v > 0.5f) ++leak;
        }
    score.acne = 100.0 * acne / std::max(1, score.scored);
    score.leak = 100.0 * leak / std::max(1, score.scored);
    return score;
}

}  // namespace

TEST(OpenFloor, BiasFreeFiltersWithDefaultSettings) {
    ScratchDir dir("open-floor");
    for (const Scene& s : {sphereScene(), boxesScene()})
        for (const char* filter : {"second", "midpoint", "dual"})
            for (bool twoPass : {true, false})
                for (bool mirrored : {false, true}) {
                    Score sc = renderAndScore(dir, s, filter, twoPass, mirrored, mirrored);
                    std::printf("%-7s %-9s %-9s %-9s acne %6.3f%%  leak %6.3f%%  (%d px)\n", s.name, filter,
                                twoPass ? "two-pass" : "auto", mirrored ? "mirrored" : "plain", sc.acne, sc.leak,
                                sc.scored);
                    EXPECT_GT(sc.scored, kImage * kImage / 3);
                    EXPECT_EQ(sc.acne, 0.0) << s.name << " " << filter << (twoPass ? " two-pass" : " auto")
                                            << (mirrored ? " mirrored" : "");
                    EXPECT_LE(sc.leak, 0.2) << s.name << " " << filter << (twoPass ? " two-pass" : " auto")
                                            << (mirrored ? " mirrored" : "");
                }
}

// A curved solid's rim, seen from the light, often lies inside one grid
// (here the wall of a lying cylinder): the depth pass once kept one layer
// per grid, so texels through the rim stored the floor as their second
// depth and the floor beside the shadow's outline was lit (1.4% of the
// shadow-quality study's torus_cylinder scene at 256^2).
TEST(OpenFloor, SecondDepthKeepsTheFarSideOfARimInsideOneGrid) {
    ScratchDir dir("open-floor-rim");
    const Scene s = cylinderScene();
    for (const char* filter : {"second", "midpoint", "dual"})
        for (bool twoPass : {true, false}) {
            Score sc = renderAndScore(dir, s, filter, twoPass, false, false);
            std::printf("%-8s %-9s %-9s acne %6.3f%%  leak %6.3f%%  (%d px)\n", s.name, filter,
                        twoPass ? "two-pass" : "auto", sc.acne, sc.leak, sc.scored);
            EXPECT_GT(sc.scored, kImage * kImage / 3);
            EXPECT_EQ(sc.acne, 0.0) << filter << (twoPass ? " two-pass" : " auto");
            EXPECT_LE(sc.leak, 0.2) << filter << (twoPass ? " two-pass" : " auto");
        }
}

// The issue's baseline: `min` (Reeves' PCF) on the same scenes, at the
// constant bias of a sweep that scores best, reported beside the
// bias-free filters. (A call's bias of 0 means the default, PRMan's 0.225,
// so the sweep starts above it.) A constant bias only moves every
// comparison the same way (a sample is shadowed when z - bias > stored z),
// so raising it can only light points: acne never grows and leak never
// shrinks along the sweep; a bias applied with the wrong sign or scale
// breaks that. Under the light 16 degrees up, the floor's depth changes by
// about 0.08 across a texel of the 256^2 map, so a bias far below that
// leaves the floor shadowing itself (Reeves' Figure 9).
TEST(OpenFloor, MinIsReportedAtItsBestConstantBias) {
    ScratchDir dir("open-floor-min");
    const float biases[] = {0.005f, 0.01f, 0.02f, 0.05f, 0.1f, 0.2f, 0.3f};
    for (const Scene& s : {sphereScene(), boxesScene()})
        for (bool twoPass : {true, false}) {
            Score best;
            float bestBias = 0;
            std::optional<Score> previous;
            for (float bias : biases) {
                Score sc = renderAndScore(dir, s, "min", twoPass, false, false, bias);
                std::printf("%-7s min %-9s bias %-5g acne %6.3f%%  leak %6.3f%%  (%d px)\n", s.name,
                            twoPass ? "two-pass" : "auto", bias, sc.acne, sc.leak, sc.scored);
                EXPECT_GT(sc.scored, kImage * kImage / 3);
                if (previous) {
                    EXPECT_LE(sc.acne, previous->acne) << s.name << " bias " << bias;
                    EXPECT_GE(sc.leak, previous->leak) << s.name << " bias " << bias;
                } else if (std::string(s.name) == "boxes") {
                    EXPECT_GT(sc.acne, 10.0) << "bias " << bias;
                }
                if (!previous || sc.acne + sc.leak < best.acne + best.leak) {
                    best = sc;
                    bestBias = bias;
                }
                previous = sc;
            }
            std::printf("%-7s min %-9s best bias %g: acne %.3f%%  leak %.3f%%\n", s.name,
                        twoPass ? "two-pass" : "auto", bestBias, best.acne, best.leak);
        }
}
