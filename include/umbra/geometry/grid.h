#pragma once
// Grids: the unit of REYES work.
//
// A *grid* is a primitive diced into a rectangular (nu+1) x (nv+1) array of
// vertices in its parametric (u, v) domain; each cell of four neighbouring
// vertices is a *micropolygon*. Every shading and hiding step works on whole
// grids. Vertex (i, j) is stored at index j * (nu + 1) + i, u along a row:
//
//      v ^  (0,nv) ... (nu,nv)
//        |    .          .
//        |  (0,0) ...  (nu,0)   --> u

#include "umbra/ri/param_list.h"
#include "umbra/util/math.h"

#include <string>
#include <string_view>
#include <vector>

namespace umbra::geometry {

/// A primitive variable carried onto a grid: one value per vertex
/// (varying, vertex, facevarying classes after interpolation) or one for
/// the whole grid (constant, uniform).
struct GridVar {
    std::string name;
    ri::ParamType type = ri::ParamType::Float;
    int components = 1;          // floats per value (array size included)
    bool perVertex = true;       // false: `data` holds a single value
    std::vector<float> data;
    /// A string variable: `data` holds indices into this table.
    const std::vector<std::string>* strings = nullptr;

    const float* at(int vertex) const { return data.data() + (perVertex ? vertex * components : 0); }
};

/// A diced grid. Positions and normals are in the space the grid was
/// transformed to (object space from Primitive::dice, then "current" =
/// camera space once the renderer transforms it).
struct Grid {
    int nu = 0, nv = 0;                 // micropolygons along u and v
    std::vector<Vec3> P;                // (nu+1)*(nv+1) positions
    std::vector<Vec3> N;                // shading normals, or empty: derive from P
    bool ownNormals = false;            // N is the family's outward normal (e.g. a quadric's
                                        // closed form), not user-supplied: it follows Orientation
    bool derivativeNormals = false;     // ... and is dPdu x dPdv, whose length the
                                        // transform to "current" space keeps (RI 3.2: N = Ng)
    std::vector<float> u, v;            // surface parameters of each vertex
    float du = 0, dv = 0;               // parametric spacing between vertices
    std::vector<GridVar> vars;          // s, t, Cs, Os, user primitive variables
    /// Points (geometry/curves.h): micropolygon (2k, 0) is point k's
    /// square, drawn as its inscribed disc; odd columns join neighbouring
    /// points and are never drawn.
    bool discs = false;

    int vertexCount() const { return (nu + 1) * (nv + 1); }
    int index(int i, int j) const { return j * (nu + 1) + i; }
    GridVar* find(std::string_view name);
    const GridVar* find(std::string_view name) const;

    /// Moves positions, normals and point/vector/normal variables into
    /// another space: points and vectors by `M`, normals by its inverse
    /// transpose (`inverseM` is M's inverse).
    void transform(const Mat4& M, const Mat4& inverseM);
    /// Swaps the roles of u and v: vertex (i, j) becomes (j, i), the counts,
    /// parameters and spacings trade places. Per-vertex data moves with its
    /// vertex; the surface's orientation (dPdu x dPdv) flips.
    void transpose();
};

}  // namespace umbra::geometry
