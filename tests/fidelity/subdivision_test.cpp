// SubdivisionMesh rendered end to end. The independent answers: the limit
// surface's projected area from a fine tessellation made here with Bfr
// directly (Bfr::Tessellation, not the renderer's dicing), the side shown
// by the same faces written as PointsPolygons, the picture of the plain
// camera for a mirrored one, and the shadow a cube must cast.

#include "support/render_harness.h"

#include <opensubdiv/bfr/refinerSurfaceFactory.h>
#include <opensubdiv/bfr/surface.h>
#include <opensubdiv/bfr/tessellation.h>
#include <opensubdiv/far/topologyDescriptor.h>
#include <opensubdiv/far/topologyRefinerFactory.h>

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <fstream>

using namespace umbra;

namespace {

namespace osd = OpenSubdiv;

const float kCubeP[] = {-1, -1, -1, 1, -1, -1, -1, 1, -1, 1, 1, -1, -1, -1, 1, 1, -1, 1, -1, 1, 1, 1, 1, 1};
const int kCubeNverts[] = {4, 4, 4, 4, 4, 4};
const int kCubeVerts[] = {0, 2, 3, 1, 4, 5, 7, 6, 0, 1, 5, 4, 2, 6, 7, 3, 0, 4, 6, 2, 1, 3, 7, 5};

std::string cubeArrays() {
    std::string s = "[4 4 4 4 4 4] [";
    for (int v : kCubeVerts) s += fmt::format("{} ", v);
    s += "]";
    return s;
}
std::string cubeP() {
    std::string s = "\"P\" [";
    for (float p : kCubeP) s += fmt::format("{} ", p);
    return s + "]";
}

/// Red where Ng faces the camera, green where it faces away.
const char* kFacingShader = R"(
surface facing() {
    if (Ng . I < 0) Ci = color(1, 0, 0); else Ci = color(0, 1, 0);
    Oi = 1;
}
)";

constexpr int kSize = 200;
constexpr float kHalfWidth = 2;  // orthographic screen window [-2, 2]^2
constexpr float kRotX = 30, kRotY = 40;

struct Scene {
    test::ScratchDir dir{"subdiv"};
    Scene() { std::ofstream(dir.file("facing.sl")) << kFacingShader; }

    test::Image render(const std::string& geometry, const std::string& camera = "Translate 0 0 10",
                       const std::string& projection = "Projection \"orthographic\"") {
        const std::string image = dir.file("out.tif");
        const std::string rib = fmt::format(R"(
Option "searchpath" "shader" ["{}:&"]
Format {} {} 1
PixelSamples 4 4
ScreenWindow -{} {} -{} {}
Display "{}" "file" "rgba"
{}
{}
WorldBegin
Sides 2
Surface "facing"
AttributeBegin
Rotate {} 1 0 0
Rotate {} 0 1 0
{}
AttributeEnd
WorldEnd
)",
                                            dir.file(""), kSize, kSize, kHalfWidth, kHalfWidth, kHalfWidth, kHalfWidth,
                                            image, projection, camera, kRotX, kRotY, geometry);
        Diagnostics diag;
        diag.setQuiet(true);
        test::renderRib(rib, diag);
        EXPECT_EQ(diag.errorCount(), 0) << rib;
        test::Image img;
        EXPECT_TRUE(test::readImage(image, &img));
        return img;
    }

    /// The errors a world holding `geometry` reports (and its warnings).
    int renderErrors(const std::string& geometry, int* warnings = nullptr) {
        const std::string rib = fmt::format("Display \"{}\" \"file\" \"rgba\" Format 16 16 1 WorldBegin {} WorldEnd",
                                            dir.file("errors.tif"), geometry);
        Diagnostics diag;
        diag.setQuiet(true);
        test::renderRib(rib, diag);
        if (warnings) *warnings = diag.warningCount();
        return diag.errorCount();
    }
};

/// Covered area in screen units (alpha summed over pixels).
double coveredArea(const test::Image& img) {
    const double pixel = (2.0 * kHalfWidth / kSize) * (2.0 * kHalfWidth / kSize);
    return img.channelSum(3) * pixel;
}

