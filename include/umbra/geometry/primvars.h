#pragma once
// Primitive variables of one record, validated once and shared by every
// piece the record is split into, and their interpolation onto grids.
//
// RenderMan interpolates a primitive variable by its storage class (RI spec
// 3.2 §5.6): constant (one value), uniform (one per face or patch), varying
// (one per patch corner, bilinear), vertex (one per control vertex, with the
// surface's own basis), facevarying (one per face corner, bilinear). Every
// piece here is diced over a bilinear "corner domain": a quad whose four
// corners index the varying, vertex and facevarying arrays, in RenderMan's
// bilinear-patch order
//
//      2 ---- 3      corner c sits at (u, v) = (c & 1, c >> 1)
//      |      |
//      0 ---- 1  --> u

#include "umbra/geometry/grid.h"
#include "umbra/ri/param_list.h"
#include "umbra/scene/scene.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <deque>
#include <vector>

namespace umbra::geometry {

/// Expected value counts of each storage class for one record.
struct ClassCounts {
    size_t uniform = 1;
    size_t varying = 4;
    size_t vertex = 4;
    size_t faceVarying = 4;
    /// How the counts read in error messages, e.g. "one per vertex".
    const char* uniformWhat = "one per face";
    const char* varyingWhat = "one per corner";
    const char* vertexWhat = "one per vertex";
    const char* faceVaryingWhat = "one per face corner";
};

/// One primitive variable as stored in the record: element k is the
/// `components` floats starting at data + k * stride + offset (offset and
/// stride let "st" feed separate "s" and "t" variables).
struct PrimVar {
    std::string name;
    ri::ParamType type = ri::ParamType::Float;
    ri::StorageClass storage = ri::StorageClass::Constant;
    int components = 1;
    int stride = 1;
    int offset = 0;
    const float* data = nullptr;
    size_t count = 0;
    bool isNormal = false;  // "N" (or "Np"): goes to Grid::N, not Grid::vars
    /// A string variable (constant or uniform): its values are indices into
    /// this table, so they ride on grids as every other variable does.
    const std::vector<std::string>* strings = nullptr;

    const float* at(size_t k) const { return data + k * size_t(stride) + size_t(offset); }
};

/// The validated primitive variables and positions of one record. Points
/// into the record's parameter lists, so it lives as long as the record
/// (pieces keep the record alive through Primitive::recordPtr()).
struct SurfaceData {
    /// Positions: `posDim` floats per vertex: 3 (P), or 4 (Pw, homogeneous,
    /// divided after interpolation). Pz is expanded into `ownedPos`.
    const float* pos = nullptr;
    int posDim = 3;
    size_t posCount = 0;
    std::vector<float> ownedPos;
    std::vector<PrimVar> vars;
    /// String variables' tables and index arrays (deques: PrimVar points
    /// into them).
    std::deque<std::vector<std::string>> stringTables;
    std::deque<std::vector<float>> stringIndices;
    bool hasS = false, hasT = false;
    /// TextureCoordinates (s, t at the (u, v) corners (0,0) (1,0) (0,1)
    /// (1,1)): the default s and t of parametric primitives (quadrics,
    /// patches, patch meshes, NURBS) given no "s"/"t"/"st", RI Spec 3.2
    /// section 4.1.3. Identity unless the primitive is parametric.
    float cornerST[8] = {0, 0, 1, 0, 0, 1, 1, 1};
    Color defaultCs{1, 1, 1}, defaultOs{1, 1, 1};
    bool hasCs = false, hasOs = false;

