// Noise and colour-space helpers for the shadeops.

#include "vm.h"

#include "umbra/util/rng.h"

#include <cmath>

namespace umbra::shading {

namespace {

inline float fade(float t) { return t * t * t * (t * (t * 6 - 15) + 10); }

/// Hash of integer lattice coordinates.
uint32_t latticeHash(const int* c, int dims, uint32_t seed) {
    uint32_t h = hash32(seed * 0x9e3779b9U + 0x85ebca6bU);
    for (int k = 0; k < dims; ++k) h = hashCombine(h, uint32_t(c[k]));
    return h;
}

}  // namespace

float gradientNoise(const float* p, int dims, const float* period, uint32_t seed) {
    int base[4];
    float f[4];
    for (int k = 0; k < dims; ++k) {
        float fl = std::floor(p[k]);
        if (!std::isfinite(fl) || std::fabs(fl) > 1e9f) return 0.5f;
        base[k] = int(fl);
        f[k] = p[k] - fl;
    }
    float sum = 0;
    int corners = 1 << dims;
    for (int c = 0; c < corners; ++c) {
        int lat[4];
        float w = 1, g = 0;
        for (int k = 0; k < dims; ++k) {
            int bit = (c >> k) & 1;
            lat[k] = base[k] + bit;
            if (period && period[k] >= 1 && period[k] < 1e9f) {
                int per = int(period[k]);
                lat[k] = ((lat[k] % per) + per) % per;
            }
            float t = fade(f[k]);
            w *= bit ? t : 1 - t;
        }
        uint32_t h = latticeHash(lat, dims, seed);
        for (int k = 0; k < dims; ++k) {
            float gk = float((h >> (8 * k)) & 255u) * (2.0f / 255.0f) - 1.0f;
            g += gk * (f[k] - float((c >> k) & 1));
        }
        sum += w * g;
    }
    // Gradients in [-1,1]^d: the extreme value is about sqrt(d)/2; scale
    // to [-1,1] and then to RenderMan's [0,1] range with mean 0.5.
    float scaled = sum * (2.0f / std::sqrt(float(dims)));
    return clamp(0.5f + 0.5f * scaled, 0.f, 1.f);
}

float cellNoise(const float* p, int dims, uint32_t seed) {
    int lat[4];
    for (int k = 0; k < dims; ++k) {
        float fl = std::floor(p[k]);
        lat[k] = std::isfinite(fl) && std::fabs(fl) < 2e9f ? int(fl) : 0;
    }
    return hashToUnit(latticeHash(lat, dims, seed + 0x51ed27u));
}

namespace {

Vec3 hsvToRgb(const Vec3& c) {
    float h = c.x, s = c.y, v = c.z;
    if (s <= 0) return Vec3(v);
    if (!std::isfinite(h)) h = 0;
    h = (h - std::floor(h)) * 6;
    int i = int(h) % 6;
    float f = h - float(int(h));
    float p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
    switch (i) {
    case 0: return {v, t, p};
    case 1: return {q, v, p};
    case 2: return {p, v, t};
    case 3: return {p, q, v};
    case 4: return {t, p, v};
    default: return {v, p, q};
    }
}
Vec3 rgbToHsv(const Vec3& c) {
    float mx = std::max(c.x, std::max(c.y, c.z)), mn = std::min(c.x, std::min(c.y, c.z));
    float d = mx - mn;
    float h = 0, s = mx > 0 ? d / mx : 0;
    if (d > 0) {
        if (mx == c.x) h = (c.y - c.z) / d;
        else if (mx == c.y) h = 2 + (c.z - c.x) / d;
        else h = 4 + (c.x - c.y) / d;
        h /= 6;
        if (h < 0) h += 1;
    }
    return {h, s, mx};
}
float hueToRgb(float m1, float m2, float h) {
    h -= std::floor(h);
    if (6 * h < 1) return m1 + (m2 - m1) * h * 6;
    if (2 * h < 1) return m2;
    if (3 * h < 2) return m1 + (m2 - m1) * (2.0f / 3 - h) * 6;
    return m1;
}
Vec3 hslToRgb(const Vec3& c) {
    float h = c.x, s = c.y, l = c.z;
    if (s <= 0) return Vec3(l);
    float m2 = l <= 0.5f ? l * (1 + s) : l + s - l * s;
    float m1 = 2 * l - m2;
    return {hueToRgb(m1, m2, h + 1.0f / 3), hueToRgb(m1, m2, h), hueToRgb(m1, m2, h - 1.0f / 3)};
}
Vec3 rgbToHsl(const Vec3& c) {
    float mx = std::max(c.x, std::max(c.y, c.z)), mn = std::min(c.x, std::min(c.y, c.z));
    float l = 0.5f * (mx + mn), d = mx - mn;
    if (d <= 0) return {0, 0, l};
    float s = l <= 0.5f ? d / (mx + mn) : d / (2 - mx - mn);
    float h = rgbToHsv(c).x;
    return {h, s, l};
}
// CIE XYZ with Rec. 709 primaries and D65 white.
Vec3 xyzToRgb(const Vec3& c) {
    return {3.240479f * c.x - 1.537150f * c.y - 0.498535f * c.z, -0.969256f * c.x + 1.875991f * c.y + 0.041556f * c.z,
            0.055648f * c.x - 0.204043f * c.y + 1.057311f * c.z};
}
Vec3 rgbToXyz(const Vec3& c) {
    return {0.412453f * c.x + 0.357580f * c.y + 0.180423f * c.z, 0.212671f * c.x + 0.715160f * c.y + 0.072169f * c.z,
            0.019334f * c.x + 0.119193f * c.y + 0.950227f * c.z};
}
Vec3 yiqToRgb(const Vec3& c) {
    return {c.x + 0.956f * c.y + 0.621f * c.z, c.x - 0.272f * c.y - 0.647f * c.z, c.x - 1.106f * c.y + 1.703f * c.z};
}
Vec3 rgbToYiq(const Vec3& c) {
    return {0.299f * c.x + 0.587f * c.y + 0.114f * c.z, 0.596f * c.x - 0.274f * c.y - 0.322f * c.z,
            0.211f * c.x - 0.523f * c.y + 0.312f * c.z};
}

}  // namespace

bool colorToRgb(const std::string& space, const Vec3& c, Vec3* rgb) {
    if (space == "rgb") *rgb = c;
    else if (space == "hsv") *rgb = hsvToRgb(c);
    else if (space == "hsl") *rgb = hslToRgb(c);
    else if (space == "xyz" || space == "XYZ") *rgb = xyzToRgb(c);
    else if (space == "yiq" || space == "YIQ") *rgb = yiqToRgb(c);
    else {
        *rgb = c;
        return false;
    }
    return true;
}

bool colorFromRgb(const std::string& space, const Vec3& rgb, Vec3* c) {
    if (space == "rgb") *c = rgb;
    else if (space == "hsv") *c = rgbToHsv(rgb);
    else if (space == "hsl") *c = rgbToHsl(rgb);
    else if (space == "xyz" || space == "XYZ") *c = rgbToXyz(rgb);
    else if (space == "yiq" || space == "YIQ") *c = rgbToYiq(rgb);
    else {
        *c = rgb;
        return false;
    }
    return true;
}

}  // namespace umbra::shading
