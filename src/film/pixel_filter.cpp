#include "umbra/film/pixel_filter.h"

#include "umbra/util/error.h"
#include "umbra/util/math.h"

#include <cmath>

namespace umbra::film {

namespace {

float sincPi(float x) {
    if (x == 0.0f) return 1.0f;
    float px = kPi * x;
    return std::sin(px) / px;
}

}  // namespace

std::optional<PixelFilter> PixelFilter::create(std::string_view name, float xwidth, float ywidth) {
    FilterKind kind;
    if (name == "box" || name == "RiBoxFilter")
        kind = FilterKind::Box;
    else if (name == "triangle" || name == "RiTriangleFilter")
        kind = FilterKind::Triangle;
    else if (name == "gaussian" || name == "RiGaussianFilter")
        kind = FilterKind::Gaussian;
    else if (name == "catmull-rom" || name == "RiCatmullRomFilter")
        kind = FilterKind::CatmullRom;
    else if (name == "sinc" || name == "RiSincFilter")
        kind = FilterKind::Sinc;
    else
        return std::nullopt;
    if (!(xwidth > 0) || !(ywidth > 0)) return std::nullopt;
    return PixelFilter(kind, xwidth, ywidth);
}

PixelFilter::PixelFilter(FilterKind kind, float xwidth, float ywidth)
    : m_kind(kind), m_xRadius(0.5f * xwidth), m_yRadius(0.5f * ywidth), m_separable(kind != FilterKind::CatmullRom) {
    UMBRA_CHECK(xwidth > 0 && ywidth > 0, "pixel filter widths must be positive ({} {})", xwidth, ywidth);
    buildTables();
}

const char* PixelFilter::name() const {
    switch (m_kind) {
    case FilterKind::Box: return "box";
    case FilterKind::Triangle: return "triangle";
    case FilterKind::Gaussian: return "gaussian";
    case FilterKind::CatmullRom: return "catmull-rom";
    case FilterKind::Sinc: return "sinc";
    }
    return "?";
}

float PixelFilter::factor1d(float t, float radius) const {
    if (!(t >= -radius && t <= radius)) return 0.0f;
    float u = t / radius;  // [-1, 1]
    switch (m_kind) {
    case FilterKind::Box: return 1.0f;
    case FilterKind::Triangle: return 1.0f - std::fabs(u);
    case FilterKind::Gaussian: return std::exp(-2.0f * u * u);
    case FilterKind::Sinc: return sincPi(t) * sincPi(u);
    case FilterKind::CatmullRom: break;
    }
    return 0.0f;
}

float PixelFilter::evaluate(float x, float y) const {
    if (!(x >= -m_xRadius && x <= m_xRadius && y >= -m_yRadius && y <= m_yRadius)) return 0.0f;
    if (m_separable) return factor1d(x, m_xRadius) * factor1d(y, m_yRadius);
    // Catmull-Rom, radial: r in [0, 2) over the support.
    float sx = 2.0f * x / m_xRadius, sy = 2.0f * y / m_yRadius;
    float r2 = sx * sx + sy * sy;
    float r = std::sqrt(r2);
    if (r >= 2.0f) return 0.0f;  // also the support's corners, outside the circle
    if (r < 1.0f) return 3.0f * r * r2 - 5.0f * r2 + 2.0f;
    return -r * r2 + 5.0f * r2 - 8.0f * r + 4.0f;
}

void PixelFilter::buildTables() {
    if (!m_separable) return;
    auto build = [&](std::vector<float>& lut, float radius) {
        size_t n = size_t(std::ceil(2.0f * radius * kLutPerPixel)) + 2;
        lut.resize(n);
        for (size_t i = 0; i < n; ++i) {
            float t = float(-double(radius) + double(i) / kLutPerPixel);
            // The last entry may lie past the support; clamp so the
            // interpolation up to the edge stays continuous.
            if (t > radius) t = radius;
            lut[i] = factor1d(t, radius);
        }
    };
    build(m_lutX, m_xRadius);
    build(m_lutY, m_yRadius);
}

int PixelFilter::xMargin() const { return int(std::floor(m_xRadius + 0.5f)); }
int PixelFilter::yMargin() const { return int(std::floor(m_yRadius + 0.5f)); }

}  // namespace umbra::film
