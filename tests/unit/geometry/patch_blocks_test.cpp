// Blocks of bicubic patches (BicubicBlock, geometry/patch.h): a block's
// grid is, vertex for vertex, what its patches give one by one.

#include "geometry_test_util.h"

#include "umbra/geometry/patch.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace umbra;
using namespace umbra::geometry;
using namespace umbra::testutil;

namespace {

// A nu x nv control mesh, wavy in z; "h" (vertex) equals x, so it must
// follow P.x under any basis (the bases reproduce affine functions).
std::shared_ptr<scene::PrimitiveRecord> mesh(int nu, const char* uwrap, int nv, const char* vwrap,
                                             const scene::Basis& basis, int patchBlock,
                                             std::vector<ri::Param> extra = {}) {
    std::vector<float> P, h;
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i < nu; ++i) {
            P.insert(P.end(), {float(i), float(j) + 0.1f * float(i % 3), std::sin(0.7f * float(i)) * std::cos(0.4f * float(j))});
            h.push_back(float(i));
        }
    extra.push_back(pointParam(P));
    extra.push_back(floatParam("h", ri::ParamType::Float, h, ri::StorageClass::Vertex));
    auto rec = record("PatchMesh", {}, std::move(extra));
    rec->stringArgs = {"bicubic", uwrap, vwrap};
    rec->intArgs = {nu, nv};
    auto attrs = std::make_shared<scene::Attributes>();
    attrs->uBasis = attrs->vBasis = basis;
    ri::Param side;
    side.decl.name = "patchblock";
    side.decl.type = ri::ParamType::Integer;
    side.ints = {patchBlock};
    attrs->user["umbra:patchblock"] = side;
    rec->attributes = attrs;
    return rec;
}

std::vector<PrimitivePtr> make(std::shared_ptr<scene::PrimitiveRecord> rec) {
    Diagnostics diag;
    auto prims = makePrimitives(std::move(rec), diag);
    EXPECT_EQ(diag.errorCount(), 0);
    return prims;
}

// Checks a block's nu x nv grid against the patches of the same mesh made
// one by one (`patches`, row after row, `columns` across): vertex i of a
// row lies i * bu / nu patch widths into the block, on the patch it falls
// in (the earlier one on a shared edge) at the remaining fraction.
void expectBlockMatchesPatches(const BicubicBlock& block, int i0, int j0, int nu, int nv,
                               const std::vector<PrimitivePtr>& patches, int columns, int rows) {
    const Grid g = block.dice(nu, nv);
    ASSERT_EQ(g.nu, nu);
    ASSERT_EQ(g.nv, nv);
    const int bu = block.columns(), bv = block.rows();
    const GridVar* h = g.find("h");
    const GridVar* s = g.find("s");
    const GridVar* w = g.find("w");
    ASSERT_TRUE(h && s);
    for (int j = 0; j <= nv; ++j)
        for (int i = 0; i <= nu; ++i) {
            const double U = double(bu) * i / nu, V = double(bv) * j / nv;
            const int p = std::min(int(std::floor(U)), bu - 1), q = std::min(int(std::floor(V)), bv - 1);
            const auto* patch = dynamic_cast<const BicubicPatch*>(patches[size_t((j0 + q) * columns + i0 + p)].get());
            ASSERT_NE(patch, nullptr);
            const Vec3 want = patch->evaluate(float(U - p), float(V - q));
            const int k = g.index(i, j);
            EXPECT_LT(length(g.P[size_t(k)] - want), 2e-5f) << i << " " << j;
            // Grid u, v over the whole mesh, patch by patch; s, t default to them.
            EXPECT_NEAR(g.u[size_t(k)], (i0 + U) / columns, 1e-6);
            EXPECT_NEAR(g.v[size_t(k)], (j0 + V) / rows, 1e-6);
            EXPECT_NEAR(s->at(k)[0], g.u[size_t(k)], 1e-6);
            EXPECT_NEAR(h->at(k)[0], g.P[size_t(k)].x, 2e-5f);
            // Varying "w" = column + 10 row of its patch corner: bilinear
            // per patch, so U + 10 V across the mesh.
            if (w) {
                EXPECT_NEAR(w->at(k)[0], (i0 + U) + 10 * (j0 + V), 1e-4);
            }
        }
    EXPECT_NEAR(g.du, double(bu) / nu / columns, 1e-7);
    EXPECT_NEAR(g.dv, double(bv) / nv / rows, 1e-7);
    // dicePositions gives the same points.
    std::vector<Vec3> P;
    block.dicePositions(nu, nv, P);
    ASSERT_EQ(P.size(), g.P.size());
    for (size_t k = 0; k < P.size(); ++k) EXPECT_EQ(P[k], g.P[k]);
    // And the bound holds them all.
    const Bound3 b = block.bound();
    for (const Vec3& p : g.P) EXPECT_TRUE(inside(b, p, 1e-5f));
}

