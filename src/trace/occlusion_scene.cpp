#include "umbra/trace/occlusion_scene.h"
#include "umbra/util/parallel.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace umbra::trace {

namespace {

// Splits beyond this depth mean a primitive that never becomes diceable or
// a rate that never fits maxGridSide: a bug or absurd input, left out.
constexpr int kMaxSplitDepth = 40;
// Float positions cannot place triangles closer to a surface than about
// this fraction of its size, so finer tolerances are not honoured.
constexpr float kMinRelativeTolerance = 1e-6f;
// Rays traced per rtcOccluded1M call in a batch.
constexpr int kStreamSize = 64;

bool finite(const Vec3& p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z); }

/// Triangles of one diced piece, in world space, with its own vertex numbering.
struct Chunk {
    std::vector<Vec3> P;
    std::vector<uint32_t> tris;
    float chordError = 0;
};

/// Everything the recursive tessellation reads but does not change.
struct Tessellator {
    const TessellationOptions& options;
    Diagnostics* diag;

    // Dices `p` at exactly (nu, nv), splitting into equal halves while a side
    // exceeds maxGridSide so that all pieces keep the same rate and their
    // shared edges carry the same vertices.
    void fixedRate(const geometry::Primitive& p, int nu, int nv, float error, float tol, int depth,
                   std::vector<Chunk>& out) const {
        const int maxSide = std::max(1, options.maxGridSide);
        if ((nu > maxSide || nv > maxSide) && depth < kMaxSplitDepth) {
            const bool splitU = nu >= nv;
            std::vector<geometry::PrimitivePtr> halves;
            p.split(splitU, halves);
            const bool regular = halves.size() == 2 && halves[0]->diceable() && halves[1]->diceable();
            if (regular) {
                const int cu = splitU ? (nu + 1) / 2 : nu, cv = splitU ? nv : (nv + 1) / 2;
                std::vector<Chunk> a, b;
                parallelInvoke([&] { fixedRate(*halves[0], cu, cv, error, tol, depth + 1, a); },
                               [&] { fixedRate(*halves[1], cu, cv, error, tol, depth + 1, b); });
                appendChunks(out, a);
                appendChunks(out, b);
                return;
            }
            // A family that splits some other way: measure each piece anew.
            for (auto& h : halves) adaptive(*h, tol, depth + 1, out);
            return;
        }
        emitGrid(p, nu, nv, error, out);
    }

    // Splits `p` until diceable, then dices each piece at the rate its own
    // curvature asks for.
    void adaptive(const geometry::Primitive& p, float tol, int depth, std::vector<Chunk>& out) const {
        if (depth > kMaxSplitDepth) {
            warn(p, "still not diceable after {} splits; left out of the ray-traced shadow scene", kMaxSplitDepth);
            return;
        }
        if (!p.diceable()) {
            std::vector<geometry::PrimitivePtr> pieces;
            p.split(depth % 2 == 0, pieces);
            std::vector<std::vector<Chunk>> parts(pieces.size());
            parallelFor(size_t(0), pieces.size(),
                        [&](size_t i) { adaptive(*pieces[i], tol, depth + 1, parts[i]); });
            for (auto& part : parts) appendChunks(out, part);
            return;
        }
        // Top-level pieces get the full test lattice; pieces of split meshes
        // (usually planar faces, in large numbers) a small one.
        const int m = std::max(2, depth == 0 ? options.testLattice : options.testLattice / 4);
        std::vector<Vec3> lattice;
        p.dicePositions(m, m, lattice);
        if (lattice.size() != size_t(m + 1) * size_t(m + 1)) return;
        const Mat4& M = p.record().worldFromObject;
        for (Vec3& q : lattice) {
            q = M.point(q);
            if (!finite(q)) {
                warn(p, "has non-finite positions; left out of the ray-traced shadow scene");
                return;
            }
        }
        DiceRate rate = chooseDiceRate(lattice.data(), m, tol);
        const int64_t cap = std::max<int64_t>(1, options.maxMicropolygonsPerPrimitive);
        if (int64_t(rate.nu) * rate.nv > cap) {
            const double s = std::sqrt(double(cap) / (double(rate.nu) * rate.nv));
            const int nu = std::max(1, int(rate.nu * s)), nv = std::max(1, int(rate.nv * s));
            warn(p, "needs {}x{} micropolygons for a chord error of {}; diced at {}x{} (maxMicropolygonsPerPrimitive)",
                 rate.nu, rate.nv, tol, nu, nv);
            const double ku = double(nu) / rate.nu, kv = double(nv) / rate.nv;
            rate.chordError = float(rate.chordError / std::min(ku * ku, kv * kv));
            rate.nu = nu;
            rate.nv = nv;
        }
        fixedRate(p, rate.nu, rate.nv, rate.chordError, tol, depth, out);
    }

