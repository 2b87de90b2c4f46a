// SubdivisionMesh through OpenSubdiv Bfr. The independent answers: limit
// points from Far (uniform refinement, PrimvarRefiner::Interpolate, then
// the exact limit masks of PrimvarRefiner::Limit), the Catmull-Clark first
// level computed by hand, and the cube's outward directions.

#include "geometry_test_util.h"
#include "umbra/geometry/subdivision.h"

#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/topologyDescriptor.h>
#include <opensubdiv/far/topologyRefinerFactory.h>

#include <gtest/gtest.h>

#include <map>

using namespace umbra;
using namespace umbra::geometry;
using testutil::pointParam;

namespace {

namespace osd = OpenSubdiv;

// A cube of side 2 wound as outward-facing RenderMan polygons:
// (p1 - p0) x (p2 - p0) points out of every face.
const std::vector<float> kCubeP = {-1, -1, -1, 1, -1, -1, -1, 1, -1, 1, 1, -1,
                                   -1, -1, 1,  1, -1, 1,  -1, 1, 1,  1, 1, 1};
const std::vector<int> kCubeNverts = {4, 4, 4, 4, 4, 4};
const std::vector<int> kCubeVerts = {0, 2, 3, 1, 4, 5, 7, 6, 0, 1, 5, 4, 2, 6, 7, 3, 0, 4, 6, 2, 1, 3, 7, 5};

std::shared_ptr<scene::PrimitiveRecord> subdivRecord(const std::string& scheme, std::vector<int> nverts,
                                                     std::vector<int> verts, std::vector<float> P,
                                                     std::vector<std::string> tags = {}, std::vector<int> nargs = {},
                                                     std::vector<int> intargs = {}, std::vector<float> floatargs = {},
                                                     std::vector<ri::Param> extra = {}) {
    std::vector<ri::Param> params = {pointParam(std::move(P))};
    for (auto& e : extra) params.push_back(std::move(e));
    auto r = testutil::record("SubdivisionMesh", std::move(floatargs), std::move(params));
    r->stringArgs = {scheme};
    for (auto& t : tags) r->stringArgs.push_back(t);
    r->intArrays = {std::move(nverts), std::move(verts)};
    if (!r->stringArgs.empty() && r->stringArgs.size() > 1) {
        r->intArrays.push_back(std::move(nargs));
        r->intArrays.push_back(std::move(intargs));
    }
    return r;
}

std::vector<PrimitivePtr> diceablePieces(const std::shared_ptr<scene::PrimitiveRecord>& rec, Diagnostics& diag) {
    return testutil::splitToDiceable(makePrimitives(rec, diag));
}

const SubdivFace* findFace(const std::vector<PrimitivePtr>& pieces, int face, int subFace) {
    for (const auto& p : pieces)
        if (auto* f = dynamic_cast<const SubdivFace*>(p.get()); f && f->face() == face && f->subFace() == subFace)
            return f;
    return nullptr;
}

struct XYZ {
    float p[3] = {0, 0, 0};
    void Clear() { p[0] = p[1] = p[2] = 0; }
    void AddWithWeight(const XYZ& s, float w) {
        for (int k = 0; k < 3; ++k) p[k] += w * s.p[k];
    }
    void SetPosition(float x, float y, float z) { p[0] = x, p[1] = y, p[2] = z; }
};

TEST(Subdivision, CubeWithTagsMatchesFarLimitPoints) {
    // Crease along 4-5-7, an infinitely sharp corner at 2, face 2 a hole.
    const std::vector<std::string> tags = {"crease", "corner", "hole", "interpolateboundary"};
    const std::vector<int> nargs = {3, 1, 1, 1, 1, 0, 0, 0};
    const std::vector<int> intargs = {4, 5, 7, 2, 2};
    const std::vector<float> floatargs = {2.5f, 10.0f};
    Diagnostics diag;
    diag.setQuiet(true);
    auto pieces = diceablePieces(
        subdivRecord("catmull-clark", kCubeNverts, kCubeVerts, kCubeP, tags, nargs, intargs, floatargs), diag);
    EXPECT_EQ(diag.errorCount(), 0);
    EXPECT_EQ(pieces.size(), 5u);  // six faces less the hole
    EXPECT_EQ(findFace(pieces, 2, -1), nullptr);

    // The same mesh refined uniformly four times by Far (enough for the
    // crease's sharpness 2.5 to have decayed, so the limit masks are
    // exact); a vertex of level 2 at parameter (i/4, j/4) of a base face
    // keeps that parameter through its child vertices.
    osd::Far::TopologyDescriptor desc;
    desc.numVertices = 8;
    desc.numFaces = 6;
    desc.numVertsPerFace = kCubeNverts.data();
    desc.vertIndicesPerFace = kCubeVerts.data();
    const int creasePairs[] = {4, 5, 5, 7};
    const float creaseWeights[] = {2.5f, 2.5f};
    const int corner[] = {2};
    const float cornerWeight[] = {10.0f};
    const int hole[] = {2};
    desc.numCreases = 2;
    desc.creaseVertexIndexPairs = creasePairs;
    desc.creaseWeights = creaseWeights;
    desc.numCorners = 1;
    desc.cornerVertexIndices = corner;
    desc.cornerWeights = cornerWeight;
    desc.numHoles = 1;
    desc.holeIndices = hole;
    osd::Sdc::Options sdc;
    sdc.SetVtxBoundaryInterpolation(osd::Sdc::Options::VTX_BOUNDARY_EDGE_AND_CORNER);
    using Factory = osd::Far::TopologyRefinerFactory<osd::Far::TopologyDescriptor>;
    std::unique_ptr<osd::Far::TopologyRefiner> refiner(
        Factory::Create(desc, Factory::Options(osd::Sdc::SCHEME_CATMARK, sdc)));
    ASSERT_TRUE(refiner);
    constexpr int kLevels = 4;
    osd::Far::TopologyRefiner::UniformOptions uniform(kLevels);
    uniform.fullTopologyInLastLevel = true;
    refiner->RefineUniform(uniform);
    std::vector<std::vector<XYZ>> levels(kLevels + 1);
    for (int l = 0; l <= kLevels; ++l) levels[size_t(l)].resize(size_t(refiner->GetLevel(l).GetNumVertices()));
    for (int k = 0; k < 8; ++k)
        levels[0][size_t(k)].SetPosition(kCubeP[size_t(k) * 3], kCubeP[size_t(k) * 3 + 1], kCubeP[size_t(k) * 3 + 2]);
    osd::Far::PrimvarRefiner pr(*refiner);
    for (int l = 1; l <= kLevels; ++l) pr.Interpolate(l, levels[size_t(l) - 1], levels[size_t(l)]);
    std::vector<XYZ> lim(levels[kLevels].size());
    pr.Limit(levels[kLevels], lim);
    auto limitOf = [&](int level, osd::Far::Index v) -> const XYZ& {
        for (int l = level; l < kLevels; ++l) v = refiner->GetLevel(l).GetVertexChildVertex(v);
        return lim[size_t(v)];
    };

    const auto& L0 = refiner->GetLevel(0);
    const auto& L1 = refiner->GetLevel(1);
    int checked = 0;
    for (int f : {0, 1, 3, 4, 5}) {
        const SubdivFace* face = findFace(pieces, f, -1);
        ASSERT_NE(face, nullptr) << f;
        // Child face k of a quad holds corner k; its centre (a level-2
        // vertex) sits at the centre of quadrant k.
        const auto children = L0.GetFaceChildFaces(f);
        const float centres[4][2] = {{0.25f, 0.25f}, {0.75f, 0.25f}, {0.75f, 0.75f}, {0.25f, 0.75f}};
        for (int k = 0; k < 4; ++k) {
            const XYZ& want = limitOf(2, L1.GetFaceChildVertex(children[k]));
            const Vec3 got = face->evaluate(centres[k][0], centres[k][1]);
            EXPECT_NEAR(got.x, want.p[0], 1e-3f) << "face " << f << " quadrant " << k;
            EXPECT_NEAR(got.y, want.p[1], 1e-3f) << "face " << f << " quadrant " << k;
            EXPECT_NEAR(got.z, want.p[2], 1e-3f) << "face " << f << " quadrant " << k;
            ++checked;
        }
        // The face's first corner: the limit point of its vertex.
        const osd::Far::Index v = L0.GetFaceVertices(f)[0];
        const XYZ& want = limitOf(0, v);
        const Vec3 got = face->evaluate(0, 0);
        EXPECT_NEAR(got.x, want.p[0], 1e-4f);
        EXPECT_NEAR(got.y, want.p[1], 1e-4f);
        EXPECT_NEAR(got.z, want.p[2], 1e-4f);
    }
    EXPECT_EQ(checked, 20);
    // The infinitely sharp corner stays where it is.
    const Vec3 c = findFace(pieces, 0, -1)->evaluate(1, 0);  // face 0 = (0 2 3 1): corner 1 is vertex 2
    EXPECT_NEAR(c.x, -1, 1e-5f);
    EXPECT_NEAR(c.y, 1, 1e-5f);
    EXPECT_NEAR(c.z, -1, 1e-5f);
}

TEST(Subdivision, CubeNormalsPointOutward) {
    Diagnostics diag;
    auto pieces = diceablePieces(subdivRecord("catmull-clark", kCubeNverts, kCubeVerts, kCubeP), diag);
    ASSERT_EQ(pieces.size(), 6u);
    for (const auto& p : pieces) {
        const Grid g = p->dice(4, 4);
        ASSERT_TRUE(g.ownNormals);
        for (int j = 0; j < 4; ++j)
            for (int i = 0; i < 4; ++i) {
                const Vec3 p00 = g.P[size_t(g.index(i, j))];
                const Vec3 n = cross(g.P[size_t(g.index(i + 1, j))] - p00, g.P[size_t(g.index(i, j + 1))] - p00);
                EXPECT_GT(dot(n, p00), 0.0f);  // the cube's centre is the origin
                EXPECT_GT(dot(g.N[size_t(g.index(i, j))], p00), 0.0f);
            }
        // Every piece lies inside its bound.
        for (const Vec3& q : g.P) EXPECT_TRUE(testutil::inside(p->bound(), q, 1e-5f));
    }
}

// A pentagonal prism: two pentagons and five quads, closed and smooth.
struct Prism {
    std::vector<float> P;
    std::vector<int> nverts, verts;
    Prism() {
        for (int z = 0; z < 2; ++z)
            for (int k = 0; k < 5; ++k) {
                const float a = 2 * kPi * float(k) / 5;
                P.insert(P.end(), {std::cos(a), std::sin(a), z ? 1.5f : -1.0f});
            }
        nverts = {5, 5};
        verts = {4, 3, 2, 1, 0, 5, 6, 7, 8, 9};
        for (int k = 0; k < 5; ++k) {
            const int n = (k + 1) % 5;
            nverts.push_back(4);
            verts.insert(verts.end(), {k, n, n + 5, k + 5});
        }
    }
};

// One Catmull-Clark step by hand on a closed, uncreased mesh: face points,
// edge points, vertex points, and each face's quads (V_k, E_k, F, E_{k-1}).
void catmullClarkLevel(const std::vector<Vec3>& P, const std::vector<int>& nverts, const std::vector<int>& verts,
                       std::vector<Vec3>& outP, std::vector<int>& outVerts, std::vector<int>& quadOf) {
    const size_t nf = nverts.size();
    std::vector<int> start(nf + 1, 0);
    for (size_t f = 0; f < nf; ++f) start[f + 1] = start[f] + nverts[f];
    std::vector<Vec3> F(nf, Vec3(0.0f));
    for (size_t f = 0; f < nf; ++f) {
        for (int k = start[f]; k < start[f + 1]; ++k) F[f] = F[f] + P[size_t(verts[size_t(k)])];
        F[f] = F[f] / float(nverts[f]);
    }
    std::map<std::pair<int, int>, std::vector<int>> edgeFaces;
    for (size_t f = 0; f < nf; ++f)
        for (int k = 0; k < nverts[f]; ++k) {
            int a = verts[size_t(start[f] + k)], b = verts[size_t(start[f] + (k + 1) % nverts[f])];
            edgeFaces[{std::min(a, b), std::max(a, b)}].push_back(int(f));
        }
    outP.clear();
    const size_t nv = P.size();
    std::vector<Vec3> Q(nv, Vec3(0.0f)), R(nv, Vec3(0.0f));
    std::vector<int> valence(nv, 0), faces(nv, 0);
    for (size_t f = 0; f < nf; ++f)
        for (int k = start[f]; k < start[f + 1]; ++k) {
            Q[size_t(verts[size_t(k)])] = Q[size_t(verts[size_t(k)])] + F[f];
            ++faces[size_t(verts[size_t(k)])];
        }
    std::map<std::pair<int, int>, int> edgeIndex;
    for (const auto& [e, fs] : edgeFaces) {
        const Vec3 mid = (P[size_t(e.first)] + P[size_t(e.second)]) * 0.5f;
        for (int v : {e.first, e.second}) {
            R[size_t(v)] = R[size_t(v)] + mid;
            ++valence[size_t(v)];
        }
        edgeIndex[e] = int(nv + nf + edgeIndex.size());
    }
    outP.resize(nv + nf + edgeFaces.size());
    for (size_t v = 0; v < nv; ++v) {
        const float n = float(valence[v]);
        outP[v] = (Q[v] / float(faces[v]) + R[v] / n * 2.0f + P[v] * (n - 3)) / n;
    }
    for (size_t f = 0; f < nf; ++f) outP[nv + f] = F[f];
    for (const auto& [e, fs] : edgeFaces)
        outP[size_t(edgeIndex[e])] = (P[size_t(e.first)] + P[size_t(e.second)] + F[size_t(fs[0])] + F[size_t(fs[1])]) * 0.25f;
    outVerts.clear();
    quadOf.clear();
    for (size_t f = 0; f < nf; ++f)
        for (int k = 0; k < nverts[f]; ++k) {
            const int n = nverts[f];
            const int vk = verts[size_t(start[f] + k)], vn = verts[size_t(start[f] + (k + 1) % n)],
                      vp = verts[size_t(start[f] + (k + n - 1) % n)];
            const int ek = edgeIndex[{std::min(vk, vn), std::max(vk, vn)}];
            const int ep = edgeIndex[{std::min(vk, vp), std::max(vk, vp)}];
            outVerts.insert(outVerts.end(), {vk, ek, int(nv + f), ep});
            quadOf.push_back(int(f) * 8 + k);
        }
}

TEST(Subdivision, NGonsMatchTheirFirstLevelQuads) {
    const Prism prism;
    std::vector<Vec3> P;
    for (size_t k = 0; k < prism.P.size(); k += 3) P.emplace_back(prism.P[k], prism.P[k + 1], prism.P[k + 2]);
    std::vector<Vec3> P1;
    std::vector<int> verts1, quadOf;
    catmullClarkLevel(P, prism.nverts, prism.verts, P1, verts1, quadOf);
    std::vector<float> flat1;
    for (const Vec3& p : P1) flat1.insert(flat1.end(), {p.x, p.y, p.z});
    Diagnostics diag;
    auto coarse = diceablePieces(subdivRecord("catmull-clark", prism.nverts, prism.verts, prism.P), diag);
    auto fine = diceablePieces(
        subdivRecord("catmull-clark", std::vector<int>(verts1.size() / 4, 4), verts1, flat1), diag);
    EXPECT_EQ(diag.errorCount(), 0);
    EXPECT_EQ(coarse.size(), 2u * 5 + 5);  // the pentagons' sub-faces and the quads
    float worst = 0;
    for (size_t q = 0; q < quadOf.size(); ++q) {
        const int f = quadOf[q] / 8, k = quadOf[q] % 8;
        const SubdivFace* quad = findFace(fine, int(q), -1);
        ASSERT_NE(quad, nullptr);
        for (float s : {0.0f, 0.3f, 0.5f, 1.0f})
            for (float t : {0.0f, 0.6f, 1.0f}) {
                Vec3 want = quad->evaluate(s, t), got;
                if (prism.nverts[size_t(f)] == 5) {
                    got = findFace(coarse, f, k)->evaluate(s, t);
                } else if (k == 0) {
                    got = findFace(coarse, f, -1)->evaluate(s / 2, t / 2);  // quadrant 0 of a quad
                } else {
                    continue;
                }
                worst = std::max(worst, length(got - want));
            }
    }
    EXPECT_LT(worst, 1e-3f);
}

TEST(Subdivision, InterpolateBoundaryTwoSharpensTheEdgesButNotTheCorners) {
    // PRMan's interpolateboundary: 1 makes the boundary edges sharp creases
    // and the corners (boundary vertices of two edges) sharp corners; 2
    // makes the edges creases and leaves the vertices alone (RenderMan's
    // subdivision documentation), as RiCPP's one-quad sample writes it.
    // One quad, 1.8 on a side: with 1 its limit is the square itself; with
    // 2 its boundary is the closed cubic B-spline of its four corners, each
    // corner's limit (P_prev + 4 P + P_next) / 6 at |x| = |y| = 0.6 and each
    // edge's middle (P0 + 23 P1 + 23 P2 + P3) / 48, 0.825 from the centre.
    // (Pixie and Aqsis read 2 as 1 and draw the square.)
    const std::vector<float> P = {-0.9f, -0.9f, 0, 0.9f, -0.9f, 0, 0.9f, 0.9f, 0, -0.9f, 0.9f, 0};
    for (const int mode : {1, 2}) {
        SCOPED_TRACE(mode);
        Diagnostics diag;
        auto pieces =
            diceablePieces(subdivRecord("catmull-clark", {4}, {0, 1, 2, 3}, P, {"interpolateboundary"}, {1, 0}, {mode}),
                           diag);
        EXPECT_EQ(diag.errorCount(), 0);
        ASSERT_EQ(pieces.size(), 1u);
        const auto* face = dynamic_cast<const SubdivFace*>(pieces[0].get());
        ASSERT_NE(face, nullptr);
        const float corner = mode == 1 ? 0.9f : 0.6f, edge = mode == 1 ? 0.9f : 0.825f;
        for (const float u : {0.0f, 1.0f})
            for (const float v : {0.0f, 1.0f}) {
                const Vec3 c = face->evaluate(u, v);
                EXPECT_NEAR(std::abs(c.x), corner, 1e-5f) << u << " " << v;
                EXPECT_NEAR(std::abs(c.y), corner, 1e-5f) << u << " " << v;
            }
        for (const Vec3 m : {face->evaluate(0.5f, 0), face->evaluate(0.5f, 1), face->evaluate(0, 0.5f),
                             face->evaluate(1, 0.5f)}) {
            EXPECT_NEAR(std::max(std::abs(m.x), std::abs(m.y)), edge, 1e-5f);
            EXPECT_NEAR(std::min(std::abs(m.x), std::abs(m.y)), 0.0f, 1e-5f);
        }
    }
}

TEST(Subdivision, WholeFaceBoundsHoldTheirLimitSurfaceAndHugRegularFaces) {
    // A bumpy 6 x 6 sheet with its boundary interpolated (regular interior,
    // boundary and corner faces) and the creased, holed cube (irregular
    // faces): every whole face's bound holds its limit surface sampled
    // finely, and a regular face's bound is tighter than the box of its 16
    // B-spline points, which is what it was before.
    std::vector<float> P;
    std::vector<int> nverts, verts;
    const int n = 6;
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) P.insert(P.end(), {float(i), float(j), 0.8f * std::sin(float(i * 7 + j * 3))});
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            nverts.push_back(4);
            verts.insert(verts.end(), {j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1, (j + 1) * (n + 1) + i});
        }
    Diagnostics diag;
    auto sheet = diceablePieces(
        subdivRecord("catmull-clark", nverts, verts, P, {"interpolateboundary"}, {0, 0}), diag);
    auto cube = diceablePieces(subdivRecord("catmull-clark", kCubeNverts, kCubeVerts, kCubeP, {"crease", "corner", "hole"},
                                            {3, 1, 1, 1, 1, 0}, {4, 5, 7, 2, 2}, {2.5f, 10.0f}),
                               diag);
    EXPECT_EQ(diag.errorCount(), 0);
    ASSERT_EQ(sheet.size(), size_t(n * n));
    int tighter = 0;
    for (const auto* pieces : {&sheet, &cube})
        for (const auto& piece : *pieces) {
            const auto* face = dynamic_cast<const SubdivFace*>(piece.get());
            ASSERT_NE(face, nullptr);
            const Bound3 b = face->bound();
            for (int j = 0; j <= 16; ++j)
                for (int i = 0; i <= 16; ++i) {
                    const Vec3 p = face->evaluate(i / 16.0f, j / 16.0f);
                    EXPECT_TRUE(p.x >= b.min.x && p.y >= b.min.y && p.z >= b.min.z && p.x <= b.max.x &&
                                p.y <= b.max.y && p.z <= b.max.z)
                        << "face " << face->face() << " at " << i << "," << j;
                }
            // The box of the face's control points: the vertices of the
            // faces around an interior face of the sheet.
            if (pieces == &sheet) {
                const int f = face->face(), fi = f % n, fj = f / n;
                if (fi == 0 || fj == 0 || fi == n - 1 || fj == n - 1) continue;
                Bound3 control;
                for (int j = fj - 1; j <= fj + 2; ++j)
                    for (int i = fi - 1; i <= fi + 2; ++i) {
                        const size_t v = size_t(j * (n + 1) + i) * 3;
                        control.extend(Vec3(P[v], P[v + 1], P[v + 2]));
                    }
                const Vec3 d = b.diagonal(), c = control.diagonal();
                if (d.x * d.y * d.z < 0.5f * c.x * c.y * c.z) ++tighter;
            }
        }
    EXPECT_EQ(tighter, (n - 2) * (n - 2));
}