ri::Param varyingW(int columns, int rows) {
    std::vector<float> w;
    for (int j = 0; j < rows; ++j)
        for (int i = 0; i < columns; ++i) w.push_back(float(i + 10 * j));
    return floatParam("w", ri::ParamType::Float, w, ri::StorageClass::Varying);
}

}  // namespace

TEST(PatchBlocks, DicePointsEqualPerPatchEvaluation) {
    // 10 x 8 B-spline control points: 7 x 5 patches, one block; 8 x 6
    // varying values.
    const auto basis = scene::Basis::bspline();
    auto blocks = make(mesh(10, "nonperiodic", 8, "nonperiodic", basis, 8, {varyingW(8, 6)}));
    auto patches = make(mesh(10, "nonperiodic", 8, "nonperiodic", basis, 0, {varyingW(8, 6)}));
    ASSERT_EQ(patches.size(), 35u);
    ASSERT_EQ(blocks.size(), 1u);
    const auto* block = dynamic_cast<const BicubicBlock*>(blocks[0].get());
    ASSERT_NE(block, nullptr);
    EXPECT_EQ(block->columns(), 7);
    EXPECT_EQ(block->rows(), 5);
    // Counts that put patch edges on grid lines and counts that do not,
    // finer and coarser than the patches.
    for (auto [nu, nv] : {std::pair{14, 10}, std::pair{17, 9}, std::pair{5, 3}, std::pair{7, 5}, std::pair{1, 1}})
        expectBlockMatchesPatches(*block, 0, 0, nu, nv, patches, 7, 5);
}

TEST(PatchBlocks, PeriodicBezierMeshWithStep) {
    // Bezier, step 3: periodic in u (12 points: 4 patches), 7 rows in v
    // (2 patches), vertex and varying variables.
    const auto basis = scene::Basis::bezier();
    auto blocks = make(mesh(12, "periodic", 7, "nonperiodic", basis, 8, {varyingW(4, 3)}));
    auto patches = make(mesh(12, "periodic", 7, "nonperiodic", basis, 0, {varyingW(4, 3)}));
    ASSERT_EQ(patches.size(), 8u);
    ASSERT_EQ(blocks.size(), 1u);
    const auto* block = dynamic_cast<const BicubicBlock*>(blocks[0].get());
    ASSERT_NE(block, nullptr);
    // "w" wraps around in u, so it is not U + 10 V on the last column:
    // check positions and vertex values with a mesh without it.
    auto plainBlocks = make(mesh(12, "periodic", 7, "nonperiodic", basis, 8));
    auto plainPatches = make(mesh(12, "periodic", 7, "nonperiodic", basis, 0));
    expectBlockMatchesPatches(dynamic_cast<const BicubicBlock&>(*plainBlocks[0]), 0, 0, 13, 6, plainPatches, 4, 2);
    // The wrapped varying values: patch 3's right edge takes column 0's.
    const Grid g = block->dice(8, 2);
    const GridVar* w = g.find("w");
    ASSERT_TRUE(w);
    for (int j = 0; j <= 2; ++j) {
        EXPECT_NEAR(w->at(g.index(6, j))[0], 3 + 10 * j, 1e-5);     // u = 3/4: column 3
        EXPECT_NEAR(w->at(g.index(7, j))[0], 1.5 + 10 * j, 1e-5);   // halfway from column 3 to column 0
        EXPECT_NEAR(w->at(g.index(8, j))[0], 0 + 10 * j, 1e-5);     // the seam: column 0 again
    }
}