/// The smooth cube's limit surface tessellated finely by Bfr, rotated as
/// the scene rotates it, and its outline's area in the view plane: the
/// limit surface is convex and closed, so that area is the sum of the
/// facets' projected areas facing one way.
double limitProjectedArea() {
    osd::Far::TopologyDescriptor desc;
    desc.numVertices = 8;
    desc.numFaces = 6;
    desc.numVertsPerFace = kCubeNverts;
    desc.vertIndicesPerFace = kCubeVerts;
    using Factory = osd::Far::TopologyRefinerFactory<osd::Far::TopologyDescriptor>;
    osd::Sdc::Options sdc;
    sdc.SetVtxBoundaryInterpolation(osd::Sdc::Options::VTX_BOUNDARY_NONE);
    std::unique_ptr<osd::Far::TopologyRefiner> refiner(
        Factory::Create(desc, Factory::Options(osd::Sdc::SCHEME_CATMARK, sdc)));
    osd::Bfr::RefinerSurfaceFactory<> factory(*refiner);
    // RenderMan's Rotate x then y, applied to points as y first, then x.
    const double ax = kRotX * M_PI / 180, ay = kRotY * M_PI / 180;
    auto project = [&](const float* p, double* xy) {
        double x = p[0] * std::cos(ay) + p[2] * std::sin(ay), z = -p[0] * std::sin(ay) + p[2] * std::cos(ay);
        double y = p[1] * std::cos(ax) - z * std::sin(ax);
        xy[0] = x;
        xy[1] = y;
    };
    double pos = 0, neg = 0;
    for (int f = 0; f < 6; ++f) {
        osd::Bfr::Surface<float> s;
        if (!factory.InitVertexSurface(f, &s)) continue;
        std::vector<float> pp(size_t(s.GetNumPatchPoints()) * 3);
        s.PreparePatchPoints(kCubeP, 3, pp.data(), 3);
        osd::Bfr::Tessellation tess(s.GetParameterization(), 64);
        std::vector<float> uv(size_t(tess.GetNumCoords()) * 2), P(size_t(tess.GetNumCoords()) * 3);
        tess.GetCoords(uv.data());
        for (int k = 0; k < tess.GetNumCoords(); ++k) s.Evaluate(&uv[size_t(k) * 2], pp.data(), 3, &P[size_t(k) * 3]);
        std::vector<int> facets(size_t(tess.GetNumFacets()) * size_t(tess.GetFacetSize()));
        tess.GetFacets(facets.data());
        for (size_t t = 0; t < facets.size(); t += size_t(tess.GetFacetSize())) {
            const int n = tess.GetFacetSize() == 4 && facets[t + 3] >= 0 ? 4 : 3;
            double a = 0, q[4][2];
            for (int c = 0; c < n; ++c) project(&P[size_t(facets[t + size_t(c)]) * 3], q[c]);
            for (int c = 0; c < n; ++c) a += q[c][0] * q[(c + 1) % n][1] - q[(c + 1) % n][0] * q[c][1];
            (a > 0 ? pos : neg) += 0.5 * std::abs(a);
        }
    }
    EXPECT_NEAR(pos, neg, 1e-3 * pos);  // closed: the two sides cover the same area
    return 0.5 * (pos + neg);
}

std::string subdivCube(const std::string& tags = "") {
    return fmt::format("SubdivisionMesh \"catmull-clark\" {} {} {}", cubeArrays(), tags, cubeP());
}

TEST(Subdivision, CubeSilhouetteAreaMatchesTheLimitSurface) {
    Scene scene;
    const test::Image img = scene.render(subdivCube());
    const double want = limitProjectedArea();
    EXPECT_NEAR(coveredArea(img), want, 0.01 * want);
    // Every covered pixel shows the outward side (red).
    int green = 0;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x)
            if (img.at(x, y, 3) > 0.5f && img.at(x, y, 1) > 0.1f) ++green;
    EXPECT_EQ(green, 0);
}

