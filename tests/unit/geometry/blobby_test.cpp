// Blobby implicit surfaces: the field against its closed form (written
// again here), the diced surface on the threshold with outward normals and
// windings, per-leaf values blended by field weight, depth-map repelling
// planes against Application Note #31's field of the height above a map
// written here, and malformed code reported at the request's location.

#include "geometry_test_util.h"

#include "umbra/geometry/blobby.h"
#include "umbra/shadow/depth_image.h"

#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <functional>

using namespace umbra;
using namespace umbra::geometry;
using namespace umbra::testutil;

namespace {

constexpr float kT = 0.421875f;  // 0.75^3: a lone leaf's surface at half its unit radius

std::shared_ptr<scene::PrimitiveRecord> blobby(int nleaf, std::vector<int> code, std::vector<float> floats,
                                               std::vector<ri::Param> params = {}) {
    auto r = record("Blobby", std::move(floats), std::move(params));
    r->intArgs = {nleaf};
    r->intArgs.insert(r->intArgs.end(), code.begin(), code.end());
    r->intArrays = {std::move(code)};
    r->stringArgs = {""};
    return r;
}

// A sphere leaf of unit-space scale s centred at c, in RIB order.
std::vector<float> sphereLeaf(float s, Vec3 c) { return {s, 0, 0, 0, 0, s, 0, 0, 0, 0, s, 0, c.x, c.y, c.z, 1}; }

std::vector<float> concat(std::vector<float> a, const std::vector<float>& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
}

// The leaf field written independently: (1 - r^2)^3 inside the unit ball.
double bump(double r2) { return r2 < 1 ? std::pow(1 - r2, 3) : 0; }
double sphereField(const Vec3& p, float s, Vec3 c) {
    const Vec3 d = (p - c) / s;
    return bump(double(dot(d, d)));
}

std::shared_ptr<const BlobbyField> field(const std::shared_ptr<scene::PrimitiveRecord>& r) {
    Diagnostics diag;
    auto f = BlobbyField::fromRecord(*r, diag);
    EXPECT_EQ(diag.errorCount(), 0);
    return f;
}

// A repelling plane's field, written again from PRMan Application Note #31:
// z is the height above the surface stored in the plane's depth map.
double noteBump(double r) { return r <= 0 || r >= 2 ? 0 : (((6 - r) * r - 12) * r + 8) * r * r * r; }
double noteEase(double r) { return r <= 0 ? 0 : r >= 1 ? 1 : r * r * (3 - 2 * r); }
double noteRepulsion(double z, double A, double B, double C, double D) {
    if (z >= A) return 0;
    if (z <= 1e-6) z = 1e-6;
    return (D * noteBump(z / C) - B / z) * (1 - noteEase(z / A));
}

// A 64x64 zfile seen from world z = 5 looking down -z (orthographic, over
// x, y in [-2, 2]: a texel is 1/16 unit) of the ground z = ground(x, y):
// each texel stores the depth 5 - ground of its centre.
std::string writeGroundMap(const std::string& name, const std::function<float(float, float)>& ground) {
    DepthImage img(64, 64);
    img.projection = Projection::Orthographic;
    img.lightFromWorld.m[2][2] = -1;
    img.lightFromWorld.m[2][3] = 5;
    img.ndcFromWorld = img.lightFromWorld;
    img.ndcFromWorld.m[0][0] = 0.25f;
    img.ndcFromWorld.m[0][3] = 0.5f;
    img.ndcFromWorld.m[1][1] = -0.25f;
    img.ndcFromWorld.m[1][3] = 0.5f;
    for (int j = 0; j < 64; ++j)
        for (int i = 0; i < 64; ++i) img.at(i, j) = 5 - ground((float(i) + 0.5f) / 16 - 2, 2 - (float(j) + 0.5f) / 16);
    const std::string path =
        (std::filesystem::temp_directory_path() / (name + "-" + std::to_string(::getpid()) + ".zfile")).string();
    EXPECT_TRUE(writeZFile(path, img));
    return path;
}

// An ellipsoid (sphere leaf of scale `s` at `c`) added to a repelling plane
// with parameters A B C D, RI spec 3.2's example code.
std::shared_ptr<scene::PrimitiveRecord> sphereOverPlane(float s, Vec3 c, const std::string& map,
                                                        std::vector<float> abcd) {
    auto rec = blobby(2, {1001, 0, 1003, 0, 16, 0, 2, 0, 1}, concat(sphereLeaf(s, c), abcd));
    rec->stringArgs = {map};
    return rec;
}

}  // namespace