    // The chord-error limit of a primitive as given to the scene; 0 for
    // one without extent (nothing to hit) or with a non-finite bound.
    float tolerance(const geometry::Primitive& p) const {
        const Bound3 b = transformBound(p.record().worldFromObject, p.bound());
        const float diag = b.empty() ? 0.0f : length(b.diagonal());
        if (!std::isfinite(diag) || !(diag > 0)) return 0;
        const float tol = std::min(options.absoluteTolerance, options.relativeTolerance * diag);
        return std::max(tol, kMinRelativeTolerance * diag);
    }

    void emitGrid(const geometry::Primitive& p, int nu, int nv, float error, std::vector<Chunk>& out) const {
        Chunk c;
        c.chordError = error;
        p.dicePositions(nu, nv, c.P);
        if (c.P.size() != size_t(nu + 1) * size_t(nv + 1)) return;
        const Mat4& M = p.record().worldFromObject;
        for (Vec3& q : c.P) {
            q = M.point(q);
            if (!finite(q)) {
                warn(p, "has non-finite positions; left out of the ray-traced shadow scene");
                return;
            }
        }
        // Two triangles per micropolygon; those with two coincident corners
        // (at a sphere's poles, a cone's apex) have no area and are dropped.
        c.tris.reserve(size_t(nu) * size_t(nv) * 6);
        auto add = [&](uint32_t a, uint32_t b, uint32_t d) {
            if (c.P[a] == c.P[b] || c.P[b] == c.P[d] || c.P[a] == c.P[d]) return;
            c.tris.insert(c.tris.end(), {a, b, d});
        };
        const uint32_t row = uint32_t(nu) + 1;
        for (uint32_t j = 0; j < uint32_t(nv); ++j)
            for (uint32_t i = 0; i < uint32_t(nu); ++i) {
                const uint32_t p00 = j * row + i, p10 = p00 + 1, p01 = p00 + row, p11 = p01 + 1;
                add(p00, p10, p11);
                add(p00, p11, p01);
            }
        out.push_back(std::move(c));
    }

    static void appendChunks(std::vector<Chunk>& out, std::vector<Chunk>& in) {
        for (auto& c : in) out.push_back(std::move(c));
    }

    // Once per record and message: the pieces of one mesh would repeat it.
    template <typename... Args>
    void warn(const geometry::Primitive& p, fmt::format_string<Args...> f, Args&&... args) const {
        if (!diag) return;
        const std::string message = fmt::format(f, std::forward<Args>(args)...);
        diag->warningOnce(fmt::format("trace:{}:{}", p.record().loc.str(), message),
                          p.record().loc, "{} {}", p.record().type, message);
    }
};

void embreeError(void* user, RTCError code, const char* message) {
    if (auto* diag = static_cast<Diagnostics*>(user))
        diag->error(FileLoc{}, "Embree error {} while building the ray-traced shadow scene: {}", int(code),
                    message ? message : "");
}

void fillRay(RTCRay& ray, const Vec3& org, const Vec3& dir, float tnear, float tfar) {
    ray.org_x = org.x;
    ray.org_y = org.y;
    ray.org_z = org.z;
    ray.tnear = tnear;
    ray.dir_x = dir.x;
    ray.dir_y = dir.y;
    ray.dir_z = dir.z;
    ray.time = 0;
    ray.tfar = tfar;
    ray.mask = 0xFFFFFFFFu;
    ray.id = 0;
    ray.flags = 0;
}

