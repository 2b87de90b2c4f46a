#pragma once
// Pixel reconstruction filters (RenderMan Interface Specification 3.2,
// `PixelFilter` and Appendix E).
//
// A filter is evaluated at an offset (x, y) in raster pixels from a pixel's
// centre; its support is the closed rectangle [-xwidth/2, xwidth/2] x
// [-ywidth/2, ywidth/2] (closed, so regular samples on the support's edge
// count on both sides and the filter stays symmetric). Pixel values are
// normalised by the sum of the weights of the samples that reach them.

#include <optional>
#include <string_view>
#include <vector>

namespace umbra::film {

/// The RenderMan pixel filter shapes (see PixelFilter).
enum class FilterKind { Box, Triangle, Gaussian, CatmullRom, Sinc, Mitchell, SeparableCatmullRom, BlackmanHarris, Disk, Bessel };

/// One RenderMan pixel filter with its x and y widths, plus lookup tables for
/// the renderer's hot path (each image sample is weighted for every pixel
/// whose filter support contains it).
///
/// The shapes, with x' = x / (xwidth/2) and y' = y / (ywidth/2) in [-1, 1]:
///  - box:        1
///  - triangle:   (1 - |x'|) (1 - |y'|)  (the spec's appendix code misplaces
///                a parenthesis; this is the tent it means)
///  - gaussian:   exp(-2 (x'^2 + y'^2)), exactly the spec's RiGaussianFilter
///  - catmull-rom: the spec's radial Catmull-Rom of r = |(x, y)| in pixels
///                (0 from r = 2 on), the widths only cutting the support, as
///                RiCatmullRomFilter, Pixie and Aqsis
///  - sinc:       sinc(x) sinc(x/rx) * (same in y), rx = xwidth/2: the spec's
///                separable sinc windowed by a Lanczos window so it falls to 0
///                at the support's edge instead of being truncated
///  - mitchell:   Mitchell-Netravali B = C = 1/3 cubic of 2x' (times the
///                same in y), PRMan's RiMitchellFilter
///  - separable-catmull-rom: the B = 0, C = 1/2 cubic of 2x' (times y)
///  - blackman-harris: 0.35875 + 0.48829 cos(pi x') + 0.14128 cos(2 pi x')
///                + 0.01168 cos(3 pi x') (times y), PRMan's window
///  - disk:       1 inside the ellipse x'^2 + y'^2 <= 1
///  - bessel:     2 J1(pi r) / (pi r), r = |(x, y)| in pixels, inside the
///                same ellipse (Aqsis and Pixie's RiBesselFilter shape)
/// All but catmull-rom, disk and bessel are separable:
/// w(x, y) = wx(x) * wy(y).
class PixelFilter {
public:
    /// By RenderMan name: "box", "triangle", "gaussian", "catmull-rom",
    /// "sinc", "mitchell", "separable-catmull-rom", "blackman-harris",
    /// "disk", "bessel" (also the Ri function names "RiGaussianFilter" etc.,
    /// and PRMan's "catmullrom" and "lanczos", the windowed sinc). Widths
    /// must be positive. Unknown names give nullopt; the caller reports.
    static std::optional<PixelFilter> create(std::string_view name, float xwidth, float ywidth);
    PixelFilter(FilterKind kind, float xwidth, float ywidth);

    /// The exact filter value at offset (x, y) pixels from the pixel centre.
    float evaluate(float x, float y) const;
    /// The fast weight used when filtering samples (tabulated; within ~1e-4
    /// of evaluate()).
    float weight(float x, float y) const {
        if (m_separable) return weightX(x) * weightY(y);
        return evaluate(x, y);
    }
    /// The separable factors, tabulated (separable filters only).
    float weightX(float x) const { return lookup(m_lutX, x, m_xRadius); }
    float weightY(float y) const { return lookup(m_lutY, y, m_yRadius); }

    FilterKind kind() const { return m_kind; }
    const char* name() const;
    bool separable() const { return m_separable; }
    float xWidth() const { return 2 * m_xRadius; }
    float yWidth() const { return 2 * m_yRadius; }
    float xRadius() const { return m_xRadius; }
    float yRadius() const { return m_yRadius; }
    /// How many neighbouring pixels on each side can hold samples that reach
    /// a pixel: samples of pixel q reach pixel p only when |q - p| <= margin
    /// (samples lie in [q, q+1), the centre of p is p + 0.5, so this is
    /// floor(radius + 0.5); never more than ceil(radius)).
    int xMargin() const;
    int yMargin() const;
    int margin() const { return xMargin() > yMargin() ? xMargin() : yMargin(); }

private:
    static constexpr int kLutPerPixel = 256;  // table entries per pixel of offset
    float factor1d(float t, float radius) const;  // separable factor at offset t
    void buildTables();
    static float lookup(const std::vector<float>& lut, float t, float radius) {
        if (!(t >= -radius && t <= radius)) return 0.0f;
        float f = (t + radius) * float(kLutPerPixel);
        int i = int(f);
        float a = f - float(i);
        return lut[size_t(i)] + a * (lut[size_t(i) + 1] - lut[size_t(i)]);
    }

    FilterKind m_kind;
    float m_xRadius, m_yRadius;
    bool m_separable;
    std::vector<float> m_lutX, m_lutY;  // factor at -radius + i / kLutPerPixel
};

}  // namespace umbra::film
