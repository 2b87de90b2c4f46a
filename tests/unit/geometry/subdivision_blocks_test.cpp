// Regular regions of Catmull-Clark meshes as bicubic B-spline blocks
// (makeSubdivisionMesh with a block side): every block grid vertex is the
// limit point OpenSubdiv's own per-face evaluation (SubdivFace) gives.

#include "geometry_test_util.h"
#include "umbra/geometry/patch.h"
#include "umbra/geometry/subdivision.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace umbra;
using namespace umbra::geometry;

namespace {

constexpr int kN = 12;  // quads around the torus, both ways

// An n x n torus of quads, face (i, j) = j * n + i with corners
// (i, j) (i+1, j) (i+1, j+1) (i, j+1): u along i, v along j. Optional
// crease tags along the ring j = 0.
std::shared_ptr<scene::PrimitiveRecord> torus(bool crease, std::vector<ri::Param> extra = {}) {
    std::vector<float> P;
    for (int j = 0; j < kN; ++j)
        for (int i = 0; i < kN; ++i) {
            const float a = 2 * kPi * float(i) / kN, b = 2 * kPi * float(j) / kN, r = 1 + 0.35f * std::cos(b);
            P.insert(P.end(), {r * std::cos(a), r * std::sin(a), 0.35f * std::sin(b) + 0.05f * float(i % 2)});
        }
    std::vector<int> nverts(kN * kN, 4), verts;
    auto at = [](int i, int j) { return (j % kN) * kN + i % kN; };
    for (int j = 0; j < kN; ++j)
        for (int i = 0; i < kN; ++i) verts.insert(verts.end(), {at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)});
    extra.push_back(testutil::pointParam(P));
    auto r = testutil::record("SubdivisionMesh", crease ? std::vector<float>{3} : std::vector<float>{}, std::move(extra));
    r->stringArgs = {"catmull-clark"};
    r->intArrays = {nverts, verts};
    if (crease) {
        r->stringArgs.push_back("crease");
        std::vector<int> ring;
        for (int i = 0; i <= kN; ++i) ring.push_back(at(i, 0));
        r->intArrays.push_back({int(ring.size()), 1});
        r->intArrays.push_back(ring);
    }
    return r;
}

std::vector<PrimitivePtr> make(const std::shared_ptr<scene::PrimitiveRecord>& rec, int side) {
    Diagnostics diag;
    std::vector<PrimitivePtr> out;
    makeSubdivisionMesh(rec, diag, out, side);
    EXPECT_EQ(diag.errorCount(), 0);
    return out;
}

const SubdivFace* faceOf(const std::vector<PrimitivePtr>& pieces, int face) {
    for (const auto& p : pieces)
        if (auto* f = dynamic_cast<const SubdivFace*>(p.get()); f && f->face() == face) return f;
    return nullptr;
}

}  // namespace

TEST(SubdivisionBlocks, RegularTorusDicePointsAreTheLimitSurface) {
    auto rec = torus(false);
    auto blocks = make(rec, 8);
    // Every face is regular: greedy rectangles from face 0 are 8 x 8,
    // 4 x 8 (the row meets face 0 again), 8 x 4 and 4 x 4, and no faces
    // are left to the mesh.
    ASSERT_EQ(blocks.size(), 4u);
    const int expected[4][2] = {{8, 8}, {4, 8}, {8, 4}, {4, 4}};
    const int origin[4][2] = {{0, 0}, {8, 0}, {0, 8}, {8, 8}};
    const auto faces = testutil::splitToDiceable(make(rec, 0));
    ASSERT_EQ(faces.size(), size_t(kN * kN));
    for (int b = 0; b < 4; ++b) {
        const auto* block = dynamic_cast<const BicubicBlock*>(blocks[size_t(b)].get());
        ASSERT_NE(block, nullptr);
        EXPECT_EQ(block->columns(), expected[b][0]);
        EXPECT_EQ(block->rows(), expected[b][1]);
        const int nu = 13, nv = 9;  // patch edges on and off grid lines
        const Grid g = block->dice(nu, nv);
        const Bound3 bound = block->bound();
        for (int j = 0; j <= nv; ++j)
            for (int i = 0; i <= nu; ++i) {
                const double U = double(block->columns()) * i / nu, V = double(block->rows()) * j / nv;
                const int p = std::min(int(U), block->columns() - 1), q = std::min(int(V), block->rows() - 1);
                const SubdivFace* f = faceOf(faces, (origin[b][1] + q) * kN + origin[b][0] + p);
                ASSERT_NE(f, nullptr);
                const Vec3 want = f->evaluate(float(U - p), float(V - q));
                const Vec3 got = g.P[size_t(g.index(i, j))];
                EXPECT_LT(length(got - want), 2e-5f) << b << ": " << i << " " << j;
                EXPECT_TRUE(testutil::inside(bound, got, 1e-5f));
            }
        // u, v run face by face: one unit a face, as each face's own.
        EXPECT_NEAR(g.du, double(block->columns()) / nu, 1e-6);
    }
}

