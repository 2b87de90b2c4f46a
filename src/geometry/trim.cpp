#include "umbra/geometry/trim.h"
#include "umbra/util/math.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace umbra::geometry {

namespace {

// Point of a homogeneous NURBS curve (u, v, w of n points, knots t of
// n + order) at x in [t[order-1], t[n]] by de Boor's algorithm.
void curvePoint(const float* t, int n, int order, const float* u, const float* v, const float* w, double x,
                double out[2]) {
    const int p = order - 1;
    int i = p;
    while (i < n - 1 && !(x < double(t[i + 1]))) ++i;
    while (i > p && !(double(t[i]) < double(t[i + 1]))) --i;  // the last non-empty span
    double d[32][3];
    for (int m = 0; m <= p; ++m) {
        const int k = i - p + m;
        d[m][0] = u[k];
        d[m][1] = v[k];
        d[m][2] = w[k];
    }
    for (int r = 1; r <= p; ++r)
        for (int m = p; m >= r; --m) {
            const int j = i - p + m;
            const double den = double(t[j + p + 1 - r]) - double(t[j]);
            const double a = den > 0 ? (x - double(t[j])) / den : 0;
            for (int c = 0; c < 3; ++c) d[m][c] = (1 - a) * d[m - 1][c] + a * d[m][c];
        }
    out[0] = d[p][0] / d[p][2];
    out[1] = d[p][1] / d[p][2];
}

}  // namespace

std::shared_ptr<const TrimRegion> TrimRegion::make(const scene::TrimCurveRecord& rec, bool removeInside) {
    auto r = std::make_shared<TrimRegion>();
    r->m_removeInside = removeInside;
    size_t curve = 0, knot = 0, point = 0;
    std::vector<double> loop;  // u v ... of one loop
    for (int ncurves : rec.ncurves) {
        loop.clear();
        for (int c = 0; c < ncurves; ++c, ++curve) {
            const int order = rec.order[curve], n = rec.n[curve];
            const float* t = rec.knot.data() + knot;
            const double lo = std::max(double(rec.min[curve]), double(t[order - 1]));
            const double hi = std::min(double(rec.max[curve]), double(t[n]));
            // Break points: the range's ends and the knots inside it.
            std::vector<double> breaks = {lo};
            for (int k = order; k < n; ++k)
                if (t[k] > lo && t[k] < hi && t[k] != breaks.back()) breaks.push_back(t[k]);
            breaks.push_back(hi);
            for (size_t b = 0; b + 1 < breaks.size(); ++b)
                for (int s = 0; s < kTrimSegmentsPerSpan; ++s) {
                    double q[2];
                    const double x = breaks[b] + (breaks[b + 1] - breaks[b]) * s / kTrimSegmentsPerSpan;
                    curvePoint(t, n, order, &rec.u[point], &rec.v[point], &rec.w[point], x, q);
                    loop.insert(loop.end(), {q[0], q[1]});
                }
            double q[2];
            curvePoint(t, n, order, &rec.u[point], &rec.v[point], &rec.w[point], hi, q);
            loop.insert(loop.end(), {q[0], q[1]});
            knot += size_t(n + order);
            point += size_t(n);
        }
        // Closed: the last point joins the first.
        const size_t np = loop.size() / 2;
        for (size_t k = 0; k < np; ++k) {
            const size_t k1 = (k + 1) % np;
            if (loop[2 * k] == loop[2 * k1] && loop[2 * k + 1] == loop[2 * k1 + 1]) continue;
            // A zero or negative weight sends a point to infinity (or NaN):
            // its segments bound nothing a float can hold, and are dropped.
            const auto usable = [](double c) { return std::abs(c) <= double(std::numeric_limits<float>::max()); };
            if (!usable(loop[2 * k]) || !usable(loop[2 * k + 1]) || !usable(loop[2 * k1]) || !usable(loop[2 * k1 + 1]))
                continue;
            r->m_seg.insert(r->m_seg.end(),
                            {float(loop[2 * k]), float(loop[2 * k + 1]), float(loop[2 * k1]), float(loop[2 * k1 + 1])});
        }
    }
    r->buildBands();
    return r;
}

