#include "umbra/geometry/subdivision.h"

#include "umbra/geometry/patch.h"

#include <opensubdiv/bfr/refinerSurfaceFactory.h>
#include <opensubdiv/bfr/surface.h>
#include <opensubdiv/bfr/surfaceFactoryCache.h>
#include <opensubdiv/far/topologyDescriptor.h>
#include <opensubdiv/far/topologyRefinerFactory.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <mutex>
#include <shared_mutex>

namespace umbra::geometry {

namespace osd = OpenSubdiv;

using SurfaceCache = osd::Bfr::SurfaceFactoryCacheThreaded<std::shared_mutex, std::shared_lock<std::shared_mutex>,
                                                           std::unique_lock<std::shared_mutex>>;
using SurfaceFactory = osd::Bfr::RefinerSurfaceFactory<SurfaceCache>;
using Surface = osd::Bfr::Surface<float>;

constexpr int kApproxSmooth = 4;
// A range of at most kFlatFaces faces splits into its faces; a larger one
// into kSplitWays ranges (Morton order makes each a region of space).
constexpr int kFlatFaces = 64;
constexpr int kSplitWays = 16;

/// One face-varying primitive variable as an OpenSubdiv face-varying
/// channel: the record's per-corner values welded where a vertex's corners
/// carry equal values (so texture coordinates are smooth across edges that
/// share them), and each face corner's index into the welded values.
struct FVarChannelData {
    int var = 0;                     // into SurfaceData::vars
    int components = 1;
    std::vector<float> values;       // welded, `components` floats each
    std::vector<int> valueIndices;   // one per face corner
};

struct SubdivMeshData {
    std::shared_ptr<const SurfaceData> sd;
    std::vector<float> points;                 // 3 floats per vertex (Pw divided)
    std::vector<int> faceCornerStart;          // per face; one extra entry
    std::vector<FVarChannelData> fvar;
    std::vector<int> channelOfVar;             // per SurfaceData var: its channel, or -1
    bool loop = false;
    std::unique_ptr<osd::Far::TopologyRefiner> refiner;
    std::unique_ptr<SurfaceFactory> factory;
    /// Per base face: the bound of the vertices of the faces around its
    /// corners (its one-ring), which holds its limit surface. Made once, so
    /// that a range's bound is a union of these and the split tree of a
    /// mesh of F faces costs F log F unions, not F log F one-ring walks.
    std::vector<Bound3> faceRingBound;
    /// The base faces in Morton order of their one-ring bounds' centres.
    /// SubdivMesh ranges index this, so halving a range halves a region of
    /// space: the pieces' bounds stay tight and occlusion culling works as
    /// it does for separate patches (in the order faces are written, a
    /// half of a torus is a band all round it).
    std::vector<int> faceOrder;

    Vec3 point(int v) const { return {points[size_t(v) * 3], points[size_t(v) * 3 + 1], points[size_t(v) * 3 + 2]}; }
};

struct SubdivFaceSurfaces {
    Surface vertex, varying;
    std::vector<Surface> fvar;           // per channel
    std::vector<float> patchPoints;      // of P, 3 floats each
    Bound3 hull;                         // of patchPoints
};

namespace {

using RecordPtr = std::shared_ptr<const scene::PrimitiveRecord>;

// A regular Catmull-Clark face's limit surface is one bicubic polynomial
// patch (boundary faces too: their phantom points keep it one). Its Bezier
// control points, found from 4 x 4 limit points, lie much closer to it
// than the 16 B-spline points around it, so their box bounds the face more
// tightly and more of the faces behind others are culled unshaded. The
// box is padded for rounding and clipped to the B-spline points' box,
// which always holds.
Bound3 tighterRegularBound(const SubdivFaceSurfaces& s) {
    // Rows: the Bezier points from the values at t = 0, 1/3, 2/3, 1 (the
    // inverse of the cubic Bernstein matrix at those t).
    static constexpr float kFromValues[4][4] = {
        {1, 0, 0, 0}, {-5.0f / 6, 3, -1.5f, 1.0f / 3}, {1.0f / 3, -1.5f, 3, -5.0f / 6}, {0, 0, 0, 1}};
    Vec3 values[4][4];
    for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) {
            const float uv[2] = {float(i) / 3, float(j) / 3};
            s.vertex.Evaluate(uv, s.patchPoints.data(), 3, &values[j][i].x);
        }
    Vec3 rows[4][4];  // u converted, per row of values
    for (int j = 0; j < 4; ++j)
        for (int k = 0; k < 4; ++k) {
            Vec3 c(0.0f);
            for (int i = 0; i < 4; ++i) c = c + values[j][i] * kFromValues[k][i];
            rows[j][k] = c;
        }
    Bound3 b;
    for (int l = 0; l < 4; ++l)
        for (int k = 0; k < 4; ++k) {
            Vec3 c(0.0f);
            for (int j = 0; j < 4; ++j) c = c + rows[j][k] * kFromValues[l][j];
            b.extend(c);
        }
    const Vec3 pad(1e-4f * std::max({s.hull.diagonal().x, s.hull.diagonal().y, s.hull.diagonal().z}));
    return Bound3(vmax(b.min - pad, s.hull.min), vmin(b.max + pad, s.hull.max));
}

std::shared_ptr<const SubdivFaceSurfaces> makeFaceSurfaces(const SubdivMeshData& m, int face) {
    auto s = std::make_shared<SubdivFaceSurfaces>();
    if (!m.factory->InitVertexSurface<float>(face, &s->vertex)) return nullptr;  // a hole, or no limit surface
    m.factory->InitVaryingSurface<float>(face, &s->varying);
    s->fvar.resize(m.fvar.size());
    for (size_t c = 0; c < m.fvar.size(); ++c) m.factory->InitFaceVaryingSurface<float>(face, &s->fvar[c], int(c));
    s->patchPoints.resize(size_t(s->vertex.GetNumPatchPoints()) * 3);
    s->vertex.PreparePatchPoints(m.points.data(), 3, s->patchPoints.data(), 3);
    for (size_t k = 0; k + 2 < s->patchPoints.size(); k += 3)
        s->hull.extend(Vec3(s->patchPoints[k], s->patchPoints[k + 1], s->patchPoints[k + 2]));
    // Evaluation rounds (a boundary face's limit reaches its hull's face
    // plus a few float steps): pad by a rounding margin.
    const Vec3 d = s->hull.diagonal();
    const Vec3 pad(1e-5f * std::max({d.x, d.y, d.z}));
    s->hull = Bound3(s->hull.min - pad, s->hull.max + pad);
    if (!m.loop && s->vertex.IsRegular()) s->hull = tighterRegularBound(*s);
    return s;
}

// Appends the pieces of base face `face`: one SubdivFace, N sub-faces of
// an N-gon being made when it splits; nothing for a hole.
void appendFace(const RecordPtr& rec, const std::shared_ptr<const SubdivMeshData>& mesh, int face,
                std::vector<PrimitivePtr>& out) {
    auto surfaces = makeFaceSurfaces(*mesh, face);
    if (!surfaces) return;
    out.push_back(std::make_unique<SubdivFace>(rec, mesh, std::move(surfaces), face, -1, ParamRange{}));
}

Vec3 cross3(const float a[3], const float b[3]) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

}  // namespace