TEST(Subdivision, FaceVaryingStIsContinuousAcrossSharedEdges) {
    // Two quads side by side sharing the edge 1-4; st agree along it and
    // differ (a seam) at the far corners of the right quad.
    const std::vector<float> P = {0, 0, 0, 1, 0, 0.3f, 2, 0, 0, 0, 1, 0, 1, 1, 0.3f, 2, 1, 0.1f};
    const std::vector<int> nverts = {4, 4}, verts = {0, 1, 4, 3, 1, 2, 5, 4};
    const std::vector<float> st = {0, 0, 0.4f, 0.1f, 0.5f, 0.9f, 0, 1,  // face 0
                                   0.4f, 0.1f, 3, 0, 3, 1, 0.5f, 0.9f};  // face 1
    Diagnostics diag;
    auto pieces = diceablePieces(
        subdivRecord("catmull-clark", nverts, verts, P, {"interpolateboundary"}, {0, 0}, {}, {},
                     {testutil::floatParam("st", ri::ParamType::Float, st, ri::StorageClass::FaceVarying, 2)}),
        diag);
    ASSERT_EQ(diag.errorCount(), 0);
    ASSERT_EQ(pieces.size(), 2u);
    const SubdivFace* left = findFace(pieces, 0, -1);
    const SubdivFace* right = findFace(pieces, 1, -1);
    ASSERT_TRUE(left && right);
    // Face 0's edge u = 1 (corner 1 -> 2) is face 1's edge u = 0 (corner 3 -> 0), reversed in v.
    const Grid gl = left->dice(8, 8), gr = right->dice(8, 8);
    const GridVar* sl = gl.find("s");
    const GridVar* tl = gl.find("t");
    const GridVar* sr = gr.find("s");
    const GridVar* tr = gr.find("t");
    ASSERT_TRUE(sl && tl && sr && tr);
    for (int j = 0; j <= 8; ++j) {
        const int a = gl.index(8, j), b = gr.index(0, j);
        EXPECT_NEAR(length(gl.P[size_t(a)] - gr.P[size_t(b)]), 0, 1e-5f) << j;
        EXPECT_NEAR(sl->data[size_t(a)], sr->data[size_t(b)], 1e-5f) << j;
        EXPECT_NEAR(tl->data[size_t(a)], tr->data[size_t(b)], 1e-5f) << j;
    }
    // Corners with boundary interpolation keep their own st.
    EXPECT_NEAR(sr->data[size_t(gr.index(8, 0))], 3, 1e-5f);
    EXPECT_NEAR(sl->data[0], 0, 1e-5f);
}

