// Orientation and handedness (RI spec 3.2 §4.2), as exporters write scenes:
// mirrored cameras (`Scale 1 1 -1`, `Scale -1 1 1`), `Orientation "rh"`
// inside the world, ReverseOrientation, one- and two-sided surfaces.
//
// The independent answers: each family's outward side as RenderMan defines
// it (the same in Pixie 2.2.6 and Aqsis 1.8.4: tests/fidelity/README.md),
// the spec's rule for when a primitive is inside out, the flopped picture
// of a flopping camera, and the plain scene a mirrored camera describes.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <fstream>

using namespace umbra;
using umbra::test::Image;
using umbra::test::maxAbsDiff;
using umbra::test::meanAbsDiff;
using umbra::test::ScratchDir;

namespace {

constexpr int kWidth = 480, kHeight = 120;
constexpr float kDistance = 12, kHalfFov = 15;  // degrees

/// One primitive family, placed at (x, y) in a row facing the camera, and
/// whether its outward side (dPdu x dPdv in a left-handed space, or the
/// spec's closed form) faces the camera there.
struct Family {
    const char* name;
    float x, y;
    const char* rib;  // in its own frame, centred on the origin
    bool outwardFacesCamera;
    bool closed;      // seen from outside, its inside is behind it
};

const Family kFamilies[] = {
    {"sphere", -5.5f, 1, "Sphere 0.8 -0.8 0.8 360", true, true},
    {"cylinder", -3.5f, 1, "Rotate 90 1 0 0 Cylinder 0.6 -0.6 0.6 360", true, true},
    {"cone", -1.5f, 1, "Cone 1 0.7 360", false, false},
    {"disk", 0.5f, 1, "Disk 0 0.7 360", false, false},
    {"torus", 2.5f, 1, "Torus 0.6 0.25 0 360 360", true, true},
    {"hyperboloid", 4.5f, 1, "Rotate 90 1 0 0 Hyperboloid 0.5 0 -0.5  0.5 0 0.5 360", true, true},
    {"polygon", -5.5f, -1, "Polygon \"P\" [-0.7 -0.7 0  -0.7 0.7 0  0.7 0.7 0  0.7 -0.7 0]", true, false},
    {"bilinear patch", -3.5f, -1, "Patch \"bilinear\" \"P\" [-0.7 -0.7 0  0.7 -0.7 0  -0.7 0.7 0  0.7 0.7 0]", false,
     false},
    {"bicubic patch", -1.5f, -1,
     "Scale 0.45 0.45 1 Patch \"bicubic\" \"P\" [-1.5 -1.5 0 -0.5 -1.5 0 0.5 -1.5 0 1.5 -1.5 0  -1.5 -0.5 0 -0.5 "
     "-0.5 0 0.5 -0.5 0 1.5 -0.5 0  -1.5 0.5 0 -0.5 0.5 0 0.5 0.5 0 1.5 0.5 0  -1.5 1.5 0 -0.5 1.5 0 0.5 1.5 0 1.5 "
     "1.5 0]",
     false, false},
    {"points polygons", 0.5f, -1,
     "PointsPolygons [3 3] [0 1 2 0 2 3] \"P\" [-0.7 -0.7 0  -0.7 0.7 0  0.7 0.7 0  0.7 -0.7 0]", true, false},
    {"general polygon", 2.5f, -1,
     "GeneralPolygon [4] \"P\" [-0.7 -0.7 0  -0.7 0.7 0  0.7 0.7 0  0.7 -0.7 0]", true, false},
    {"nupatch (bicubic Bezier knots)", 6.5f, -1,
     "Scale 0.45 0.45 1 NuPatch 4 4 [0 0 0 0 1 1 1 1] 0 1 4 4 [0 0 0 0 1 1 1 1] 0 1 \"P\" [-1.5 -1.5 0 -0.5 -1.5 0 "
     "0.5 -1.5 0 1.5 -1.5 0  -1.5 -0.5 0 -0.5 -0.5 0 0.5 -0.5 0 1.5 -0.5 0  -1.5 0.5 0 -0.5 0.5 0 0.5 0.5 0 1.5 0.5 "
     "0  -1.5 1.5 0 -0.5 1.5 0 0.5 1.5 0 1.5 1.5 0]",
     false, false},
    {"nurbs sphere", 6.5f, 1,
     "NuPatch 9 3 [0 0 0 0.25 0.25 0.5 0.5 0.75 0.75 1 1 1] 0 1 5 3 [0 0 0 0.5 0.5 1 1 1] 0 1 \"Pw\" [0 0 -0.8 1 "
     "0 0 -0.565685 0.707107 0 0 -0.8 1 0 0 -0.565685 0.707107 0 0 -0.8 1 0 0 -0.565685 0.707107 0 0 -0.8 1 0 0 "
     "-0.565685 0.707107 0 0 -0.8 1  0.565685 0 -0.565685 0.707107 0.4 0.4 -0.4 0.5 0 0.565685 -0.565685 0.707107 "
     "-0.4 0.4 -0.4 0.5 -0.565685 0 -0.565685 0.707107 -0.4 -0.4 -0.4 0.5 0 -0.565685 -0.565685 0.707107 0.4 -0.4 "
     "-0.4 0.5 0.565685 0 -0.565685 0.707107  0.8 0 0 1 0.565685 0.565685 0 0.707107 0 0.8 0 1 -0.565685 0.565685 0 "
     "0.707107 -0.8 0 0 1 -0.565685 -0.565685 0 0.707107 0 -0.8 0 1 0.565685 -0.565685 0 0.707107 0.8 0 0 1  "
     "0.565685 0 0.565685 0.707107 0.4 0.4 0.4 0.5 0 0.565685 0.565685 0.707107 -0.4 0.4 0.4 0.5 -0.565685 0 "
     "0.565685 0.707107 -0.4 -0.4 0.4 0.5 0 -0.565685 0.565685 0.707107 0.4 -0.4 0.4 0.5 0.565685 0 0.565685 "
     "0.707107  0 0 0.8 1 0 0 0.565685 0.707107 0 0 0.8 1 0 0 0.565685 0.707107 0 0 0.8 1 0 0 0.565685 0.707107 0 "
     "0 0.8 1 0 0 0.565685 0.707107 0 0 0.8 1]",
     true, true},
    {"patch mesh", 4.5f, -1,
     "PatchMesh \"bilinear\" 2 \"nonperiodic\" 2 \"nonperiodic\" \"P\" [-0.7 -0.7 0  0.7 -0.7 0  -0.7 0.7 0  0.7 "
     "0.7 0]",
     false, false},
};

/// Red where the outward normal Ng faces the camera, green where it faces away.
const char* kFacingShader = R"(
surface facing() {
    if (Ng . I < 0) Ci = color(1, 0, 0); else Ci = color(0, 1, 0);
    Oi = 1;
}
)";