SubdivMesh::SubdivMesh(RecordPtr record, std::shared_ptr<const SubdivMeshData> mesh, int firstFace, int endFace)
    : Primitive(std::move(record)), m_mesh(std::move(mesh)), m_first(firstFace), m_end(endFace) {
    for (int k = m_first; k < m_end; ++k) m_bound.extend(m_mesh->faceRingBound[size_t(m_mesh->faceOrder[size_t(k)])]);
}

void SubdivMesh::split(bool, std::vector<PrimitivePtr>& out) const {
    const int count = m_end - m_first;
    if (count <= kFlatFaces) {
        for (int k = m_first; k < m_end; ++k) appendFace(recordPtr(), m_mesh, m_mesh->faceOrder[size_t(k)], out);
        return;
    }
    for (int part = 0; part < kSplitWays; ++part) {
        const int first = m_first + int(int64_t(count) * part / kSplitWays);
        const int end = m_first + int(int64_t(count) * (part + 1) / kSplitWays);
        if (end > first) out.push_back(std::make_unique<SubdivMesh>(recordPtr(), m_mesh, first, end));
    }
}

Grid SubdivMesh::dice(int, int) const {
    UMBRA_CHECK(false, "SubdivMesh::dice called on a mesh that must be split first ({})", record().type);
    return {};
}

SubdivFace::SubdivFace(RecordPtr record, std::shared_ptr<const SubdivMeshData> mesh,
                       std::shared_ptr<const SubdivFaceSurfaces> surfaces, int face, int subFace,
                       const ParamRange& range)
    : Primitive(std::move(record)), m_mesh(std::move(mesh)), m_surfaces(std::move(surfaces)), m_face(face),
      m_subFace(subFace), m_range(range) {
    m_bound = m_surfaces->hull;
    const bool whole = range.u0 == 0 && range.v0 == 0 && range.u1 == 1 && range.v1 == 1;
    if (whole || !diceable()) return;
    // A part of a face: the limit points of a 9 x 9 lattice of the range,
    // padded by the longest step between neighbours (a curve between two
    // samples strays from their bound by a fraction of their distance
    // unless it turns sharply), clipped to the hull bound that always holds.
    // A step's length is bounded by sqrt(3) times its largest coordinate
    // difference, not computed: squaring coordinates beyond 1.8e19
    // overflows float, and an infinite pad kept every piece at the hull,
    // so splitting never shrank it.
    constexpr int n = 8;
    std::vector<Vec3> P;
    dicePositions(n, n, P);
    Bound3 b;
    float step = 0;
    auto widen = [&step](const Vec3& d) { step = std::max({step, std::abs(d.x), std::abs(d.y), std::abs(d.z)}); };
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) {
            const Vec3& p = P[size_t(j * (n + 1) + i)];
            b.extend(p);
            if (i < n) widen(P[size_t(j * (n + 1) + i + 1)] - p);
            if (j < n) widen(P[size_t((j + 1) * (n + 1) + i)] - p);
        }
    const Vec3 pad(step * 1.7320508f);
    m_bound = Bound3(vmax(b.min - pad, m_bound.min), vmin(b.max + pad, m_bound.max));
}

bool SubdivFace::diceable() const {
    return m_subFace >= 0 || !m_surfaces->vertex.GetParameterization().HasSubFaces();
}

