#pragma once
// The grid-at-a-time interpreter. An Exec runs one shader instance over
// every point of a ShadingGrid: each instruction loops over the active
// points (a run-mask stack implements varying control flow), and uniform
// registers hold a single value, so dispatch costs once per grid.
//
// Register storage for n points (one float block per Exec, reused):
//   uniform float  : 1 float        varying float  : n floats
//   uniform triple : 3 floats       varying triple : 3n floats (xyz xyz ...)
//   matrix         : 16 (or 16n)    arrays         : one such block per element

#include "slc.h"

#include <deque>
#include <map>
#include <memory>
#include <string>
#include <cstring>
#include <vector>

namespace umbra::shading {

struct Exec;

/// A light evaluated once over a grid: its Cl and L (from the light to the
/// surface) at each point, and which points it reached.
struct LightRun {
    const ShaderInstance* instance = nullptr;
    Exec* exec = nullptr;  // alive until the grid is shaded; L and Cl point into it
    const float* Lp = nullptr;
    const float* Clp = nullptr;
    int Ls = 0, Cls = 0;              // strides: 0 when uniform
    const uint8_t* litp = nullptr;    // null: every point (ambient lights)
    const Vec3* dir = nullptr;        // unit vector from the surface towards the light
    bool ambient = false;  // no illuminate() or solar(): only ambient() reads it

    Vec3 L(int i) const { return {Lp[3 * i * Ls], Lp[3 * i * Ls + 1], Lp[3 * i * Ls + 2]}; }
    Vec3 Cl(int i) const { return {Clp[3 * i * Cls], Clp[3 * i * Cls + 1], Clp[3 * i * Cls + 2]}; }
    bool lit(int i) const { return !litp || litp[i]; }
};

/// The directions towards a light that the surface's lighting reads: a cone
/// about `axis` (per point, or one uniform axis) whose cosine is at least
/// `cosLimit`. The non-ambient lights run under the cone of the surface's
/// first diffuse(), specular(), phong() or illuminance loop, and their
/// illuminate() and solar() skip the points whose light falls outside it:
/// on a closed object, the half that faces away from each light, shadow
/// lookups and all. The limit is a little wider than the loop's own test
/// (kReceiverSlack), so that every point the loop accepts was lit.
struct ReceiverCone {
    static constexpr float kReceiverSlack = 1e-5f;
    bool restricts = false;
    std::vector<Vec3> axis;
    bool uniformAxis = false;
    float cosLimit = -2;

    bool admits(const Vec3& towardLight, int i) const {
        const Vec3& ax = axis[uniformAxis ? 0 : size_t(i)];
        return !(dot(towardLight, ax) < cosLimit * length(towardLight) * length(ax));
    }
};

/// State shared by the shaders run on one grid.
struct ShadeContext {
    const ShadingSystem* system = nullptr;
    ShadingGrid* grid = nullptr;
    RendererServices* services = nullptr;
    std::vector<LightRun> lights;  // run lazily: see needLights()
    bool lightsRun = false;        // the non-ambient lights
    bool ambientLightsRun = false;
    ReceiverCone receiver;         // what the non-ambient lights ran under
    std::vector<Vec3> litAt;       // where they ran (one value when uniform): Ps
    bool litAtUniform = false;
    Exec* surface = nullptr;
    Exec* displacement = nullptr;
    Exec* atmosphere = nullptr;
    std::map<std::string, Mat4> spaces;  // currentFromSpace cache (not "shader")
    Mat4 currentFromWorld;
    bool haveWorld = false;
};

/// The random streams of a grid's shaders (Exec::randomStream); light l of
/// the grid's light list has stream kFirstLightStream + l.
enum : uint32_t { kDisplacementStream = 1, kSurfaceStream = 2, kAtmosphereStream = 3, kImagerStream = 4, kFirstLightStream = 16 };

/// One running shader instance.
struct Exec {
    const CompiledShader* cs = nullptr;
    const ShaderInstance* inst = nullptr;
    ShadeContext* ctx = nullptr;
    int n = 0, nu = 0, nv = 0;
    float invNu = 0;  // 1/nu: deriv() splits point indices without a divide
    std::vector<float> store;
    std::vector<float*> ptr;
    std::vector<uint8_t> vary;
    std::vector<std::vector<std::string>> strs;  // per string register (array elements)
    std::deque<std::vector<uint8_t>> frames;  // deque: references stay valid as it grows
    int depth = 0;
    std::vector<int> active;
    bool allOn = true;
    // illuminance loops in progress (nested illuminance is allowed)
    struct Illum {
        int next = 0;
        int p = -1, axis = -1, angle = -1;
        std::string category;
    };
    std::vector<Illum> illum;
    int currentLight = -1;
    /// Light shaders: 1 inside illuminate(), 2 inside solar(), else 0
    /// (what shadow("raytrace") traces towards).
    int lightConstruct = 0;
    std::vector<uint8_t> lit;        // light shaders: points some illuminate/solar reached
    std::vector<Vec3> ownPs;         // light shaders: Ps
    std::vector<Vec3> lightP;        // light shaders: P, the light's origin
    std::vector<Vec3> lightDir;      // light shaders: unit -L, for diffuse()/specular()
    Mat4 currentFromShader;
    /// Random numbers (random(), shadow()'s samples) come from the grid's
    /// seed, this shader's stream, the instruction and the count of random
    /// calls this Exec made: a light's numbers do not depend on what other
    /// shaders, or other lights, did or skipped on the grid.
    uint32_t randomStream = 0;
    uint32_t randomCalls = 0;
    uint32_t randomSeed(const Instr& in);

