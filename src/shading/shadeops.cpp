// Built-in functions ("shadeops") over a grid: math, geometry, derivatives,
// transforms, colour, matrices, strings, noise, lighting, texture, shadow
// and message passing. Each runs once per grid over the active points.

#include "builtins.h"
#include "vm.h"

#include "umbra/util/rng.h"


#include <algorithm>
#include <cstring>
#include <re2/re2.h>

namespace umbra::shading {

namespace {

/// Bounds of what string built-ins make (docs/rib.md, "Limits").
constexpr size_t kMaxStringBytes = size_t(1) << 20;
constexpr long kMaxFormatWidth = 256;

template <class F> void forActive(const Exec& x, bool varying, F&& f) {
    if (!varying) f(0);
    else if (x.allOn) for (int i = 0; i < x.n; ++i) f(i);
    else for (int i : x.active) f(i);
}

template <class F, class... A> void map(Exec& x, int dst, F&& f, A... args) {
    float* d = x.ptr[size_t(dst)];
    forActive(x, x.vary[size_t(dst)], [&](int i) { put(d, i, f(args[i]...)); });
}

/// Operand helper for one Call instruction.
struct Args {
    Exec& x;
    const Instr& in;
    int reg(int k) const { return x.cs->args[size_t(in.argBase + k)]; }
    In<float> f(int k) const { return {x.ptr[size_t(reg(k))], x.vary[size_t(reg(k))]}; }
    In<Vec3> v(int k) const { return {x.ptr[size_t(reg(k))], x.vary[size_t(reg(k))]}; }
    In<M16> m(int k) const { return {x.ptr[size_t(reg(k))], x.vary[size_t(reg(k))]}; }
    const std::string& s(int k) const { return x.strs[size_t(reg(k))][0]; }
    Ty ty(int k) const { return x.cs->regs[size_t(reg(k))].ty; }
    bool varying(int k) const { return x.vary[size_t(reg(k))] != 0; }
};

/// float to int without undefined behaviour for NaN or huge values.
int toInt(float f) {
    if (!(f > -2e9f)) return f != f ? 0 : -2000000000;
    if (!(f < 2e9f)) return 2000000000;
    return int(f);
}
int clampIndexM(float f) { return f >= 0 ? std::min(toInt(f), 3) : 0; }
float safeSqrt(float a) { return a > 0 ? std::sqrt(a) : 0.f; }
float fixNan(float a) { return std::isfinite(a) ? a : 0.f; }
/// pow() that is 0 where the real power is undefined or infinite.
float safePow(float a, float b) {
    if (a < 0 && b != std::floor(b)) return 0.f;
    return fixNan(std::pow(a, b));
}

Vec3 faceforward(const Vec3& N, const Vec3& I, const Vec3& Nref) { return dot(I, Nref) < 0 ? N : -N; }
Vec3 reflect(const Vec3& I, const Vec3& N) { return I - N * (2 * dot(I, N)); }
Vec3 refract(const Vec3& I, const Vec3& N, float eta) {
    float IdotN = dot(I, N);
    float k = 1 - eta * eta * (1 - IdotN * IdotN);
    return k < 0 ? Vec3(0.f) : I * eta - N * (eta * IdotN + std::sqrt(k));
}
void fresnel(const Vec3& I, const Vec3& N, float eta, float* Kr, float* Kt) {
    Vec3 In = normalize(I), Nn = normalize(N);
    float ci = -dot(In, Nn);
    if (ci < 0) ci = -ci;
    float st2 = eta * eta * (1 - ci * ci);
    if (st2 >= 1) {
        *Kr = 1;
        *Kt = 0;
        return;
    }
    float ct = std::sqrt(1 - st2);
    float rs = (eta * ci - ct) / (eta * ci + ct);
    float rp = (ci - eta * ct) / (ci + eta * ct);
    *Kr = fixNan(0.5f * (rs * rs + rp * rp));
    *Kt = 1 - *Kr;
}
/// clamp() as RI Spec 3.2 words it (see Bi::ClampF).
inline float clampSpec(float a, float lo, float hi) { return a < lo ? lo : (a > hi ? hi : a); }
float smoothstep(float e0, float e1, float x) {
    if (x < e0) return 0;
    if (x >= e1) return 1;
    float t = (x - e0) / (e1 - e0);
    return t * t * (3 - 2 * t);
}

/// The filters filterstep() takes (RI Spec 3.2: "box", "triangle",
/// "catmull-rom" (the default), "gaussian"), each the RI Spec's pixel
/// filter function of that name (Appendix E) taken at x = offset / w with
/// a filter width of 1, w the footprint: box [-w/2, w/2],
/// triangle [-w, w], catmull-rom [-2w, 2w], gaussian exp(-8 (x/w)^2).
/// These are the supports Pixie uses (its 10%-90% rises on the probe in
/// docs/shading-language.md); Aqsis takes every filter as a box.
enum class StepFilter { Box, Triangle, CatmullRom, Gaussian };

bool stepFilterNamed(const std::string& name, StepFilter* f) {
    if (name == "box") *f = StepFilter::Box;
    else if (name == "triangle") *f = StepFilter::Triangle;
    else if (name == "catmull-rom") *f = StepFilter::CatmullRom;
    else if (name == "gaussian") *f = StepFilter::Gaussian;
    else return false;
    return true;
}

/// The integral of the unit-area filter from -infinity to u (u in units of
/// the footprint): the step at 0 seen through the filter centred on u.
/// Catmull-Rom's lobes make its integral dip to -1/24 and peak at 25/24;
/// it is clamped to [0, 1] like a colour.
float filteredStep(StepFilter f, float u) {
    switch (f) {
    case StepFilter::Box: return clamp(u + 0.5f, 0.f, 1.f);
    case StepFilter::Triangle: {
        if (u <= -1) return 0;
        if (u >= 1) return 1;
        return u < 0 ? 0.5f * (1 + u) * (1 + u) : 1 - 0.5f * (1 - u) * (1 - u);
    }
    case StepFilter::CatmullRom: {
        // Integral from 0 to a of the Catmull-Rom kernel (B = 0, C = 1/2),
        // which has area 1/2 on each side.
        const float a = std::min(std::fabs(u), 2.f);
        float g;
        if (a <= 1) g = a * (1 + a * a * (-5.f / 6 + 0.375f * a));
        else g = 13.f / 24 + (-0.125f * a * a * a * a + 5.f / 6 * a * a * a - 2 * a * a + 2 * a) - 17.f / 24;
        return clamp(0.5f + (u < 0 ? -g : g), 0.f, 1.f);
    }
    case StepFilter::Gaussian: return 0.5f * (1 + std::erf(2.8284271f * u));  // sigma = 1/4
    }
    return 0;
}

float determinant(const M16& a) {
    Mat4 m;
    std::memcpy(m.m, a.m, sizeof a.m);
    const auto& q = m.m;
    float d = 0;
    for (int c = 0; c < 4; ++c) {
        float minor[3][3];
        for (int r = 1; r < 4; ++r)
            for (int cc = 0, k = 0; cc < 4; ++cc)
                if (cc != c) minor[r - 1][k++] = q[r][cc];
        float m3 = minor[0][0] * (minor[1][1] * minor[2][2] - minor[1][2] * minor[2][1]) -
                   minor[0][1] * (minor[1][0] * minor[2][2] - minor[1][2] * minor[2][0]) +
                   minor[0][2] * (minor[1][0] * minor[2][1] - minor[1][1] * minor[2][0]);
        d += ((c & 1) ? -1.f : 1.f) * q[0][c] * m3;
    }
    return d;
}
/// A column-vector Mat4 as an RSL (row-vector) matrix.
M16 toRsl(const Mat4& m) {
    M16 r;
    m.toRib(r.m);
    return r;
}
Vec3 rslPoint(const M16& m, const Vec3& p) {
    const float* a = m.m;
    float x = p.x * a[0] + p.y * a[4] + p.z * a[8] + a[12];
    float y = p.x * a[1] + p.y * a[5] + p.z * a[9] + a[13];
    float z = p.x * a[2] + p.y * a[6] + p.z * a[10] + a[14];
    float w = p.x * a[3] + p.y * a[7] + p.z * a[11] + a[15];
    if (w != 1 && w != 0) return {x / w, y / w, z / w};
    return {x, y, z};
}
Vec3 rslVector(const M16& m, const Vec3& p) {
    const float* a = m.m;
    return {p.x * a[0] + p.y * a[4] + p.z * a[8], p.x * a[1] + p.y * a[5] + p.z * a[9], p.x * a[2] + p.y * a[6] + p.z * a[10]};
}
Vec3 rslNormal(const M16& m, const Vec3& n) {
    Mat4 a;
    std::memcpy(a.m, m.m, sizeof m.m);
    Mat4 inv = a.inverse();  // RSL order: n' = n * inverse(m)^T
    const auto& q = inv.m;
    return Vec3(n.x * q[0][0] + n.y * q[0][1] + n.z * q[0][2], n.x * q[1][0] + n.y * q[1][1] + n.z * q[1][2],
                n.x * q[2][0] + n.y * q[2][1] + n.z * q[2][2]);
}

/// currentFromSpace for a named space.
Mat4 spaceMatrix(Exec& x, const std::string& name, const Instr& in) {
    if (name == "current" || name == "camera") return Mat4::identity();
    if (name == "shader") return x.currentFromShader;
    auto it = x.ctx->spaces.find(name);
    if (it != x.ctx->spaces.end()) return it->second;
    Mat4 m;
    if (!x.ctx->services->getMatrix(*x.ctx->grid, name, &m)) {
        x.ctx->system->diagnostics().warningOnce("shading:space:" + name, FileLoc::inFile(x.cs->fileName, in.loc.line, in.loc.col),
                                                 "unknown coordinate system '{}' (using \"current\")", name);
        m = Mat4::identity();
    }
    x.ctx->spaces[name] = m;
    return m;
}

enum class XKind { Point, Vector, Normal };
Vec3 xform(const Mat4& m, const Mat4& inv, XKind k, const Vec3& v) {
    switch (k) {
    case XKind::Point: return m.point(v);
    case XKind::Vector: return m.vector(v);
    case XKind::Normal: return Mat4::normal(inv, v);
    }
    return v;
}

/// The difference of `a` at point i along one grid direction (neighbours
/// `stride` apart; i is at `pos` of `count` points along it), per unit of
/// `step`: central inside, one-sided at the edges.
/// (Selects rather than branches: the neighbours before and after, the
/// point itself at an edge, halved when both are neighbours.)
template <class T> inline T gridDifference(In<T> a, int i, int stride, int pos, int count, float step) {
    if (count < 2) return T(0);
    const int before = pos > 0 ? i - stride : i, after = pos < count - 1 ? i + stride : i;
    return (a[after] - a[before]) * ((after - before == 2 * stride ? 0.5f : 1.0f) / step);
}
/// Derivative along u (dir 0) or v (dir 1) of register r at point i, per
/// unit of u/v: central differences inside, one-sided at the edges.
template <class T> T deriv(const Exec& x, In<T> a, int i, int dir, float step) {
    if (a.s == 0 || step == 0) return T(0);
    int nu = x.nu, nv = x.nv;
    // i = iv nu + iu without an integer divide (the costliest step here):
    // i is exact in float, and one step fixes the reciprocal's rounding.
    int iv = int(float(i) * x.invNu);
    if (iv * nu > i) --iv;
    else if ((iv + 1) * nu <= i) ++iv;
    const int iu = i - iv * nu;
    return dir == 0 ? gridDifference(a, i, 1, iu, nu, step) : gridDifference(a, i, nu, iv, nv, step);
}
/// deriv(x, a, i, 0, 1) and deriv(x, a, i, 1, 1) of every active point,
/// in order: the active indices ascend, so each point's grid row follows
/// from the last one's without a division.
template <class T> void derivsOfActive(const Exec& x, In<T> a, T* du, T* dv) {
    const int nu = x.nu, nv = x.nv;
    if (nu < 1 || a.s == 0) {  // no rows to walk, or uniform: deriv() gives 0 too
        std::fill_n(du, x.active.size(), T(0));
        std::fill_n(dv, x.active.size(), T(0));
        return;
    }
    int iv = 0, rowStart = 0;
    for (size_t k = 0; k < x.active.size(); ++k) {
        const int i = x.active[k];
        while (i >= rowStart + nu) rowStart += nu, ++iv;
        du[k] = gridDifference(a, i, 1, i - rowStart, nu, 1.0f);
        dv[k] = gridDifference(a, i, nu, iv, nv, 1.0f);
    }
}
float gridDu(const Exec& x) { return x.ctx->grid->du; }
float gridDv(const Exec& x) { return x.ctx->grid->dv; }

// --- splines ------------------------------------------------------------

struct SplineBasis {
    float m[4][4];
    int step;
};
bool splineBasis(const std::string& name, SplineBasis* b) {
    static const SplineBasis kCatmull = {{{-0.5f, 1.5f, -1.5f, 0.5f}, {1, -2.5f, 2, -0.5f}, {-0.5f, 0, 0.5f, 0}, {0, 1, 0, 0}}, 1};
    static const SplineBasis kBezier = {{{-1, 3, -3, 1}, {3, -6, 3, 0}, {-3, 3, 0, 0}, {1, 0, 0, 0}}, 3};
    static const SplineBasis kBspline = {{{-1 / 6.f, 3 / 6.f, -3 / 6.f, 1 / 6.f}, {3 / 6.f, -6 / 6.f, 3 / 6.f, 0}, {-3 / 6.f, 0, 3 / 6.f, 0}, {1 / 6.f, 4 / 6.f, 1 / 6.f, 0}}, 1};
    static const SplineBasis kHermite = {{{2, 1, -2, 1}, {-3, -2, 3, -1}, {0, 1, 0, 0}, {1, 0, 0, 0}}, 2};
    static const SplineBasis kLinear = {{{0, 0, 0, 0}, {0, 0, 0, 0}, {0, -1, 1, 0}, {0, 1, 0, 0}}, 1};
    if (name == "catmull-rom" || name == "catrom") *b = kCatmull;
    else if (name == "bezier") *b = kBezier;
    else if (name == "bspline" || name == "b-spline") *b = kBspline;
    else if (name == "hermite") *b = kHermite;
    else if (name == "linear") *b = kLinear;
    else return false;
    return true;
}
template <class T, class Get> T evalSpline(const SplineBasis& b, float t, int count, Get get) {
    if (count < 4) return T(0);
    int segs = (count - 4) / b.step + 1;
    float ft = (t >= 0 ? std::min(t, 1.f) : 0.f) * float(segs);  // NaN -> 0
    int seg = std::min(int(ft), segs - 1);
    float u = ft - float(seg);
    float w[4];
    for (int k = 0; k < 4; ++k) w[k] = ((b.m[0][k] * u + b.m[1][k]) * u + b.m[2][k]) * u + b.m[3][k];
    T r = get(seg * b.step) * w[0];
    for (int k = 1; k < 4; ++k) r = r + get(seg * b.step + k) * w[k];
    return r;
}

void spline(Exec& x, const Instr& in, Args& A, bool triple, bool hasBasis) {
    int k = 0;
    SplineBasis basis;
    splineBasis("catmull-rom", &basis);
    if (hasBasis) {
        const std::string& name = A.s(k++);
        if (!splineBasis(name, &basis))
            x.ctx->system->diagnostics().warningOnce("shading:spline:" + name, FileLoc::inFile(x.cs->fileName, in.loc.line, in.loc.col),
                                                     "unknown spline basis '{}' (using catmull-rom)", name);
    }
    In<float> t = A.f(k++);
    int first = k;
    int valuesReg = A.reg(first);
    const RegInfo& vr = x.cs->regs[size_t(valuesReg)];
    bool array = vr.arrayLen > 0 && in.nargs == first + 1;
    int count = array ? vr.arrayLen : in.nargs - first;
    float* d = x.ptr[size_t(in.dst)];
    int comps = triple ? 3 : 1;
    forActive(x, x.vary[size_t(in.dst)], [&](int i) {
        auto get = [&](int j) -> Vec3 {
            if (array) {
                int vs = x.vary[size_t(valuesReg)];
                const float* p = x.ptr[size_t(valuesReg)] + size_t(j) * size_t(comps) * size_t(vs ? x.n : 1) + size_t(i * vs * comps);
                return triple ? Vec3(p[0], p[1], p[2]) : Vec3(p[0]);
            }
            return triple ? A.v(first + j)[i] : Vec3(A.f(first + j)[i]);
        };
        Vec3 r = evalSpline<Vec3>(basis, t[i], count, get);
        if (triple) put(d, i, r);
        else d[i] = r.x;
    });
}

// --- strings ------------------------------------------------------------

std::string formatString(Exec& x, Args& A, int first, int i) {
    const std::string& f = A.s(first);
    std::string out;
    int arg = first + 1;
    for (size_t k = 0; k < f.size(); ++k) {
        if (f[k] != '%') {
            out += f[k];
            continue;
        }
        size_t b = k++;
        while (k < f.size() && std::strchr("-+ #0123456789.", f[k])) ++k;
        if (k >= f.size()) break;
        char c = f[k];
        std::string flags = f.substr(b, k - b);
        // Field widths and precisions are bounded: "%999999999d" would pad
        // a gigabyte (snprintf computes it all before cutting).
        std::string bounded;
        for (size_t p = 0; p < flags.size();) {
            if (flags[p] >= '0' && flags[p] <= '9' && (flags[p] != '0' || (p > 0 && flags[p - 1] == '.'))) {
                size_t q = p;
                while (q < flags.size() && flags[q] >= '0' && flags[q] <= '9') ++q;
                long v = std::strtol(flags.substr(p, q - p).c_str(), nullptr, 10);
                if (q - p > 3 || v > kMaxFormatWidth) {
                    x.ctx->system->diagnostics().warningOnce("shading:format:" + x.cs->name, FileLoc::inFile(x.cs->fileName, A.in.loc.line, A.in.loc.col),
                                                             "shader '{}': a format width or precision above {} is cut to it",
                                                             x.cs->name, kMaxFormatWidth);
                    v = kMaxFormatWidth;
                }
                bounded += std::to_string(v);
                p = q;
            } else {
                bounded += flags[p++];
            }
        }
        flags = bounded;
        if (c == '%') {
            out += '%';
            continue;
        }
        if (arg >= A.in.nargs) {
            out += "<missing>";
            continue;
        }
        int r = A.reg(arg++);
        Ty t = x.cs->regs[size_t(r)].ty;
        char buf[2 * kMaxFormatWidth + 64];  // width and precision at most kMaxFormatWidth each
        auto fmtF = [&](float v, char conv) {
            std::string spec = flags + conv;
            std::snprintf(buf, sizeof buf, spec.c_str(), double(v));
            return std::string(buf);
        };
        if (t == Ty::String) {
            // With C's width and precision ("%-8s", "%.2s"); the string
            // itself may be longer than the buffer, so it is padded here.
            const std::string& str = x.strs[size_t(r)][0];
            const size_t dot = flags.find('.');
            const bool left = flags.find('-') != std::string::npos;
            std::string digits = flags.substr(1, dot == std::string::npos ? std::string::npos : dot - 1);
            digits.erase(0, digits.find_first_of("123456789"));
            const size_t width = digits.empty() ? 0 : std::strtoul(digits.c_str(), nullptr, 10);
            const size_t precision = dot == std::string::npos ? str.size() : std::strtoul(flags.c_str() + dot + 1, nullptr, 10);
            const std::string shown = str.substr(0, precision);
            const std::string pad(width > shown.size() ? width - shown.size() : 0, ' ');
            out += left ? shown + pad : pad + shown;
        } else if (t == Ty::Float) {
            float v = In<float>{x.ptr[size_t(r)], x.vary[size_t(r)]}[i];
            if (c == 'd' || c == 'i') {
                std::string spec = flags + "d";
                std::snprintf(buf, sizeof buf, spec.c_str(), toInt(v));
                out += buf;
            } else {
                out += fmtF(v, c == 'e' || c == 'g' ? c : 'f');
            }
        } else if (t == Ty::Matrix) {
            M16 m = In<M16>{x.ptr[size_t(r)], x.vary[size_t(r)]}[i];
            for (int e = 0; e < 16; ++e) {
                if (e) out += ' ';
                out += fmtF(m.m[e], 'f');
            }
        } else {
            Vec3 v = In<Vec3>{x.ptr[size_t(r)], x.vary[size_t(r)]}[i];
            out += fmtF(v.x, 'f') + " " + fmtF(v.y, 'f') + " " + fmtF(v.z, 'f');
        }
    }
    return out;
}

// --- lighting -----------------------------------------------------------

/// The lights of diffuse(), specular() and phong(): those reaching the front
/// hemisphere of `N` (a cone of pi/2), at P.
void needLightsAbout(Exec& x, In<Vec3> N) {
    int Pr = x.cs->globalRegs[gP];
    needLights(x, x.ptr[size_t(Pr)], x.vary[size_t(Pr)], N.p, N.s, float(kPi / 2));
}

[[gnu::always_inline]] inline Vec3 unit(const Vec3& v) {
    float l2 = dot(v, v);
    if (l2 > 0.999999f && l2 < 1.000001f) return v;  // already unit (Nf, normalize()d vectors)
    return l2 > 0 ? v * (1.0f / std::sqrt(l2)) : v;
}

/// The exponent of specular() and specularbrdf() for a roughness. The RI
/// spec's sample text writes 1/roughness, but PRMan and BMRT use
/// 8/roughness (Aqsis copies them, Pixie uses 10/roughness): the scenes
/// users have were tuned for that, so umbra uses it (docs/shading-language.md).
inline float specularExponent(float roughness) { return 8.0f / roughness; }

/// A light's float parameter `name` (its value after the light ran) and
/// its stride (0: uniform); null when the light has no such float.
std::pair<const float*, int> lightFloat(const Exec* light, const char* name) {
    if (!light || !light->cs) return {nullptr, 0};
    const CompiledShader& cs = *light->cs;
    for (size_t p = 0; p < cs.params.size(); ++p) {
        if (cs.params[p].name != name) continue;
        const int r = cs.paramRegs[p];
        const RegInfo& ri = cs.regs[size_t(r)];
        if (ri.ty != Ty::Float || ri.arrayLen > 0) return {nullptr, 0};
        return {light->ptr[size_t(r)], light->vary[size_t(r)] ? 1 : 0};
    }
    return {nullptr, 0};
}

/// diffuse(), specular(), phong(): sums over the non-ambient lights that
/// reached each point from the front hemisphere of N, point by point so
/// that the normalised N and V are computed once for all lights.
///
/// Light categories by convention (PRMan, and the shaders of Advanced
/// RenderMan): a light's float parameter `__nondiffuse` takes it out of
/// diffuse(), `__nonspecular` out of specular() and phong(). 1 excludes
/// the light, 0 (or no such parameter) keeps it; a value between scales
/// its contribution by 1 - value, as those shaders' own loops do.
enum class LightModel { Diffuse, Specular, Phong };
template <LightModel model> void lightSum(Exec& x, const Instr& in, const Args& A) {
    needLightsAbout(x, A.v(0));
    float* d = x.ptr[size_t(in.dst)];
    // The non-ambient lights, flattened for the inner loop.
    constexpr int kMax = 64;
    struct Src {
        const Vec3* dir;
        const float* cl;
        int cls;
        const uint8_t* lit;
        const float* non;  // __nondiffuse or __nonspecular; null: none
        int nons;
        float weight(int i) const { return non ? 1.0f - std::clamp(non[i * nons], 0.0f, 1.0f) : 1.0f; }
    };
    Src local[kMax];
    std::vector<Src> many;
    Src* src = local;
    int count = 0;
    for (const LightRun& lr : x.ctx->lights)
        if (!lr.ambient) ++count;
    if (count > kMax) {
        many.resize(size_t(count));
        src = many.data();
    }
    count = 0;
    constexpr const char* category = model == LightModel::Diffuse ? "__nondiffuse" : "__nonspecular";
    for (const LightRun& lr : x.ctx->lights)
        if (!lr.ambient) {
            const auto [non, nons] = lightFloat(lr.exec, category);
            src[count++] = {lr.dir, lr.Clp, 3 * lr.Cls, lr.litp, non, nons};
        }
    In<Vec3> N = A.v(0);
    In<Vec3> V = model == LightModel::Diffuse ? N : A.v(1);
    In<float> k = model == LightModel::Diffuse ? In<float>{nullptr, 0} : A.f(2);
    auto one = [&](int i) {
        Vec3 Nn = unit(N[i]);
        Vec3 sum(0.f);
        if constexpr (model == LightModel::Diffuse) {
            for (int l = 0; l < count; ++l) {
                const Src& s = src[l];
                if (!s.lit[i]) continue;
                float c = dot(s.dir[i], Nn);
                if (c <= 0) continue;
                const float w = s.weight(i);
                if (w <= 0) continue;
                const float* cl = s.cl + i * s.cls;
                sum += Vec3(cl[0], cl[1], cl[2]) * (c * w);
            }
        } else if constexpr (model == LightModel::Specular) {
            Vec3 Vn = unit(V[i]);
            float r = k[i];
            if (r > 0) {
                const float e = specularExponent(r);
                for (int l = 0; l < count; ++l) {
                    const Src& s = src[l];
                    if (!s.lit[i]) continue;
                    const Vec3& Ln = s.dir[i];
                    if (dot(Ln, Nn) <= 0) continue;
                    const float w = s.weight(i);
                    if (w <= 0) continue;
                    Vec3 H = unit(Ln + Vn);
                    const float* cl = s.cl + i * s.cls;
                    sum += Vec3(cl[0], cl[1], cl[2]) * (w * std::pow(std::max(0.f, dot(Nn, H)), e));
                }
            }
        } else {
            Vec3 R = reflect(-unit(V[i]), Nn);
            float size = k[i];
            for (int l = 0; l < count; ++l) {
                const Src& s = src[l];
                if (!s.lit[i]) continue;
                const Vec3& Ln = s.dir[i];
                if (dot(Ln, Nn) <= 0) continue;
                const float w = s.weight(i);
                if (w <= 0) continue;
                const float* cl = s.cl + i * s.cls;
                sum += Vec3(cl[0], cl[1], cl[2]) * (w * std::pow(std::max(0.f, dot(R, Ln)), size));
            }
        }
        put(d, i, sum);
    };
    if (x.allOn) for (int i = 0; i < x.n; ++i) one(i);
    else for (int i : x.active) one(i);
}

// --- texture ------------------------------------------------------------

TextureOptions textureOptions(Exec& x, Args& A, int pairsAt, float* swidth, float* twidth) {
    TextureOptions opt;
    int pairs = toInt(A.f(pairsAt)[0]);
    for (int k = 0; k < pairs; ++k) {
        const std::string& name = A.s(pairsAt + 1 + 2 * k);
        int vr = A.reg(pairsAt + 2 + 2 * k);
        const RegInfo& ri = x.cs->regs[size_t(vr)];
        float v = ri.ty == Ty::String ? 0.f : x.ptr[size_t(vr)][0];
        if (name == "blur") opt.sblur = opt.tblur = v;
        else if (name == "sblur") opt.sblur = v;
        else if (name == "tblur") opt.tblur = v;
        else if (name == "width") *swidth = *twidth = v;
        else if (name == "swidth") *swidth = v;
        else if (name == "twidth") *twidth = v;
        else if (name == "fill") opt.fill = v;
        else if (name == "filter" || name == "samples" || name == "lerp") {
        } else {
            x.ctx->system->diagnostics().warningOnce("shading:texparam:" + name, FileLoc::inFile(x.cs->fileName, A.in.loc.line, A.in.loc.col),
                                                     "unknown texture parameter '{}' ignored", name);
        }
    }
    opt.swidth = *swidth;
    opt.twidth = *twidth;
    return opt;
}

/// A texture or environment map that a lookup could not read: one error per
/// file, the rule shadow maps follow (docs/shading-language.md), located at
/// the primitive whose shader asked and naming the call; its lookups read 0.
void reportUnreadable(Exec& x, const Instr& in, const char* call, const std::string& name) {
    const FileLoc callSite = FileLoc::inFile(x.cs->fileName, in.loc.line, in.loc.col);
    FileLoc where = x.ctx->services && x.ctx->grid ? x.ctx->services->primitiveLocation(*x.ctx->grid) : FileLoc();
    if (!where.file) where = callSite;
    x.ctx->system->diagnostics().errorOnce("lookup:" + name, where,
                                           "{}(): cannot read \"{}\" (the call at {}); its lookups read 0", call, name,
                                           callSite.str());
}

void texture(Exec& x, const Instr& in, Args& A, bool color, bool fourPoint) {
    TextureBackend* ts = x.ctx->system->textures();
    if (A.s(0).empty()) {  // no texture named: 0, as RenderMan
        float* d = x.ptr[size_t(in.dst)];
        forActive(x, x.vary[size_t(in.dst)], [&](int i) {
            if (color) put(d, i, Vec3(0.f));
            else d[i] = 0;
        });
        return;
    }
    int nc = color ? 3 : 1;
    float* d = x.ptr[size_t(in.dst)];
    bool vd = x.vary[size_t(in.dst)];
    const std::string& name = A.s(0);
    int channel = std::max(0, std::min(toInt(A.f(1)[0]), 1 << 16));
    int pairsAt = fourPoint ? 10 : 4;
    float sw = 1, tw = 1;
    TextureOptions opt = textureOptions(x, A, pairsAt, &sw, &tw);
    opt.firstChannel = channel;
    const std::string& file = name;
    bool ok = true;
    forActive(x, vd, [&](int i) {
        float s, t, dsdx, dtdx, dsdy, dtdy;
        if (fourPoint) {
            float ss[4], tt[4];
            for (int k = 0; k < 4; ++k) {
                ss[k] = A.f(2 + 2 * k)[i];
                tt[k] = A.f(3 + 2 * k)[i];
            }
            s = 0.25f * (ss[0] + ss[1] + ss[2] + ss[3]);
            t = 0.25f * (tt[0] + tt[1] + tt[2] + tt[3]);
            dsdx = ss[1] - ss[0];
            dtdx = tt[1] - tt[0];
            dsdy = ss[2] - ss[0];
            dtdy = tt[2] - tt[0];
        } else {
            In<float> S = A.f(2), T = A.f(3);
            s = S[i];
            t = T[i];
            dsdx = deriv(x, S, i, 0, 1.f);
            dtdx = deriv(x, T, i, 0, 1.f);
            dsdy = deriv(x, S, i, 1, 1.f);
            dtdy = deriv(x, T, i, 1, 1.f);
        }
        float r[3] = {0, 0, 0};
        if (!ts || !ts->texture(file, opt, s, t, dsdx, dtdx, dsdy, dtdy, nc, r)) ok = false;
        if (color) put(d, i, Vec3(r[0], r[1], r[2]));
        else d[i] = r[0];
    });
    if (!ok) reportUnreadable(x, in, "texture", name);
}

void environment(Exec& x, const Instr& in, Args& A, bool color, bool fourDirections) {
    TextureBackend* ts = x.ctx->system->textures();
    int nc = color ? 3 : 1;
    float* d = x.ptr[size_t(in.dst)];
    const std::string& name = A.s(0);
    float sw = 1, tw = 1;
    TextureOptions opt = textureOptions(x, A, fourDirections ? 6 : 3, &sw, &tw);
    opt.firstChannel = std::max(0, std::min(toInt(A.f(1)[0]), 1 << 16));
    const std::string& file = name;
    In<Vec3> R = A.v(2);  // in the space the caller chose (shinymetal passes "world")
    bool ok = true;
    forActive(x, x.vary[size_t(in.dst)], [&](int i) {
        Vec3 r = R[i], dx, dy;
        TextureOptions o = opt;
        if (fourDirections) {
            // The region the four directions span: a box over its angular
            // extent about their mean direction, along the longitude and
            // the latitude, as "sblur" and "tblur" filter (a blur b is
            // 2 pi b radians).
            const Vec3 c[4] = {R[i], A.v(3)[i], A.v(4)[i], A.v(5)[i]};
            r = c[0] + c[1] + c[2] + c[3];
            auto lonLat = [](const Vec3& d, float* lon, float* lat) {
                const float len = length(d);
                *lon = std::atan2(d.y, d.x);
                *lat = len > 0 ? std::asin(std::clamp(d.z / len, -1.0f, 1.0f)) : 0.0f;
            };
            float lon0, lat0;
            lonLat(r, &lon0, &lat0);
            float alongLon = 0, alongLat = 0;
            for (const Vec3& d : c) {
                float lon, lat;
                lonLat(d, &lon, &lat);
                const float turn = std::remainder(lon - lon0, 2 * kPi);
                alongLon = std::max(alongLon, std::abs(turn) * std::cos(lat0));
                alongLat = std::max(alongLat, std::abs(lat - lat0));
            }
            if (std::isfinite(alongLon) && std::isfinite(alongLat)) {
                o.sblur += 2 * alongLon / (2 * kPi);
                o.tblur += 2 * alongLat / (2 * kPi);
            }
            dx = dy = Vec3(0.f);
        } else {
            dx = deriv(x, R, i, 0, 1.f);
            dy = deriv(x, R, i, 1, 1.f);
        }
        float out[3] = {0, 0, 0};
        if (!ts || !ts->environment(file, o, r, dx, dy, nc, out))
            ok = false;
        if (color) put(d, i, Vec3(out[0], out[1], out[2]));
        else d[i] = out[0];
    });
    if (!ok) reportUnreadable(x, in, "environment", name);
}

void shadow(Exec& x, const Instr& in, Args& A, bool four) {
    float* d = x.ptr[size_t(in.dst)];
    // The result is varying (marked by codegen).
    for (int i : x.active) d[i] = 0;
    // The query is per-thread scratch too: its parameters' names and values
    // keep their storage from call to call.
    thread_local ShadowQuery q;
    q.mapName = A.s(0);
    for (const Vec3*& c : q.corners) c = nullptr;
    q.L = nullptr;
    q.lightAtInfinity = false;
    int first = 2;
    int nPoints = four ? 4 : 1;
    int nArg = first + nPoints;
    int pairsAt = nArg + 1;
    // Per-thread scratch, one entry per active point: a shadow() call runs
    // once per grid and light, and must not allocate each time.
    // They only grow: resizing down and up again would zero the regrown
    // entries on every call.
    thread_local std::vector<Vec3> P, dPdu, dPdv, N, corners[4], Lv;
    thread_local std::vector<float> result;
    const size_t count = x.active.size();
    auto atLeast = [count](auto& v) {
        if (v.size() < count) v.resize(count);
    };
    for (auto* v : {&P, &dPdu, &dPdv, &N}) atLeast(*v);
    atLeast(result);
    In<Vec3> Pin = A.v(first);
    In<Vec3> Nin = A.v(nArg);
    // The normal turned towards the camera, faceforward(N, I): the side of
    // the surface the camera sees is the one whose light the lookup
    // measures. An open two-sided floor lit from above and seen from above
    // is then light-facing whichever way its parameters wind, and its
    // virtual samples light it; the far side of a solid stays unlit.
    const std::vector<Vec3>& eyeRays = x.ctx->grid->I;
    for (size_t k = 0; k < count; ++k) {
        const int i = x.active[k];
        P[k] = Pin[i];
        N[k] = Nin[i];
        if (size_t(i) < eyeRays.size() && dot(N[k], eyeRays[size_t(i)]) > 0) N[k] = -N[k];
    }
    derivsOfActive(x, Pin, dPdu.data(), dPdv.data());
    if (four) {
        for (int c = 0; c < 4; ++c) {
            atLeast(corners[c]);
            In<Vec3> cin = A.v(first + c);
            for (size_t k = 0; k < count; ++k) corners[c][k] = cin[x.active[k]];
            q.corners[c] = corners[c].data();
        }
        for (size_t k = 0; k < count; ++k) P[k] = (corners[0][k] + corners[1][k] + corners[2][k] + corners[3][k]) * 0.25f;
    }
    if (x.cs->kind == ShaderKind::Light && x.lightConstruct != 0) {
        // Inside illuminate()/solar(): where the light is, for "raytrace".
        const int Lreg = x.cs->globalRegs[gL];
        In<Vec3> Lin{x.ptr[size_t(Lreg)], x.vary[size_t(Lreg)]};
        atLeast(Lv);
        for (size_t k = 0; k < count; ++k) Lv[k] = Lin[x.active[k]];
        q.L = Lv.data();
        q.lightAtInfinity = x.lightConstruct == 2;
    }
    q.count = int(count);
    q.indices = x.active.data();
    q.P = P.data();
    q.dPdu = dPdu.data();
    q.dPdv = dPdv.data();
    q.N = N.data();
    int pairs = toInt(A.f(pairsAt)[0]);
    q.params.resize(size_t(std::max(pairs, 0)));
    for (int k = 0; k < pairs; ++k) {
        ShadeValue& v = q.params[size_t(k)];
        v.name = A.s(pairsAt + 1 + 2 * k);
        v.strings.clear();
        int vr = A.reg(pairsAt + 2 + 2 * k);
        const RegInfo& ri = x.cs->regs[size_t(vr)];
        if (ri.ty == Ty::String) {
            v.type = ValueType::String;
            v.floats.clear();
            v.strings.push_back(x.strs[size_t(vr)][0]);
        } else {
            v.type = valueTypeOf(ri.ty);
            v.floats.assign(x.ptr[size_t(vr)], x.ptr[size_t(vr)] + tyFloats(ri.ty));
        }
    }
    q.seed = x.randomSeed(in);
    q.callFile = &x.cs->fileName;
    q.callLine = in.loc.line;
    q.callColumn = in.loc.col;
    // No map: unshadowed (the renderer reports it).
    if (!x.ctx->services->shadow(*x.ctx->grid, q, result.data())) return;
    for (size_t k = 0; k < count; ++k) d[x.active[k]] = fixNan(result[k]);
}

// --- message passing ----------------------------------------------------

/// Copies another shader's parameter `name` into output register `dst`
/// (for the active points); false when there is no such parameter of a
/// compatible type.
bool copyParam(Exec& x, const Exec* from, const std::string& name, int dst) {
    if (!from) return false;
    const RegInfo& d = x.cs->regs[size_t(dst)];
    for (size_t p = 0; p < from->cs->params.size(); ++p) {
        if (from->cs->params[p].name != name) continue;
        int sr = from->cs->paramRegs[p];
        const RegInfo& s = from->cs->regs[size_t(sr)];
        bool compatible = s.ty == d.ty || (isSpatial(s.ty) && isSpatial(d.ty));
        if (!compatible || s.arrayLen != d.arrayLen) return false;
        if (d.ty == Ty::String) {
            x.strs[size_t(dst)] = from->strs[size_t(sr)];
            return true;
        }
        int comps = tyFloats(d.ty) * std::max(1, d.arrayLen);
        int sv = from->vary[size_t(sr)];
        float* dp = x.ptr[size_t(dst)];
        const float* sp = from->ptr[size_t(sr)];
        // A uniform variable takes one value: the first active point's.
        const bool dv = x.vary[size_t(dst)] != 0;
        const int first = x.allOn || x.active.empty() ? 0 : x.active[0];
        auto source = [&](int i) { return sv ? (dv ? i : first) : 0; };
        if (d.arrayLen > 0) {
            int c = tyFloats(d.ty);
            for (int e = 0; e < d.arrayLen; ++e)
                forActive(x, dv, [&](int i) {
                    std::memcpy(dp + size_t(e) * size_t(c) * size_t(dv ? x.n : 1) + size_t(i * c),
                                sp + size_t(e) * size_t(c) * size_t(sv ? x.n : 1) + size_t(source(i) * c),
                                sizeof(float) * size_t(c));
                });
            return true;
        }
        forActive(x, dv, [&](int i) {
            std::memcpy(dp + i * comps, sp + source(i) * comps, sizeof(float) * size_t(comps));
        });
        return true;
    }
    return false;
}

/// Stores one value (all of an array's elements) at the active points of
/// register dst. A varying array is element-major: each element's n values
/// together (as bindParam() and copyParam() lay it out).
void storeAtActive(Exec& x, int dst, const float* value) {
    const RegInfo& d = x.cs->regs[size_t(dst)];
    const int comps = tyFloats(d.ty), elems = std::max(1, d.arrayLen);
    const bool dv = x.vary[size_t(dst)] != 0;
    float* dp = x.ptr[size_t(dst)];
    forActive(x, dv, [&](int i) {
        for (int e = 0; e < elems; ++e)
            std::memcpy(dp + size_t(e) * size_t(comps) * size_t(dv ? x.n : 1) + size_t(i) * size_t(comps),
                        value + size_t(e) * size_t(comps), sizeof(float) * size_t(comps));
    });
}

bool fromShadeValue(Exec& x, const ShadeValue& v, int dst) {
    const RegInfo& d = x.cs->regs[size_t(dst)];
    if (d.ty == Ty::String) {
        if (v.strings.empty()) return false;
        for (size_t k = 0; k < x.strs[size_t(dst)].size() && k < v.strings.size(); ++k) x.strs[size_t(dst)][k] = v.strings[k];
        return true;
    }
    if (int(v.floats.size()) < d.floatsPerValue()) return false;
    storeAtActive(x, dst, v.floats.data());
    return true;
}


void setResult(Exec& x, const Instr& in, float v) {
    if (in.dst >= 0) forActive(x, x.vary[size_t(in.dst)], [&](int i) { x.ptr[size_t(in.dst)][i] = v; });
}

void noise(Exec& x, const Instr& in, Args& A, int dims, bool triple, bool periodic, bool cell) {
    float* d = x.ptr[size_t(in.dst)];
    // Argument layout: 1: f; 2: f f; 3: p; 4: p f. Periodic forms then
    // give the periods in the same layout (RI Spec 3.2: pnoise(u, v,
    // uperiod, vperiod), pnoise(P, t, Pperiod, tperiod)).
    const bool pFirst = dims >= 3;
    const int positions = dims == 2 || dims == 4 ? 2 : 1;
    forActive(x, x.vary[size_t(in.dst)], [&](int i) {
        float p[4] = {0, 0, 0, 0}, per[4] = {0, 0, 0, 0};
        auto read = [&](int k, float* into) {
            if (pFirst) {
                const Vec3 v = A.v(k)[i];
                into[0] = v.x, into[1] = v.y, into[2] = v.z;
                if (dims == 4) into[3] = A.f(k + 1)[i];
            } else {
                into[0] = A.f(k)[i];
                if (dims == 2) into[1] = A.f(k + 1)[i];
            }
        };
        read(0, p);
        if (periodic) read(positions, per);
        if (!triple) {
            d[i] = cell ? cellNoise(p, dims, 0) : gradientNoise(p, dims, periodic ? per : nullptr, 0);
        } else {
            Vec3 r;
            for (int c = 0; c < 3; ++c)
                r[c] = cell ? cellNoise(p, dims, uint32_t(c + 1)) : gradientNoise(p, dims, periodic ? per : nullptr, uint32_t(c + 1));
            put(d, i, r);
        }
    });
}

}  // namespace

void execCall(Exec& x, const Instr& in) {
    Args A{x, in};
    int dst = in.dst;
    switch (Bi(in.sub)) {
    case Bi::Sin: map(x, dst, [](float a) { return std::sin(a); }, A.f(0)); break;
    case Bi::Cos: map(x, dst, [](float a) { return std::cos(a); }, A.f(0)); break;
    case Bi::Tan: map(x, dst, [](float a) { return fixNan(std::tan(a)); }, A.f(0)); break;
    case Bi::Asin: map(x, dst, [](float a) { return std::asin(clamp(a, -1.f, 1.f)); }, A.f(0)); break;
    case Bi::Acos: map(x, dst, [](float a) { return std::acos(clamp(a, -1.f, 1.f)); }, A.f(0)); break;
    case Bi::Atan: map(x, dst, [](float a) { return std::atan(a); }, A.f(0)); break;
    case Bi::Atan2: map(x, dst, [](float y, float xx) { return std::atan2(y, xx); }, A.f(0), A.f(1)); break;
    case Bi::Exp: map(x, dst, [](float a) { return fixNan(std::exp(a)); }, A.f(0)); break;
    case Bi::Log: map(x, dst, [](float a) { return a > 0 ? std::log(a) : 0.f; }, A.f(0)); break;
    case Bi::LogBase: map(x, dst, [](float a, float b) { return a > 0 && b > 0 && b != 1 ? std::log(a) / std::log(b) : 0.f; }, A.f(0), A.f(1)); break;
    case Bi::Sqrt: map(x, dst, [](float a) { return safeSqrt(a); }, A.f(0)); break;
    case Bi::InvSqrt: map(x, dst, [](float a) { return a > 0 ? 1.0f / std::sqrt(a) : 0.f; }, A.f(0)); break;
    case Bi::Abs: map(x, dst, [](float a) { return std::fabs(a); }, A.f(0)); break;
    case Bi::AbsT: map(x, dst, [](const Vec3& a) { return Vec3(std::fabs(a.x), std::fabs(a.y), std::fabs(a.z)); }, A.v(0)); break;
    case Bi::Sign: map(x, dst, [](float a) { return a > 0 ? 1.f : a < 0 ? -1.f : 0.f; }, A.f(0)); break;
    case Bi::Floor: map(x, dst, [](float a) { return std::floor(a); }, A.f(0)); break;
    case Bi::FloorT: map(x, dst, [](const Vec3& a) { return Vec3(std::floor(a.x), std::floor(a.y), std::floor(a.z)); }, A.v(0)); break;
    case Bi::Ceil: map(x, dst, [](float a) { return std::ceil(a); }, A.f(0)); break;
    case Bi::CeilT: map(x, dst, [](const Vec3& a) { return Vec3(std::ceil(a.x), std::ceil(a.y), std::ceil(a.z)); }, A.v(0)); break;
    case Bi::Round: map(x, dst, [](float a) { return std::round(a); }, A.f(0)); break;
    case Bi::Radians: map(x, dst, [](float a) { return radians(a); }, A.f(0)); break;
    case Bi::Degrees: map(x, dst, [](float a) { return degrees(a); }, A.f(0)); break;
    case Bi::Pow: map(x, dst, safePow, A.f(0), A.f(1)); break;
    case Bi::PowT:
        map(x, dst, [](const Vec3& a, float b) { return Vec3(safePow(a.x, b), safePow(a.y, b), safePow(a.z, b)); },
            A.v(0), A.f(1));
        break;
    case Bi::Mod: map(x, dst, [](float a, float b) { return b == 0 ? 0.f : a - b * std::floor(a / b); }, A.f(0), A.f(1)); break;
    case Bi::ModT:
        map(x, dst, [](const Vec3& a, float b) {
            auto m = [b](float v) { return b == 0 ? 0.f : v - b * std::floor(v / b); };
            return Vec3(m(a.x), m(a.y), m(a.z));
        }, A.v(0), A.f(1));
        break;
    case Bi::MinF: map(x, dst, [](float a, float b) { return std::min(a, b); }, A.f(0), A.f(1)); break;
    case Bi::MaxF: map(x, dst, [](float a, float b) { return std::max(a, b); }, A.f(0), A.f(1)); break;
    case Bi::MinT: map(x, dst, [](const Vec3& a, const Vec3& b) { return vmin(a, b); }, A.v(0), A.v(1)); break;
    case Bi::MaxT: map(x, dst, [](const Vec3& a, const Vec3& b) { return vmax(a, b); }, A.v(0), A.v(1)); break;
    // RI Spec 3.2: min if a is below min, else max if a is above max, else
    // a -- in that order, which decides a min above max (ARMan's smoke
    // clamps its last step so; Pixie and Aqsis read it the same way).
    case Bi::ClampF: map(x, dst, [](float a, float lo, float hi) { return clampSpec(a, lo, hi); }, A.f(0), A.f(1), A.f(2)); break;
    case Bi::ClampT:
        map(x, dst, [](const Vec3& a, const Vec3& lo, const Vec3& hi) {
            return Vec3(clampSpec(a.x, lo.x, hi.x), clampSpec(a.y, lo.y, hi.y), clampSpec(a.z, lo.z, hi.z));
        }, A.v(0), A.v(1), A.v(2));
        break;
    case Bi::MixF: map(x, dst, [](float a, float b, float t) { return a + (b - a) * t; }, A.f(0), A.f(1), A.f(2)); break;
    case Bi::MixTF: map(x, dst, [](const Vec3& a, const Vec3& b, float t) { return a + (b - a) * t; }, A.v(0), A.v(1), A.f(2)); break;
    case Bi::MixT: map(x, dst, [](const Vec3& a, const Vec3& b, const Vec3& t) { return a + (b - a) * t; }, A.v(0), A.v(1), A.v(2)); break;
    case Bi::Step: map(x, dst, [](float e, float a) { return a < e ? 0.f : 1.f; }, A.f(0), A.f(1)); break;
    case Bi::SmoothStep: map(x, dst, [](float a, float b, float c) { return smoothstep(a, b, c); }, A.f(0), A.f(1), A.f(2)); break;
    case Bi::FilterStep:
    case Bi::FilterStep2: {
        // The step filtered over a footprint w (RI Spec 3.2): one value s,
        // w = |Du(s) du| + |Dv(s) dv|, the change of s across the
        // micropolygon, centred on s; two values s1, s2, w = |s2 - s1|
        // centred between them. "width" ("swidth") multiplies w; "filter"
        // names the filter (catmull-rom when not given).
        bool two = Bi(in.sub) == Bi::FilterStep2;
        int first = two ? 3 : 2;
        const float one = 1;
        In<float> widthScale{&one, 0};
        StepFilter filter = StepFilter::CatmullRom;
        const FileLoc where = FileLoc::inFile(x.cs->fileName, in.loc.line, in.loc.col);
        for (int k = first; k + 1 < in.nargs; k += 2) {
            const std::string name = A.ty(k) == Ty::String ? A.s(k) : std::string();
            if ((name == "width" || name == "swidth") && A.ty(k + 1) == Ty::Float) widthScale = A.f(k + 1);
            else if (name == "filter" && A.ty(k + 1) == Ty::String) {
                const std::string& kind = A.s(k + 1);
                if (!stepFilterNamed(kind, &filter))
                    x.ctx->system->diagnostics().warningOnce("shading:filterstep:filter:" + kind, where,
                                                             "unknown filterstep filter '{}'; using catmull-rom", kind);
            } else
                x.ctx->system->diagnostics().warningOnce("shading:filterstep:" + name, where,
                                                         "unknown filterstep parameter '{}' ignored", name);
        }
        In<float> e = A.f(0), v = A.f(1), v2 = two ? A.f(2) : A.f(1);
        float* d = x.ptr[size_t(dst)];
        forActive(x, x.vary[size_t(dst)], [&](int i) {
            float mid, w;
            if (two) {
                mid = 0.5f * (v[i] + v2[i]);
                w = std::fabs(v2[i] - v[i]);
            } else {
                mid = v[i];
                w = std::fabs(deriv(x, v, i, 0, 1.f)) + std::fabs(deriv(x, v, i, 1, 1.f));
            }
            w *= std::max(0.f, widthScale[i]);
            d[i] = w > 0 && std::isfinite(w) ? filteredStep(filter, (mid - e[i]) / w) : (mid < e[i] ? 0.f : 1.f);
        });
        break;
    }
    case Bi::SplineF: spline(x, in, A, false, false); break;
    case Bi::SplineT: spline(x, in, A, true, false); break;
    case Bi::SplineBasisF: spline(x, in, A, false, true); break;
    case Bi::SplineBasisT: spline(x, in, A, true, true); break;
    case Bi::Xcomp: map(x, dst, [](const Vec3& a) { return a.x; }, A.v(0)); break;
    case Bi::Ycomp: map(x, dst, [](const Vec3& a) { return a.y; }, A.v(0)); break;
    case Bi::Zcomp: map(x, dst, [](const Vec3& a) { return a.z; }, A.v(0)); break;
    case Bi::SetXcomp:
    case Bi::SetYcomp:
    case Bi::SetZcomp: {
        int c = in.sub - int16_t(Bi::SetXcomp);
        int r = A.reg(0);
        In<float> v = A.f(1);
        float* p = x.ptr[size_t(r)];
        forActive(x, x.vary[size_t(r)], [&](int i) { p[3 * i + c] = v[i]; });
        break;
    }
    case Bi::CompM: map(x, dst, [](const M16& m, float r, float c) { return m.m[clampIndexM(r) * 4 + clampIndexM(c)]; }, A.m(0), A.f(1), A.f(2)); break;
    case Bi::SetCompM: {
        int r = A.reg(0);
        In<float> row = A.f(1), col = A.f(2), v = A.f(3);
        float* p = x.ptr[size_t(r)];
        forActive(x, x.vary[size_t(r)], [&](int i) { p[16 * i + clampIndexM(row[i]) * 4 + clampIndexM(col[i])] = v[i]; });
        break;
    }
    case Bi::Length: map(x, dst, [](const Vec3& a) { return length(a); }, A.v(0)); break;
    case Bi::Distance: map(x, dst, [](const Vec3& a, const Vec3& b) { return length(a - b); }, A.v(0), A.v(1)); break;
    case Bi::Normalize: map(x, dst, [](const Vec3& a) { return unit(a); }, A.v(0)); break;
    case Bi::FaceForward: {
        // faceforward(N, I): the spec's reference is Ng, which keeps a
        // smooth normal that turns away at a silhouette from flipping. An
        // exporter's normals that point against the winding (a mesh written
        // clockwise with outward N, no ReverseOrientation) would then all be
        // flipped inwards and the surface shade black, where Pixie and Aqsis
        // (whose faceforward turns N itself to the viewer) light it. So Ng
        // is taken on N's side: the spec's answer wherever N and Ng agree,
        // theirs where they disagree.
        int ng = x.cs->globalRegs[gNg];
        map(x, dst, [](const Vec3& n, const Vec3& i, const Vec3& r) { return faceforward(n, i, dot(n, r) < 0 ? -r : r); },
            A.v(0), A.v(1), In<Vec3>{x.ptr[size_t(ng)], x.vary[size_t(ng)]});
        break;
    }
    case Bi::FaceForward3: map(x, dst, [](const Vec3& n, const Vec3& i, const Vec3& r) { return faceforward(n, i, r); }, A.v(0), A.v(1), A.v(2)); break;
    case Bi::Reflect: map(x, dst, [](const Vec3& i, const Vec3& n) { return reflect(i, n); }, A.v(0), A.v(1)); break;
    case Bi::Refract: map(x, dst, [](const Vec3& i, const Vec3& n, float e) { return refract(i, n, e); }, A.v(0), A.v(1), A.f(2)); break;
    case Bi::Fresnel:
    case Bi::FresnelRT: {
        bool rt = Bi(in.sub) == Bi::FresnelRT;
        In<Vec3> I = A.v(0), N = A.v(1);
        In<float> eta = A.f(2);
        int kr = A.reg(3), kt = A.reg(4);
        bool v = x.vary[size_t(kr)] || x.vary[size_t(kt)] || (rt && (x.vary[size_t(A.reg(5))] || x.vary[size_t(A.reg(6))]));
        forActive(x, v, [&](int i) {
            float r, t;
            fresnel(I[i], N[i], eta[i], &r, &t);
            x.ptr[size_t(kr)][i * x.vary[size_t(kr)]] = r;
            x.ptr[size_t(kt)][i * x.vary[size_t(kt)]] = t;
            if (rt) {
                put(x.ptr[size_t(A.reg(5))], i * x.vary[size_t(A.reg(5))], reflect(I[i], normalize(N[i])));
                put(x.ptr[size_t(A.reg(6))], i * x.vary[size_t(A.reg(6))], refract(normalize(I[i]), normalize(N[i]), eta[i]));
            }
        });
        break;
    }
    case Bi::Transform: case Bi::VTransform: case Bi::NTransform:
    case Bi::TransformFT: case Bi::VTransformFT: case Bi::NTransformFT: {
        Bi id = Bi(in.sub);
        bool ft = id == Bi::TransformFT || id == Bi::VTransformFT || id == Bi::NTransformFT;
        XKind kind = (id == Bi::Transform || id == Bi::TransformFT) ? XKind::Point
                     : (id == Bi::VTransform || id == Bi::VTransformFT) ? XKind::Vector : XKind::Normal;
        Mat4 currentFromFrom = ft ? spaceMatrix(x, A.s(0), in) : Mat4::identity();
        const std::string& to = A.s(ft ? 1 : 0);
        Mat4 toFromFrom = (to == "current" || to == "camera") ? currentFromFrom
                                                              : spaceMatrix(x, to, in).inverse() * currentFromFrom;
        Mat4 inv = kind == XKind::Normal ? toFromFrom.inverse() : Mat4();
        map(x, dst, [&](const Vec3& p) { return xform(toFromFrom, inv, kind, p); }, A.v(ft ? 2 : 1));
        break;
    }
    case Bi::TransformSM: case Bi::VTransformSM: case Bi::NTransformSM: {
        // From the named space to "current", then by the matrix, as
        // transform(m, transform(from, "current", p)).
        Bi id = Bi(in.sub);
        XKind kind = id == Bi::TransformSM ? XKind::Point : id == Bi::VTransformSM ? XKind::Vector : XKind::Normal;
        Mat4 currentFromFrom = spaceMatrix(x, A.s(0), in);
        Mat4 inv = currentFromFrom.inverse();
        map(x, dst, [&](const M16& m, const Vec3& p) {
            Vec3 c = xform(currentFromFrom, inv, kind, p);
            if (kind == XKind::Point) return rslPoint(m, c);
            if (kind == XKind::Vector) return rslVector(m, c);
            return rslNormal(m, c);
        }, A.m(1), A.v(2));
        break;
    }
    case Bi::TransformM: map(x, dst, rslPoint, A.m(0), A.v(1)); break;
    case Bi::VTransformM: map(x, dst, rslVector, A.m(0), A.v(1)); break;
    case Bi::NTransformM: map(x, dst, rslNormal, A.m(0), A.v(1));
        break;
    case Bi::SpaceMatrix: {
        M16 spaceToCurrent = toRsl(spaceMatrix(x, A.s(0), in));
        map(x, dst, [&](const M16& m) { return mulM(m, spaceToCurrent); }, A.m(1));
        break;
    }
    case Bi::ColorFromSpace: {
        const std::string& space = A.s(0);
        Vec3 probe;
        if (!colorToRgb(space, Vec3(0.f), &probe))
            x.ctx->system->diagnostics().warningOnce("shading:color:" + space, FileLoc::inFile(x.cs->fileName, in.loc.line, in.loc.col),
                                                     "unknown color space '{}'", space);
        map(x, dst, [&](const Vec3& c) {
            Vec3 r = c;
            colorToRgb(space, c, &r);
            return r;
        }, A.v(1));
        break;
    }
    case Bi::CTransform:
    case Bi::CTransformFT: {
        bool ft = Bi(in.sub) == Bi::CTransformFT;
        std::string from = ft ? A.s(0) : "rgb", to = A.s(ft ? 1 : 0);
        for (const std::string& space : {from, to}) {
            Vec3 probe;
            if (!colorToRgb(space, Vec3(0.f), &probe))
                x.ctx->system->diagnostics().warningOnce("shading:color:" + space, FileLoc::inFile(x.cs->fileName, in.loc.line, in.loc.col),
                                                         "unknown color space '{}' (taken as \"rgb\")", space);
        }
        map(x, dst, [&](const Vec3& c) {
            Vec3 rgb = c, r = c;
            colorToRgb(from, c, &rgb);
            colorFromRgb(to, rgb, &r);
            return r;
        }, A.v(ft ? 2 : 1));
        break;
    }
    case Bi::CalculateNormal: {
        In<Vec3> P = A.v(0);
        bool flip = x.ctx->grid->flipNormals;
        float du = gridDu(x), dv = gridDv(x);
        float* d = x.ptr[size_t(dst)];
        forActive(x, x.vary[size_t(dst)], [&](int i) {
            Vec3 pu = deriv(x, P, i, 0, du), pv = deriv(x, P, i, 1, dv);
            Vec3 n = cross(pu, pv);
            const float uu = dot(pu, pu) * du * du, vv = dot(pv, pv) * dv * dv;
            if ((uu <= 1e-8f * vv || vv <= 1e-8f * uu || dot(n, n) == 0) && P.s != 0 && x.nu > 1 && x.nv > 1) {
                // A degenerate row or column (a sphere's pole): the cross of
                // the cell's diagonals, (a+b) x (b-a) = 2 a x b, scaled back
                // to a derivative cross product.
                const int iu = i % x.nu, iv = i / x.nu;
                const int i0 = std::max(0, iu - 1), i1 = std::min(x.nu - 1, iu + 1);
                const int j0 = std::max(0, iv - 1), j1 = std::min(x.nv - 1, iv + 1);
                Vec3 d1 = P[j1 * x.nu + i1] - P[j0 * x.nu + i0], d2 = P[j1 * x.nu + i0] - P[j0 * x.nu + i1];
                float scale = 2.0f * float(i1 - i0) * float(j1 - j0) * du * dv;
                n = scale > 0 ? cross(d1, d2) / scale : cross(d1, d2);
            }
            put(d, i, flip ? -n : n);
        });
        break;
    }
    case Bi::Area: {
        In<Vec3> P = A.v(0);
        float du = gridDu(x), dv = gridDv(x);
        float* d = x.ptr[size_t(dst)];
        forActive(x, x.vary[size_t(dst)], [&](int i) {
            d[i] = length(cross(deriv(x, P, i, 0, du) * du, deriv(x, P, i, 1, dv) * dv));
        });
        break;
    }
    case Bi::Depth: {
        float nearZ = x.ctx->grid->nearClip, farZ = x.ctx->grid->farClip;
        map(x, dst, [&](const Vec3& p) { return farZ > nearZ ? (p.z - nearZ) / (farZ - nearZ) : 0.f; }, A.v(0));
        break;
    }
    case Bi::PtLined:
        map(x, dst, [](const Vec3& a, const Vec3& b, const Vec3& q) {
            Vec3 ab = b - a;
            float l2 = dot(ab, ab);
            float t = l2 > 0 ? clamp(dot(q - a, ab) / l2, 0.f, 1.f) : 0.f;
            return length(q - (a + ab * t));
        }, A.v(0), A.v(1), A.v(2));
        break;
    case Bi::Rotate3:
        map(x, dst, [](const Vec3& p, float angle, const Vec3& p0, const Vec3& p1) {
            Vec3 axis = p1 - p0;
            if (length(axis) <= 0) return p;
            return Mat4::rotate(degrees(angle), axis).point(p - p0) + p0;
        }, A.v(0), A.f(1), A.v(2), A.v(3));
        break;
    case Bi::DuF:
    case Bi::DvF: {
        int dir = Bi(in.sub) == Bi::DvF;
        float step = dir ? gridDv(x) : gridDu(x);
        In<float> a = A.f(0);
        float* d = x.ptr[size_t(dst)];
        forActive(x, x.vary[size_t(dst)], [&](int i) { d[i] = deriv(x, a, i, dir, step); });
        break;
    }
    case Bi::DuT:
    case Bi::DvT: {
        int dir = Bi(in.sub) == Bi::DvT;
        float step = dir ? gridDv(x) : gridDu(x);
        In<Vec3> a = A.v(0);
        float* d = x.ptr[size_t(dst)];
        forActive(x, x.vary[size_t(dst)], [&](int i) { put(d, i, deriv(x, a, i, dir, step)); });
        break;
    }
    case Bi::DerivF: {
        In<float> num = A.f(0), den = A.f(1);
        float du = gridDu(x), dv = gridDv(x);
        float* d = x.ptr[size_t(dst)];
        forActive(x, x.vary[size_t(dst)], [&](int i) {
            float a = deriv(x, den, i, 0, du), b = deriv(x, den, i, 1, dv);
            d[i] = (a != 0 ? deriv(x, num, i, 0, du) / a : 0.f) + (b != 0 ? deriv(x, num, i, 1, dv) / b : 0.f);
        });
        break;
    }
    case Bi::DerivT: {
        In<Vec3> num = A.v(0);
        In<float> den = A.f(1);
        float du = gridDu(x), dv = gridDv(x);
        float* d = x.ptr[size_t(dst)];
        forActive(x, x.vary[size_t(dst)], [&](int i) {
            float a = deriv(x, den, i, 0, du), b = deriv(x, den, i, 1, dv);
            Vec3 r(0.f);
            if (a != 0) r += deriv(x, num, i, 0, du) / a;
            if (b != 0) r += deriv(x, num, i, 1, dv) / b;
            put(d, i, r);
        });
        break;
    }
    case Bi::Determinant: map(x, dst, determinant, A.m(0)); break;
    case Bi::TranslateM: map(x, dst, [](const M16& m, const Vec3& t) { return mulM(toRsl(Mat4::translate(t)), m); }, A.m(0), A.v(1)); break;
    case Bi::ScaleM: map(x, dst, [](const M16& m, const Vec3& s) { return mulM(toRsl(Mat4::scale(s)), m); }, A.m(0), A.v(1)); break;
    case Bi::RotateM:
        map(x, dst, [](const M16& m, float angle, const Vec3& axis) { return mulM(toRsl(Mat4::rotate(degrees(angle), axis)), m); }, A.m(0), A.f(1), A.v(2));
        break;
    case Bi::Concat: {
        // Strings are bounded (kMaxStringBytes): doubling a string 40 times
        // would take terabytes.
        std::string s;
        for (int k = 0; k < in.nargs; ++k) s += A.s(k);
        if (s.size() > kMaxStringBytes) {
            x.ctx->system->diagnostics().warningOnce("shading:concat:" + x.cs->name, FileLoc::inFile(x.cs->fileName, in.loc.line, in.loc.col),
                                                     "shader '{}': concat() made a string longer than {} bytes; cut "
                                                     "to that length", x.cs->name, kMaxStringBytes);
            s.resize(kMaxStringBytes);
        }
        x.strs[size_t(dst)][0] = std::move(s);
        break;
    }
    case Bi::Format: x.strs[size_t(dst)][0] = formatString(x, A, 0, x.active.empty() ? 0 : x.active[0]); break;
    case Bi::Printf: {
        bool anyVarying = false;
        for (int k = 1; k < in.nargs; ++k) anyVarying = anyVarying || A.varying(k);
        forActive(x, anyVarying, [&](int i) { x.ctx->services->print(formatString(x, A, 0, i)); });
        break;
    }
    case Bi::Match: {
        // RE2 matches in time linear in the subject: a pattern such as
        // "(a*)*b" cannot backtrack for ever. POSIX extended syntax, as the
        // RI spec asks of match().
        float r = 0;
        RE2::Options opt;
        opt.set_posix_syntax(true);
        opt.set_log_errors(false);
        RE2 re(A.s(0), opt);
        if (re.ok())
            r = RE2::PartialMatch(A.s(1), re) ? 1.f : 0.f;
        else
            x.ctx->system->diagnostics().warningOnce("shading:regex:" + A.s(0), FileLoc::inFile(x.cs->fileName, in.loc.line, in.loc.col),
                                                     "invalid regular expression '{}' in match(): {}", A.s(0), re.error());
        setResult(x, in, r);
        break;
    }
    case Bi::NoiseF1: noise(x, in, A, 1, false, false, false); break;
    case Bi::NoiseF2: noise(x, in, A, 2, false, false, false); break;
    case Bi::NoiseF3: noise(x, in, A, 3, false, false, false); break;
    case Bi::NoiseF4: noise(x, in, A, 4, false, false, false); break;
    case Bi::NoiseT1: noise(x, in, A, 1, true, false, false); break;
    case Bi::NoiseT2: noise(x, in, A, 2, true, false, false); break;
    case Bi::NoiseT3: noise(x, in, A, 3, true, false, false); break;
    case Bi::NoiseT4: noise(x, in, A, 4, true, false, false); break;
    case Bi::PNoiseF1: noise(x, in, A, 1, false, true, false); break;
    case Bi::PNoiseF2: noise(x, in, A, 2, false, true, false); break;
    case Bi::PNoiseF3: noise(x, in, A, 3, false, true, false); break;
    case Bi::PNoiseF4: noise(x, in, A, 4, false, true, false); break;
    case Bi::PNoiseT1: noise(x, in, A, 1, true, true, false); break;
    case Bi::PNoiseT2: noise(x, in, A, 2, true, true, false); break;
    case Bi::PNoiseT3: noise(x, in, A, 3, true, true, false); break;
    case Bi::PNoiseT4: noise(x, in, A, 4, true, true, false); break;
    case Bi::CellF1: noise(x, in, A, 1, false, false, true); break;
    case Bi::CellF2: noise(x, in, A, 2, false, false, true); break;
    case Bi::CellF3: noise(x, in, A, 3, false, false, true); break;
    case Bi::CellF4: noise(x, in, A, 4, false, false, true); break;
    case Bi::CellT1: noise(x, in, A, 1, true, false, true); break;
    case Bi::CellT2: noise(x, in, A, 2, true, false, true); break;
    case Bi::CellT3: noise(x, in, A, 3, true, false, true); break;
    case Bi::CellT4: noise(x, in, A, 4, true, false, true); break;
    case Bi::RandomF:
    case Bi::RandomT: {
        uint32_t call = x.randomSeed(in);
        float* d = x.ptr[size_t(dst)];
        bool t = Bi(in.sub) == Bi::RandomT;
        forActive(x, x.vary[size_t(dst)], [&](int i) {
            uint32_t h = hashKeys(call, uint32_t(i));
            if (t) put(d, i, Vec3(hashToUnit(h), hashToUnit(hash32(h + 1)), hashToUnit(hash32(h + 2))));
            else d[i] = hashToUnit(h);
        });
        break;
    }
    case Bi::Ambient: {
        needAmbientLights(x);
        float* d = x.ptr[size_t(dst)];
        forActive(x, true, [&](int i) { put(d, i, Vec3(0.f)); });
        for (const LightRun& lr : x.ctx->lights)
            if (lr.ambient)
                forActive(x, true, [&](int i) {
                    Vec3 c = In<Vec3>{d, 1}[i] + lr.Cl(i);
                    put(d, i, c);
                });
        break;
    }
    case Bi::Diffuse: lightSum<LightModel::Diffuse>(x, in, A); break;
    case Bi::Specular: lightSum<LightModel::Specular>(x, in, A); break;
    case Bi::Phong: lightSum<LightModel::Phong>(x, in, A); break;
    case Bi::SpecularBrdf:
        map(x, dst, [](const Vec3& L, const Vec3& N, const Vec3& V, float r) {
            Vec3 H = normalize(normalize(L) + normalize(V));
            return Vec3(r > 0 ? std::pow(std::max(0.f, dot(normalize(N), H)), specularExponent(r)) : 0.f);
        }, A.v(0), A.v(1), A.v(2), A.f(3));
        break;
    case Bi::TextureF: texture(x, in, A, false, false); break;
    case Bi::TextureC: texture(x, in, A, true, false); break;
    case Bi::TextureF4: texture(x, in, A, false, true); break;
    case Bi::TextureC4: texture(x, in, A, true, true); break;
    case Bi::EnvironmentF: environment(x, in, A, false, false); break;
    case Bi::EnvironmentC: environment(x, in, A, true, false); break;
    case Bi::EnvironmentF4: environment(x, in, A, false, true); break;
    case Bi::EnvironmentC4: environment(x, in, A, true, true); break;
    case Bi::Shadow: shadow(x, in, A, false); break;
    case Bi::Shadow4: shadow(x, in, A, true); break;
    case Bi::TextureInfo: {
        TextureBackend* ts = x.ctx->system->textures();
        int out = A.reg(2);
        const RegInfo& ri = x.cs->regs[size_t(out)];
        bool ok = false;
        if (ts) {
            if (ri.ty == Ty::String) {
                std::string s;
                ok = ts->textureInfoString(A.s(0), A.s(1), &s);
                if (ok) x.strs[size_t(out)][0] = s;
            } else {
                int per = ri.floatsPerValue();
                std::vector<float> f(static_cast<size_t>(per), 0.f);
                ok = ts->textureInfoFloats(A.s(0), A.s(1), per, f.data());
                if (ok && per == 16 && (A.s(1) == "viewingmatrix" || A.s(1) == "projectionmatrix")) {
                    // The file holds the map's camera from world space; a
                    // shader applies it to P, in current space (Aqsis, and
                    // the PRMan shaders that name it CurrentToShadowCamSpace).
                    M16 fromWorld;
                    std::copy(f.begin(), f.end(), fromWorld.m);
                    const M16 fromCurrent = mulM(toRsl(spaceMatrix(x, "world", in).inverse()), fromWorld);
                    std::copy(fromCurrent.m, fromCurrent.m + 16, f.begin());
                }
                if (ok) storeAtActive(x, out, f.data());
            }
        }
        setResult(x, in, ok ? 1.f : 0.f);
        break;
    }
    case Bi::LightSource: {
        bool ok = x.currentLight >= 0 && copyParam(x, x.ctx->lights[size_t(x.currentLight)].exec, A.s(0), A.reg(1));
        setResult(x, in, ok);
        break;
    }
    case Bi::SurfaceMsg: setResult(x, in, copyParam(x, x.ctx->surface, A.s(0), A.reg(1))); break;
    case Bi::DisplacementMsg: setResult(x, in, copyParam(x, x.ctx->displacement, A.s(0), A.reg(1))); break;
    case Bi::AtmosphereMsg: setResult(x, in, copyParam(x, x.ctx->atmosphere, A.s(0), A.reg(1))); break;
    // umbra has no interior or exterior volume shaders (Interior/Exterior
    // are ignored), so there is never a value to read.
    case Bi::Incident:
    case Bi::Opposite: setResult(x, in, 0); break;
    case Bi::ShaderNameOf: {
        // The name of the grid's shader of that kind; "" if it has none.
        const std::string& kind = A.s(0);
        const Exec* e = kind == shaderKindName(x.cs->kind) ? &x
                        : kind == "surface" ? x.ctx->surface : kind == "displacement" ? x.ctx->displacement
                        : kind == "atmosphere" ? x.ctx->atmosphere
                        : kind == "light" && x.currentLight >= 0 ? x.ctx->lights[size_t(x.currentLight)].exec
                                                                 : nullptr;
        x.strs[size_t(dst)][0] = e && e->cs ? e->cs->name : std::string();
        break;
    }
    case Bi::Attribute:
    case Bi::Option:
    case Bi::RendererInfo: {
        ShadeValue v;
        int out = A.reg(1);
        v.name = A.s(0);
        v.type = valueTypeOf(x.cs->regs[size_t(out)].ty);
        bool ok = Bi(in.sub) == Bi::Attribute ? x.ctx->services->attribute(*x.ctx->grid, v.name, &v)
                  : Bi(in.sub) == Bi::Option   ? x.ctx->services->option(v.name, &v)
                                               : x.ctx->services->rendererInfo(v.name, &v);
        setResult(x, in, ok && fromShadeValue(x, v, out));
        break;
    }
    case Bi::Count: break;
    }
}

}  // namespace umbra::shading
