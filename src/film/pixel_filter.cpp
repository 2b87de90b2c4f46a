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

/// The Mitchell-Netravali family of cubics at |x| in [0, 2] (B, C as in
/// their 1988 paper): B = C = 1/3 is "mitchell", B = 0, C = 1/2 the
/// separable Catmull-Rom.
float cubicBC(float x, float B, float C) {
    x = std::fabs(x);
    if (x < 1) return ((12 - 9 * B - 6 * C) * x * x * x + (-18 + 12 * B + 6 * C) * x * x + (6 - 2 * B)) / 6;
    if (x < 2)
        return ((-B - 6 * C) * x * x * x + (6 * B + 30 * C) * x * x + (-12 * B - 48 * C) * x + (8 * B + 24 * C)) / 6;
    return 0;
}

/// 2 J1(pi r) / (pi r): the Airy pattern, 1 at r = 0, first zero at r = 1.22.
float jinc(float r) {
    if (r < 1e-6f) return 1.0f;
    const double pr = double(kPi) * r;
    return float(2 * std::cyl_bessel_j(1.0, pr) / pr);
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
    else if (name == "catmull-rom" || name == "catmullrom" || name == "RiCatmullRomFilter")
        kind = FilterKind::CatmullRom;
    else if (name == "sinc" || name == "lanczos" || name == "RiSincFilter")  // PRMan's lanczos: the windowed sinc
        kind = FilterKind::Sinc;
    else if (name == "mitchell" || name == "RiMitchellFilter")
        kind = FilterKind::Mitchell;
    else if (name == "separable-catmull-rom" || name == "RiSeparableCatmullRomFilter")
        kind = FilterKind::SeparableCatmullRom;
    else if (name == "blackman-harris" || name == "RiBlackmanHarrisFilter")
        kind = FilterKind::BlackmanHarris;
    else if (name == "disk" || name == "RiDiskFilter")
        kind = FilterKind::Disk;
    else if (name == "bessel" || name == "RiBesselFilter")
        kind = FilterKind::Bessel;
    else
        return std::nullopt;
    if (!(xwidth > 0) || !(ywidth > 0)) return std::nullopt;
    return PixelFilter(kind, xwidth, ywidth);
}

PixelFilter::PixelFilter(FilterKind kind, float xwidth, float ywidth)
    : m_kind(kind), m_xRadius(0.5f * xwidth), m_yRadius(0.5f * ywidth), 
      m_separable(kind != FilterKind::CatmullRom && kind != FilterKind::Disk && kind != FilterKind::Bessel) {
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
    case FilterKind::Mitchell: return "mitchell";
    case FilterKind::SeparableCatmullRom: return "separable-catmull-rom";
    case FilterKind::BlackmanHarris: return "blackman-harris";
    case FilterKind::Disk: return "disk";
    case FilterKind::Bessel: return "bessel";
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
    case FilterKind::Mitchell: return cubicBC(2 * u, 1.0f / 3, 1.0f / 3);
    case FilterKind::SeparableCatmullRom: return cubicBC(2 * u, 0, 0.5f);
    case FilterKind::BlackmanHarris:
        return 0.35875f + 0.48829f * std::cos(kPi * u) + 0.14128f * std::cos(2 * kPi * u) +
               0.01168f * std::cos(3 * kPi * u);
    case FilterKind::CatmullRom:
    case FilterKind::Disk:
    case FilterKind::Bessel: break;
    }
    return 0.0f;
}

float PixelFilter::evaluate(float x, float y) const {
    if (!(x >= -m_xRadius && x <= m_xRadius && y >= -m_yRadius && y <= m_yRadius)) return 0.0f;
    if (m_separable) return factor1d(x, m_xRadius) * factor1d(y, m_yRadius);
    const float ex = x / m_xRadius, ey = y / m_yRadius;
    if (m_kind == FilterKind::Disk) return ex * ex + ey * ey <= 1.0f ? 1.0f : 0.0f;
    if (m_kind == FilterKind::Bessel) return ex * ex + ey * ey <= 1.0f ? jinc(std::sqrt(x * x + y * y)) : 0.0f;
    // Catmull-Rom, radial, as RI Spec 3.2 writes RiCatmullRomFilter: r is
    // the distance in pixels (zero from 2 on) and the widths only cut the
    // support, as in Pixie and Aqsis. umbra stretched r to reach 2 at the
    // support's edge, which is the same only at width 4.
    float r2 = x * x + y * y;
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