// The shadow ray from P towards `light`, started `eps` off the surface on
// the light's side when N is given. False when there is nothing to trace
// (P at the light, or non-finite input).
bool shadowRay(const Vec3& P, const LightTarget& light, const Vec3* N, float eps, Vec3* org, Vec3* dir,
               float* tfar) {
    if (!finite(P)) return false;
    auto toward = [&](const Vec3& from, Vec3* d, float* far) {
        if (light.atInfinity) {
            *d = light.v;
            *far = kInfinity;
            return true;
        }
        const Vec3 v = light.v - from;
        const float len = length(v);
        if (!(len > 2 * eps)) return false;
        *d = v / len;
        *far = len - eps;  // a light sitting on geometry does not shadow itself
        return true;
    };
    *org = P;
    if (!toward(P, dir, tfar)) return false;
    if (N) {
        Vec3 n = normalize(*N);
        if (finite(n) && dot(n, n) > 0) {
            if (dot(n, *dir) < 0) n = -n;
            *org = P + n * eps;
            if (!toward(*org, dir, tfar)) return false;
        }
    }
    return finite(*dir) && dot(*dir, *dir) > 0;
}

}  // namespace

DiceRate chooseDiceRate(const Vec3* lattice, int m, float tolerance) {
    UMBRA_CHECK(m >= 1, "test lattice of {} cells", m);
    auto at = [&](int i, int j) { return lattice[size_t(j) * size_t(m + 1) + size_t(i)]; };
    // Inside the surface only the part of a second difference along the
    // normal moves triangles off it; the tangential part merely
    // reparametrises (a sphere's latitude-longitude cells are planar
    // trapezoids although P_uv is not zero). Along the boundary the whole
    // difference counts: there a chord cuts off part of the surface (a
    // disk's rim). Where the normal is degenerate (a pole, an apex) the
    // whole difference is taken too, to stay on the safe side.
    auto normalPart = [](const Vec3& d, const Vec3& a, const Vec3& b) {
        const Vec3 n = cross(a, b);
        const float nn = length(n);
        if (!(nn > 1e-12f * std::max(dot(a, a), dot(b, b)))) return double(length(d));
        return std::abs(double(dot(d, n))) / nn;
    };
    auto tangentU = [&](int i, int j) { return at(std::min(i + 1, m), j) - at(std::max(i - 1, 0), j); };
    auto tangentV = [&](int i, int j) { return at(i, std::min(j + 1, m)) - at(i, std::max(j - 1, 0)); };
    // Second differences over one lattice step h = 1/m: h^2 P_uu, h^2 P_vv, h^2 P_uv.
    double d2u = 0, d2v = 0, dx = 0;
    for (int j = 0; j <= m; ++j)
        for (int i = 1; i < m; ++i) {
            const Vec3 d = at(i - 1, j) - at(i, j) * 2 + at(i + 1, j);
            const bool edge = j == 0 || j == m;
            d2u = std::max(d2u, edge ? double(length(d)) : normalPart(d, tangentU(i, j), tangentV(i, j)));
        }
    for (int j = 1; j < m; ++j)
        for (int i = 0; i <= m; ++i) {
            const Vec3 d = at(i, j - 1) - at(i, j) * 2 + at(i, j + 1);
            const bool edge = i == 0 || i == m;
            d2v = std::max(d2v, edge ? double(length(d)) : normalPart(d, tangentU(i, j), tangentV(i, j)));
        }
    for (int j = 0; j < m; ++j)
        for (int i = 0; i < m; ++i) {
            const Vec3 p00 = at(i, j), p10 = at(i + 1, j), p01 = at(i, j + 1), p11 = at(i + 1, j + 1);
            dx = std::max(dx, normalPart(p00 - p10 - p01 + p11, p11 - p00, p01 - p10));
        }

    // Dicing at n cells divides the lattice step by k = n / m and the
    // second differences by k^2; each of the three error terms (u, v,
    // twist) gets a third of the budget.
    const double tol = std::max(double(tolerance), 1e-30);
    const double kMin = 1.0 / m;
    double ku = std::max(kMin, std::sqrt(3 * d2u / (8 * tol)));
    double kv = std::max(kMin, std::sqrt(3 * d2v / (8 * tol)));
    const double twistNeed = 3 * dx / (4 * tol);
    if (ku * kv < twistNeed) {
        const double s = std::sqrt(twistNeed / (ku * kv));
        ku *= s;
        kv *= s;
    }
    constexpr double kMaxRate = 1 << 20;
    auto rate = [&](double k) { return int(std::clamp(std::ceil(k * m - 1e-6), 1.0, kMaxRate)); };
    DiceRate r;
    r.nu = rate(ku);
    r.nv = rate(kv);
    const double fu = double(r.nu) / m, fv = double(r.nv) / m;
    r.chordError = float(d2u / (8 * fu * fu) + d2v / (8 * fv * fv) + dx / (4 * fu * fv));
    return r;
}