struct Orientation {
    const char* request;  // given inside the world, before the geometry
    // Inside out in a left-handed and in a right-handed world (RI spec:
    // "outside" matches the current handedness, "inside" is opposite, "lh"
    // and "rh" are absolute, ReverseOrientation toggles the default).
    bool insideOutInLeft, insideOutInRight;
};

const Orientation kOrientations[] = {
    {"", false, false},
    {"Orientation \"outside\"", false, false},
    {"Orientation \"inside\"", true, true},
    {"Orientation \"lh\"", false, true},
    {"Orientation \"rh\"", true, false},
    {"ReverseOrientation", true, true},
};

enum class Camera { Plain, Flopped, MirroredZ };

/// The camera looks down world +z from z = -12 (Plain), the same with the
/// picture flopped left to right (`Scale -1 1 1`), or from z = +12 down
/// world -z with a right-handed world, as exporters write it (`Scale 1 1
/// -1`).
std::string cameraRib(Camera c) {
    switch (c) {
    case Camera::Plain: return fmt::format("Translate 0 0 {}", kDistance);
    case Camera::Flopped: return fmt::format("Scale -1 1 1 Translate 0 0 {}", kDistance);
    case Camera::MirroredZ: return fmt::format("Scale 1 1 -1 Translate 0 0 {}", -kDistance);
    }
    return "";
}

class FamilyScene {
public:
    explicit FamilyScene(const std::string& name) : m_dir(name) {
        std::ofstream(m_dir.file("facing.sl")) << kFacingShader;
    }

    /// Renders every family with one orientation request and Sides setting.
    Image render(Camera camera, const std::string& orientation, int sides, int threads = 0, int bucket = 0) {
        std::string prims;
        for (const Family& f : kFamilies)
            prims += fmt::format("AttributeBegin Translate {} {} 0 {} AttributeEnd\n", f.x, f.y, f.rib);
        std::string image = m_dir.file("families.tif");
        std::string rib = fmt::format(R"(
Option "searchpath" "shader" ["{}:&"]
Format {} {} 1
PixelSamples 2 2
Display "{}" "file" "rgb"
Projection "perspective" "fov" {}
{}
WorldBegin
{}
Sides {}
Surface "facing"
{}
WorldEnd
)",
                                      m_dir.file(""), kWidth, kHeight, image, 2 * kHalfFov, cameraRib(camera),
                                      orientation, sides, prims);
        Diagnostics diag;
        diag.setQuiet(true);
        Image img = test::renderImage(rib, image, diag, threads, bucket);
        EXPECT_EQ(diag.errorCount(), 0) << rib;
        return img;
    }