TEST(Subdivision, HierarchicalMeshIsTheMeshItsTagsDescribe) {
    // Exporters write HierarchicalSubdivisionMesh: three counts per tag
    // (integers, floats, strings) and the string arguments last. Its
    // crease, corner and hole tags are the plain request's; a hierarchical
    // edit is warned about and left out, so the picture is the plain mesh's.
    Scene scene;
    const test::Image plain = scene.render(subdivCube(
        "[\"crease\" \"corner\" \"hole\" \"interpolateboundary\"] [3 1 1 1 1 0 0 0] [4 5 7 2 2] [2.5 10]"));
    const std::string hierarchical = fmt::format(
        "HierarchicalSubdivisionMesh \"catmull-clark\" {} "
        "[\"crease\" \"vertexedit\" \"corner\" \"hole\" \"interpolateboundary\"] "
        "[3 1 0  3 3 2  1 1 0  1 0 0  0 0 0] [4 5 7  1 1 3  2 2] [2.5  0.1 0.2 0.3  10] "
        "[\"add\" \"value\"] {}",
        cubeArrays(), cubeP());
    const test::Image hier = scene.render(hierarchical);
    ASSERT_EQ(hier.width, plain.width);
    EXPECT_EQ(test::maxAbsDiff(hier, plain, 4), 0.0);
    // The tags took effect: the holed, creased cube is not the plain cube.
    EXPECT_GT(test::maxAbsDiff(hier, scene.render(subdivCube()), 4), 0.5);

    // Counts that do not come in threes are a located error.
    EXPECT_EQ(scene.renderErrors(fmt::format("HierarchicalSubdivisionMesh \"catmull-clark\" {} [\"hole\"] [1 0] [2] "
                                             "[] [] {}", cubeArrays(), cubeP())), 1);
}

TEST(Subdivision, ANonManifoldMeshIsWarnedOf) {
    // Three faces on one edge: its faces have no limit surface. All three
    // renderers draw nothing there; umbra said nothing (Aqsis names the
    // vertices). A manifold mesh of the same points is not warned of.
    Scene scene;
    int warnings = 0;
    EXPECT_EQ(scene.renderErrors("SubdivisionMesh \"catmull-clark\" [3 3 3] [0 1 2 0 1 3 0 1 4] [] [] [] [] "
                                 "\"P\" [0 0 0 1 0 0 0 1 0 0 -1 0 0 0 1]",
                                 &warnings),
              0);
    EXPECT_EQ(warnings, 1);
    EXPECT_EQ(scene.renderErrors("SubdivisionMesh \"catmull-clark\" [3 3] [0 1 2 1 0 3] [] [] [] [] "
                                 "\"P\" [0 0 0 1 0 0 0 1 0 0 -1 0]",
                                 &warnings),
              0);
    EXPECT_EQ(warnings, 0);
}

TEST(Subdivision, OutwardSideIsThatOfThePolygonsOfTheControlMesh) {
    // A bumped 3 x 3 sheet of quads in z = 0, wound both ways: the
    // subdivided sheet shows the side its polygons show.
    std::string P = "\"P\" [";
    for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i)
            P += fmt::format("{} {} {} ", i - 1.5f, j - 1.5f, (i == 1 || i == 2) && (j == 1 || j == 2) ? -0.3f : 0.0f);
    P += "]";
    for (bool reversed : {false, true}) {
        std::string verts = "[";
        for (int j = 0; j < 3; ++j)
            for (int i = 0; i < 3; ++i) {
                const int a = j * 4 + i, b = a + 1, c = a + 5, d = a + 4;
                verts += reversed ? fmt::format("{} {} {} {} ", a, d, c, b) : fmt::format("{} {} {} {} ", a, b, c, d);
            }
        verts += "]";
        const std::string arrays = "[4 4 4 4 4 4 4 4 4] " + verts;
        Scene scene;
        const test::Image sub = scene.render(fmt::format(
            "SubdivisionMesh \"catmull-clark\" {} [\"interpolateboundary\"] [0 0] [] [] {}", arrays, P));
        const test::Image poly = scene.render(fmt::format("PointsPolygons {} {}", arrays, P));
        auto count = [](const test::Image& img, int channel) {
            int n = 0;
            for (int y = 0; y < img.height; ++y)
                for (int x = 0; x < img.width; ++x)
                    if (img.at(x, y, 3) > 0.99f && img.at(x, y, channel) > 0.9f) ++n;
            return n;
        };
        const int polyRed = count(poly, 0), polyGreen = count(poly, 1);
        const int subRed = count(sub, 0), subGreen = count(sub, 1);
        EXPECT_GT(polyRed + polyGreen, 5000);
        EXPECT_GT(subRed + subGreen, 3000);
        if (polyRed > polyGreen) EXPECT_EQ(subGreen, 0) << reversed;
        else EXPECT_EQ(subRed, 0) << reversed;
        EXPECT_TRUE(polyRed == 0 || polyGreen == 0) << reversed;
        // Wound a -> b -> c -> d, (b - a) x (d - a) = +z: the outward side faces away from the camera.
        EXPECT_EQ(reversed, polyRed > polyGreen);
    }
}