struct OcclusionScene::Embree {
    RTCDevice device = nullptr;
    RTCScene scene = nullptr;
    ~Embree() {
        if (scene) rtcReleaseScene(scene);
        if (device) rtcReleaseDevice(device);
    }
};

OcclusionScene::OcclusionScene(const std::vector<geometry::PrimitivePtr>& primitives,
                               const TessellationOptions& options, Diagnostics* diag) {
    const Tessellator tess{options, diag};
    std::vector<std::vector<Chunk>> parts(primitives.size());
    parallelFor(size_t(0), primitives.size(), [&](size_t i) {
        const geometry::Primitive& p = *primitives[i];
        if (!p.attributes().castsShadows) return;
        const float tol = tess.tolerance(p);
        if (!(tol > 0)) return;  // empty or degenerate bound: nothing to hit
        tess.adaptive(p, tol, 0, parts[i]);
    });

    // Concatenate in primitive order, so the buffers do not depend on
    // thread scheduling.
    std::vector<const Chunk*> chunks;
    for (const auto& part : parts)
        for (const Chunk& c : part)
            if (!c.tris.empty()) chunks.push_back(&c);
    std::vector<size_t> vertexStart(chunks.size() + 1, 0), triStart(chunks.size() + 1, 0);
    for (size_t k = 0; k < chunks.size(); ++k) {
        vertexStart[k + 1] = vertexStart[k] + chunks[k]->P.size();
        triStart[k + 1] = triStart[k] + chunks[k]->tris.size();
        m_maxChordError = std::max(m_maxChordError, chunks[k]->chordError);
    }
    m_vertexCount = vertexStart.back();
    if (m_vertexCount > size_t(std::numeric_limits<uint32_t>::max())) {
        if (diag)
            diag->error(FileLoc{}, "ray-traced shadow scene has {} vertices, more than 32-bit indices allow; "
                        "raise the tessellation tolerance", m_vertexCount);
        m_vertexCount = 0;
        return;
    }
    m_vertices.assign(m_vertexCount * 3 + 1, 0.0f);
    m_indices.resize(triStart.back());
    std::vector<Bound3> bounds(chunks.size());
    parallelFor(size_t(0), chunks.size(), [&](size_t k) {
        const Chunk& c = *chunks[k];
        float* v = m_vertices.data() + vertexStart[k] * 3;
        for (const Vec3& q : c.P) {
            *v++ = q.x;
            *v++ = q.y;
            *v++ = q.z;
            bounds[k].extend(q);
        }
        const uint32_t base = uint32_t(vertexStart[k]);
        uint32_t* t = m_indices.data() + triStart[k];
        for (uint32_t idx : c.tris) *t++ = base + idx;
    });
    parts.clear();
    for (const Bound3& b : bounds) m_bound.extend(b);

    const float extent = m_bound.empty()
                             ? 0.0f
                             : std::max({length(m_bound.diagonal()), std::abs(m_bound.min.x), std::abs(m_bound.min.y),
                                         std::abs(m_bound.min.z), std::abs(m_bound.max.x), std::abs(m_bound.max.y),
                                         std::abs(m_bound.max.z)});
    m_rayEpsilon = std::max(2 * m_maxChordError, 1e-6f * extent);
    if (m_indices.empty()) return;  // nothing can occlude: queries answer without Embree

    m_embree = std::make_unique<Embree>();
    m_embree->device = rtcNewDevice(nullptr);
    if (!m_embree->device) {
        if (diag) diag->error(FileLoc{}, "Embree device creation failed: ray-traced shadows are unavailable");
        m_embree.reset();
        return;
    }
    rtcSetDeviceErrorFunction(m_embree->device, embreeError, diag);
    m_embree->scene = rtcNewScene(m_embree->device);
    // Robust traversal: a ray through a shared edge or vertex of two
    // triangles cannot slip between them.
    rtcSetSceneFlags(m_embree->scene, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(m_embree->scene, RTC_BUILD_QUALITY_HIGH);
    RTCGeometry geom = rtcNewGeometry(m_embree->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetGeometryBuildQuality(geom, RTC_BUILD_QUALITY_HIGH);
    rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, m_vertices.data(), 0,
                               3 * sizeof(float), m_vertexCount);
    rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, m_indices.data(), 0,
                               3 * sizeof(uint32_t), m_indices.size() / 3);
    rtcCommitGeometry(geom);
    rtcAttachGeometry(m_embree->scene, geom);
    rtcReleaseGeometry(geom);
    rtcCommitScene(m_embree->scene);
    const bool failed = rtcGetDeviceError(m_embree->device) != RTC_ERROR_NONE;
    // `diag` need not outlive the scene: queries report nothing.
    rtcSetDeviceErrorFunction(m_embree->device, nullptr, nullptr);
    if (failed) m_embree.reset();
}