void SubdivFace::split(bool splitU, std::vector<PrimitivePtr>& out) const {
    if (!diceable()) {
        const int n = m_surfaces->vertex.GetFaceSize();
        for (int k = 0; k < n; ++k)
            out.push_back(std::make_unique<SubdivFace>(recordPtr(), m_mesh, m_surfaces, m_face, k, ParamRange{}));
        return;
    }
    for (int h = 0; h < 2; ++h)
        out.push_back(
            std::make_unique<SubdivFace>(recordPtr(), m_mesh, m_surfaces, m_face, m_subFace, m_range.half(splitU, h)));
}

void SubdivFace::faceCoord(float u, float v, float uv[2]) const {
    if (m_subFace >= 0) {
        const float st[2] = {u, v};
        m_surfaces->vertex.GetParameterization().ConvertNormalizedSubFaceToCoord(m_subFace, st, uv);
    } else if (m_mesh->loop) {
        // The unit square onto the triangle u, v >= 0, u + v <= 1, its edge
        // v = 1 collapsed onto the corner (0, 1); orientation is kept.
        uv[0] = u * (1 - v);
        uv[1] = v;
    } else {
        uv[0] = u;
        uv[1] = v;
    }
}

Vec3 SubdivFace::evaluate(float u, float v, Vec3* dPdu, Vec3* dPdv) const {
    float uv[2], P[3], Du[3], Dv[3];
    faceCoord(u, v, uv);
    const Surface& s = m_surfaces->vertex;
    s.Evaluate(uv, m_surfaces->patchPoints.data(), 3, P, Du, Dv);
    if (m_mesh->loop && m_subFace < 0) {
        // Chain rule through faceCoord: d/du = (1 - v) d/da, d/dv = -u d/da + d/db.
        for (int k = 0; k < 3; ++k) {
            const float a = Du[k], b = Dv[k];
            Du[k] = (1 - v) * a;
            Dv[k] = b - u * a;
        }
    }
    if (dPdu) *dPdu = Vec3(Du[0], Du[1], Du[2]);
    if (dPdv) *dPdv = Vec3(Dv[0], Dv[1], Dv[2]);
    return {P[0], P[1], P[2]};
}

void SubdivFace::dicePositions(int nu, int nv, std::vector<Vec3>& P) const {
    thread_local std::vector<float> a, b;
    m_range.steps(nu, nv, a, b);
    P.resize(size_t(nu + 1) * size_t(nv + 1));
    const Surface& s = m_surfaces->vertex;
    size_t k = 0;
    for (float v : b)
        for (float u : a) {
            float uv[2];
            faceCoord(u, v, uv);
            s.Evaluate(uv, m_surfaces->patchPoints.data(), 3, &P[k++].x);
        }
}

Grid SubdivFace::dice(int nu, int nv) const {
    Grid g;
    std::vector<float> a, b;
    initGrid(g, nu, nv, m_range, ParamMap{}, a, b);
    const size_t n = g.P.size();
    const SubdivMeshData& m = *m_mesh;
    const SurfaceData& sd = *m.sd;
    const SubdivFaceSurfaces& fs = *m_surfaces;

    // Limit positions and the normal dPdu x dPdv from the limit
    // derivatives, kept only when it is defined everywhere on the grid.
    std::vector<Vec3> N(n);
    bool normalsOk = true;
    size_t k = 0;
    for (float v : b)
        for (float u : a) {
            Vec3 du, dv;
            g.P[k] = evaluate(u, v, &du, &dv);
            const float d[3] = {du.x, du.y, du.z}, e[3] = {dv.x, dv.y, dv.z};
            const Vec3 c = cross3(d, e);
            const float len = length(c);
            if (!(len > 1e-12f * std::max(1.0f, length(du) * length(dv)))) normalsOk = false;
            N[k++] = normalsOk ? c : Vec3(0.0f);
        }

    // Every other variable goes through one limit stencil per vertex and
    // class, applied to the record's data.
    thread_local std::vector<float> stencil;
    auto applyClass = [&](const Surface& s, const float* data, int comps, int stride, float* out, int outStride) {
        stencil.resize(size_t(std::max(s.GetNumControlPoints(), 1)));
        size_t q = 0;
        for (float v : b)
            for (float u : a) {
                float uv[2];
                faceCoord(u, v, uv);
                s.EvaluateStencil(uv, stencil.data());
                s.ApplyStencilFromMesh(stencil.data(), data, Surface::PointDescriptor(comps, stride),
                                       out + q * size_t(outStride));
                ++q;
            }
    };
    // ApplyStencilFromMesh needs every value of a point contiguous, so a
    // strided variable ("s" from "st") is read with its stride.
    for (size_t vi = 0; vi < sd.vars.size(); ++vi) {
        const PrimVar& v = sd.vars[vi];
        const Surface* surf = nullptr;
        const float* data = v.data + v.offset;
        int stride = v.stride;
        switch (v.storage) {
        case ri::StorageClass::Vertex: surf = &fs.vertex; break;
        case ri::StorageClass::Varying: surf = &fs.varying; break;
        case ri::StorageClass::FaceVarying:
        case ri::StorageClass::FaceVertex: {
            const int c = m.channelOfVar[vi];
            surf = &fs.fvar[size_t(c)];
            data = m.fvar[size_t(c)].values.data();
            stride = v.components;
            break;
        }
        default: break;
        }
        if (v.isNormal) {
            g.N.resize(n);
            if (surf) {
                applyClass(*surf, data, 3, stride, &g.N[0].x, 3);
            } else {
                const float* c = v.at(v.storage == ri::StorageClass::Uniform ? size_t(m_face) : 0);
                std::fill(g.N.begin(), g.N.end(), Vec3(c[0], c[1], c[2]));
            }
            continue;
        }
        if (surf) {
            GridVar& gv = addGridVar(g, v, true);
            applyClass(*surf, data, v.components, stride, gv.data.data(), v.components);
        } else {
            GridVar& gv = addGridVar(g, v, false);
            const float* c = v.at(v.storage == ri::StorageClass::Uniform ? size_t(m_face) : 0);
            std::copy(c, c + v.components, gv.data.begin());
        }
    }
    if (g.N.empty() && normalsOk) {
        g.N = std::move(N);  // dPdu x dPdv, as the regular faces' blocks give it
        g.ownNormals = true;
        g.derivativeNormals = true;
    }

    addDefaultVars(sd, g);
    return g;
}