void TrimRegion::buildBands() {
    const size_t n = m_seg.size() / 4;
    if (n == 0) return;
    m_vLo = kInfinity;
    m_vHi = -kInfinity;
    for (size_t k = 0; k < n; ++k) {
        m_vLo = std::min({m_vLo, m_seg[4 * k + 1], m_seg[4 * k + 3]});
        m_vHi = std::max({m_vHi, m_seg[4 * k + 1], m_seg[4 * k + 3]});
    }
    const int bands = std::clamp(int(std::sqrt(double(n)) * 4), 1, 4096);
    m_bandScale = m_vHi > m_vLo ? float(bands) / (m_vHi - m_vLo) : 0;
    m_bands.assign(size_t(bands), {});
    for (size_t k = 0; k < n; ++k) {
        const float a = std::min(m_seg[4 * k + 1], m_seg[4 * k + 3]), b = std::max(m_seg[4 * k + 1], m_seg[4 * k + 3]);
        const int b0 = std::clamp(int((a - m_vLo) * m_bandScale), 0, bands - 1);
        const int b1 = std::clamp(int((b - m_vLo) * m_bandScale), 0, bands - 1);
        for (int bb = b0; bb <= b1; ++bb) m_bands[size_t(bb)].push_back(int(k));
    }
}

bool TrimRegion::insideLoops(float u, float v) const {
    if (m_bands.empty() || !(v >= m_vLo && v <= m_vHi)) return false;
    const int band = std::clamp(int((v - m_vLo) * m_bandScale), 0, int(m_bands.size()) - 1);
    bool inside = false;
    for (int k : m_bands[size_t(band)]) {
        const float* s = &m_seg[size_t(k) * 4];
        // Half-open in v, so a ray through a shared vertex counts once.
        if ((s[1] > v) == (s[3] > v)) continue;
        const float x = s[0] + (v - s[1]) * (s[2] - s[0]) / (s[3] - s[1]);
        if (x > u) inside = !inside;
    }
    return inside;
}

TrimRegion::Cover TrimRegion::classify(float u0, float u1, float v0, float v1) const {
    if (!m_bands.empty() && v1 >= m_vLo && v0 <= m_vHi) {
        const int last = int(m_bands.size()) - 1;
        // Clamped before the conversion: a piece's v range can reach far
        // past the loops' (a corrupt NuPatch's, 2.5e37 once).
        const int b0 = floorToIntClamped(double(v0 - m_vLo) * m_bandScale, 0, last);
        const int b1 = floorToIntClamped(double(v1 - m_vLo) * m_bandScale, 0, last);
        for (int b = b0; b <= b1; ++b)
            for (int k : m_bands[size_t(b)]) {
                const float* s = &m_seg[size_t(k) * 4];
                if (std::max(s[0], s[2]) >= u0 && std::min(s[0], s[2]) <= u1 && std::max(s[1], s[3]) >= v0 &&
                    std::min(s[1], s[3]) <= v1)
                    return Cover::Mixed;
            }
    }
    return keeps(0.5f * (u0 + u1), 0.5f * (v0 + v1)) ? Cover::Kept : Cover::Removed;
}

std::shared_ptr<const TrimRegion> trimRegionOf(const scene::Attributes& attrs) {
    if (!attrs.trimCurves) return nullptr;
    // The "sense" names the side kept: "inside" (the default) keeps what
    // lies inside an odd number of loops, as Aqsis and PRMan do; exporters
    // (Maya, Houdini) write a loop round the whole kept region and one
    // round each hole. "outside" keeps the rest.
    bool removeInside = false;
    auto it = attrs.user.find("trimcurve:sense");
    if (it != attrs.user.end() && !it->second.strings.empty()) removeInside = it->second.strings[0] == "outside";
    return TrimRegion::make(*attrs.trimCurves, removeInside);
}

}  // namespace umbra::geometry