TEST(Blobby, OperationsCombineLeavesAsTheSpecSays) {
    const Vec3 c0(-0.3f, 0, 0), c1(0.4f, 0.1f, 0);
    const auto leaves = concat(concat(sphereLeaf(1.5f, c0), sphereLeaf(1.2f, c1)), {0.25f});
    struct Case {
        std::vector<int> ops;  // after the three leaves (instructions 0, 1, 2)
        double (*expect)(double a, double b, double k);
    };
    const Case cases[] = {
        {{0, 3, 0, 1, 2}, [](double a, double b, double k) { return a + b + k; }},
        {{1, 2, 0, 1}, [](double a, double b, double) { return a * b; }},
        {{2, 2, 0, 1}, [](double a, double b, double) { return std::max(a, b); }},
        {{3, 2, 0, 1}, [](double a, double b, double) { return std::min(a, b); }},
        {{4, 0, 1}, [](double a, double b, double) { return a - b; }},
        {{5, 0, 2}, [](double a, double, double k) { return a / k; }},
        {{6, 1}, [](double, double b, double) { return -b; }},
        {{7, 0}, [](double a, double, double) { return a; }},
    };
    for (const Case& c : cases) {
        std::vector<int> code = {1001, 0, 1001, 16, 1000, 32};
        code.insert(code.end(), c.ops.begin(), c.ops.end());
        auto f = field(blobby(3, code, leaves));
        ASSERT_TRUE(f);
        for (float x = -1.2f; x <= 1.2f; x += 0.1f) {
            const Vec3 p(x, 0.05f, -0.1f);
            const double a = sphereField(p, 1.5f, c0), b = sphereField(p, 1.2f, c1);
            EXPECT_NEAR(f->value(p), c.expect(a, b, 0.25), 1e-5) << "opcode " << c.ops[0] << " at x " << x;
        }
    }
    // A zero divisor gives 0 (Aqsis), never an infinity.
    auto f = field(blobby(2, {1001, 0, 1000, 16, 5, 0, 1}, concat(sphereLeaf(1, {}), {0.0f})));
    EXPECT_EQ(f->value(Vec3(0.1f, 0, 0)), 0.0f);
}

TEST(Blobby, GradientIsTheFieldsDerivative) {
    // Every operation, a sheared ellipsoid and a turned segment blob: the
    // gradient against central differences of the field (in double steps
    // large enough for float values).
    std::vector<float> floats = {1.4f, 0.3f, 0, 0, 0, 1.1f, 0.2f, 0, 0.1f, 0, 0.9f, 0, -0.2f, 0.1f, 0, 1};
    const std::vector<float> seg = {-0.4f, 0, 0, 0.4f, 0.2f, 0, 0.9f, 0, 1, 0, 0, -1, 0, 0, 0, 0, 0, 1, 0, 0.3f, 0, 0,
                                    1};
    floats.insert(floats.end(), seg.begin(), seg.end());
    floats.push_back(0.6f);
    for (const std::vector<int>& ops : std::vector<std::vector<int>>{
             {0, 3, 0, 1, 2}, {1, 3, 0, 1, 2}, {2, 2, 0, 1}, {3, 2, 0, 1}, {4, 0, 1}, {5, 0, 2}, {6, 0}, {7, 1}}) {
        std::vector<int> code = {1001, 0, 1002, 16, 1000, 39};
        code.insert(code.end(), ops.begin(), ops.end());
        auto f = field(blobby(3, code, floats));
        ASSERT_TRUE(f);
        for (const Vec3& p : {Vec3(0.1f, 0.2f, 0.05f), Vec3(-0.3f, -0.1f, 0.2f), Vec3(0.35f, 0.3f, -0.1f)}) {
            const float e = 1e-3f;
            const Vec3 fd((f->value(p + Vec3(e, 0, 0)) - f->value(p - Vec3(e, 0, 0))) / (2 * e),
                          (f->value(p + Vec3(0, e, 0)) - f->value(p - Vec3(0, e, 0))) / (2 * e),
                          (f->value(p + Vec3(0, 0, e)) - f->value(p - Vec3(0, 0, e))) / (2 * e));
            const Vec3 g = f->gradient(p);
            const float scale = std::max(1.0f, length(fd));
            EXPECT_NEAR(g.x, fd.x, 2e-3f * scale) << "opcode " << ops[0];
            EXPECT_NEAR(g.y, fd.y, 2e-3f * scale) << "opcode " << ops[0];
            EXPECT_NEAR(g.z, fd.z, 2e-3f * scale) << "opcode " << ops[0];
        }
    }
}

