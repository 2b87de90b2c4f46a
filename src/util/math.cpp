#include "umbra/util/math.h"

namespace umbra {

Mat4 Mat4::inverse(bool* ok) const {
    // Gauss-Jordan elimination with partial pivoting, in double precision.
    double a[4][8];
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            a[i][j] = m[i][j];
            a[i][j + 4] = (i == j) ? 1.0 : 0.0;
        }
    for (int c = 0; c < 4; ++c) {
        int pivot = c;
        for (int r = c + 1; r < 4; ++r)
            if (std::abs(a[r][c]) > std::abs(a[pivot][c])) pivot = r;
        if (a[pivot][c] == 0.0) {
            if (ok) *ok = false;
            Mat4 z;
            for (auto& row : z.m)
                for (float& v : row) v = 0;
            return z;
        }
        if (pivot != c)
            for (int j = 0; j < 8; ++j) std::swap(a[c][j], a[pivot][j]);
        double inv = 1.0 / a[c][c];
        for (int j = 0; j < 8; ++j) a[c][j] *= inv;
        for (int r = 0; r < 4; ++r) {
            if (r == c || a[r][c] == 0.0) continue;
            double f = a[r][c];
            for (int j = 0; j < 8; ++j) a[r][j] -= f * a[c][j];
        }
    }
    Mat4 r;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) r.m[i][j] = float(a[i][j + 4]);
    if (ok) *ok = true;
    return r;
}

Bound3 transformBound(const Mat4& M, const Bound3& b) {
    Bound3 r;
    if (b.empty()) return r;
    for (int i = 0; i < 8; ++i) r.extend(M.point(b.corner(i)));
    return r;
}

}  // namespace umbra