TEST(Subdivision, MirroredCameraRendersTheSame) {
    Scene scene;
    const std::string tags = "[\"crease\" \"corner\"] [3 1 1 1] [4 5 7 2] [2.5 10]";
    const test::Image plain = scene.render(subdivCube(tags));
    const test::Image mirrored = scene.render(subdivCube(tags), "Scale 1 1 -1 Translate 0 0 -10");
    ASSERT_EQ(plain.pixels.size(), mirrored.pixels.size());
    double diff = 0;
    for (size_t k = 0; k < plain.pixels.size(); ++k) diff += std::abs(plain.pixels[k] - mirrored.pixels[k]);
    EXPECT_LT(diff / double(kSize * kSize), 1e-3);
}

TEST(Subdivision, CubeCastsAShadowIntoAnAutomaticDepthMap) {
    test::ScratchDir dir("subdiv-shadow");
    // The same scene with the cube casting shadows and not (transmission
    // off): the pictures differ only by the cube's shadow on the floor.
    auto render = [&](bool casts) {
        const std::string image = dir.file(casts ? "casts.tif" : "none.tif");
        const std::string rib = fmt::format(R"(
Display "{}" "file" "rgb"
Format 120 120 1
PixelSamples 2 2
Option "umbra" "shadowmapsize" [256]
Projection "perspective" "fov" [40]
Translate 0 -0.5 9
Rotate -40 1 0 0
WorldBegin
  LightSource "shadowspot" 1 "from" [0 8 0] "to" [0 0 0] "intensity" [64] "coneangle" [0.7]
      "shadowname" ["auto"] "samples" [16]
  Surface "matte"
  Patch "bilinear" "P" [-5 0 -5  5 0 -5  -5 0 5  5 0 5]
  {}
WorldEnd
)",
                                            image,
                                            std::string("AttributeBegin Translate 0 2 0 ") +
                                                (casts ? "" : "Attribute \"visibility\" \"transmission\" [0] ") +
                                                subdivCube() + " AttributeEnd");
        Diagnostics diag;
        diag.setQuiet(true);
        test::renderRib(rib, diag);
        EXPECT_EQ(diag.errorCount(), 0);
        test::Image img;
        EXPECT_TRUE(test::readImage(image, &img));
        return img;
    };
    const test::Image floor = render(false), cube = render(true);
    int darkened = 0, pixels = 0, brighter = 0;
    for (int y = 0; y < floor.height; ++y)
        for (int x = 0; x < floor.width; ++x) {
            const float lit = floor.at(x, y, 0), shaded = cube.at(x, y, 0);
            if (lit > 0.2f) {
                ++pixels;
                if (shaded < 0.3f * lit) ++darkened;
            }
            if (shaded > lit + 0.02f) ++brighter;
        }
    EXPECT_GT(pixels, 1000);
    EXPECT_GT(darkened, 200);
    EXPECT_EQ(brighter, 0);
}

}  // namespace