private:
    ScratchDir m_dir;
};

/// What one family's square of the picture shows.
struct Region {
    int covered = 0, red = 0, green = 0, pixels = 0;
};

/// The pixels within 0.75 units of a family's centre (raster position of
/// a point at depth kDistance), flopped if the camera flops the picture.
Region regionOf(const Image& img, const Family& f, bool flopped) {
    const float pixelsPerUnit = (kHeight / 2.0f) / (kDistance * std::tan(kHalfFov * 3.14159265f / 180));
    float cx = kWidth / 2.0f + (flopped ? -f.x : f.x) * pixelsPerUnit;
    float cy = kHeight / 2.0f - f.y * pixelsPerUnit;
    int r = int(0.75f * pixelsPerUnit);
    Region out;
    for (int y = int(cy) - r; y <= int(cy) + r; ++y)
        for (int x = int(cx) - r; x <= int(cx) + r; ++x) {
            float red = img.at(x, y, 0), green = img.at(x, y, 1);
            ++out.pixels;
            if (red + green > 0.5f) ++out.covered;
            if (red > 0.9f && green < 0.1f) ++out.red;
            if (green > 0.9f && red < 0.1f) ++out.green;
        }
    return out;
}

/// Checks every family's square against the spec's answer: with Sides 2
/// the whole visible surface shows its outward side exactly when the
/// family's outward side faces the camera and it is not inside out; with
/// Sides 1 only outward sides facing the camera are drawn, so an open
/// surface turned away vanishes and a closed one shows its inside.
void expectSpecAnswer(const Image& img, bool insideOut, int sides, bool flopped, const std::string& what) {
    for (const Family& f : kFamilies) {
        Region r = regionOf(img, f, flopped);
        SCOPED_TRACE(fmt::format("{}: {} (covered {}, red {}, green {} of {})", what, f.name, r.covered, r.red,
                                 r.green, r.pixels));
        const bool outwardSeen = f.outwardFacesCamera != insideOut;
        const bool drawn = sides == 2 || outwardSeen || f.closed;
        if (!drawn) {
            EXPECT_EQ(r.covered, 0);
            continue;
        }
        ASSERT_GT(r.covered, r.pixels / 5);
        // Edge pixels mix the colours: 80% of the covered pixels must be pure
        // (a wrong orientation makes it 0%).
        const bool red = sides == 1 || outwardSeen;
        EXPECT_GE(red ? r.red : r.green, r.covered * 8 / 10);
    }
}

}  // namespace

TEST(Orientation, EveryFamilyOutsideAsTheSpecSaysUnderPlainAndMirroringCameras) {
    FamilyScene scene("orient-families");
    for (Camera camera : {Camera::Plain, Camera::Flopped})
        for (const Orientation& o : kOrientations)
            for (int sides : {1, 2}) {
                // A flopping camera makes the world right-handed.
                bool insideOut = camera == Camera::Plain ? o.insideOutInLeft : o.insideOutInRight;
                Image img = scene.render(camera, o.request, sides);
                expectSpecAnswer(img, insideOut, sides, camera == Camera::Flopped,
                                 fmt::format("camera {}, '{}', Sides {}", int(camera), o.request, sides));
            }
}

TEST(Orientation, FloppingCameraGivesTheFloppedPicture) {
    // "outside" under a flopping camera is "outside" of the flopped world,
    // so the picture is the plain one, flopped: pixel for pixel but for the
    // sample positions, which do not flop.
    FamilyScene scene("orient-flop");
    for (int sides : {1, 2}) {
        Image plain = scene.render(Camera::Plain, "", sides);
        Image flopped = scene.render(Camera::Flopped, "", sides);
        double diff = 0;
        for (int y = 0; y < kHeight; ++y)
            for (int x = 0; x < kWidth; ++x)
                for (int c = 0; c < 3; ++c) diff += std::fabs(plain.at(x, y, c) - flopped.at(kWidth - 1 - x, y, c));
        // Only antialiased edge pixels may differ.
        EXPECT_LT(diff / (kWidth * kHeight * 3), 0.01) << "Sides " << sides;
    }
}