    /// Position of vertex k, homogeneous (w = 1 for P).
    void position(size_t k, float out[4]) const {
        const float* p = pos + k * size_t(posDim);
        out[0] = p[0];
        out[1] = p[1];
        out[2] = p[2];
        out[3] = posDim == 4 ? p[3] : 1.0f;
    }
    /// Position of vertex k divided by w.
    Vec3 point(size_t k) const {
        const float* p = pos + k * size_t(posDim);
        if (posDim == 4) return Vec3(p[0], p[1], p[2]) / p[3];
        return {p[0], p[1], p[2]};
    }
};

/// Which elements of each class a piece's four corners use.
struct CornerRefs {
    int vertex[4] = {0, 1, 2, 3};
    int varying[4] = {0, 1, 2, 3};
    int faceVarying[4] = {0, 1, 2, 3};
    int uniform = 0;
};

/// A rectangle of the corner domain ([0,1]^2 before any split).
struct ParamRange {
    float u0 = 0, u1 = 1, v0 = 0, v1 = 1;
    ParamRange half(bool splitU, bool second) const {
        ParamRange r = *this;
        if (splitU) {
            float m = 0.5f * (u0 + u1);
            (second ? r.u0 : r.u1) = m;
        } else {
            float m = 0.5f * (v0 + v1);
            (second ? r.v0 : r.v1) = m;
        }
        return r;
    }
    /// How many times half(splitU, ...) can go on halving the range while
    /// its halves stay narrower than it (Primitive::splitsLeft).
    int halvingsLeft(bool splitU) const { return splitU ? spanHalvings(u0, u1) : spanHalvings(v0, v1); }
    static int spanHalvings(float lo, float hi) {
        // Down to 2^-23 of the span's magnitude, where each half is a float
        // step or two: a [0, 1] range halves 23 times each way, so a
        // surface 130 million pixels across still dices into 16-pixel
        // pieces (a ground plane 10^5 units long seen at 1080p from a unit
        // above is 10^8 pixels wide at the bottom of the frame; at 2^-22 a
        // few of its pixels were diced coarsely, at 2^-23 none).
        const float least = std::max({1.0f, std::abs(lo), std::abs(hi)}) * 0x1p-23f;
        int n = 0;
        for (float w = std::abs(hi - lo); w > least && n < 64; w *= 0.5f) ++n;
        return n;
    }
    /// The parameters of an nu x nv dicing of this range: nu+1 values of u
    /// in `us`, nv+1 of v in `vs`.
    void steps(int nu, int nv, std::vector<float>& us, std::vector<float>& vs) const {
        us.resize(size_t(nu) + 1);
        vs.resize(size_t(nv) + 1);
        for (int i = 0; i <= nu; ++i) us[size_t(i)] = u0 + (u1 - u0) * float(i) / float(nu);
        for (int j = 0; j <= nv; ++j) vs[size_t(j)] = v0 + (v1 - v0) * float(j) / float(nv);
    }
};

/// Maps the corner domain to the u, v the grid reports (e.g. a patch of a
/// patch mesh covers [i/n, (i+1)/n] of the mesh's u).
struct ParamMap {
    float uOffset = 0, uScale = 1, vOffset = 0, vScale = 1;
};

/// Reads, validates and shares the primitive variables of `record`.
/// `posRequired`: P, Pw (or Pz when `allowPz`) must be present with
/// `counts.vertex` values. Reports problems through `diag` as
/// "<request>: ..." at record.loc and returns null.
std::shared_ptr<const SurfaceData> readSurfaceData(const scene::PrimitiveRecord& record, const ClassCounts& counts,
                                                   bool posRequired, Diagnostics& diag, bool allowPz = false,
                                                   int pzNu = 0, int pzNv = 0, bool pzPeriodicU = false,
                                                   bool pzPeriodicV = false);

/// Lays out a grid of nu x nv micropolygons over `range` of the corner
/// domain: sizes P, u, v, du, dv, and fills `a` (corner-domain u of each
/// column) and `b` (v of each row).
void initGrid(Grid& g, int nu, int nv, const ParamRange& range, const ParamMap& map, std::vector<float>& a,
              std::vector<float>& b);

/// The grid's N as dPdu x dPdv, from the homogeneous positions `H` and
/// their partial derivatives `Ha`, `Hb` along the corner domain's a and b
/// (4 floats a vertex; P = H / w when `posDim` is 4, else H's xyz), per unit
/// of the primitive's u and v (u = uOffset + uScale a: ParamMap). Exact, so
/// grids that share an edge give its vertices the same normal and a
/// displaced surface does not crack between them. Marks N the family's own
/// derivative normal (Grid::derivativeNormals). Leaves N empty and returns
/// false when it vanishes anywhere on the grid (a pole, a collapsed edge):
/// the shading grid's differences then stand in.
bool setDerivativeNormals(Grid& g, const float* H, const float* Ha, const float* Hb, int posDim, const ParamMap& map);

/// Interpolates every primitive variable onto `g` (already laid out by
/// initGrid): varying, facevarying and (unless `skipVertex`) vertex classes
/// bilinearly from the corners, uniform and constant as single values, N
/// into Grid::N, and default s, t (= grid u, v), Cs and Os.
void interpolateVars(const SurfaceData& sd, const CornerRefs& refs, const std::vector<float>& a,
                     const std::vector<float>& b, bool skipVertex, Grid& g);
/// The variables a grid gets when its primitive gives none: s and t from
/// u and v, Cs and Os from the attributes (SurfaceData's defaults).
void addDefaultVars(const SurfaceData& sd, Grid& g);

/// Appends a per-vertex variable to `g` and returns its storage.
GridVar& addGridVar(Grid& g, const PrimVar& v, bool perVertex);

}  // namespace umbra::geometry