TEST(Blobby, SegmentBlobFieldFallsWithDistanceFromTheSegment) {
    // Ends (-1, 0, 0) and (1, 0, 0), radius 0.8, identity matrix.
    std::vector<float> seg = {-1, 0, 0, 1, 0, 0, 0.8f, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    auto f = field(blobby(1, {1002, 0}, seg));
    ASSERT_TRUE(f);
    for (float y : {0.0f, 0.2f, 0.5f, 0.79f}) {
        EXPECT_NEAR(f->value(Vec3(0.3f, y, 0)), bump(double(y * y) / 0.64), 1e-5);
        // Beyond an end the distance is to the end point.
        EXPECT_NEAR(f->value(Vec3(1.3f, y, 0)), bump(double(0.09f + y * y) / 0.64), 1e-5);
    }
}

TEST(Blobby, DicedSphereLiesOnTheThresholdWithOutwardNormalsAndWinding) {
    const Vec3 c(0.2f, -0.1f, 0.3f);
    Diagnostics diag;
    auto prims = makePrimitives(blobby(1, {1001, 0}, sphereLeaf(2, c)), diag);
    ASSERT_EQ(prims.size(), 1u);
    EXPECT_FALSE(prims[0]->diceable());
    auto pieces = splitToDiceable(std::move(prims));
    ASSERT_GT(pieces.size(), 8u);
    double area = 0;
    for (const auto& piece : pieces) {
        Grid g = piece->dice(4, 4);
        ASSERT_TRUE(g.ownNormals);
        const Bound3 b = piece->bound();
        for (int k = 0; k < g.vertexCount(); ++k) {
            const Vec3 p = g.P[size_t(k)];
            // The surface of scale 2 is the sphere of radius 1 about c.
            EXPECT_NEAR(length(p - c), 1.0f, 1e-4f);
            EXPECT_GT(dot(g.N[size_t(k)], normalize(p - c)), 0.999f);
            EXPECT_TRUE(inside(b, p, 1e-5f));
        }
        // dPdu x dPdv, the geometric normal, points outward too.
        const Vec3 p00 = g.P[size_t(g.index(0, 0))], p20 = g.P[size_t(g.index(2, 0))];
        const Vec3 p02 = g.P[size_t(g.index(0, 2))];
        EXPECT_GT(dot(cross(p20 - p00, p02 - p00), p00 - c), 0);
        area += gridArea(piece->dice(16, 16));
    }
    EXPECT_NEAR(area, 4 * kPi, 4 * kPi * 0.005);
}

TEST(Blobby, VertexAndVaryingValuesBlendByEachLeafsShareOfTheField) {
    const Vec3 c0(-0.6f, 0, 0), c1(0.6f, 0, 0);
    auto rec = blobby(2, {1001, 0, 1001, 16, 0, 2, 0, 1}, concat(sphereLeaf(2, c0), sphereLeaf(2, c1)),
                      {testsupport::floatParam("Cs", ri::ParamType::Color, {1, 0, 0, 0, 0, 1}, ri::StorageClass::Vertex),
                       testsupport::floatParam("st", ri::ParamType::Float, {0, 1, 2, 5}, ri::StorageClass::Varying, 2)});
    Diagnostics diag;
    auto pieces = splitToDiceable(makePrimitives(rec, diag));
    EXPECT_EQ(diag.errorCount(), 0);
    ASSERT_FALSE(pieces.empty());
    int checked = 0;
    for (const auto& piece : pieces) {
        Grid g = piece->dice(3, 3);
        const GridVar* cs = g.find("Cs");
        const GridVar* gs = g.find("s");
        const GridVar* gt = g.find("t");
        ASSERT_TRUE(cs && cs->perVertex && gs && gt);
        for (int k = 0; k < g.vertexCount(); ++k) {
            const Vec3 p = g.P[size_t(k)];
            const double w0 = sphereField(p, 2, c0), w1 = sphereField(p, 2, c1);
            EXPECT_NEAR(w0 + w1, kT, 1e-4);  // on the surface of the sum
            EXPECT_NEAR(cs->at(k)[0], w0 / (w0 + w1), 1e-4);
            EXPECT_NEAR(cs->at(k)[2], w1 / (w0 + w1), 1e-4);
            EXPECT_NEAR(cs->at(k)[1], 0, 1e-6);
            // "st" feeds s and t, each blended alike.
            EXPECT_NEAR(gs->at(k)[0], 2 * w1 / (w0 + w1), 2e-4);
            EXPECT_NEAR(gt->at(k)[0], (w0 + 5 * w1) / (w0 + w1), 5e-4);
            ++checked;
        }
    }
    EXPECT_GT(checked, 100);
}

TEST(Blobby, MalformedCodeIsReportedAtTheRequest) {
    struct Case {
        int nleaf;
        std::vector<int> code;
        size_t floats;
        const char* message;
    };
    const Case cases[] = {
        {1, {1001, 0}, 15, "test.rib:3:1: error: Blobby: instruction 0 (ellipsoid) reads floats 0..15, but the floats "
                           "array has 15"},
        {1, {1001}, 16, "test.rib:3:1: error: Blobby: the code array ends inside instruction 0, expected the float "
                        "index of an ellipsoid's matrix"},
        {2, {1001, 0, 0, 2, 0, 1}, 16, "test.rib:3:1: error: Blobby: instruction 1 refers to instruction 1, expected "
                                       "one of 0..0"},
        {2, {1001, 0}, 16, "test.rib:3:1: error: Blobby: nleaf is 2, but the code has 1 leaves (opcodes 1000-1003)"},
        {1, {1001, 0, 42}, 16, "test.rib:3:1: error: Blobby: unknown opcode 42 at code position 2, expected 0-7 "
                               "(operations) or 1000-1003 (leaves)"},
        {1, {1001, 0, 0, 0}, 16, "test.rib:3:1: error: Blobby: instruction 1 has 0 operands, expected at least 1"},
        {2, {1001, 0, 1003, 1, 16, 0, 2, 0, 1}, 20, "test.rib:3:1: error: Blobby: instruction 1 (depth-map plane) "
                                                    "reads string 1, but the strings array has 1"},
        {2, {1001, 0, 1003, 0, 16, 0, 2, 0, 1}, 20, "test.rib:3:1: error: Blobby: instruction 1 (depth-map plane) has "
                                                    "parameters 0 0 0 0, expected finite ones with a positive cut-off "
                                                    "height (the first) and bulge height (the third)"},
    };
    for (const Case& c : cases) {
        Diagnostics diag;
        diag.setRecord(true);
        diag.setQuiet(true);
        std::vector<float> floats(c.floats, 0.0f);
        for (size_t k = 0; k < std::min<size_t>(16, floats.size()); k += 5) floats[k] = 1;
        EXPECT_TRUE(makePrimitives(blobby(c.nleaf, c.code, floats), diag).empty());
        ASSERT_EQ(diag.recorded().size(), 1u);
        EXPECT_EQ(diag.recorded()[0].str(), c.message);
    }
}

TEST(Blobby, DepthMapPlaneWhoseMapCannotBeReadIsWarnedAndContributesNothing) {
    // RI spec 3.2's example: an ellipsoid added to a repelling plane, whose
    // map is not there.
    auto rec = sphereOverPlane(1.5f, {0, 0, -.1f}, "no-such-dir/flat.zfile", {.4f, .01f, .3f, .08f});
    Diagnostics diag;
    diag.setRecord(true);
    diag.setQuiet(true);
    auto prims = makePrimitives(rec, diag);
    EXPECT_EQ(prims.size(), 1u);
    ASSERT_EQ(diag.recorded().size(), 1u);
    EXPECT_EQ(diag.recorded()[0].str(),
              "test.rib:3:1: warning: Blobby: cannot read the depth map of repelling plane leaf 1 (opcode 1003): "
              "cannot open \"no-such-dir/flat.zfile\"; the leaf contributes nothing to the field");
    // The field is the ellipsoid's alone, and so is the surface.
    auto f = field(rec);
    auto alone = field(blobby(1, {1001, 0}, sphereLeaf(1.5f, {0, 0, -.1f})));
    ASSERT_TRUE(f && alone);
    for (int i = 0; i < 50; ++i) {
        const Vec3 p(std::sin(1.3f * float(i)), std::cos(0.7f * float(i)), 0.04f * float(i) - 1);
        EXPECT_EQ(f->value(p), alone->value(p)) << i;
    }
    Diagnostics quiet;
    auto aloneMade = makePrimitives(blobby(1, {1001, 0}, sphereLeaf(1.5f, {0, 0, -.1f})), quiet);
    ASSERT_EQ(aloneMade.size(), 1u);
    EXPECT_EQ(prims[0]->bound().min, aloneMade[0]->bound().min);
    EXPECT_EQ(prims[0]->bound().max, aloneMade[0]->bound().max);
}

TEST(Blobby, DepthMapPlaneFieldIsTheNotesRepulsionOfTheHeightAboveTheMap) {
    // A sloping ground z = 0.1 x in a zfile; the Blobby's object space is
    // moved by (0.3, -0.2, 0.1) in the world, so a point p is at height
    // (p + t).z - 0.1 (p + t).x above the ground (bilinear filtering between
    // texel centres is exact for the linear depth).
    const std::string map = writeGroundMap("blobby-slope", [](float x, float) { return 0.1f * x; });
    const Vec3 t(0.3f, -0.2f, 0.1f), c(0.1f, 0.1f, 0.35f);
    const double A = 0.4, B = 0.01, C = 0.3, D = 0.08;
    auto rec = sphereOverPlane(1.2f, c, map, {float(A), float(B), float(C), float(D)});
    rec->worldFromObject = Mat4::translate(t);
    auto f = field(rec);
    ASSERT_TRUE(f);
    auto expected = [&](double x, double y, double z) {
        const double dx = (x - c.x) / 1.2, dy = (y - c.y) / 1.2, dz = (z - c.z) / 1.2;
        const double height = (z + t.z) - 0.1 * (x + t.x);
        return bump(dx * dx + dy * dy + dz * dz) + noteRepulsion(height, A, B, C, D);
    };
    int compared = 0, repelled = 0, bulged = 0, gradients = 0;
    float leaves[2];
    for (int i = 0; i < 2000; ++i) {
        const Vec3 p = c + Vec3(std::sin(1.7f * float(i)), std::cos(2.3f * float(i)), std::sin(0.37f * float(i))) *
                               1.1f;
        const double height = double(p.z + t.z) - 0.1 * double(p.x + t.x);
        if (std::abs(height) < 0.01) continue;  // B / z: the float height's rounding would dominate
        const double e = expected(p.x, p.y, p.z);
        EXPECT_NEAR(f->value(p, leaves), e, 1e-4 * std::abs(e) + 1e-5) << i;
        EXPECT_NEAR(leaves[1], e - bump(double(dot((p - c) / 1.2f, (p - c) / 1.2f))), 1e-4 * std::abs(e) + 1e-5);
        ++compared;
        repelled += leaves[1] < -0.01f;
        bulged += leaves[1] > 0.001f;
        // The gradient, against central differences of the field written
        // here, away from the clamp and the cut-off's kinks.
        if (height > 0.02 && height < A - 0.02) {
            const double h = 1e-5;
            const Vec3 g = f->gradient(p);
            const double gx = (expected(p.x + h, p.y, p.z) - expected(p.x - h, p.y, p.z)) / (2 * h);
            const double gy = (expected(p.x, p.y + h, p.z) - expected(p.x, p.y - h, p.z)) / (2 * h);
            const double gz = (expected(p.x, p.y, p.z + h) - expected(p.x, p.y, p.z - h)) / (2 * h);
            const double tol = 2e-3 * std::max(1.0, std::sqrt(gx * gx + gy * gy + gz * gz));
            EXPECT_NEAR(g.x, gx, tol) << i;
            EXPECT_NEAR(g.y, gy, tol) << i;
            EXPECT_NEAR(g.z, gz, tol) << i;
            ++gradients;
        }
    }
    EXPECT_GT(compared, 1500);
    EXPECT_GT(repelled, 100);
    EXPECT_GT(bulged, 50);
    EXPECT_GT(gradients, 100);
    // Outside the ellipsoid's support box the plane does not act (it has
    // no support of its own), even right at the ground.
    const Vec3 far(c.x + 1.3f, c.y, 0.1f * (c.x + 1.3f + t.x) - t.z + 0.05f);
    EXPECT_EQ(f->value(far), 0.0f);
    std::filesystem::remove(map);
}

TEST(Blobby, DepthMapPlaneReadsItsMapAgainOnceItIsRewritten) {
    // Blobbies naming one map share what was read, but not past a rewrite:
    // the ground moves from z = 0 to z = 0.1 under the same name while the
    // first Blobby still holds the old one.
    const double A = 0.4, B = 0.01, C = 0.3, D = 0.08;
    const Vec3 p(0.1f, 0, 0.15f);
    const double sphere = sphereField(p, 1.2f, {0, 0, 0.45f});
    const std::string map = writeGroundMap("blobby-rewrite", [](float, float) { return 0.0f; });
    auto make = [&] {
        return field(sphereOverPlane(1.2f, {0, 0, 0.45f}, map, {float(A), float(B), float(C), float(D)}));
    };
    auto before = make();
    EXPECT_EQ(writeGroundMap("blobby-rewrite", [](float, float) { return 0.1f; }), map);
    auto after = make(), again = make();
    ASSERT_TRUE(before && after && again);
    EXPECT_NEAR(before->value(p), sphere + noteRepulsion(0.15, A, B, C, D), 1e-5);
    EXPECT_NEAR(after->value(p), sphere + noteRepulsion(0.05, A, B, C, D), 1e-4);
    EXPECT_EQ(again->value(p), after->value(p));
    std::filesystem::remove(map);
}

TEST(Blobby, DepthMapPlanePushesTheDicedSurfaceOffTheGround) {
    // A sphere leaf of surface radius 0.6 above a flat ground, added to the
    // spec's example plane: the plane pushes its bottom up to where the
    // combined field along the vertical through the centre first reaches
    // the threshold (the field is largest on that line at every height, so
    // the surface's lowest point is on it). Found here by bisection. Centred
    // 0.45 up, the sphere alone would reach 0.15 under the ground; centred
    // 0.02 under it, Newton steps from inside overshoot into the ground,
    // where the plane's field is flat, and must come back.
    const std::string map = writeGroundMap("blobby-flat", [](float, float) { return 0.0f; });
    const double A = 0.4, B = 0.01, C = 0.3, D = 0.08;
    for (const double centre : {0.45, -0.02}) {
        SCOPED_TRACE(centre);
        auto field = [&](double r2xy, double z) {
            return bump((r2xy + (z - centre) * (z - centre)) / 1.44) + noteRepulsion(z, A, B, C, D);
        };
        double lo = 1e-6, hi = 0.3;
        for (int k = 0; k < 60; ++k) (field(0, (lo + hi) / 2) >= kT ? hi : lo) = (lo + hi) / 2;
        const double lowest = hi;
        EXPECT_GT(lowest, centre > 0 ? 0.03 : 0.005);  // off the ground
        Diagnostics diag;
        auto prims = makePrimitives(
            sphereOverPlane(1.2f, {0, 0, float(centre)}, map, {float(A), float(B), float(C), float(D)}), diag);
        EXPECT_EQ(diag.warningCount() + diag.errorCount(), 0);
        ASSERT_EQ(prims.size(), 1u);
        float minZ = kInfinity, maxZ = -kInfinity;
        int outsideBound = 0, offSurface = 0;
        for (const auto& piece : splitToDiceable(std::move(prims))) {
            const Grid g = piece->dice(8, 8);
            const Bound3 b = piece->bound();
            for (const Vec3& p : g.P) {
                outsideBound += !inside(b, p, 1e-5f);
                minZ = std::min(minZ, p.z);
                maxZ = std::max(maxZ, p.z);
                offSurface += !(std::abs(field(double(p.x * p.x + p.y * p.y), p.z) - kT) < 1e-4);
            }
        }
        EXPECT_EQ(offSurface, 0);
        EXPECT_EQ(outsideBound, 0);  // each piece's bound holds its surface, flattened part and all
        EXPECT_GE(minZ, lowest - 1e-4);
        EXPECT_NEAR(minZ, lowest, 5e-3);
        EXPECT_NEAR(maxZ, centre + 0.6, 2e-3);  // the top, above the cut-off height, is the sphere's
    }
    std::filesystem::remove(map);
}

TEST(Blobby, DepthMapPlaneOverAWavyGroundKeepsEveryDicedPointOnTheSurfaceAboveIt) {
    // Three blobs pressed into a wavy ground: coarse triangles bridge its
    // hollows, so some points start under it, where the plane's field is
    // flat; each must still end on the threshold (the field evaluated by
    // the code under test, whose values are checked above) and above the
    // ground (within the bilinear map's error, about 0.002 here).
    auto ground = [](float x, float y) { return 0.12f * std::sin(4 * x) * std::cos(3 * y); };
    const std::string map = writeGroundMap("blobby-wavy", ground);
    auto rec = blobby(4, {1001, 0, 1001, 16, 1001, 32, 1003, 0, 48, 0, 4, 0, 1, 2, 3},
                      concat(concat(concat(sphereLeaf(1.6f, {-0.5f, 0, 0.2f}), sphereLeaf(1.2f, {0.4f, 0.3f, 0.1f})),
                                    sphereLeaf(1.0f, {0.1f, -0.5f, 0.0f})),
                             {0.4f, 0.01f, 0.3f, 0.08f}));
    rec->stringArgs = {map};
    Diagnostics diag;
    auto prims = makePrimitives(rec, diag);
    ASSERT_EQ(prims.size(), 1u);
    auto f = field(rec);
    ASSERT_TRUE(f);
    int points = 0, offSurface = 0, under = 0;
    for (const auto& piece : splitToDiceable(std::move(prims))) {
        const Grid g = piece->dice(6, 6);
        for (const Vec3& p : g.P) {
            ++points;
            // Distance to the surface, to first order: within float
            // precision (near the ground the field is steep).
            offSurface += !(std::abs(f->value(p) - kT) / std::max(1.0f, length(f->gradient(p))) < 1e-5f);
            under += p.z < ground(p.x, p.y) + 0.002f;
        }
    }
    EXPECT_GT(points, 10000);
    EXPECT_EQ(offSurface, 0);
    EXPECT_EQ(under, 0);
    std::filesystem::remove(map);
}

TEST(Blobby, PolygonisationIsCappedWithAWarning) {
    // A leaf a thousand times smaller than the other would ask for a
    // lattice of thousands of cells along each axis.
    auto rec = blobby(2, {1001, 0, 1001, 16, 0, 2, 0, 1},
                      concat(sphereLeaf(2, {}), sphereLeaf(0.002f, {3, 0, 0})));
    Diagnostics diag;
    diag.setRecord(true);
    diag.setQuiet(true);
    auto prims = makePrimitives(rec, diag);
    ASSERT_EQ(diag.recorded().size(), 1u);
    EXPECT_NE(diag.recorded()[0].str().find("test.rib:3:1: warning: Blobby: its smallest leaf asks for"), std::string::npos)
        << diag.recorded()[0].str();
    // The big leaf is still there.
    ASSERT_EQ(prims.size(), 1u);
    EXPECT_NEAR(prims[0]->bound().max.x, 1, 0.1);
}

// A Blobby inside MotionBegin: `first` and the other shapes, at times 0, 1, ...
std::shared_ptr<scene::PrimitiveRecord> deforming(std::shared_ptr<scene::PrimitiveRecord> first,
                                                  const std::vector<std::shared_ptr<scene::PrimitiveRecord>>& others) {
    first->shapeTimes = {0};
    for (const auto& o : others) {
        first->shapeTimes.push_back(float(first->shapeTimes.size()));
        first->shapes.push_back(*o);
    }
    return first;
}

// Every shape of every piece diced at 5x5: shape k's points, piece after piece.
std::vector<std::vector<Vec3>> dicedShapes(std::vector<PrimitivePtr> prims, int shapes) {
    std::vector<std::vector<Vec3>> out(static_cast<size_t>(shapes));
    for (const auto& piece : splitToDiceable(std::move(prims))) {
        EXPECT_EQ(piece->shapeCount(), shapes);
        for (int k = 0; k < shapes; ++k) {
            std::vector<Vec3> P;
            piece->diceShape(k, 5, 5, ViewContext{}, P);
            out[size_t(k)].insert(out[size_t(k)].end(), P.begin(), P.end());
        }
    }
    return out;
}

TEST(Blobby, DeformationBlurCarriesARigidlyMovedLeafPointForPoint) {
    // One sphere leaf, moved and turned between the shapes: shape 1's
    // surface is shape 0's under the same rigid motion, point for point
    // (the corners are carried exactly; projection commutes with a rigid
    // motion), and on the second field's threshold.
    const float c = std::cos(0.5f), s = std::sin(0.5f);
    // Leaf scale 2 turned by 0.5 rad about z and centred at (1, 0.5, -0.25), RIB order (row vectors).
    const std::vector<float> turned = {2 * c, 2 * s, 0, 0, -2 * s, 2 * c, 0, 0, 0, 0, 2, 0, 1, 0.5f, -0.25f, 1};
    auto rec = deforming(blobby(1, {1001, 0}, sphereLeaf(2, {})), {blobby(1, {1001, 0}, turned)});
    Diagnostics diag;
    auto prims = makePrimitives(rec, diag);
    EXPECT_EQ(diag.errorCount() + diag.warningCount(), 0);
    ASSERT_EQ(prims.size(), 1u);
    EXPECT_NEAR(prims[0]->bound().max.x, 2, 0.1);  // both shapes: out to 1 + 1
    EXPECT_NEAR(prims[0]->bound().min.x, -1, 0.1);
    const auto shapes = dicedShapes(std::move(prims), 2);
    ASSERT_GT(shapes[0].size(), 500u);
    ASSERT_EQ(shapes[0].size(), shapes[1].size());
    auto f1 = field(blobby(1, {1001, 0}, turned));
    int moved = 0, offSurface = 0;
    for (size_t i = 0; i < shapes[0].size(); ++i) {
        const Vec3 p = shapes[0][i];
        const Vec3 expected(c * p.x - s * p.y + 1, s * p.x + c * p.y + 0.5f, p.z - 0.25f);
        moved += length(shapes[1][i] - expected) < 1e-4f;
        offSurface += !(std::abs(f1->value(shapes[1][i]) - kT) < 1e-4f);
    }
    EXPECT_EQ(moved, int(shapes[0].size()));
    EXPECT_EQ(offSurface, 0);
}

TEST(Blobby, DeformationBlurOfLeavesMovingApartStaysOnEachShapesSurface) {
    // Two bridged leaves, the second moving away and growing, a segment
    // blob sliding: every shape's diced points lie on that shape's surface,
    // and the shapes differ where the leaves moved.
    auto shape = [](float x, float scale, float slide) {
        std::vector<float> segment = {slide, 0, 0, slide + 1, 0, 0, 0.5f};
        const std::vector<float> identity = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, -1.2f, 0, 1};
        segment.insert(segment.end(), identity.begin(), identity.end());
        return blobby(3, {1001, 0, 1001, 16, 1002, 32, 0, 3, 0, 1, 2},
                      concat(concat(sphereLeaf(1.6f, {}), sphereLeaf(scale, {x, 0, 0})), segment));
    };
    auto rec = deforming(shape(1.0f, 1.6f, 0), {shape(1.3f, 1.8f, 0.2f), shape(1.5f, 2.0f, 0.4f)});
    Diagnostics diag;
    auto prims = makePrimitives(rec, diag);
    EXPECT_EQ(diag.errorCount(), 0);
    const auto shapes = dicedShapes(std::move(prims), 3);
    ASSERT_GT(shapes[0].size(), 500u);
    const std::shared_ptr<const BlobbyField> fields[3] = {field(shape(1.0f, 1.6f, 0)), field(shape(1.3f, 1.8f, 0.2f)),
                                                          field(shape(1.5f, 2.0f, 0.4f))};
    for (int k = 0; k < 3; ++k) {
        int offSurface = 0;
        for (const Vec3& p : shapes[size_t(k)])
            offSurface += !(std::abs(fields[k]->value(p) - kT) / std::max(1.0f, length(fields[k]->gradient(p))) < 1e-4f);
        EXPECT_EQ(offSurface, 0) << "shape " << k;
    }
    float reach[3] = {-kInfinity, -kInfinity, -kInfinity};
    for (int k = 0; k < 3; ++k)
        for (const Vec3& p : shapes[size_t(k)]) reach[k] = std::max(reach[k], p.x);
    // The moving leaf's far side: 1 + 0.8, 1.3 + 0.9, 1.5 + 1 (a lone leaf's surface at half its scale).
    EXPECT_NEAR(reach[0], 1.8f, 0.05f);
    EXPECT_NEAR(reach[1], 2.2f, 0.05f);
    EXPECT_NEAR(reach[2], 2.5f, 0.05f);
}