namespace {

/// The issue's case: a plastic sphere lit from the upper left, under an
/// exporter's right-handed camera or the plain camera that sees the same.
std::string litSphere(const std::string& image, bool mirrored, const std::string& inWorld, int sides,
                      const std::string& surface = "plastic", const std::string& displacement = "",
                      const std::string& options = "") {
    return fmt::format(R"(
{}
Format 200 150 1
Display "{}" "file" "rgb"
Projection "perspective" "fov" 40
{}
WorldBegin
LightSource "distantlight" 1 "from" [-1 1 {}] "to" [0 0 0]
{}
Sides {}
Surface "{}"
{}
Sphere 1 -1 1 360
WorldEnd
)",
                       options, image, mirrored ? "Scale 1 1 -1 Translate 0 0 -5" : "Translate 0 0 5", mirrored ? 1 : -1,
                       inWorld, sides, surface, displacement);
}

Image renderTo(const ScratchDir& dir, const std::string& rib, int threads = 0, int bucket = 0) {
    Diagnostics diag;
    diag.setQuiet(true);
    Image img = test::renderImage(rib, dir.file("sphere.tif"), diag, threads, bucket);
    EXPECT_EQ(diag.errorCount(), 0);
    return img;
}

}  // namespace

TEST(Orientation, MirroredCameraSphereMatchesThePlainScene) {
    // Scale 1 1 -1 before WorldBegin with the light's z negated describes the
    // same picture as the plain camera; the sphere is symmetric in z, so
    // they agree up to rounding of the mirrored positions.
    ScratchDir dir("orient-mirror");
    const std::string image = dir.file("sphere.tif");
    Image reference = renderTo(dir, litSphere(image, false, "", 2));
    ASSERT_GT(reference.channelSum(0), 1000.0);
    for (const char* inWorld : {"", "Orientation \"rh\"", "Orientation \"outside\""})
        for (int sides : {1, 2}) {
            Image mirrored = renderTo(dir, litSphere(image, true, inWorld, sides));
            EXPECT_LT(meanAbsDiff(mirrored, reference), 1e-4) << "'" << inWorld << "', Sides " << sides;
        }
    // Displacement along N and calculatenormal() follow the same rule: the
    // bumps stand out of the sphere in both.
    std::ofstream(dir.file("ripple.sl"))
        << "displacement ripple() { P += 0.1 * sin(20 * s) * normalize(N); N = calculatenormal(P); }\n";
    const std::string path = fmt::format("Option \"searchpath\" \"shader\" [\"{}:&\"]", dir.file(""));
    const std::string bumps = "Attribute \"displacementbound\" \"sphere\" [0.1] Displacement \"ripple\"";
    Image bumpyReference = renderTo(dir, litSphere(image, false, "", 2, "plastic", bumps, path));
    EXPECT_GT(meanAbsDiff(bumpyReference, reference), 1e-2);  // the ripples show
    for (const char* inWorld : {"", "Orientation \"rh\""}) {
        Image mirrored = renderTo(dir, litSphere(image, true, inWorld, 2, "plastic", bumps, path));
        EXPECT_LT(meanAbsDiff(mirrored, bumpyReference), 1e-3) << "bumpy, '" << inWorld << "'";
    }
}

TEST(Orientation, FaceForwardShadersOnTwoSidedSurfacesIgnoreOrientation) {
    // plastic and matte shade faceforward(normalize(N), I): the picture of a
    // two-sided surface must not depend on its orientation at all.
    ScratchDir dir("orient-ff");
    const std::string image = dir.file("sphere.tif");
    for (const char* surface : {"plastic", "matte"})
        for (bool mirrored : {false, true}) {
            Image reference = renderTo(dir, litSphere(image, mirrored, "", 2, surface));
            for (const char* o : {"Orientation \"inside\"", "Orientation \"lh\"", "Orientation \"rh\"",
                                  "ReverseOrientation"}) {
                Image img = renderTo(dir, litSphere(image, mirrored, o, 2, surface));
                EXPECT_EQ(meanAbsDiff(img, reference), 0.0) << surface << ", mirrored " << mirrored << ", " << o;
            }
        }
}

