// The interpreter loop and the core opcodes (see vm.h for the storage
// layout). Built-in functions are in shadeops.cpp.

#include "vm.h"

#include "umbra/util/rng.h"

#include <algorithm>
#include <cstring>

namespace umbra::shading {

void execCall(Exec& x, const Instr& in);  // shadeops.cpp

namespace {
// The loop budget of one shader run on one grid: 2^18 iterations of all
// its loops together, whatever the grid's size. Ray-marching shaders take
// tens of thousands of steps a point (Advanced RenderMan's cellclouds:
// 20,000), a shader several such loops; Pixie and Aqsis run them to the
// end. A loop that never ends is stopped instead of hanging the render. It
// depends on nothing but the shader: images stay deterministic.
constexpr int64_t kLoopIterations = int64_t(1) << 18;
}  // namespace

namespace {



/// dst = f(args[i]...) over the active points (once for a uniform dst).
template <class F, class... A> void map(Exec& x, int dst, F&& f, A... args) {
    float* d = x.ptr[size_t(dst)];
    if (!x.vary[size_t(dst)]) {
        put(d, 0, f(args[0]...));
        return;
    }
    if (x.allOn) {
        for (int i = 0, n = x.n; i < n; ++i) put(d, i, f(args[i]...));
    } else {
        for (int i : x.active) put(d, i, f(args[i]...));
    }
}

inline float safeDiv(float a, float b) { return b == 0 ? 0.f : a / b; }
inline Vec3 safeDiv3(const Vec3& a, const Vec3& b) { return {safeDiv(a.x, b.x), safeDiv(a.y, b.y), safeDiv(a.z, b.z)}; }

M16 invM(const M16& a) {
    Mat4 m;
    std::memcpy(m.m, a.m, sizeof a.m);
    Mat4 inv = m.inverse();
    M16 r;
    std::memcpy(r.m, inv.m, sizeof r.m);
    return r;
}

int regFloats(const RegInfo& r) { return tyFloats(r.ty); }

}  // namespace

// --- per-thread pool ----------------------------------------------------

namespace {
struct ExecPool {
    std::vector<std::unique_ptr<Exec>> execs;
    size_t used = 0;
};
thread_local ExecPool t_pool;
}  // namespace

Exec* acquireExec() {
    if (t_pool.used == t_pool.execs.size()) t_pool.execs.push_back(std::make_unique<Exec>());
    return t_pool.execs[t_pool.used++].get();
}
size_t execMark() { return t_pool.used; }
void releaseExecs(size_t mark) { t_pool.used = mark; }

// --- setup ----------------------------------------------------------------

void Exec::refreshActive() {
    const std::vector<uint8_t>& m = frames[size_t(depth)];
    if (n > 0 && std::memchr(m.data(), 0, size_t(n)) == nullptr) {
        // Every point active: the list is 0..n-1, often already built.
        allOn = true;
        if (int(active.size()) != n || (n > 0 && active[size_t(n - 1)] != n - 1)) {
            active.resize(size_t(n));
            for (int i = 0; i < n; ++i) active[size_t(i)] = i;
        }
        return;
    }
    active.clear();
    for (int i = 0; i < n; ++i)
        if (m[size_t(i)]) active.push_back(i);
    allOn = false;
}

uint32_t Exec::randomSeed(const Instr& in) {
    return hashKeys(ctx->grid->seed, randomStream, uint32_t(&in - cs->code.data()), randomCalls++);
}

void Exec::setup(const CompiledShader& code, const ShaderInstance* instance, ShadeContext& context, uint32_t stream,
                 const float* Ps, int PsStride) {
    cs = &code;
    randomStream = stream;
    randomCalls = 0;
    inst = instance;
    ctx = &context;
    ShadingGrid& g = *context.grid;
    n = g.size();
    nu = g.uVertices();
    invNu = nu > 0 ? 1.0f / float(nu) : 0.0f;
    nv = g.vVertices();
    size_t nregs = code.regs.size();
    ptr.assign(nregs, nullptr);
    vary.assign(nregs, 0);
    strs.resize(nregs);
    illum.clear();
    currentLight = -1;
    lightConstruct = 0;
    // "shader" space: the instance's worldFromShader seen from camera space.
    if (!context.haveWorld) {
        Mat4 m;
        if (!context.services->getMatrix(g, "world", &m)) m = Mat4::identity();
        context.currentFromWorld = m;
        context.haveWorld = true;
    }
    currentFromShader = instance ? context.currentFromWorld * instance->worldFromShader() : context.currentFromWorld;
    if (code.kind == ShaderKind::Light) {
        lit.assign(size_t(n), 0);
        ownPs.resize(size_t(n));
        for (int i = 0; i < n; ++i) ownPs[size_t(i)] = Ps ? Vec3(Ps[3 * i * PsStride], Ps[3 * i * PsStride + 1], Ps[3 * i * PsStride + 2]) : g.P[size_t(i)];
        // A light's P is the point on the light (RI 3.2, light source
        // variables); a light that is not an area light is its shader
        // space's origin, so the Companion's `illuminate(P)` shines from
        // where the light was placed (as Aqsis; Pixie gives the lit point).
        lightP.assign(size_t(n), currentFromShader.point({0, 0, 0}));
    }
    // Which globals live in the grid's own arrays.
    auto gridArray = [&](int gid) -> float* {
        auto v3 = [](std::vector<Vec3>& v) { return reinterpret_cast<float*>(v.data()); };
        bool light = code.kind == ShaderKind::Light;
        switch (gid) {
        case gP: return light ? v3(lightP) : v3(g.P);
        case gPs: return light ? v3(ownPs) : nullptr;
        case gN: return v3(g.N);
        case gNs: return light ? v3(g.N) : nullptr;
        case gNg: return v3(g.Ng);
        case gI: return v3(g.I);
        case gDPdu: return v3(g.dPdu);
        case gDPdv: return v3(g.dPdv);
        case gCs: return v3(g.Cs);
        case gOs: return v3(g.Os);
        case gCi: return light ? nullptr : v3(g.Ci);
        case gOi: return light ? nullptr : v3(g.Oi);
        case gS: return g.s.data();
        case gT: return g.t.data();
        case gU: return g.u.data();
        case gV: return g.v.data();
        case gAlpha: return g.alpha.size() == size_t(n) ? g.alpha.data() : nullptr;
        case gDPdtime: return g.dPdtime.size() == size_t(n) ? v3(g.dPdtime) : nullptr;  // else 0: still
        default: return nullptr;
        }
    };
    size_t total = 0;
    std::vector<size_t> offsets(nregs, 0);
    for (size_t r = 0; r < nregs; ++r) {
        const RegInfo& ri = code.regs[r];
        vary[r] = ri.varying ? 1 : 0;
        if (ri.ty == Ty::String) {
            strs[r].assign(size_t(std::max(1, ri.arrayLen)), std::string());
            if (ri.kind == RegKind::Const) strs[r][0] = code.constStrings[size_t(ri.constIndex)];
            vary[r] = 0;
            continue;
        }
        if (ri.kind == RegKind::Global) {
            if (float* p = gridArray(ri.global)) {
                ptr[r] = p;
                continue;
            }
        }
        offsets[r] = total;
        total += size_t(ri.floatsPerValue()) * (ri.varying ? size_t(n) : 1);
    }
    store.assign(total + 1, 0.0f);
    for (size_t r = 0; r < nregs; ++r) {
        const RegInfo& ri = code.regs[r];
        if (ri.ty == Ty::String || ptr[r]) continue;
        ptr[r] = store.data() + offsets[r];
        if (ri.kind == RegKind::Const) std::memcpy(ptr[r], &code.consts[size_t(ri.constIndex)], sizeof(float) * size_t(tyFloats(ri.ty)));
    }
    auto setU = [&](int gid, float v) {
        int r = code.globalRegs[gid];
        if (r >= 0) ptr[size_t(r)][0] = v;
    };
    setU(gDu, g.du);
    setU(gDv, g.dv);
    setU(gTime, g.time);
    setU(gDtime, g.dtime);
    setU(gNcomps, 3);
    if (int r = code.globalRegs[gE]; r >= 0) put(ptr[size_t(r)], 0, g.E);
    if (int r = code.globalRegs[gOl]; r >= 0) {
        float* p = ptr[size_t(r)];
        for (int i = 0; i < (vary[size_t(r)] ? n : 1); ++i) put(p, i, Vec3(1, 1, 1));
    }
    if (frames.size() < 8) frames.resize(8);
    frames[0].assign(size_t(n), 1);
    depth = 0;
    refreshActive();
}

namespace {

void pushFrame(Exec& x) {
    ++x.depth;
    if (x.frames.size() <= size_t(x.depth)) x.frames.resize(size_t(x.depth) + 1);
}

/// Loads an instance binding or primitive variable into parameter register
/// `r`; false when neither exists.
bool bindParam(Exec& x, int r) {
    const RegInfo& ri = x.cs->regs[size_t(r)];
    int p = ri.param;
    const ShadingGrid& g = *x.ctx->grid;
    int per = ri.floatsPerValue();
    float* dst = x.ptr[size_t(r)];
    bool varying = x.vary[size_t(r)];
    // A light is not the primitive's: its parameters are its LightSource's,
    // whatever variables the lit surface carries (a floor's "intensity" or
    // "width" changed every light's, where PRMan, Pixie and Aqsis bind
    // primitive variables only to the primitive's own shaders).
    const std::vector<geometry::GridVar>* primvars = x.cs->kind == ShaderKind::Light ? nullptr : g.primvars;
    if (primvars && ri.ty == Ty::String && ri.arrayLen == 0) {
        // A constant or uniform string variable: one value per grid.
        for (const geometry::GridVar& gv : *primvars) {
            if (gv.name != ri.name || !gv.strings || gv.data.empty()) continue;
            const float k = gv.data[0];
            if (!(k >= 0 && k < float(gv.strings->size()))) continue;
            x.strs[size_t(r)][0] = (*gv.strings)[size_t(k)];
            return true;
        }
    }
    if (primvars && ri.ty != Ty::String) {
        for (const geometry::GridVar& gv : *primvars) {
            if (gv.name != ri.name || gv.components != per || gv.strings) continue;
            if (!varying && gv.perVertex) {
                // A value per vertex has no place in a uniform parameter:
                // it keeps its value, as in Pixie and Aqsis (umbra took the
                // first vertex's, silently).
                x.ctx->system->diagnostics().warningOnce(
                    "shading:uniformparam:" + x.cs->name + ":" + ri.name, FileLoc::inFile(x.cs->fileName),
                    "shader '{}': primitive variable '{}' has a value per vertex, but the parameter is uniform; the "
                    "parameter keeps its value (declare it varying in the shader to read the variable)",
                    x.cs->name, ri.name);
                break;
            }
            if (varying && gv.perVertex) {
                // arrays: element-major blocks of n values each
                int comps = tyFloats(ri.ty);
                int elems = std::max(1, ri.arrayLen);
                for (int e = 0; e < elems; ++e)
                    for (int i = 0; i < x.n; ++i)
                        std::memcpy(dst + size_t(e) * size_t(comps) * size_t(x.n) + size_t(i) * size_t(comps),
                                    gv.at(i) + e * comps, sizeof(float) * size_t(comps));
            } else if (varying) {
                int comps = tyFloats(ri.ty);
                int elems = std::max(1, ri.arrayLen);
                for (int e = 0; e < elems; ++e)
                    for (int i = 0; i < x.n; ++i)
                        std::memcpy(dst + size_t(e) * size_t(comps) * size_t(x.n) + size_t(i) * size_t(comps),
                                    gv.at(0) + e * comps, sizeof(float) * size_t(comps));
            } else {
                std::memcpy(dst, gv.at(0), sizeof(float) * size_t(per));
            }
            return true;
        }
    }
    if (!x.inst) return false;
    for (const ShaderInstance::Binding& b : x.inst->bindings()) {
        if (b.param != p) continue;
        if (ri.ty == Ty::String) {
            for (size_t k = 0; k < b.strings.size() && k < x.strs[size_t(r)].size(); ++k) x.strs[size_t(r)][k] = b.strings[k];
            return true;
        }
        if (int(b.floats.size()) != per) return false;
        int comps = tyFloats(ri.ty);
        int elems = std::max(1, ri.arrayLen);
        for (int e = 0; e < elems; ++e) {
            const float* src = b.floats.data() + e * comps;
            float tmp[16];
            std::memcpy(tmp, src, sizeof(float) * size_t(comps));
            Vec3 v(tmp[0], tmp[1 % comps], tmp[2 % comps]);
            const Mat4& m = x.currentFromShader;
            if (ri.ty == Ty::Point) v = m.point(v);
            else if (ri.ty == Ty::Vector) v = m.vector(v);
            else if (ri.ty == Ty::Normal) v = Mat4::normal(m.inverse(), v);
            if (ri.ty == Ty::Point || ri.ty == Ty::Vector || ri.ty == Ty::Normal) {
                tmp[0] = v.x;
                tmp[1] = v.y;
                tmp[2] = v.z;
            }
            int count = varying ? x.n : 1;
            float* block = dst + size_t(e) * size_t(comps) * size_t(count);
            for (int i = 0; i < count; ++i) std::memcpy(block + size_t(i) * size_t(comps), tmp, sizeof(float) * size_t(comps));
        }
        return true;
    }
    return false;
}

void movValue(Exec& x, int dst, int src) {
    int comps = regFloats(x.cs->regs[size_t(dst)]);
    if (comps == 1) map(x, dst, [](float a) { return a; }, rd<float>(x, src));
    else if (comps == 3) map(x, dst, [](const Vec3& a) { return a; }, rd<Vec3>(x, src));
    else map(x, dst, [](const M16& a) { return a; }, rd<M16>(x, src));
}

void movArray(Exec& x, int dst, int src) {
    const RegInfo& d = x.cs->regs[size_t(dst)];
    if (d.ty == Ty::String) {
        x.strs[size_t(dst)] = x.strs[size_t(src)];
        return;
    }
    int comps = tyFloats(d.ty);
    int dv = x.vary[size_t(dst)], sv = x.vary[size_t(src)];
    for (int e = 0; e < d.arrayLen; ++e) {
        float* dp = x.ptr[size_t(dst)] + size_t(e) * size_t(comps) * size_t(dv ? x.n : 1);
        const float* sp = x.ptr[size_t(src)] + size_t(e) * size_t(comps) * size_t(sv ? x.n : 1);
        auto copy = [&](int i) { std::memcpy(dp + i * comps, sp + i * sv * comps, sizeof(float) * size_t(comps)); };
        if (!dv) copy(0);
        else if (x.allOn) for (int i = 0; i < x.n; ++i) copy(i);
        else for (int i : x.active) copy(i);
    }
}

int clampIndex(float f, int len) {
    if (!(f >= 0)) return 0;  // also NaN
    if (f >= float(len)) return len - 1;
    return int(f);
}

void loadElem(Exec& x, const Instr& in) {
    const RegInfo& a = x.cs->regs[size_t(in.a)];
    if (a.ty == Ty::String) {
        x.strs[size_t(in.dst)][0] = x.strs[size_t(in.a)][size_t(clampIndex(x.ptr[size_t(in.b)][0], a.arrayLen))];
        return;
    }
    int comps = tyFloats(a.ty);
    size_t block = size_t(comps) * size_t(x.vary[size_t(in.a)] ? x.n : 1);
    const float* base = x.ptr[size_t(in.a)];
    const float* idx = x.ptr[size_t(in.b)];
    int is = x.vary[size_t(in.b)], as = x.vary[size_t(in.a)];
    float* d = x.ptr[size_t(in.dst)];
    auto one = [&](int i) {
        int e = clampIndex(idx[i * is], a.arrayLen);
        std::memcpy(d + i * comps, base + size_t(e) * block + size_t(i * as * comps), sizeof(float) * size_t(comps));
    };
    if (!x.vary[size_t(in.dst)]) one(0);
    else if (x.allOn) for (int i = 0; i < x.n; ++i) one(i);
    else for (int i : x.active) one(i);
}

void storeElem(Exec& x, const Instr& in) {
    const RegInfo& d = x.cs->regs[size_t(in.dst)];
    if (d.ty == Ty::String) {
        x.strs[size_t(in.dst)][size_t(clampIndex(x.ptr[size_t(in.a)][0], d.arrayLen))] = x.strs[size_t(in.b)][0];
        return;
    }
    int comps = tyFloats(d.ty);
    size_t block = size_t(comps) * size_t(x.vary[size_t(in.dst)] ? x.n : 1);
    float* base = x.ptr[size_t(in.dst)];
    const float* idx = x.ptr[size_t(in.a)];
    const float* v = x.ptr[size_t(in.b)];
    int is = x.vary[size_t(in.a)], vs = x.vary[size_t(in.b)], ds = x.vary[size_t(in.dst)];
    auto one = [&](int i) {
        int e = clampIndex(idx[i * is], d.arrayLen);
        std::memcpy(base + size_t(e) * block + size_t(i * ds * comps), v + i * vs * comps, sizeof(float) * size_t(comps));
    };
    if (!ds) one(0);
    else if (x.allOn) for (int i = 0; i < x.n; ++i) one(i);
    else for (int i : x.active) one(i);
}

void illumNext(Exec& x, const Instr& in, int* pc);
void illuminate(Exec& x, const Instr& in, bool solar, int* pc);

}  // namespace

void Exec::run() {
    const Instr* code = cs->code.data();
    int pc = 0, end = int(cs->code.size());
    // A shader whose loop never ends would hang the render: after this many
    // iterations of all its loops, loops are ended with a warning.
    const int64_t loopBudgetAtStart = kLoopIterations;
    int64_t loopBudget = loopBudgetAtStart;
    while (pc < end) {
        const Instr& in = code[pc];
        if (active.empty()) {
            switch (in.op) {
            case Op::Jump: case Op::IfBegin: case Op::Else: case Op::EndIf: case Op::LoopBegin: case Op::LoopCond:
            case Op::LoopCont: case Op::LoopEnd: case Op::Break: case Op::IllumBegin: case Op::IllumNext:
            case Op::Illuminate: case Op::Solar: case Op::ParamInit:
                break;
            default:
                ++pc;
                continue;
            }
        }
        Exec& x = *this;
        switch (in.op) {
        case Op::Nop: break;
        case Op::Mov: movValue(x, in.dst, in.a); break;
        case Op::MovS: strs[size_t(in.dst)][0] = strs[size_t(in.a)][0]; break;
        case Op::MovArr: movArray(x, in.dst, in.a); break;
        case Op::Promote3: map(x, in.dst, [](float a) { return Vec3(a); }, rd<float>(x, in.a)); break;
        case Op::PromoteM:
            map(x, in.dst, [](float a) {
                M16 m{};
                m.m[0] = m.m[5] = m.m[10] = m.m[15] = a;
                return m;
            }, rd<float>(x, in.a));
            break;
        case Op::Make3:
            map(x, in.dst, [](float a, float b, float c) { return Vec3(a, b, c); }, rd<float>(x, in.a), rd<float>(x, in.b), rd<float>(x, in.c));
            break;
        case Op::MakeM: {
            In<float> e[16];
            for (int k = 0; k < 16; ++k) e[k] = rd<float>(x, cs->args[size_t(in.argBase + k)]);
            float* d = ptr[size_t(in.dst)];
            auto one = [&](int i) {
                for (int k = 0; k < 16; ++k) d[i * 16 + k] = e[k][i];
            };
            if (!vary[size_t(in.dst)]) one(0);
            else if (allOn) for (int i = 0; i < n; ++i) one(i);
            else for (int i : active) one(i);
            break;
        }
        case Op::LoadElem: loadElem(x, in); break;
        case Op::StoreElem: storeElem(x, in); break;
        case Op::Comp:
            map(x, in.dst, [](const Vec3& a, float i) { return a[clampIndex(i, 3)]; }, rd<Vec3>(x, in.a), rd<float>(x, in.b));
            break;
        case Op::SetComp:
            map(x, in.dst, [](const Vec3& d, float i, float v) {
                Vec3 r = d;
                r[clampIndex(i, 3)] = v;
                return r;
            }, rd<Vec3>(x, in.dst), rd<float>(x, in.a), rd<float>(x, in.b));
            break;
        case Op::AddF: map(x, in.dst, [](float a, float b) { return a + b; }, rd<float>(x, in.a), rd<float>(x, in.b)); break;
        case Op::SubF: map(x, in.dst, [](float a, float b) { return a - b; }, rd<float>(x, in.a), rd<float>(x, in.b)); break;
        case Op::MulF: map(x, in.dst, [](float a, float b) { return a * b; }, rd<float>(x, in.a), rd<float>(x, in.b)); break;
        case Op::DivF: map(x, in.dst, [](float a, float b) { return safeDiv(a, b); }, rd<float>(x, in.a), rd<float>(x, in.b)); break;
        case Op::NegF: map(x, in.dst, [](float a) { return -a; }, rd<float>(x, in.a)); break;
        case Op::Add3: map(x, in.dst, [](const Vec3& a, const Vec3& b) { return a + b; }, rd<Vec3>(x, in.a), rd<Vec3>(x, in.b)); break;
        case Op::Sub3: map(x, in.dst, [](const Vec3& a, const Vec3& b) { return a - b; }, rd<Vec3>(x, in.a), rd<Vec3>(x, in.b)); break;
        case Op::Mul3: map(x, in.dst, [](const Vec3& a, const Vec3& b) { return a * b; }, rd<Vec3>(x, in.a), rd<Vec3>(x, in.b)); break;
        case Op::Div3: map(x, in.dst, [](const Vec3& a, const Vec3& b) { return safeDiv3(a, b); }, rd<Vec3>(x, in.a), rd<Vec3>(x, in.b)); break;
        case Op::Neg3: map(x, in.dst, [](const Vec3& a) { return -a; }, rd<Vec3>(x, in.a)); break;
        case Op::Mul3F: map(x, in.dst, [](const Vec3& a, float b) { return a * b; }, rd<Vec3>(x, in.a), rd<float>(x, in.b)); break;
        case Op::Div3F:
            map(x, in.dst, [](const Vec3& a, float b) { return b == 0 ? Vec3(0.f) : a * (1.0f / b); }, rd<Vec3>(x, in.a), rd<float>(x, in.b));
            break;
        case Op::Dot: map(x, in.dst, [](const Vec3& a, const Vec3& b) { return dot(a, b); }, rd<Vec3>(x, in.a), rd<Vec3>(x, in.b)); break;
        case Op::Cross: map(x, in.dst, [](const Vec3& a, const Vec3& b) { return cross(a, b); }, rd<Vec3>(x, in.a), rd<Vec3>(x, in.b)); break;
        case Op::MulM: map(x, in.dst, mulM, rd<M16>(x, in.a), rd<M16>(x, in.b)); break;
        case Op::DivM: map(x, in.dst, [](const M16& a, const M16& b) { return mulM(a, invM(b)); }, rd<M16>(x, in.a), rd<M16>(x, in.b)); break;
        case Op::LtF: map(x, in.dst, [](float a, float b) { return float(a < b); }, rd<float>(x, in.a), rd<float>(x, in.b)); break;
        case Op::LeF: map(x, in.dst, [](float a, float b) { return float(a <= b); }, rd<float>(x, in.a), rd<float>(x, in.b)); break;
        case Op::GtF: map(x, in.dst, [](float a, float b) { return float(a > b); }, rd<float>(x, in.a), rd<float>(x, in.b)); break;
        case Op::GeF: map(x, in.dst, [](float a, float b) { return float(a >= b); }, rd<float>(x, in.a), rd<float>(x, in.b)); break;
        case Op::EqF: map(x, in.dst, [](float a, float b) { return float(a == b); }, rd<float>(x, in.a), rd<float>(x, in.b)); break;
        case Op::NeF: map(x, in.dst, [](float a, float b) { return float(a != b); }, rd<float>(x, in.a), rd<float>(x, in.b)); break;
        case Op::Eq3: map(x, in.dst, [](const Vec3& a, const Vec3& b) { return float(a == b); }, rd<Vec3>(x, in.a), rd<Vec3>(x, in.b)); break;
        case Op::Ne3: map(x, in.dst, [](const Vec3& a, const Vec3& b) { return float(a != b); }, rd<Vec3>(x, in.a), rd<Vec3>(x, in.b)); break;
        case Op::EqS:
        case Op::NeS: {
            // Strings are uniform, but the result may live in a varying
            // register (inside a varying block): fill every active point.
            float v = float((strs[size_t(in.a)][0] == strs[size_t(in.b)][0]) != (in.op == Op::NeS));
            float* d = ptr[size_t(in.dst)];
            if (vary[size_t(in.dst)])
                for (int i : active) d[i] = v;
            else
                d[0] = v;
            break;
        }
        case Op::EqM:
        case Op::NeM: {
            bool ne = in.op == Op::NeM;
            map(x, in.dst, [ne](const M16& a, const M16& b) { return float((std::memcmp(a.m, b.m, sizeof a.m) == 0) != ne); }, rd<M16>(x, in.a), rd<M16>(x, in.b));
            break;
        }
        case Op::And: map(x, in.dst, [](float a, float b) { return float(a != 0 && b != 0); }, rd<float>(x, in.a), rd<float>(x, in.b)); break;
        case Op::Or: map(x, in.dst, [](float a, float b) { return float(a != 0 || b != 0); }, rd<float>(x, in.a), rd<float>(x, in.b)); break;
        case Op::Not: map(x, in.dst, [](float a) { return float(a == 0); }, rd<float>(x, in.a)); break;
        case Op::Select: {
            if (cs->regs[size_t(in.dst)].ty == Ty::String) {  // a uniform condition (the compiler's check)
                const float c = ptr[size_t(in.c)][vary[size_t(in.c)] && !active.empty() ? active[0] : 0];
                strs[size_t(in.dst)][0] = strs[size_t(c != 0 ? in.a : in.b)][0];
                break;
            }
            int comps = regFloats(cs->regs[size_t(in.dst)]);
            if (comps == 1) map(x, in.dst, [](float a, float b, float c) { return c != 0 ? a : b; }, rd<float>(x, in.a), rd<float>(x, in.b), rd<float>(x, in.c));
            else if (comps == 3) map(x, in.dst, [](const Vec3& a, const Vec3& b, float c) { return c != 0 ? a : b; }, rd<Vec3>(x, in.a), rd<Vec3>(x, in.b), rd<float>(x, in.c));
            else map(x, in.dst, [](const M16& a, const M16& b, float c) { return c != 0 ? a : b; }, rd<M16>(x, in.a), rd<M16>(x, in.b), rd<float>(x, in.c));
            break;
        }
        case Op::Call: execCall(x, in); break;
        case Op::Jump: pc = in.target; continue;
        case Op::IfBegin:
        case Op::Else: {
            if (in.op == Op::IfBegin) pushFrame(x);
            const std::vector<uint8_t>& parent = frames[size_t(depth - 1)];
            std::vector<uint8_t>& m = frames[size_t(depth)];
            m.resize(size_t(n));
            const float* c = ptr[size_t(in.a)];
            bool want = in.op == Op::IfBegin;
            if (!vary[size_t(in.a)]) {
                bool on = (c[0] != 0) == want;
                for (int i = 0; i < n; ++i) m[size_t(i)] = on ? parent[size_t(i)] : 0;
            } else {
                for (int i = 0; i < n; ++i) m[size_t(i)] = parent[size_t(i)] && ((c[i] != 0) == want);
            }
            refreshActive();
            if (active.empty()) {
                pc = in.target;
                continue;
            }
            break;
        }
        case Op::EndIf:
        case Op::LoopCont:
        case Op::LoopEnd:
            --depth;
            refreshActive();
            break;
        case Op::LoopBegin:
            pushFrame(x);
            frames[size_t(depth)] = frames[size_t(depth - 1)];
            break;
        case Op::LoopCond: {
            std::vector<uint8_t>& m = frames[size_t(depth)];
            const float* c = ptr[size_t(in.a)];
            int s = vary[size_t(in.a)];
            bool any = false;
            if (--loopBudget < 0) {
                ctx->system->diagnostics().warningOnce("shading:loop:" + cs->name, FileLoc::inFile(cs->fileName, in.loc.line, in.loc.col),
                                                       "shader '{}': loops ran more than {} iterations on a grid of {} "
                                                       "points; stopped (every grid stops its loops there)",
                                                       cs->name, loopBudgetAtStart, n);
                c = nullptr;
            }
            for (int i = 0; i < n; ++i) {
                m[size_t(i)] = m[size_t(i)] && c && c[i * s] != 0;
                any = any || m[size_t(i)];
            }
            if (!any) {
                refreshActive();
                pc = in.target;
                continue;
            }
            pushFrame(x);
            frames[size_t(depth)] = frames[size_t(depth - 1)];
            refreshActive();
            break;
        }
        case Op::Break:
            for (int f = in.c; f <= depth; ++f)
                for (int i : active) frames[size_t(f)][size_t(i)] = 0;
            refreshActive();
            break;
        case Op::IllumBegin: {
            pushFrame(x);
            frames[size_t(depth)] = frames[size_t(depth - 1)];
            Illum il;
            il.p = in.a;
            il.axis = in.b;
            il.angle = in.c;
            int cat = cs->args[size_t(in.argBase)];
            if (cat >= 0) il.category = strs[size_t(cat)][0];
            illum.push_back(il);
            const bool uniformAngle = in.c >= 0 && !vary[size_t(in.c)];
            needLights(*this, ptr[size_t(in.a)], vary[size_t(in.a)], uniformAngle && in.b >= 0 ? ptr[size_t(in.b)] : nullptr,
                       in.b >= 0 ? vary[size_t(in.b)] : 0, uniformAngle ? ptr[size_t(in.c)][0] : kPi);
            break;
        }
        case Op::IllumNext: illumNext(x, in, &pc); continue;
        case Op::Illuminate: illuminate(x, in, false, &pc); continue;
        case Op::Solar: illuminate(x, in, true, &pc); continue;
        case Op::ParamInit:
            if (bindParam(x, in.dst)) {
                pc = in.target;
                continue;
            }
            break;
        }
        ++pc;
    }
}

namespace {

bool categoryMatches(const std::string& want, const std::string& have) {
    if (want.empty()) return true;
    bool negate = want[0] == '-';
    std::string name = negate ? want.substr(1) : want;
    bool found = false;
    size_t b = 0;
    while (b <= have.size()) {
        size_t e = have.find(',', b);
        if (e == std::string::npos) e = have.size();
        std::string item = have.substr(b, e - b);
        while (!item.empty() && item.front() == ' ') item.erase(item.begin());
        while (!item.empty() && item.back() == ' ') item.pop_back();
        if (item == name) found = true;
        b = e + 1;
    }
    return negate ? !found : found;
}

/// The cone test of illuminate() and illuminance(): L lies within `angle`
/// of `axis` (angles of pi or more accept everything). Uniform angles and
/// axes are worked out once.
struct ConeOf {
    In<Vec3> axis;
    In<float> angle;
    bool uniformAngle = false, uniformAxis = false;
    float cosAngle = 0, axisLength = 0;
    ConeOf(bool cone, In<Vec3> ax, In<float> an) : axis(ax), angle(an) {
        if (!cone) return;
        uniformAngle = angle.s == 0;
        uniformAxis = axis.s == 0;
        if (uniformAngle) cosAngle = std::cos(angle[0]);
        if (uniformAxis) axisLength = length(axis[0]);
    }
    bool contains(const Vec3& L, int i) const {
        const float a = angle[i];
        if (!(a < kPi)) return true;
        const Vec3 ax = axis[i];
        const float ll = length(L), la = uniformAxis ? axisLength : length(ax);
        return ll > 0 && la > 0 && !(dot(L, ax) < (uniformAngle ? cosAngle : std::cos(a)) * ll * la);
    }
};

void illumNext(Exec& x, const Instr& in, int* pc) {
    Exec::Illum& il = x.illum.back();
    auto& lights = x.ctx->lights;
    const std::vector<uint8_t>& loop = x.frames[size_t(x.depth)];
    int Lreg = x.cs->globalRegs[gL], Clreg = x.cs->globalRegs[gCl], Olreg = x.cs->globalRegs[gOl];
    for (; il.next < int(lights.size()); ++il.next) {
        const LightRun& lr = lights[size_t(il.next)];
        if (lr.ambient) continue;
        if (!categoryMatches(il.category, lr.instance->category())) continue;
        pushFrame(x);
        std::vector<uint8_t>& m = x.frames[size_t(x.depth)];
        m.assign(size_t(x.n), 0);
        In<Vec3> P = rd<Vec3>(x, il.p);
        (void)P;
        bool cone = il.axis >= 0 && il.angle >= 0;
        In<Vec3> axis = cone ? rd<Vec3>(x, il.axis) : In<Vec3>{nullptr, 0};
        In<float> angle = cone ? rd<float>(x, il.angle) : In<float>{nullptr, 0};
        bool any = false;
        float* Ld = x.ptr[size_t(Lreg)];
        float* Cd = x.ptr[size_t(Clreg)];
        // Ol, the light's opacity (RI Spec 3.2, table 12.1), where the shader
        // reads it.
        float* Od = Olreg >= 0 ? x.ptr[size_t(Olreg)] : nullptr;
        const int lightOl = Od && lr.exec ? lr.exec->cs->globalRegs[gOl] : -1;
        const In<Vec3> Ol = lightOl >= 0 ? In<Vec3>{lr.exec->ptr[size_t(lightOl)], lr.exec->vary[size_t(lightOl)]}
                                         : In<Vec3>{nullptr, 0};
        const ConeOf coneOf(cone, axis, angle);
        for (int i = 0; i < x.n; ++i) {
            if (!loop[size_t(i)] || !lr.lit(i)) continue;
            Vec3 L = -lr.L(i);
            if (cone && !coneOf.contains(L, i)) continue;
            m[size_t(i)] = 1;
            any = true;
            put(Ld, i, L);
            put(Cd, i, lr.Cl(i));
            if (Od) put(Od, i, lightOl >= 0 ? Ol[i] : Vec3(0.f));
        }
        if (!any) {
            --x.depth;
            continue;
        }
        x.currentLight = il.next;
        ++il.next;
        x.refreshActive();
        ++*pc;
        return;
    }
    x.illum.pop_back();
    // Back in an enclosing loop's body (nested illuminance), lightsource()
    // reads that loop's light again: the one before its `next`.
    x.currentLight = x.illum.empty() ? -1 : x.illum.back().next - 1;
    x.refreshActive();
    *pc = in.target;
}

void illuminate(Exec& x, const Instr& in, bool solar, int* pc) {
    const std::vector<uint8_t>& parent = x.frames[size_t(x.depth)];
    pushFrame(x);
    std::vector<uint8_t>& m = x.frames[size_t(x.depth)];
    m.assign(size_t(x.n), 0);
    float* Ld = x.ptr[size_t(x.cs->globalRegs[gL])];
    In<Vec3> Ps = rd<Vec3>(x, x.cs->globalRegs[gPs]);
    In<Vec3> N = rd<Vec3>(x, x.cs->globalRegs[gN]);
    In<Vec3> A = in.a >= 0 ? rd<Vec3>(x, in.a) : N;
    bool cone = !solar && in.b >= 0 && in.c >= 0;
    In<Vec3> axis = cone ? rd<Vec3>(x, in.b) : A;
    In<float> angle = cone ? rd<float>(x, in.c) : In<float>{nullptr, 0};
    bool any = false;
    // A uniform cone (the usual case) has its cosine and axis length worked
    // out once, not per point: the same values, without a cos per point.
    const ConeOf coneOf(cone, axis, angle);
    const ReceiverCone& receiver = x.ctx->receiver;
    for (int i = 0; i < x.n; ++i) {
        if (!parent[size_t(i)]) continue;
        Vec3 L;
        if (solar) {
            L = in.a >= 0 ? A[i] : -N[i];
        } else {
            L = Ps[i] - A[i];
            if (cone && !coneOf.contains(L, i)) continue;
        }
        if (receiver.restricts && !receiver.admits(-L, i)) continue;
        put(Ld, i, L);
        m[size_t(i)] = 1;
        x.lit[size_t(i)] = 1;
        any = true;
    }
    x.refreshActive();
    x.lightConstruct = solar ? 2 : 1;
    *pc = any ? *pc + 1 : in.target;
}

}  // namespace

namespace {

/// Runs the ambient lights, or the others, over the grid.
void runLights(ShadeContext& ctx, const float* Ps, int stride, bool ambient) {
    for (size_t l = 0; l < ctx.lights.size(); ++l) {
        LightRun& lr = ctx.lights[l];
        if (lr.ambient != ambient) continue;
        const CompiledShader& code = lr.instance->shader().code();
        // Run again at other positions (needLights()), a light reuses its
        // Exec: its earlier results are not read any more.
        Exec* e = lr.exec ? lr.exec : acquireExec();
        lr.exec = e;
        e->setup(code, lr.instance, ctx, kFirstLightStream + uint32_t(l), Ps, stride);
        e->run();
        int Lr = code.globalRegs[gL], Clr = code.globalRegs[gCl];
        lr.Lp = e->ptr[size_t(Lr)];
        lr.Ls = e->vary[size_t(Lr)];
        lr.Clp = e->ptr[size_t(Clr)];
        lr.Cls = e->vary[size_t(Clr)];
        lr.litp = lr.ambient ? nullptr : e->lit.data();
        if (lr.ambient) continue;
        int n = e->n;
        e->lightDir.resize(size_t(n));
        for (int i = 0; i < n; ++i) {
            Vec3 L = -lr.L(i);
            float l2 = dot(L, L);
            e->lightDir[size_t(i)] = l2 > 0 ? L * (1.0f / std::sqrt(l2)) : Vec3(0.f);
        }
        lr.dir = e->lightDir.data();
    }
}

}  // namespace

void needLights(Exec& x, const float* Ps, int stride, const float* axis, int axisStride, float angle) {
    ShadeContext& ctx = *x.ctx;
    ReceiverCone& rc = ctx.receiver;
    const bool restricts = axis && angle < kPi;
    const float cosLimit = restricts ? std::cos(angle) - ReceiverCone::kReceiverSlack : -2.0f;
    In<Vec3> ax{axis, axisStride};
    // The lights ran for the points' own positions; a loop gathering at
    // others (a second illuminance at P - I/2, a volume's ray-march steps:
    // RI Spec 3.2's illuminance(position)) runs them again there.
    const In<Vec3> at{Ps, stride};
    auto samePlace = [&] {  // at every point, active or not: results are kept for all
        const int count = stride == 0 && ctx.litAtUniform ? 1 : x.n;
        for (int i = 0; i < count; ++i)
            if (!(at[i] == ctx.litAt[ctx.litAtUniform ? 0 : size_t(i)])) return false;
        return true;
    };
    if (ctx.lightsRun && samePlace()) {
        if (!rc.restricts) return;
        // Covered when this cone is no wider and has the same axis wherever
        // this loop looks: every light it accepts was then admitted.
        auto same = [&](int i) { return ax[i] == rc.axis[rc.uniformAxis ? 0 : size_t(i)]; };
        bool covered = restricts && cosLimit >= rc.cosLimit;
        if (covered && rc.uniformAxis && axisStride == 0) covered = same(0);
        else if (covered) covered = std::all_of(x.active.begin(), x.active.end(), same);
        if (covered) return;
        rc.restricts = false;  // run them again, at every point
    } else {
        rc.restricts = restricts;
        if (restricts) {
            rc.uniformAxis = axisStride == 0;
            rc.cosLimit = cosLimit;
            const int count = rc.uniformAxis ? 1 : x.n;
            rc.axis.resize(size_t(count));
            for (int i = 0; i < count; ++i) rc.axis[size_t(i)] = ax[i];
        }
    }
    ctx.litAtUniform = stride == 0;
    ctx.litAt.resize(size_t(ctx.litAtUniform ? 1 : x.n));
    for (size_t i = 0; i < ctx.litAt.size(); ++i) ctx.litAt[i] = at[int(i)];
    runLights(ctx, Ps, stride, false);
    ctx.lightsRun = true;
}

void needAmbientLights(Exec& x) {
    if (x.ctx->ambientLightsRun) return;
    x.ctx->ambientLightsRun = true;
    const int Pr = x.cs->globalRegs[gP];
    runLights(*x.ctx, x.ptr[size_t(Pr)], x.vary[size_t(Pr)], true);
}

}  // namespace umbra::shading