OcclusionScene::~OcclusionScene() = default;

bool OcclusionScene::occludedAlong(const Vec3& from, const Vec3& direction, float tnearEpsilon, float tfar) const {
    if (!m_embree) return false;
    const Vec3 dir = normalize(direction);
    if (!finite(from) || !finite(dir) || dot(dir, dir) == 0 || !(tfar > tnearEpsilon)) return false;
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRay ray;
    fillRay(ray, from, dir, std::max(0.0f, tnearEpsilon), tfar);
    rtcOccluded1(m_embree->scene, &context, &ray);
    return ray.tfar < 0;  // Embree sets tfar to -inf on a hit
}

bool OcclusionScene::occluded(const Vec3& from, const Vec3& to, float tnearEpsilon) const {
    const Vec3 d = to - from;
    const float len = length(d);
    if (!(len > 0)) return false;
    return occludedAlong(from, d, tnearEpsilon, len - std::max(0.0f, tnearEpsilon));
}

float OcclusionScene::shadowFraction(const Vec3& P, const LightTarget& light, const Vec3* N, float epsilon) const {
    if (!m_embree) return 0;
    const float eps = epsilon < 0 ? m_rayEpsilon : epsilon;
    Vec3 org, dir;
    float tfar;
    if (!shadowRay(P, light, N, eps, &org, &dir, &tfar)) return 0;
    return occludedAlong(org, dir, eps, tfar) ? 1.0f : 0.0f;
}

void OcclusionScene::occludedBatch(int count, const Vec3* P, const Vec3* N, const LightTarget& light,
                                   float* outShadowed, float epsilon) const {
    std::fill(outShadowed, outShadowed + std::max(count, 0), 0.0f);
    if (!m_embree || count <= 0) return;
    const float eps = epsilon < 0 ? m_rayEpsilon : epsilon;
    // Embree's coherent (packet) mode measured slower than its default
    // incoherent stream mode on scattered points and no faster on
    // grid-ordered ones, so the default stays.
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRay rays[kStreamSize];
    int which[kStreamSize];
    int n = 0;
    auto flush = [&] {
        if (n == 0) return;
        rtcOccluded1M(m_embree->scene, &context, rays, unsigned(n), sizeof(RTCRay));
        for (int k = 0; k < n; ++k) outShadowed[which[k]] = rays[k].tfar < 0 ? 1.0f : 0.0f;
        n = 0;
    };
    for (int i = 0; i < count; ++i) {
        Vec3 org, dir;
        float tfar;
        if (!shadowRay(P[i], light, N ? &N[i] : nullptr, eps, &org, &dir, &tfar) || !(tfar > eps)) continue;
        fillRay(rays[n], org, dir, eps, tfar);
        which[n++] = i;
        if (n == kStreamSize) flush();
    }
    flush();
}

std::unique_ptr<OcclusionScene> buildOcclusionScene(const scene::WorldRecord& world, Diagnostics& diag,
                                                    const TessellationOptions& options) {
    std::vector<geometry::PrimitivePtr> prims;
    for (const scene::PrimitiveRecord& rec : world.primitives) {
        auto made = geometry::makePrimitives(std::make_shared<const scene::PrimitiveRecord>(rec), diag);
        for (auto& p : made) prims.push_back(std::move(p));
    }
    return std::make_unique<OcclusionScene>(prims, options, &diag);
}

}  // namespace umbra::trace
