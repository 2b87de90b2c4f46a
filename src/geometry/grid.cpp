#include "umbra/geometry/grid.h"

namespace umbra::geometry {

GridVar* Grid::find(std::string_view name) {
    for (GridVar& v : vars)
        if (v.name == name) return &v;
    return nullptr;
}

const GridVar* Grid::find(std::string_view name) const {
    for (const GridVar& v : vars)
        if (v.name == name) return &v;
    return nullptr;
}

void Grid::transform(const Mat4& M, const Mat4& inverseM) {
    for (Vec3& p : P) p = M.point(p);
    for (Vec3& n : N) n = Mat4::normal(inverseM, n);
    for (GridVar& var : vars) {
        const ri::ParamType t = var.type;
        if (t != ri::ParamType::Point && t != ri::ParamType::Vector && t != ri::ParamType::Normal) continue;
        // Arrays of points (`point[2]`) transform element by element.
        for (size_t k = 0; k + 3 <= var.data.size(); k += 3) {
            Vec3 x(var.data[k], var.data[k + 1], var.data[k + 2]);
            if (t == ri::ParamType::Point) x = M.point(x);
            else if (t == ri::ParamType::Vector) x = M.vector(x);
            else x = Mat4::normal(inverseM, x);
            var.data[k] = x.x;
            var.data[k + 1] = x.y;
            var.data[k + 2] = x.z;
        }
    }
}

void Grid::transpose() {
    const int cols = nu + 1, rows = nv + 1;
    // New vertex (i', j') = (j, i) sits at i' + j' * (rows) = j + i * rows.
    auto moved = [&](auto& values, int per) {
        if (values.size() != size_t(cols) * size_t(rows) * size_t(per)) return;
        auto old = values;
        for (int j = 0; j < rows; ++j)
            for (int i = 0; i < cols; ++i)
                for (int c = 0; c < per; ++c)
                    values[(size_t(i) * size_t(rows) + size_t(j)) * size_t(per) + size_t(c)] =
                        old[(size_t(j) * size_t(cols) + size_t(i)) * size_t(per) + size_t(c)];
    };
    moved(P, 1);
    moved(N, 1);
    moved(u, 1);
    moved(v, 1);
    for (GridVar& var : vars)
        if (var.perVertex) moved(var.data, var.components);
    std::swap(u, v);
    std::swap(du, dv);
    std::swap(nu, nv);
}

}  // namespace umbra::geometry