TEST(Orientation, SameImageWhateverTheThreadsAndBuckets) {
    // A grid's normals once depended on the orientation of the grid the same
    // thread shaded before it: mirrored scenes with ReverseOrientation
    // differed from run to run on two threads.
    ScratchDir dir("orient-determinism");
    const std::string image = dir.file("sphere.tif");
    for (const char* o : {"ReverseOrientation", "Orientation \"rh\"", "Orientation \"lh\""}) {
        Image one = renderTo(dir, litSphere(image, true, o, 2), 1, 16);
        for (int threads : {1, 2})
            for (int bucket : {8, 16, 32}) {
                Image img = renderTo(dir, litSphere(image, true, o, 2), threads, bucket);
                EXPECT_EQ(meanAbsDiff(img, one), 0.0) << o << ", threads " << threads << ", bucket " << bucket;
            }
    }
}

namespace {

/// A scene as VTK's RIB exporter writes one: a mirroring `Transform`
/// camera, `Orientation "rh"` before the world, and each object as
/// separate `Polygon`s carrying per-vertex outward normals. A tessellated
/// sphere, wound counter-clockwise seen from outside (as the exporter's
/// meshes are) or clockwise (as many hand-written and older exporters'
/// meshes are, with the same outward normals).
std::string exportedPolygonSphere(const std::string& image, bool woundAgainstNormals, const std::string& surface) {
    std::string rib = fmt::format(
        "FrameBegin 1\nDisplay \"{}\" \"file\" \"rgb\"\nDeclare \"color\" \"uniform color\"\nPixelSamples 2 2\n"
        "Format 160 120 1\nProjection \"perspective\" \"fov\" [30.000000]\nIdentity\n"
        "Transform [-1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1 ]\nRotate 180 0 1 0\nTranslate 0 0 -6\nOrientation \"rh\"\n"
        "WorldBegin\nLightSource \"ambientlight\" 1 \"intensity\" [0.1]\n"
        "LightSource \"distantlight\" 2 \"intensity\" [1.0] \"from\" [2 3 6] \"to\" [0 0 0]\n"
        "AttributeBegin\nTransformBegin\nColor [0.9 0.4 0.3]\nSurface \"{}\"\n",
        image, surface);
    constexpr int kRings = 12, kSegments = 24;
    const float pi = 3.14159265f;
    auto vertex = [&](int ring, int segment) {
        const float theta = pi * float(ring) / kRings, phi = 2 * pi * float(segment) / kSegments;
        return Vec3(std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi));
    };
    for (int i = 0; i < kRings; ++i)
        for (int j = 0; j < kSegments; ++j) {
            // (i, j+1) -> (i+1, j+1) turns counter-clockwise about the outward normal.
            Vec3 q[4] = {vertex(i, j), vertex(i, j + 1), vertex(i + 1, j + 1), vertex(i + 1, j)};
            if (woundAgainstNormals) std::swap(q[1], q[3]);
            std::string p = "Polygon \"P\" [", n = "] \"N\" [";
            for (const Vec3& v : q) {
                p += fmt::format("{} {} {} ", v.x, v.y, v.z);
                n += fmt::format("{} {} {} ", v.x, v.y, v.z);  // the unit sphere's normal is its point
            }
            rib += p + n + "]\n";
        }
    return rib + "TransformEnd\nAttributeEnd\nWorldEnd\nFrameEnd\n";
}

}  // namespace

TEST(Orientation, NormalsWoundAgainstTheirPolygonsShadeAsPixieAndAqsisShadeThem) {
    // A mesh wound clockwise about its own outward normals: by the spec its
    // Ng points in, and faceforward(N, I) with Ng as the reference turned
    // every normal inwards, so plastic and matte spheres shaded black from
    // the front (Pixie 2.2.6 and Aqsis 1.8.4 light them: their faceforward
    // turns N itself to the viewer). The picture must be the one of the same
    // mesh wound the exporter's way, and lit from the front.
    ScratchDir dir("orient-winding");
    const std::string image = dir.file("sphere.tif");
    for (const char* surface : {"plastic", "matte"}) {
        Image wound = renderTo(dir, exportedPolygonSphere(image, false, surface));
        Image against = renderTo(dir, exportedPolygonSphere(image, true, surface));
        EXPECT_EQ(meanAbsDiff(against, wound), 0.0) << surface;
        // The sphere's centre faces the camera (at z = +6 in VTK's
        // right-handed world) and the light from (2, 3, 6): N.L = 6/7, so
        // its red is at least Cs * (ambient 0.1 + Kd 0.5 * 6/7) (plastic's
        // Kd; matte's is 1), where the inward normals left the ambient
        // 0.9 * 0.1 alone.
        const float lit = 0.9f * (0.1f + 0.5f * 6.0f / 7.0f);
        EXPECT_GT(wound.at(80, 60, 0), 0.95f * lit) << surface;
    }
}