TEST(PatchBlocks, SplitsIntoSubBlocksThenPatches) {
    // 20 x 3 patches tile into blocks of at most 8 across: 6 + 7 + 7.
    const auto basis = scene::Basis::bspline();
    auto blocks = make(mesh(23, "nonperiodic", 6, "nonperiodic", basis, 8));
    auto patches = make(mesh(23, "nonperiodic", 6, "nonperiodic", basis, 0));
    ASSERT_EQ(patches.size(), 60u);
    ASSERT_EQ(blocks.size(), 3u);
    int first = 0;
    for (const auto& b : blocks) {
        const auto* block = dynamic_cast<const BicubicBlock*>(b.get());
        ASSERT_NE(block, nullptr);
        EXPECT_EQ(block->rows(), 3);
        expectBlockMatchesPatches(*block, first, 0, 11, 4, patches, 20, 3);
        first += block->columns();
    }
    EXPECT_EQ(first, 20);
    // Splitting (across u as asked while the block is wider than a patch,
    // else across v) ends in the 7 x 3 single patches, each the very patch
    // the mesh makes one by one.
    std::vector<PrimitivePtr> todo;
    blocks[2]->split(true, todo);
    ASSERT_EQ(todo.size(), 2u);
    EXPECT_EQ(dynamic_cast<const BicubicBlock&>(*todo[0]).columns(), 3);
    EXPECT_EQ(dynamic_cast<const BicubicBlock&>(*todo[1]).columns(), 4);
    std::vector<PrimitivePtr> singles;
    while (!todo.empty()) {
        PrimitivePtr p = std::move(todo.back());
        todo.pop_back();
        if (dynamic_cast<const BicubicBlock*>(p.get())) p->split(false, todo);
        else singles.push_back(std::move(p));
    }
    ASSERT_EQ(singles.size(), 21u);
    double area = 0, want = 0;
    for (const auto& s : singles) area += gridArea(s->dice(6, 6));
    for (int j = 0; j < 3; ++j)
        for (int i = 13; i < 20; ++i) want += gridArea(patches[size_t(j * 20 + i)]->dice(6, 6));
    EXPECT_NEAR(area, want, 1e-4 * want);
}

TEST(PatchBlocks, ClassesABlockCannotCarryStayPatchByPatch) {
    // Uniform (one per patch) and facevarying (four per patch) values
    // change from patch to patch: such meshes are diced patch by patch.
    const auto basis = scene::Basis::bspline();
    std::vector<float> id(12);
    for (int k = 0; k < 12; ++k) id[size_t(k)] = float(k);
    auto uniform = make(mesh(7, "nonperiodic", 6, "nonperiodic", basis, 8,
                             {floatParam("id", ri::ParamType::Float, id, ri::StorageClass::Uniform)}));
    EXPECT_EQ(uniform.size(), 12u);
    std::vector<float> fv(48, 0.5f);
    auto faceVarying = make(mesh(7, "nonperiodic", 6, "nonperiodic", basis, 8,
                                 {floatParam("q", ri::ParamType::Float, fv, ri::StorageClass::FaceVarying)}));
    EXPECT_EQ(faceVarying.size(), 12u);
    // Constant values ride on a block as they do on a patch.
    auto constant = make(mesh(7, "nonperiodic", 6, "nonperiodic", basis, 8,
                              {floatParam("k", ri::ParamType::Float, {3}, ri::StorageClass::Constant)}));
    ASSERT_EQ(constant.size(), 1u);
    const Grid g = constant[0]->dice(4, 4);
    ASSERT_TRUE(g.find("k"));
    EXPECT_EQ(g.find("k")->data[0], 3.0f);
    EXPECT_FALSE(g.find("k")->perVertex);
}