namespace {

// The tags of a SubdivisionMesh record turned into Sdc options and
// descriptor arrays.
struct Tags {
    osd::Sdc::Options options;
    std::vector<int> creasePairs;
    std::vector<float> creaseWeights;
    std::vector<int> corners;
    std::vector<float> cornerWeights;
    std::vector<int> holes;
};

bool readTags(const scene::PrimitiveRecord& rec, int nfaces, long npoints, Tags& t, Diagnostics& diag) {
    using Opt = osd::Sdc::Options;
    const std::string& what = rec.type;
    // RenderMan's default: no boundary interpolation (boundary faces have no
    // limit surface and are not drawn).
    t.options.SetVtxBoundaryInterpolation(Opt::VTX_BOUNDARY_NONE);
    t.options.SetFVarLinearInterpolation(Opt::FVAR_LINEAR_CORNERS_ONLY);
    // HierarchicalSubdivisionMesh gives three counts per tag (integers,
    // floats, strings) and its string arguments after the tag names; the
    // plain request gives two counts and no strings.
    const bool hierarchical = what == "HierarchicalSubdivisionMesh";
    const size_t countsPerTag = hierarchical ? 3 : 2;
    static const std::vector<int> kNone;
    const std::vector<int>& nargs = rec.intArrays.size() > 2 ? rec.intArrays[2] : kNone;
    const size_t ntags = hierarchical ? nargs.size() / 3 : rec.stringArgs.size() - 1;
    if (ntags == 0 && (!hierarchical || nargs.empty())) return true;
    if (rec.intArrays.size() < 3) {
        diag.error(rec.loc, "{}: {} tags but no nargs", what, ntags);
        return false;
    }
    const std::vector<int>& ints = rec.intArrays.size() > 3 ? rec.intArrays[3] : kNone;
    const std::vector<float>& floats = rec.floatArgs;
    if (nargs.size() != countsPerTag * ntags || rec.stringArgs.size() < 1 + ntags) {
        if (hierarchical)
            diag.error(rec.loc, "{}: nargs has {} values for {} tag names and string arguments, expected three counts "
                       "per tag (integers, floats, strings)", what, nargs.size(), rec.stringArgs.size() - 1);
        else
            diag.error(rec.loc, "{}: nargs has {} values, expected {} (an integer and a float count per tag)", what,
                       nargs.size(), countsPerTag * ntags);
        return false;
    }
    const size_t nstrings = rec.stringArgs.size() - 1 - ntags;
    size_t ip = 0, fp = 0, sp = 0;
    bool propagateCorners = false;
    for (size_t k = 0; k < ntags; ++k) {
        const std::string& name = rec.stringArgs[k + 1];
        const int ni = nargs[countsPerTag * k], nf = nargs[countsPerTag * k + 1];
        const int ns = hierarchical ? nargs[countsPerTag * k + 2] : 0;
        if (ni < 0 || nf < 0 || ns < 0 || ip + size_t(ni) > ints.size() || fp + size_t(nf) > floats.size() ||
            sp + size_t(ns) > nstrings) {
            diag.error(rec.loc, "{}: tag \"{}\" asks for {} integers, {} floats and {} strings, more than given",
                       what, name, ni, nf, ns);
            return false;
        }
        const int* iv = ints.data() + ip;
        const float* fv = floats.data() + fp;
        ip += size_t(ni);
        fp += size_t(nf);
        sp += size_t(ns);
        auto badVertex = [&](int c) {
            for (int q = 0; q < c; ++q)
                if (iv[q] < 0 || iv[q] >= npoints) {
                    diag.error(rec.loc, "{}: tag \"{}\" names vertex {}, outside 0..{}", what, name, iv[q],
                               npoints - 1);
                    return true;
                }
            return false;
        };
        if (name == "interpolateboundary") {
            const int mode = ni > 0 ? iv[0] : 1;
            if (mode == 0) t.options.SetVtxBoundaryInterpolation(Opt::VTX_BOUNDARY_NONE);
            else if (mode == 1) t.options.SetVtxBoundaryInterpolation(Opt::VTX_BOUNDARY_EDGE_AND_CORNER);
            else if (mode == 2) t.options.SetVtxBoundaryInterpolation(Opt::VTX_BOUNDARY_EDGE_ONLY);
            else diag.warning(rec.loc, "{}: interpolateboundary {} unknown (expected 0, 1 or 2); ignored", what, mode);
        } else if (name == "facevaryinginterpolateboundary") {
            // The integer codes of OpenSubdiv's own RIB shape reader.
            static const Opt::FVarLinearInterpolation kModes[] = {
                Opt::FVAR_LINEAR_NONE,          Opt::FVAR_LINEAR_CORNERS_ONLY, Opt::FVAR_LINEAR_CORNERS_PLUS1,
                Opt::FVAR_LINEAR_CORNERS_PLUS2, Opt::FVAR_LINEAR_BOUNDARIES,   Opt::FVAR_LINEAR_ALL};
            const int mode = ni > 0 ? iv[0] : 1;
            if (mode >= 0 && mode <= 5) t.options.SetFVarLinearInterpolation(kModes[mode]);
            else
                diag.warning(rec.loc, "{}: facevaryinginterpolateboundary {} unknown (expected 0 to 5); ignored", what,
                             mode);
        } else if (name == "crease") {
            if (ni < 2 || (nf != 1 && nf != ni - 1)) {
                diag.error(rec.loc, "{}: crease expects 2 or more vertices and 1 sharpness (or one per "
                                    "edge), got {} and {}", what, ni, nf);
                return false;
            }
            if (badVertex(ni)) return false;
            for (int q = 0; q + 1 < ni; ++q) {
                t.creasePairs.push_back(iv[q]);
                t.creasePairs.push_back(iv[q + 1]);
                t.creaseWeights.push_back(nf == 1 ? fv[0] : fv[q]);
            }
        } else if (name == "corner") {
            if (ni < 1 || (nf != 1 && nf != ni)) {
                diag.error(rec.loc, "{}: corner expects vertices and 1 sharpness (or one per vertex), "
                                    "got {} and {}", what, ni, nf);
                return false;
            }
            if (badVertex(ni)) return false;
            for (int q = 0; q < ni; ++q) {
                t.corners.push_back(iv[q]);
                t.cornerWeights.push_back(nf == 1 ? fv[0] : fv[q]);
            }
        } else if (name == "hole") {
            for (int q = 0; q < ni; ++q) {
                if (iv[q] < 0 || iv[q] >= nfaces) {
                    diag.error(rec.loc, "{}: hole names face {}, outside 0..{}", what, iv[q], nfaces - 1);
                    return false;
                }
                t.holes.push_back(iv[q]);
            }
        } else if (name == "facevaryingpropagatecorners") {
            propagateCorners = ni > 0 && iv[0] != 0;
        } else if (name == "vertexedit" || name == "edgeedit" || name == "faceedit") {
            diag.warningOnce("subdiv:hierarchical-edit", rec.loc,
                             "{}: hierarchical edits (\"{}\") are not supported; the mesh is drawn without them", what,
                             name);
        } else {
            std::string key = "subdiv:tag:";
            key += name;
            diag.warningOnce(key, rec.loc, "{}: tag \"{}\" not supported; ignored", what, name);
        }
    }
    // PRMan's facevaryingpropagatecorners sharpens the corners that the
    // "corners plus one" rule makes, which is OpenSubdiv's CORNERS_PLUS2.
    if (propagateCorners && t.options.GetFVarLinearInterpolation() == Opt::FVAR_LINEAR_CORNERS_PLUS1)
        t.options.SetFVarLinearInterpolation(Opt::FVAR_LINEAR_CORNERS_PLUS2);
    return true;
}

// Welds the per-corner values of a face-varying variable: corners of one
// vertex with bit-identical values share a value index.
FVarChannelData weld(const PrimVar& v, int var, const std::vector<int>& vertices, long npoints) {
    FVarChannelData c;
    c.var = var;
    c.components = v.components;
    c.valueIndices.resize(vertices.size());
    std::vector<std::vector<int>> atVertex(static_cast<size_t>(npoints));
    for (size_t corner = 0; corner < vertices.size(); ++corner) {
        const float* x = v.at(corner);
        auto& list = atVertex[size_t(vertices[corner])];
        int found = -1;
        for (int idx : list)
            if (std::equal(x, x + v.components, c.values.begin() + long(idx) * v.components)) {
                found = idx;
                break;
            }
        if (found < 0) {
            found = int(c.values.size() / size_t(v.components));
            c.values.insert(c.values.end(), x, x + v.components);
            list.push_back(found);
        }
        c.valueIndices[corner] = found;
    }
    return c;
}

// Indices of `bounds` sorted by the Morton code of their centres in the
// box of all of them (10 bits an axis); ties keep the given order.
std::vector<int> mortonOrder(const std::vector<Bound3>& bounds) {
    Bound3 all;
    for (const Bound3& b : bounds) all.extend(b);
    const Vec3 size = vmax(all.diagonal(), Vec3(1e-30f));
    auto spread = [](uint32_t v) {  // 10 bits to every third of 30
        v = (v | (v << 16)) & 0x030000FFu;
        v = (v | (v << 8)) & 0x0300F00Fu;
        v = (v | (v << 4)) & 0x030C30C3u;
        v = (v | (v << 2)) & 0x09249249u;
        return v;
    };
    auto cell = [](float t) {  // NaN (a point at infinity) goes to cell 0
        const float x = t * 1024.0f;
        return x >= 1023.0f ? 1023u : (x >= 0.0f ? uint32_t(x) : 0u);
    };
    std::vector<std::pair<uint32_t, int>> keyed(bounds.size());
    for (size_t f = 0; f < bounds.size(); ++f) {
        const Vec3 c = (bounds[f].min + bounds[f].max) * 0.5f - all.min;
        keyed[f] = {spread(cell(c.x / size.x)) | (spread(cell(c.y / size.y)) << 1) | (spread(cell(c.z / size.z)) << 2),
                    int(f)};
    }
    std::stable_sort(keyed.begin(), keyed.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    std::vector<int> order(bounds.size());
    for (size_t k = 0; k < keyed.size(); ++k) order[k] = keyed[k].second;
    return order;
}

}  // namespace

// ---------------------------------------------------------------------------
// Regular regions as bicubic B-spline blocks

namespace {

using Level = osd::Far::TopologyLevel;

/// A quad all of whose corners are smooth (no sharp edge or vertex),
/// interior, manifold vertices of valence 4 among quads, none a hole: its
/// limit surface is the uniform bicubic B-spline patch of the 16 vertices
/// of the 3 x 3 faces around it.
bool regularInteriorFace(const Level& L, int f) {
    if (L.IsFaceHole(f)) return false;
    const auto fv = L.GetFaceVertices(f);
    if (fv.size() != 4) return false;
    for (int k = 0; k < 4; ++k) {
        const int v = fv[k];
        if (L.IsVertexBoundary(v) || L.IsVertexNonManifold(v) || L.GetVertexSharpness(v) > 0 ||
            L.GetVertexRule(v) != osd::Sdc::Crease::RULE_SMOOTH)
            return false;
        const auto faces = L.GetVertexFaces(v);
        const auto edges = L.GetVertexEdges(v);
        if (faces.size() != 4 || edges.size() != 4) return false;
        for (int e = 0; e < 4; ++e)
            if (L.GetEdgeSharpness(edges[e]) > 0) return false;
        for (int g = 0; g < 4; ++g)
            if (L.IsFaceHole(faces[g]) || L.GetFaceVertices(faces[g]).size() != 4) return false;
    }
    return true;
}

/// The quad across edge (a, b) from `face`: its two other vertices, the
/// one next to a (`farA`) and the one next to b (`farB`).
bool across(const Level& L, int face, int a, int b, int* other, int* farA, int* farB) {
    const int e = L.FindEdge(a, b);
    if (e < 0) return false;
    const auto ef = L.GetEdgeFaces(e);
    if (ef.size() != 2) return false;
    const int g = ef[0] == face ? ef[1] : ef[0];
    const auto gv = L.GetFaceVertices(g);
    if (gv.size() != 4) return false;
    int ia = -1, ib = -1;
    for (int k = 0; k < 4; ++k) {
        if (gv[k] == a) ia = k;
        if (gv[k] == b) ib = k;
    }
    if (ia < 0 || ib < 0) return false;
    auto far = [&](int i, int not_) {
        const int n1 = gv[(i + 1) % 4], n3 = gv[(i + 3) % 4];
        return n1 == not_ ? n3 : n1;
    };
    *other = g;
    *farA = far(ia, b);
    *farB = far(ib, a);
    return true;
}

/// The 16 B-spline control vertices of a regular interior face, row after
/// row with u fastest, the face's corners 0, 1, 2, 3 at [1][1], [1][2],
/// [2][2], [2][1] (u from corner 0 to 1, v from corner 0 to 3, as
/// SubdivFace); also the faces across its edges 1-2 (next in u) and 2-3
/// (next in v).
bool regularControlPoints(const Level& L, int f, std::array<int, 16>& c, int* nextU, int* nextV) {
    const auto fv = L.GetFaceVertices(f);
    auto P = [&](int r, int col) -> int& { return c[size_t(r * 4 + col)]; };
    P(1, 1) = fv[0];
    P(1, 2) = fv[1];
    P(2, 2) = fv[2];
    P(2, 1) = fv[3];
    int below, right, top, left, g, unused;
    if (!across(L, f, fv[0], fv[1], &below, &P(0, 1), &P(0, 2))) return false;
    if (!across(L, f, fv[1], fv[2], &right, &P(1, 3), &P(2, 3))) return false;
    if (!across(L, f, fv[2], fv[3], &top, &P(3, 2), &P(3, 1))) return false;
    if (!across(L, f, fv[3], fv[0], &left, &P(2, 0), &P(1, 0))) return false;
    if (!across(L, below, fv[0], P(0, 1), &g, &unused, &P(0, 0))) return false;
    if (!across(L, below, fv[1], P(0, 2), &g, &unused, &P(0, 3))) return false;
    if (!across(L, top, fv[2], P(3, 2), &g, &unused, &P(3, 3))) return false;
    if (!across(L, top, fv[3], P(3, 1), &g, &unused, &P(3, 0))) return false;
    *nextU = right;
    *nextV = top;
    return true;
}

struct RegularFace {
    std::array<int, 16> ctrl;
    int nextU = -1, nextV = -1;
    bool regular = false;
};

// Whether face b continues face a one step along u (v): its control points
// are a's shifted by one column (row), so the two parameterisations line up.
bool followsInU(const RegularFace& a, const RegularFace& b) {
    for (int r = 0; r < 4; ++r)
        for (int col = 0; col < 3; ++col)
            if (b.ctrl[size_t(r * 4 + col)] != a.ctrl[size_t(r * 4 + col + 1)]) return false;
    return true;
}
bool followsInV(const RegularFace& a, const RegularFace& b) {
    for (int r = 0; r < 3; ++r)
        for (int col = 0; col < 4; ++col)
            if (b.ctrl[size_t(r * 4 + col)] != a.ctrl[size_t((r + 1) * 4 + col)]) return false;
    return true;
}

/// Groups the regular faces of the mesh into rectangles of at most side x
/// side faces whose parameterisations line up, greedily in face order
/// (grow along u, then add rows along v while every face of the next row
/// follows the one below it); appends a BicubicBlock (or a lone
/// BicubicPatch) per rectangle and marks its faces in `inBlock`.
void appendRegularBlocks(const RecordPtr& rec, const SubdivMeshData& m, int side, std::vector<char>& inBlock,
                         std::vector<PrimitivePtr>& out) {
    const Level& L = m.refiner->GetLevel(0);
    const int nfaces = L.GetNumFaces();
    std::vector<RegularFace> faces(static_cast<size_t>(nfaces));
    for (int f = 0; f < nfaces; ++f) {
        RegularFace& rf = faces[size_t(f)];
        rf.regular = regularInteriorFace(L, f) && regularControlPoints(L, f, rf.ctrl, &rf.nextU, &rf.nextV);
    }
    inBlock.assign(size_t(nfaces), 0);
    const scene::Basis bspline = scene::Basis::bspline();
    std::vector<int> row, next, block;
    for (int f = 0; f < nfaces; ++f) {
        if (!faces[size_t(f)].regular || inBlock[size_t(f)]) continue;
        auto available = [&](int g) { return g >= 0 && faces[size_t(g)].regular && !inBlock[size_t(g)]; };
        row.assign(1, f);
        inBlock[size_t(f)] = 1;
        while (int(row.size()) < side) {
            const int g = faces[size_t(row.back())].nextU;
            if (!available(g) || !followsInU(faces[size_t(row.back())], faces[size_t(g)])) break;
            row.push_back(g);
            inBlock[size_t(g)] = 1;
        }
        block = row;
        int rows = 1;
        while (rows < side) {
            next.clear();
            bool ok = true;
            for (size_t k = 0; k < row.size() && ok; ++k) {
                const int g = faces[size_t(row[k])].nextV;
                ok = available(g) && followsInV(faces[size_t(row[k])], faces[size_t(g)]) &&
                     (k == 0 || followsInU(faces[size_t(next.back())], faces[size_t(g)]));
                if (ok) {
                    next.push_back(g);
                    inBlock[size_t(g)] = 1;  // also keeps a face from coming twice in one row
                }
            }
            if (!ok) {
                for (int g : next) inBlock[size_t(g)] = 0;
                break;
            }
            block.insert(block.end(), next.begin(), next.end());
            row.swap(next);
            ++rows;
        }
        auto patches = std::make_shared<BicubicPatchArray>();
        patches->sd = m.sd;
        patches->columns = int(row.size());
        patches->rows = rows;
        for (int g : block) {
            patches->coeffs.push_back(BicubicCoeffs::make(*m.sd, faces[size_t(g)].ctrl, bspline, bspline));
            patches->bounds.push_back(bicubicHullBound(*patches->coeffs.back(), ParamRange{}));
            patches->refs.emplace_back();
        }
        BicubicBlock::appendPiece(rec, patches, 0, 0, patches->columns, patches->rows, out);
    }
}

/// Whether every variable of the mesh can ride on a bicubic block: vertex
/// class (the B-spline basis is the limit of a regular face) or constant.
bool blockableVariables(const SurfaceData& sd) {
    if (sd.posDim != 3) return false;
    for (const PrimVar& v : sd.vars)
        if (v.storage != ri::StorageClass::Vertex && v.storage != ri::StorageClass::Constant) return false;
    return true;
}

}  // namespace

void makeSubdivisionMesh(const RecordPtr& rec, Diagnostics& diag, std::vector<PrimitivePtr>& out, int blockSide) {
    const std::string& what = rec->type;
    const auto& arrays = rec->intArrays;
    if (rec->stringArgs.empty() || arrays.size() < 2) {
        diag.error(rec->loc, "{}: expected a scheme, nvertices and vertices", what);
        return;
    }
    const std::string& scheme = rec->stringArgs[0];
    osd::Sdc::SchemeType type;
    if (scheme == "catmull-clark") type = osd::Sdc::SCHEME_CATMARK;
    else if (scheme == "loop") type = osd::Sdc::SCHEME_LOOP;
    else if (scheme == "bilinear") type = osd::Sdc::SCHEME_BILINEAR;
    else {
        diag.error(rec->loc, "{}: scheme \"{}\" unknown (expected \"catmull-clark\", \"loop\" or \"bilinear\")", what,
                   scheme);
        return;
    }
    const std::vector<int>& nverts = arrays[0];
    const std::vector<int>& verts = arrays[1];
    auto mesh = std::make_shared<SubdivMeshData>();
    mesh->loop = type == osd::Sdc::SCHEME_LOOP;
    long total = 0;
    mesh->faceCornerStart.push_back(0);
    for (size_t f = 0; f < nverts.size(); ++f) {
        if (nverts[f] < 3) {
            diag.error(rec->loc, "{}: face {} has {} vertices, expected at least 3", what, f, nverts[f]);
            return;
        }
        if (mesh->loop && nverts[f] != 3) {
            diag.error(rec->loc, "{}: \"loop\" needs triangles; face {} has {} vertices", what, f, nverts[f]);
            return;
        }
        total += nverts[f];
        mesh->faceCornerStart.push_back(int(total));
    }
    if (nverts.empty() || long(verts.size()) != total) {
        diag.error(rec->loc, "{}: vertices has {} indices, expected {} (the sum of nvertices)", what,
                   verts.size(), total);
        return;
    }
    long npoints = 0;
    for (size_t k = 0; k < verts.size(); ++k) {
        if (verts[k] < 0) {
            diag.error(rec->loc, "{}: vertex index {} at position {} is negative", what, verts[k], k);
            return;
        }
        npoints = std::max(npoints, long(verts[k]) + 1);
    }
    ClassCounts counts;
    counts.uniform = nverts.size();
    counts.varying = counts.vertex = size_t(npoints);
    counts.varyingWhat = counts.vertexWhat = "one per vertex";
    counts.faceVarying = size_t(total);
    counts.faceVaryingWhat = "one per face corner";
    auto sd = readSurfaceData(*rec, counts, true, diag);
    if (!sd) return;
    Tags tags;
    if (!readTags(*rec, int(nverts.size()), npoints, tags, diag)) return;

    mesh->sd = sd;
    mesh->points.resize(size_t(npoints) * 3);
    for (long k = 0; k < npoints; ++k) {
        const Vec3 p = sd->point(size_t(k));
        std::copy(&p.x, &p.x + 3, mesh->points.begin() + k * 3);
    }
    mesh->channelOfVar.assign(sd->vars.size(), -1);
    for (size_t vi = 0; vi < sd->vars.size(); ++vi) {
        const PrimVar& v = sd->vars[vi];
        if (v.storage != ri::StorageClass::FaceVarying && v.storage != ri::StorageClass::FaceVertex) continue;
        mesh->channelOfVar[vi] = int(mesh->fvar.size());
        mesh->fvar.push_back(weld(v, int(vi), verts, npoints));
    }
    std::vector<osd::Far::TopologyDescriptor::FVarChannel> channels(mesh->fvar.size());
    for (size_t c = 0; c < channels.size(); ++c) {
        channels[c].numValues = int(mesh->fvar[c].values.size() / size_t(mesh->fvar[c].components));
        channels[c].valueIndices = mesh->fvar[c].valueIndices.data();
    }

    osd::Far::TopologyDescriptor desc;
    desc.numVertices = int(npoints);
    desc.numFaces = int(nverts.size());
    desc.numVertsPerFace = nverts.data();
    desc.vertIndicesPerFace = verts.data();
    desc.numCreases = int(tags.creaseWeights.size());
    desc.creaseVertexIndexPairs = tags.creasePairs.data();
    desc.creaseWeights = tags.creaseWeights.data();
    desc.numCorners = int(tags.corners.size());
    desc.cornerVertexIndices = tags.corners.data();
    desc.cornerWeights = tags.cornerWeights.data();
    desc.numHoles = int(tags.holes.size());
    desc.holeIndices = tags.holes.data();
    desc.numFVarChannels = int(channels.size());
    desc.fvarChannels = channels.data();
    using Factory = osd::Far::TopologyRefinerFactory<osd::Far::TopologyDescriptor>;
    mesh->refiner.reset(Factory::Create(desc, Factory::Options(type, tags.options)));
    if (!mesh->refiner) {
        diag.error(rec->loc, "{}: OpenSubdiv rejects the mesh's topology", what);
        return;
    }
    // The limit surface of a face lies in the convex hull of the points
    // that influence it, which are among the vertices of the faces around
    // its corners (its one-ring).
    const osd::Far::TopologyLevel& level = mesh->refiner->GetLevel(0);
    // Faces at a non-manifold edge or vertex have no limit surface and draw
    // nothing (Pixie and Aqsis drop such meshes too; Aqsis says where).
    int nonManifold = 0;
    for (int e = 0; e < level.GetNumEdges(); ++e) nonManifold += level.IsEdgeNonManifold(e) ? 1 : 0;
    if (nonManifold > 0)
        diag.warning(rec->loc, "{}: {} edge{} shared by more than two faces (non-manifold); the faces there have no "
                               "limit surface and are not drawn",
                     what, nonManifold, nonManifold == 1 ? " is" : "s are");
    mesh->faceRingBound.resize(nverts.size());
    for (int f = 0; f < int(nverts.size()); ++f) {
        Bound3& b = mesh->faceRingBound[size_t(f)];
        const auto fv = level.GetFaceVertices(f);
        for (int k = 0; k < fv.size(); ++k) {
            const auto ring = level.GetVertexFaces(fv[k]);
            for (int r = 0; r < ring.size(); ++r) {
                const auto rv = level.GetFaceVertices(ring[r]);
                for (int q = 0; q < rv.size(); ++q) b.extend(mesh->point(rv[q]));
            }
        }
    }
    mesh->faceOrder = mortonOrder(mesh->faceRingBound);
    SurfaceFactory::Options factoryOptions;
    factoryOptions.SetApproxLevelSmooth(kApproxSmooth);
    mesh->factory = std::make_unique<SurfaceFactory>(*mesh->refiner, factoryOptions);
    if (blockSide > 1 && type == osd::Sdc::SCHEME_CATMARK && blockableVariables(*sd)) {
        // Regular regions go out as blocks; the mesh keeps the other faces.
        std::vector<char> inBlock;
        appendRegularBlocks(rec, *mesh, blockSide, inBlock, out);
        mesh->faceOrder.erase(std::remove_if(mesh->faceOrder.begin(), mesh->faceOrder.end(),
                                             [&](int f) { return inBlock[size_t(f)] != 0; }),
                              mesh->faceOrder.end());
    }
    const int nfaces = int(mesh->faceOrder.size());
    if (nfaces > 0) out.push_back(std::make_unique<SubdivMesh>(rec, std::move(mesh), 0, nfaces));
}

}  // namespace umbra::geometry
