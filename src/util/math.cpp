#include "umbra/util/math.h"

#include <algorithm>
#include <cmath>

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

float smallestSingularValue3(const Mat4& m) {
    // A = M^T M is symmetric positive semi-definite; its eigenvalues by the
    // trigonometric closed form (Smith 1961), in double.
    double a[3][3];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            double sum = 0;
            for (int k = 0; k < 3; ++k) sum += double(m.m[k][i]) * double(m.m[k][j]);
            a[i][j] = sum;
        }
    const double off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    double least;
    if (off == 0) {
        least = std::min({a[0][0], a[1][1], a[2][2]});
    } else {
        const double q = (a[0][0] + a[1][1] + a[2][2]) / 3;
        const double p2 = (a[0][0] - q) * (a[0][0] - q) + (a[1][1] - q) * (a[1][1] - q) + (a[2][2] - q) * (a[2][2] - q) +
                          2 * off;
        const double p = std::sqrt(p2 / 6);
        double b[3][3];
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) b[i][j] = (a[i][j] - (i == j ? q : 0)) / p;
        const double detB = b[0][0] * (b[1][1] * b[2][2] - b[1][2] * b[2][1]) -
                            b[0][1] * (b[1][0] * b[2][2] - b[1][2] * b[2][0]) +
                            b[0][2] * (b[1][0] * b[2][1] - b[1][1] * b[2][0]);
        const double phi = std::acos(std::clamp(detB / 2, -1.0, 1.0)) / 3;
        least = q + 2 * p * std::cos(phi + 2 * M_PI / 3);  // the least of the three roots
    }
    return float(std::sqrt(std::max(0.0, least)));
}

}  // namespace umbra