TEST(Subdivision, MalformedRecordsAreReported) {
    Diagnostics diag;
    diag.setQuiet(true);
    diag.setRecord(true);
    EXPECT_TRUE(makePrimitives(subdivRecord("butterfly", kCubeNverts, kCubeVerts, kCubeP), diag).empty());
    EXPECT_TRUE(makePrimitives(subdivRecord("loop", kCubeNverts, kCubeVerts, kCubeP), diag).empty());
    EXPECT_TRUE(makePrimitives(subdivRecord("catmull-clark", {4, 4}, kCubeVerts, kCubeP), diag).empty());
    EXPECT_TRUE(makePrimitives(subdivRecord("catmull-clark", kCubeNverts, kCubeVerts, kCubeP, {"crease"}, {2, 1},
                                            {0, 99}, {1.0f}),
                               diag)
                    .empty());
    EXPECT_EQ(diag.errorCount(), 4);
}

TEST(Subdivision, LoopTetrahedronIsDiceable) {
    const std::vector<float> P = {1, 1, 1, -1, -1, 1, -1, 1, -1, 1, -1, -1};
    // Outward-wound triangles.
    const std::vector<int> nverts = {3, 3, 3, 3}, verts = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
    Diagnostics diag;
    auto pieces = diceablePieces(subdivRecord("loop", nverts, verts, P), diag);
    ASSERT_EQ(pieces.size(), 4u);
    for (const auto& p : pieces) {
        std::vector<Vec3> Q;
        p->dicePositions(4, 4, Q);
        for (int j = 0; j < 3; ++j)
            for (int i = 0; i < 4; ++i) {
                const Vec3 q = Q[size_t(j * 5 + i)];
                const Vec3 n = cross(Q[size_t(j * 5 + i + 1)] - q, Q[size_t((j + 1) * 5 + i)] - q);
                EXPECT_GT(dot(n, q), 0.0f);
            }
    }
}

}  // namespace