    /// Sets up registers for a grid; `Ps` (lights only) is the surface position.
    /// `Ps`/`PsStride` (lights only): the surface positions lights run for.
    /// `stream`: which shader of the grid this is (see randomStream).
    void setup(const CompiledShader& code, const ShaderInstance* instance, ShadeContext& context, uint32_t stream,
               const float* Ps = nullptr, int PsStride = 1);
    void run();

    int activeCount() const { return int(active.size()); }
    void refreshActive();
};

/// Per-thread pool of Execs, so shading a grid allocates nothing once warm.
Exec* acquireExec();
void releaseExecs(size_t mark);
size_t execMark();

/// Makes the non-ambient lights' L and Cl ready for a lighting loop of the
/// surface `x` at positions `Ps` (xyz per point, stride 0 for one position)
/// that accepts lights within `angle` of `axis` at each of its active points
/// (`axis` null, or an angle of pi or more: every direction). The lights
/// run once per grid, under that cone; a later loop the cone does not cover
/// runs them again at every point.
void needLights(Exec& x, const float* Ps, int stride, const float* axis, int axisStride, float angle);
/// The same for the ambient lights (ambient(), at P), which have no direction.
void needAmbientLights(Exec& x);

/// Gradient noise in [0,1] of 1-4 dimensions, optionally periodic
/// (`period` entries <= 0 are not periodic), and cell noise in [0,1).
float gradientNoise(const float* p, int dims, const float* period, uint32_t seed);
float cellNoise(const float* p, int dims, uint32_t seed);

/// Colour conversions between RGB and "hsv", "hsl", "xyz"/"XYZ", "yiq"/"YIQ", "rgb".
bool colorToRgb(const std::string& space, const Vec3& c, Vec3* rgb);
bool colorFromRgb(const std::string& space, const Vec3& rgb, Vec3* c);

/// A matrix value as the VM stores it: 16 floats.
struct M16 {
    float m[16];
};

/// Reads a register at point i (stride 0 for uniform registers).
template <class T> struct In;
template <> struct In<float> {
    const float* p;
    int s;
    float operator[](int i) const { return p[i * s]; }
};
template <> struct In<Vec3> {
    const float* p;
    int s;
    Vec3 operator[](int i) const {
        const float* q = p + 3 * i * s;
        return {q[0], q[1], q[2]};
    }
};
template <> struct In<M16> {
    const float* p;
    int s;
    M16 operator[](int i) const {
        M16 r;
        std::memcpy(r.m, p + 16 * i * s, sizeof r.m);
        return r;
    }
};

inline void put(float* p, int i, float v) { p[i] = v; }
inline void put(float* p, int i, const Vec3& v) {
    float* q = p + 3 * i;
    q[0] = v.x;
    q[1] = v.y;
    q[2] = v.z;
}
inline void put(float* p, int i, const M16& v) { std::memcpy(p + 16 * i, v.m, sizeof v.m); }

template <class T> In<T> rd(const Exec& x, int r) { return In<T>{x.ptr[size_t(r)], x.vary[size_t(r)]}; }

/// The product of two matrices in the VM's (row-major, RSL) layout.
inline M16 mulM(const M16& a, const M16& b) {
    M16 r;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            float s = 0;
            for (int k = 0; k < 4; ++k) s += a.m[i * 4 + k] * b.m[k * 4 + j];
            r.m[i * 4 + j] = s;
        }
    return r;
}

}  // namespace umbra::shading