TEST(Blobby, DeformationBlurOfShapesWithOtherLeavesIsAnErrorAndTheFirstShapeRenders) {
    auto rec = deforming(blobby(1, {1001, 0}, sphereLeaf(2, {})),
                         {blobby(2, {1001, 0, 1001, 16, 0, 2, 0, 1}, concat(sphereLeaf(2, {}), sphereLeaf(2, {1, 0, 0})))});
    Diagnostics diag;
    diag.setRecord(true);
    diag.setQuiet(true);
    auto prims = makePrimitives(rec, diag);
    ASSERT_EQ(prims.size(), 1u);
    EXPECT_EQ(prims[0]->shapeCount(), 1);
    EXPECT_NEAR(prims[0]->bound().max.x, 1, 0.1);  // the first shape, centred at the origin
    ASSERT_EQ(diag.recorded().size(), 1u);
    EXPECT_EQ(diag.recorded()[0].str(), "test.rib:3:1: error: Blobby: this motion shape cannot blur with the first: it "
                                        "has 2 leaves where the first shape has 1 (the Blobby renders unblurred)");
}

TEST(Blobby, ManyLeavesGiveTheFieldOfEveryLeafWhereverThePoint) {
    // 60 leaves on a helix under add, max and a subtract: the field at
    // points inside, between and beyond them, against the sum written here
    // (each point evaluates only the leaves near it).
    std::vector<float> floats;
    std::vector<Vec3> centres;
    std::vector<int> leafCode, all;
    for (int k = 0; k < 60; ++k) {
        const Vec3 c(std::cos(0.4f * float(k)) * 2, std::sin(0.4f * float(k)) * 2, 0.1f * float(k) - 3);
        centres.push_back(c);
        const auto leaf = sphereLeaf(0.7f, c);
        floats.insert(floats.end(), leaf.begin(), leaf.end());
        leafCode.insert(leafCode.end(), {1001, 16 * k});
        all.push_back(k);
    }
    auto code = [&](int op) {
        std::vector<int> c = leafCode;
        c.insert(c.end(), {op, 60});
        c.insert(c.end(), all.begin(), all.end());
        c.insert(c.end(), {4, 60, 7});  // (add or max) minus leaf 7
        return c;
    };
    for (int op : {0, 2}) {
        auto f = field(blobby(60, code(op), floats));
        ASSERT_TRUE(f);
        std::vector<float> leaves(60);
        for (int i = 0; i < 400; ++i) {
            const Vec3 p(std::sin(1.7f * float(i)) * 2.6f, std::cos(2.3f * float(i)) * 2.6f, 0.017f * float(i) - 3.4f);
            double combined = op == 0 ? 0 : -1;
            for (const Vec3& c : centres) {
                const double v = sphereField(p, 0.7f, c);
                combined = op == 0 ? combined + v : std::max(combined, v);
            }
            const double expected = combined - sphereField(p, 0.7f, centres[7]);
            EXPECT_NEAR(f->value(p, leaves.data()), expected, 1e-5) << i;
            for (int k = 0; k < 60; ++k) EXPECT_NEAR(leaves[size_t(k)], sphereField(p, 0.7f, centres[size_t(k)]), 1e-5);
        }
    }
}