TEST(SubdivisionBlocks, CreasedAndIrregularFacesStayFaces) {
    // A crease along the ring j = 0 makes the faces at its vertices
    // (rows 11 and 0) irregular: they stay with the mesh, the other 120
    // faces go into blocks.
    auto pieces = make(torus(true), 8);
    int inBlocks = 0, meshes = 0;
    for (const auto& p : pieces) {
        if (auto* b = dynamic_cast<const BicubicBlock*>(p.get())) inBlocks += b->columns() * b->rows();
        else if (dynamic_cast<const BicubicPatch*>(p.get())) inBlocks += 1;
        else if (dynamic_cast<const SubdivMesh*>(p.get())) ++meshes;
    }
    EXPECT_EQ(inBlocks, kN * kN - 2 * kN);
    EXPECT_EQ(meshes, 1);
    // The faces left to the mesh: exactly the two rows.
    std::vector<PrimitivePtr> meshOnly;
    for (auto& p : pieces)
        if (dynamic_cast<const SubdivMesh*>(p.get())) meshOnly.push_back(std::move(p));
    const auto faces = testutil::splitToDiceable(std::move(meshOnly));
    ASSERT_EQ(faces.size(), size_t(2 * kN));
    for (const auto& f : faces) {
        const int face = dynamic_cast<const SubdivFace&>(*f).face();
        EXPECT_TRUE(face / kN == 0 || face / kN == kN - 1) << face;
    }
}

TEST(SubdivisionBlocks, VariablesOtherThanVertexKeepFaces) {
    std::vector<float> w(kN * kN);
    auto pieces = make(torus(false, {testutil::floatParam("w", ri::ParamType::Float, w, ri::StorageClass::Varying)}), 8);
    ASSERT_EQ(pieces.size(), 1u);
    EXPECT_NE(dynamic_cast<const SubdivMesh*>(pieces[0].get()), nullptr);
    // Vertex-class values ride on the blocks, with the B-spline basis, which
    // is the limit of a regular face: a value equal to x follows P.x.
    std::vector<float> x;
    for (int j = 0; j < kN; ++j)
        for (int i = 0; i < kN; ++i) {
            const float a = 2 * kPi * float(i) / kN, b = 2 * kPi * float(j) / kN;
            x.push_back((1 + 0.35f * std::cos(b)) * std::cos(a));
        }
    auto withX = make(torus(false, {testutil::floatParam("h", ri::ParamType::Float, x, ri::StorageClass::Vertex)}), 8);
    ASSERT_EQ(withX.size(), 4u);
    const Grid g = withX[0]->dice(8, 8);
    const GridVar* h = g.find("h");
    ASSERT_TRUE(h);
    for (int k = 0; k < g.vertexCount(); ++k) EXPECT_NEAR(h->at(k)[0], g.P[size_t(k)].x, 1e-5f);
}
