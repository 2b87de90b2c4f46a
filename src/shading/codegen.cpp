// Semantic analysis and code generation in one walk over the AST: each
// expression is type-checked (RenderMan's implicit conversions: float
// promotes to any triple or matrix, point/vector/normal interchange) as its
// code is emitted. User functions are inlined at each call, so their
// parameters take the uniform/varying nature of the arguments; the
// uniform/varying nature of everything else is inferred afterwards
// (bytecode.cpp).

#include "builtins.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

namespace umbra::shading {

const char* tyName(Ty t) {
    switch (t) {
    case Ty::Void: return "void";
    case Ty::Float: return "float";
    case Ty::Color: return "color";
    case Ty::Point: return "point";
    case Ty::Vector: return "vector";
    case Ty::Normal: return "normal";
    case Ty::Matrix: return "matrix";
    case Ty::String: return "string";
    case Ty::Bool: return "boolean";
    case Ty::Tuple: return "triple";
    }
    return "?";
}

const std::vector<BuiltinSig>& builtinTable() {
    static const std::vector<BuiltinSig> kTable = {
        {"sin", Bi::Sin, "f", "f"}, {"cos", Bi::Cos, "f", "f"}, {"tan", Bi::Tan, "f", "f"},
        {"asin", Bi::Asin, "f", "f"}, {"acos", Bi::Acos, "f", "f"}, {"atan", Bi::Atan, "f", "f"},
        {"atan", Bi::Atan2, "f", "ff"}, {"exp", Bi::Exp, "f", "f"}, {"log", Bi::Log, "f", "f"},
        {"log", Bi::LogBase, "f", "ff"}, {"sqrt", Bi::Sqrt, "f", "f"}, {"inversesqrt", Bi::InvSqrt, "f", "f"},
        {"abs", Bi::Abs, "f", "f"}, {"abs", Bi::AbsT, "t", "t"}, {"sign", Bi::Sign, "f", "f"},
        {"floor", Bi::Floor, "f", "f"}, {"floor", Bi::FloorT, "t", "t"}, {"ceil", Bi::Ceil, "f", "f"},
        {"ceil", Bi::CeilT, "t", "t"}, {"round", Bi::Round, "f", "f"}, {"radians", Bi::Radians, "f", "f"},
        {"degrees", Bi::Degrees, "f", "f"}, {"pow", Bi::Pow, "f", "ff"}, {"pow", Bi::PowT, "t", "tf"},
        {"mod", Bi::Mod, "f", "ff"}, {"mod", Bi::ModT, "t", "tf"}, {"min", Bi::MinF, "f", "ff"}, {"min", Bi::MinT, "t", "tt"},
        {"max", Bi::MaxF, "f", "ff"}, {"max", Bi::MaxT, "t", "tt"}, {"clamp", Bi::ClampF, "f", "fff"},
        {"clamp", Bi::ClampT, "t", "ttt"}, {"mix", Bi::MixF, "f", "fff"}, {"mix", Bi::MixTF, "t", "ttf"},
        {"mix", Bi::MixT, "t", "ttt"}, {"step", Bi::Step, "f", "ff"}, {"smoothstep", Bi::SmoothStep, "f", "fff"},
        {"filterstep", Bi::FilterStep, "f", "ff*"}, {"filterstep", Bi::FilterStep2, "f", "fff*"},
        {"xcomp", Bi::Xcomp, "f", "p"}, {"ycomp", Bi::Ycomp, "f", "p"}, {"zcomp", Bi::Zcomp, "f", "p"},
        {"setxcomp", Bi::SetXcomp, "v", "&pf"}, {"setycomp", Bi::SetYcomp, "v", "&pf"},
        {"setzcomp", Bi::SetZcomp, "v", "&pf"}, {"comp", Bi::CompM, "f", "mff"},
        {"setcomp", Bi::SetCompM, "v", "&mfff"},
        {"length", Bi::Length, "f", "p"}, {"distance", Bi::Distance, "f", "pp"},
        {"normalize", Bi::Normalize, "t", "p"}, {"faceforward", Bi::FaceForward, "t", "pp"},
        {"faceforward", Bi::FaceForward3, "t", "ppp"}, {"reflect", Bi::Reflect, "t", "pp"},
        {"refract", Bi::Refract, "t", "ppf"}, {"fresnel", Bi::Fresnel, "v", "ppf&f&f"},
        {"fresnel", Bi::FresnelRT, "v", "ppf&f&f&p&p"},
        {"transform", Bi::Transform, "t", "sp"}, {"transform", Bi::TransformFT, "t", "ssp"},
        {"transform", Bi::TransformM, "t", "mp"}, {"vtransform", Bi::VTransform, "t", "sp"},
        {"vtransform", Bi::VTransformFT, "t", "ssp"}, {"vtransform", Bi::VTransformM, "t", "mp"},
        {"ntransform", Bi::NTransform, "t", "sp"}, {"ntransform", Bi::NTransformFT, "t", "ssp"},
        {"ntransform", Bi::NTransformM, "t", "mp"}, {"transform", Bi::TransformSM, "t", "smp"},
        {"vtransform", Bi::VTransformSM, "t", "smp"}, {"ntransform", Bi::NTransformSM, "t", "smp"},
        {"ctransform", Bi::CTransform, "c", "sc"},
        {"ctransform", Bi::CTransformFT, "c", "ssc"}, {"calculatenormal", Bi::CalculateNormal, "n", "p"},
        {"area", Bi::Area, "f", "p"}, {"depth", Bi::Depth, "f", "p"}, {"ptlined", Bi::PtLined, "f", "ppp"},
        {"rotate", Bi::Rotate3, "t", "pfpp"},
        {"Du", Bi::DuF, "f", "f"}, {"Dv", Bi::DvF, "f", "f"}, {"Du", Bi::DuT, "t", "t"}, {"Dv", Bi::DvT, "t", "t"},
        {"Deriv", Bi::DerivF, "f", "ff"}, {"Deriv", Bi::DerivT, "t", "tf"},
        {"determinant", Bi::Determinant, "f", "m"}, {"translate", Bi::TranslateM, "m", "mp"},
        {"rotate", Bi::RotateM, "m", "mfp"}, {"scale", Bi::ScaleM, "m", "mp"},
        {"concat", Bi::Concat, "s", "s*"}, {"format", Bi::Format, "s", "s*"}, {"printf", Bi::Printf, "v", "s*"},
        {"match", Bi::Match, "f", "ss"},
        {"noise", Bi::NoiseF1, "f", "f"}, {"noise", Bi::NoiseF2, "f", "ff"}, {"noise", Bi::NoiseF3, "f", "p"},
        {"noise", Bi::NoiseF4, "f", "pf"}, {"noise", Bi::NoiseT1, "h", "f"}, {"noise", Bi::NoiseT2, "h", "ff"},
        {"noise", Bi::NoiseT3, "h", "p"}, {"noise", Bi::NoiseT4, "h", "pf"},
        {"pnoise", Bi::PNoiseF1, "f", "ff"}, {"pnoise", Bi::PNoiseF2, "f", "ffff"}, {"pnoise", Bi::PNoiseF3, "f", "pp"},
        {"pnoise", Bi::PNoiseF4, "f", "pfpf"}, {"pnoise", Bi::PNoiseT1, "h", "ff"}, {"pnoise", Bi::PNoiseT2, "h", "ffff"},
        {"pnoise", Bi::PNoiseT3, "h", "pp"}, {"pnoise", Bi::PNoiseT4, "h", "pfpf"},
        {"cellnoise", Bi::CellF1, "f", "f"}, {"cellnoise", Bi::CellF2, "f", "ff"}, {"cellnoise", Bi::CellF3, "f", "p"},
        {"cellnoise", Bi::CellF4, "f", "pf"}, {"cellnoise", Bi::CellT1, "h", "f"}, {"cellnoise", Bi::CellT2, "h", "ff"},
        {"cellnoise", Bi::CellT3, "h", "p"}, {"cellnoise", Bi::CellT4, "h", "pf"},
        {"random", Bi::RandomF, "f", "", true}, {"random", Bi::RandomT, "h", "", true},
        {"ambient", Bi::Ambient, "c", "", true, true}, {"diffuse", Bi::Diffuse, "c", "p", true, true},
        {"specular", Bi::Specular, "c", "ppf", true, true}, {"specularbrdf", Bi::SpecularBrdf, "c", "pppf"},
        {"phong", Bi::Phong, "c", "ppf", true, true},
        {"textureinfo", Bi::TextureInfo, "f", "ss&a"},
        {"lightsource", Bi::LightSource, "f", "s&a", true}, {"surface", Bi::SurfaceMsg, "f", "s&a", true},
        {"displacement", Bi::DisplacementMsg, "f", "s&a", true}, {"atmosphere", Bi::AtmosphereMsg, "f", "s&a", true},
        {"incident", Bi::Incident, "f", "s&a", true}, {"opposite", Bi::Opposite, "f", "s&a", true},
        {"shadername", Bi::ShaderNameOf, "s", "s"},
        {"attribute", Bi::Attribute, "f", "s&a"}, {"option", Bi::Option, "f", "s&a"},
        {"rendererinfo", Bi::RendererInfo, "f", "s&a"},
    };
    return kTable;
}

namespace {

struct Val {
    int reg = -1;
    Ty ty = Ty::Void;
    explicit operator bool() const { return reg >= 0; }
};

/// The user functions of one name in one scope: one, or overloads that
/// differ in their parameters' types (Gritz's noises.h defines fBm for a
/// float and for a point, as PRMan's, Pixie's and Aqsis's compilers take).
using Overloads = std::vector<std::shared_ptr<FuncDef>>;

struct Scope {
    std::map<std::string, int> vars;
    std::map<std::string, Overloads> funcs;
    std::shared_ptr<Scope> parent;
};

/// Whether two functions take the same parameter types (then one defines
/// the other twice).
bool sameParameters(const FuncDef& a, const FuncDef& b) {
    if (a.formals.size() != b.formals.size()) return false;
    for (size_t k = 0; k < a.formals.size(); ++k) {
        const TypeSpec &x = a.formals[k].type, &y = b.formals[k].type;
        if (x.ty != y.ty || (x.arrayLen != 0) != (y.arrayLen != 0)) return false;
    }
    return true;
}

struct GlobalDef {
    const char* name;
    GlobalId id;
    Ty ty;
    bool varying;
};

const GlobalDef kGlobals[] = {
    {"P", gP, Ty::Point, true},     {"N", gN, Ty::Normal, true},    {"Ng", gNg, Ty::Normal, true},
    {"I", gI, Ty::Vector, true},    {"E", gE, Ty::Point, false},    {"s", gS, Ty::Float, true},
    {"t", gT, Ty::Float, true},     {"u", gU, Ty::Float, true},     {"v", gV, Ty::Float, true},
    {"du", gDu, Ty::Float, false},  {"dv", gDv, Ty::Float, false},  {"dPdu", gDPdu, Ty::Vector, true},
    {"dPdv", gDPdv, Ty::Vector, true}, {"Cs", gCs, Ty::Color, true}, {"Os", gOs, Ty::Color, true},
    {"Ci", gCi, Ty::Color, true},   {"Oi", gOi, Ty::Color, true},   {"L", gL, Ty::Vector, true},
    {"Cl", gCl, Ty::Color, true},   {"Ol", gOl, Ty::Color, true},   {"Ps", gPs, Ty::Point, true},
    {"ncomps", gNcomps, Ty::Float, false}, {"time", gTime, Ty::Float, false}, {"alpha", gAlpha, Ty::Float, true},
    {"Ns", gNs, Ty::Normal, true},
    // The shutter's length and P's motion over it (RI Spec 3.2, tables
    // 12.1-12.5): dPdtime is each point's velocity in "current" space,
    // (P at the shutter's close - P at its opening) / dtime, 0 on a still
    // grid (Pixie's rule; the renderer fills ShadingGrid::dPdtime).
    {"dtime", gDtime, Ty::Float, false},  {"dPdtime", gDPdtime, Ty::Vector, true},
};

bool globalVisible(ShaderKind k, GlobalId g) {
    switch (k) {
    case ShaderKind::Surface:
        // Ol: the light's opacity inside illuminance (RI Spec 3.2, table 12.1).
        return g != gPs && g != gAlpha && g != gNs;
    case ShaderKind::Light:
        // Ns: the surface point's normal (PRMan, Pixie and Aqsis give it).
        // I is the surface's incident vector (the surface point's Ps - E),
        // as in Pixie, whose ambient lights read it.
        return g != gCi && g != gOi && g != gCs && g != gOs && g != gAlpha;
    case ShaderKind::Displacement:
        return g != gCi && g != gOi && g != gL && g != gCl && g != gOl && g != gPs && g != gCs && g != gOs &&
               g != gAlpha && g != gNs;
    case ShaderKind::Volume:
        // L, Cl and Ol inside illuminance (RI Spec 3.2 section 13.3): a lit
        // atmosphere marches along I and gathers the lights at each step.
        return g == gP || g == gI || g == gCi || g == gOi || g == gE || g == gNcomps || g == gTime || g == gL ||
               g == gCl || g == gOl || g == gDtime || g == gDPdtime;
    case ShaderKind::Imager:
        // P is the pixel's raster position (x, y, 0). Aqsis's compiler
        // also accepts s and t in imagers (its filmgrain reads them);
        // umbra gives them P's x and y.
        return g == gP || g == gCi || g == gOi || g == gAlpha || g == gS || g == gT || g == gE || g == gNcomps ||
               g == gTime || g == gDtime;
    }
    return true;
}

class Codegen {
public:
    Codegen(CompiledShader& cs, CompileErrors& errs) : m_cs(cs), m_errs(errs) {}

    void run(const Program& prog, const ShaderDef& sh) {
        m_cs.name = sh.name;
        m_cs.kind = sh.kind;
        m_cs.ctls.push_back(CtlCtx{});  // context 0: the shader body, uniform control
        auto globals = std::make_shared<Scope>();
        for (auto& f : prog.functions) defineFunction(*globals, f);
        for (int g = 0; g < gGlobalCount; ++g) m_cs.globalRegs[g] = -1;
        for (const GlobalDef& g : kGlobals) {
            int r = newReg(g.ty, 0, RegKind::Global, g.name, true, g.varying);
            m_cs.regs[r].global = g.id;
            m_cs.globalRegs[g.id] = r;
            if (globalVisible(sh.kind, g.id)) globals->vars[g.name] = r;
        }
        globals->vars["PI"] = constF(kPi);
        m_scope = globals;
        pushScope();
        // m_frameDepth is the index the next pushed mask frame gets. Frame 0
        // holds every point; frame 1 is the shader's own (for `return`).
        emit(Op::LoopBegin, sh.loc);
        m_frameDepth = 2;
        m_funcs.push_back({-1, Ty::Void, 1, 0, int(m_loops.size())});
        for (const VarDecl& p : sh.params) declareParam(p);
        genStmt(*sh.body);
        m_funcs.pop_back();
        emit(Op::LoopEnd, sh.loc);
        popScope();
        // Functions never called are still checked, into a scratch shader.
        for (auto& f : prog.functions)
            if (!m_inlinedOnce.count(f.get())) checkUncalled(f, globals);
    }

private:
    // --- registers and instructions -----------------------------------
    int newReg(Ty ty, int arrayLen, RegKind kind, const std::string& name, bool fixed, bool varying) {
        RegInfo r;
        r.ty = ty == Ty::Bool ? Ty::Float : ty;
        r.arrayLen = arrayLen;
        r.kind = kind;
        r.name = name;
        r.fixed = fixed;
        r.varying = varying;
        m_cs.regs.push_back(r);
        return int(m_cs.regs.size()) - 1;
    }
    int temp(Ty ty) { return newReg(ty == Ty::Tuple ? Ty::Point : ty, 0, RegKind::Temp, "", false, false); }
    int constF(float v) {
        uint32_t bits;
        std::memcpy(&bits, &v, 4);
        auto it = m_constF.find(bits);
        if (it != m_constF.end()) return it->second;
        int r = newReg(Ty::Float, 0, RegKind::Const, "", true, false);
        m_cs.regs[r].constIndex = int(m_cs.consts.size());
        m_cs.consts.push_back(v);
        return m_constF[bits] = r;
    }
    int constS(const std::string& s) {
        auto it = m_constS.find(s);
        if (it != m_constS.end()) return it->second;
        int r = newReg(Ty::String, 0, RegKind::Const, "", true, false);
        m_cs.regs[r].constIndex = int(m_cs.constStrings.size());
        m_cs.constStrings.push_back(s);
        return m_constS[s] = r;
    }
    int constT(Ty ty, float a, float b, float c) {
        int r = newReg(ty, 0, RegKind::Const, "", true, false);
        m_cs.regs[r].constIndex = int(m_cs.consts.size());
        m_cs.consts.insert(m_cs.consts.end(), {a, b, c});
        return r;
    }
    Instr& emit(Op op, SrcLoc loc, int dst = -1, int a = -1, int b = -1, int c = -1) {
        // A string is copied by MovS whichever path copies it (Mov copies
        // floats: a function returning a string crashed the render).
        if (op == Op::Mov && dst >= 0 && m_cs.regs[size_t(dst)].ty == Ty::String) op = Op::MovS;
        Instr in;
        in.op = op;
        in.dst = dst;
        in.a = a;
        in.b = b;
        in.c = c;
        in.loc = loc;
        in.ctl = m_ctl;
        m_cs.code.push_back(in);
        return m_cs.code.back();
    }
    int here() const { return int(m_cs.code.size()); }
    int newCtl(int cond, bool always) {
        CtlCtx c;
        c.parent = m_ctl;
        c.cond = cond;
        c.alwaysVarying = always;
        m_cs.ctls.push_back(c);
        return int(m_cs.ctls.size()) - 1;
    }
    void error(const SrcLoc& loc, const std::string& msg) {
        // Inlined function bodies are checked once per call; report each
        // problem once.
        std::string key = fmt::format("{}:{}:{}:{}", loc.file, loc.line, loc.col, msg);
        if (m_reported.insert(key).second) m_errs.error(loc, msg);
    }

    void pushScope() {
        auto s = std::make_shared<Scope>();
        s->parent = m_scope;
        m_scope = s;
    }
    void popScope() { m_scope = m_scope->parent; }
    int lookupVar(const std::string& name) const {
        for (auto s = m_scope; s; s = s->parent) {
            auto it = s->vars.find(name);
            if (it != s->vars.end()) return it->second;
        }
        return -1;
    }
    /// The innermost scope's functions called `name` (null if none).
    const Overloads* lookupOverloads(const std::string& name, std::shared_ptr<Scope>* where) const {
        for (auto s = m_scope; s; s = s->parent) {
            auto it = s->funcs.find(name);
            if (it != s->funcs.end()) {
                *where = s;
                return &it->second;
            }
        }
        return nullptr;
    }
    std::shared_ptr<FuncDef> lookupFunc(const std::string& name, std::shared_ptr<Scope>* where) const {
        const Overloads* all = lookupOverloads(name, where);
        return all ? all->front() : nullptr;
    }
    void defineFunction(Scope& scope, const std::shared_ptr<FuncDef>& f) {
        Overloads& all = scope.funcs[f->name];
        for (const auto& g : all)
            if (sameParameters(*g, *f)) {
                m_errs.error(f->loc, fmt::format("function '{}' is defined twice", f->name));
                return;
            }
        all.push_back(f);
    }
    /// The type an expression will have, where it can be told without
    /// generating it (Void: not known). Enough to choose between overloads.
    Ty peekType(const Expr& e) const {
        switch (e.kind) {
        case Expr::Num: return Ty::Float;
        case Expr::Str: return Ty::String;
        case Expr::Var: {
            const int r = lookupVar(e.name);
            return r < 0 ? Ty::Void : m_cs.regs[size_t(r)].ty;
        }
        case Expr::Index: return e.kids.empty() ? Ty::Void : peekType(*e.kids[0]);
        case Expr::Cast: return e.castTy;
        case Expr::Tuple: return e.kids.size() == 3 ? Ty::Tuple : e.kids.size() == 16 ? Ty::Matrix : Ty::Void;
        case Expr::Unary: return e.kids.empty() ? Ty::Void : peekType(*e.kids[0]);
        case Expr::Assign: return e.kids.empty() ? Ty::Void : peekType(*e.kids[0]);
        case Expr::Ternary: return e.kids.size() < 2 ? Ty::Void : peekType(*e.kids[1]);
        case Expr::Binary: {
            if (e.kids.size() != 2) return Ty::Void;
            if (e.name == "." || e.name == "==" || e.name == "!=" || e.name == "<" || e.name == ">" || e.name == "<=" ||
                e.name == ">=" || e.name == "&&" || e.name == "||")
                return Ty::Float;
            const Ty a = peekType(*e.kids[0]), b = peekType(*e.kids[1]);
            if (a == Ty::Void || b == Ty::Void) return Ty::Void;
            return isTriple(a) ? a : b;
        }
        case Expr::Call: {
            std::shared_ptr<Scope> where;
            if (const Overloads* user = lookupOverloads(e.name, &where))
                return user->size() == 1 ? user->front()->ret.ty : Ty::Void;
            // A built-in whose every form returns one type.
            Ty known = Ty::Void;
            bool any = false;
            for (const BuiltinSig& sig : builtinTable()) {
                if (e.name != sig.name) continue;
                const Ty t = sig.ret[0] == 'f' ? Ty::Float : sig.ret[0] == 'c' ? Ty::Color : sig.ret[0] == 'p' ? Ty::Point
                             : sig.ret[0] == 'v' ? Ty::Void : sig.ret[0] == 's' ? Ty::String : sig.ret[0] == 'm' ? Ty::Matrix
                                                                                                : Ty::Tuple;
                if (any && t != known) return Ty::Void;
                known = t, any = true;
            }
            return known;
        }
        }
        return Ty::Void;
    }
    /// Of `all` (same name, different parameters), the one the arguments
    /// of `e` fit best: same types first, then a float widened to a triple
    /// or one triple taken as another; null when none fits.
    std::shared_ptr<FuncDef> chooseOverload(const Expr& e, const Overloads& all) const {
        if (all.size() == 1) return all.front();
        std::shared_ptr<FuncDef> best;
        int bestCost = 1 << 30;
        for (const auto& f : all) {
            if (f->formals.size() != e.kids.size()) continue;
            int cost = 0;
            for (size_t k = 0; k < e.kids.size() && cost >= 0; ++k) {
                const Ty want = f->formals[k].type.ty, have = peekType(*e.kids[k]);
                if (have == Ty::Void || have == want) continue;
                if (isTriple(want) && (isTriple(have) || have == Ty::Tuple)) cost += 1;
                else if (isTriple(want) && have == Ty::Float && !f->formals[k].type.output) cost += 2;
                else cost = -1;
            }
            if (cost >= 0 && cost < bestCost) bestCost = cost, best = f;
        }
        return best;
    }

    // --- declarations --------------------------------------------------
    void declareParam(const VarDecl& p) {
        if (p.type.ty == Ty::Void) {
            error(p.loc, "a parameter cannot be void");
            return;
        }
        bool varying = p.type.detail == Detail::Varying;
        if (p.type.ty == Ty::String && varying) error(p.loc, "varying strings are not supported");
        int arr = std::max(0, p.type.arrayLen);
        int r = newReg(p.type.ty, arr, RegKind::Param, p.name, true, varying);
        m_cs.regs[r].param = int(m_cs.params.size());
        m_cs.regs[r].loc = p.loc;
        ShaderParamInfo info;
        info.name = p.name;
        info.type = valueTypeOf(p.type.ty);
        info.varying = varying;
        info.output = p.type.output;
        info.arraySize = arr;
        info.constantDefault = constantDefault(p, &info);
        if (m_scope->vars.count(p.name)) error(p.loc, fmt::format("parameter '{}' is declared twice", p.name));
        m_scope->vars[p.name] = r;
        m_cs.params.push_back(info);
        m_cs.paramRegs.push_back(r);
        Instr& init = emit(Op::ParamInit, p.loc, r);
        int at = here() - 1;
        initVar(r, p);
        m_cs.code[at].target = here();
        (void)init;
    }


    /// Evaluates a literal default (numbers, strings, tuples, casts of them
    /// without a space) for ShaderParamInfo.
    static bool literal(const Expr& e, std::vector<float>* f, std::vector<std::string>* s) {
        switch (e.kind) {
        case Expr::Num: f->push_back(float(e.num)); return true;
        case Expr::Str: s->push_back(e.name); return true;
        case Expr::Unary:
            if (e.name == "-" && e.kids[0]->kind == Expr::Num) {
                f->push_back(-float(e.kids[0]->num));
                return true;
            }
            return false;
        case Expr::Tuple:
            for (auto& k : e.kids)
                if (!literal(*k, f, s)) return false;
            return true;
        case Expr::Cast:
            if (!e.name.empty()) return false;
            return literal(*e.kids[0], f, s);
        default: return false;
        }
    }
    static bool constantDefault(const VarDecl& p, ShaderParamInfo* info) {
        std::vector<float> f;
        std::vector<std::string> s;
        if (p.hasArrayInit) {
            for (auto& e : p.arrayInit)
                if (!literal(*e, &f, &s)) return false;
        } else if (!p.init || !literal(*p.init, &f, &s)) {
            return false;
        }
        int per = tyFloats(p.type.ty);
        int count = std::max(1, p.type.arrayLen);
        if (p.type.ty == Ty::String) {
            if (int(s.size()) != count) return false;
        } else if (int(f.size()) == count) {
            if (per == 3 || per == 16) {  // promote each float
                std::vector<float> g;
                for (float x : f)
                    for (int k = 0; k < per; ++k) g.push_back(per == 16 ? ((k % 5 == 0) ? x : 0.f) : x);
                f = g;
            }
        } else if (int(f.size()) != count * per) {
            return false;
        }
        info->defaultFloats = f;
        info->defaultStrings = s;
        return true;
    }

    void initVar(int r, const VarDecl& d) {
        const RegInfo ri = m_cs.regs[r];
        if (d.hasArrayInit) {
            if (ri.arrayLen == 0) {
                error(d.loc, fmt::format("'{}' is not an array but has an array initialiser", d.name));
                return;
            }
            if (int(d.arrayInit.size()) != ri.arrayLen) {
                error(d.loc, fmt::format("array '{}' has {} elements but {} initialisers", d.name, ri.arrayLen, d.arrayInit.size()));
            }
            for (size_t k = 0; k < d.arrayInit.size() && int(k) < ri.arrayLen; ++k) {
                Val v = coerce(gen(*d.arrayInit[k], ri.ty), ri.ty, d.arrayInit[k]->loc);
                if (v) emit(Op::StoreElem, d.loc, r, constF(float(k)), v.reg);
            }
            return;
        }
        if (!d.init) return;
        if (ri.arrayLen > 0) {
            Val v = gen(*d.init, ri.ty);
            if (v && m_cs.regs[v.reg].arrayLen == ri.arrayLen && m_cs.regs[v.reg].ty == ri.ty)
                emit(Op::MovArr, d.loc, r, v.reg);
            else if (v)
                error(d.init->loc, fmt::format("cannot initialise array '{}' from {}", d.name, describe(v)));
            return;
        }
        assignTo(r, ri.ty, *d.init, d.init->loc);
    }

    std::string describe(Val v) const {
        if (!v) return "an invalid value";
        const RegInfo& r = m_cs.regs[v.reg];
        if (r.arrayLen > 0) return fmt::format("{}[{}]", tyName(v.ty), r.arrayLen);
        return tyName(v.ty);
    }

    void declareLocal(const VarDecl& d) {
        if (d.type.ty == Ty::Void) {
            error(d.loc, "a variable cannot be void");
            return;
        }
        if (d.type.arrayLen < 0) {
            error(d.loc, fmt::format("array '{}' needs a length", d.name));
            return;
        }
        if (m_scope->vars.count(d.name)) {
            error(d.loc, fmt::format("variable '{}' is already declared in this scope", d.name));
            return;
        }
        bool fixed = d.type.detail != Detail::Default || d.type.ty == Ty::String;
        int r = newReg(d.type.ty, d.type.arrayLen, RegKind::Local, d.name, fixed, d.type.detail == Detail::Varying);
        m_cs.regs[r].loc = d.loc;
        if (d.type.ty == Ty::String && d.type.detail == Detail::Varying) error(d.loc, "varying strings are not supported");
        initVar(r, d);
        m_scope->vars[d.name] = r;
    }

    // --- statements ----------------------------------------------------
    void genStmt(const Stmt& s) {
        if (m_errs.count() > 50) return;
        switch (s.kind) {
        case Stmt::Empty: break;
        case Stmt::Block:
            pushScope();
            for (auto& b : s.body) genStmt(*b);
            popScope();
            break;
        case Stmt::ExprS: genEffect(*s.exprs[0]); break;
        case Stmt::Decl:
            for (auto& d : s.decls) declareLocal(d);
            break;
        case Stmt::Extern:
            for (auto& d : s.decls)
                if (lookupVar(d.name) < 0) error(d.loc, fmt::format("extern variable '{}' is not defined in an enclosing scope", d.name));
            break;
        case Stmt::Func:
            if (s.func) defineFunction(*m_scope, s.func);
            break;
        case Stmt::If: genIf(s); break;
        case Stmt::While:
        case Stmt::For: genLoop(s); break;
        case Stmt::Break:
        case Stmt::Continue: genBreak(s); break;
        case Stmt::Return: genReturn(s); break;
        case Stmt::Illuminance: genIlluminance(s); break;
        case Stmt::Illuminate:
        case Stmt::Solar: genIlluminate(s); break;
        }
    }

    int condition(const Expr& e) {
        Val v = gen(e, Ty::Float);
        if (!v) return constF(0);
        if (v.ty == Ty::Float) {
            int t = temp(Ty::Float);
            emit(Op::NeF, e.loc, t, v.reg, constF(0));
            return t;
        }
        if (v.ty != Ty::Bool) {
            error(e.loc, fmt::format("condition must be a boolean or float, not {}", tyName(v.ty)));
            return constF(0);
        }
        if (m_cs.regs[v.reg].kind != RegKind::Temp) {  // keep the condition safe from the branches
            int t = temp(Ty::Float);
            emit(Op::Mov, e.loc, t, v.reg);
            return t;
        }
        return v.reg;
    }

    void genIf(const Stmt& s) {
        int cond = condition(*s.exprs[0]);
        int saved = m_ctl;
        m_ctl = newCtl(cond, false);
        int ifAt = here();
        emit(Op::IfBegin, s.loc, -1, cond);
        ++m_frameDepth;
        genStmt(*s.body[0]);
        if (s.body.size() > 1) {
            int elseAt = here();
            m_cs.code[ifAt].target = elseAt;
            emit(Op::Else, s.loc, -1, cond);
            genStmt(*s.body[1]);
            m_cs.code[elseAt].target = here();
        } else {
            m_cs.code[ifAt].target = here();
        }
        emit(Op::EndIf, s.loc);
        --m_frameDepth;
        m_ctl = saved;
    }

    void genLoop(const Stmt& s) {
        bool isFor = s.kind == Stmt::For;
        if (isFor && s.exprs[0]) genEffect(*s.exprs[0]);
        int saved = m_ctl;
        emit(Op::LoopBegin, s.loc);
        int lDepth = m_frameDepth++;
        m_ctl = newCtl(-1, false);
        int ctl = m_ctl;
        int top = here();
        const Expr* condE = isFor ? s.exprs[1].get() : s.exprs[0].get();
        int cond = condE ? condition(*condE) : constF(1);
        m_cs.ctls[ctl].cond = cond;
        int condAt = here();
        emit(Op::LoopCond, s.loc, -1, cond);
        genLoopRest(s, lDepth, ctl, saved, top, condAt, isFor ? s.exprs[2].get() : nullptr);
    }

    /// The rest of a loop (while, for, illuminance) after the instruction at
    /// `exitAt` that leaves it: the body, with the loop on the break/continue
    /// stack, then `step` (may be null), back to `top`; `exitAt` jumps past
    /// the end.
    void genLoopRest(const Stmt& s, int lDepth, int ctl, int saved, int top, int exitAt, const Expr* step) {
        ++m_frameDepth;
        m_loops.push_back({lDepth, ctl});
        genStmt(*s.body[0]);
        m_loops.pop_back();
        emit(Op::LoopCont, s.loc);
        --m_frameDepth;
        if (step) genEffect(*step);
        emit(Op::Jump, s.loc).target = top;
        m_cs.code[exitAt].target = here();
        m_ctl = saved;
        emit(Op::LoopEnd, s.loc);
        --m_frameDepth;
    }

    void genBreak(const Stmt& s) {
        int base = m_funcs.empty() ? 0 : m_funcs.back().loopsBase;
        int available = int(m_loops.size()) - base;
        if (s.level > available) {
            error(s.loc, available == 0 ? fmt::format("'{}' outside a loop", s.kind == Stmt::Break ? "break" : "continue")
                                        : fmt::format("'{} {}' but only {} enclosing loop(s)", s.kind == Stmt::Break ? "break" : "continue", s.level, available));
            return;
        }
        const LoopInfo& loop = m_loops[m_loops.size() - size_t(s.level)];
        m_cs.ctls[loop.ctl].breakers.push_back(m_ctl);
        emit(Op::Break, s.loc, -1, -1, -1, s.kind == Stmt::Break ? loop.lDepth : loop.lDepth + 1);
    }

    void genReturn(const Stmt& s) {
        if (m_funcs.empty()) return;
        // A copy: the value may be a call, whose inlining pushes onto m_funcs
        // and can move its elements.
        const FuncInfo f = m_funcs.back();
        if (!s.exprs.empty()) {
            if (f.retTy == Ty::Void) {
                error(s.loc, "a void function or shader cannot return a value");
            } else {
                Val v = coerce(gen(*s.exprs[0], f.retTy), f.retTy, s.exprs[0]->loc);
                if (v) emit(Op::Mov, s.loc, f.result, v.reg);
            }
        } else if (f.retTy != Ty::Void) {
            error(s.loc, fmt::format("function must return a {}", tyName(f.retTy)));
        }
        if (f.frameDepth >= 0) {
            m_cs.ctls[f.ctl].breakers.push_back(m_ctl);
            emit(Op::Break, s.loc, -1, -1, -1, f.frameDepth);
        }
    }

    void genIlluminance(const Stmt& s) {
        if (m_cs.kind != ShaderKind::Surface && m_cs.kind != ShaderKind::Volume) {
            error(s.loc, "illuminance is only allowed in surface and volume shaders");
            return;
        }
        m_cs.usesLights = true;
        size_t k = 0;
        int category = -1;
        std::vector<Val> a;
        if (!s.exprs.empty() && s.exprs[0]->kind == Expr::Str) category = constS(s.exprs[k++]->name);
        else if (!s.exprs.empty()) {
            Val first = gen(*s.exprs[0], Ty::Point);
            if (first.ty == Ty::String) {
                category = first.reg;
                k = 1;
            } else {
                a.push_back(first);
                k = 1;
            }
        }
        for (; k < s.exprs.size(); ++k) a.push_back(gen(*s.exprs[k], Ty::Vector));
        if (a.size() != 1 && a.size() != 3) {
            error(s.loc, "illuminance expects ([category,] position [, axis, angle])");
            return;
        }
        Val p = coerce(a[0], Ty::Point, s.loc);
        Val axis, angle;
        if (a.size() == 3) {
            axis = coerce(a[1], Ty::Vector, s.loc);
            angle = coerce(a[2], Ty::Float, s.loc);
        }
        if (!p || (a.size() == 3 && (!axis || !angle))) return;
        Instr& b = emit(Op::IllumBegin, s.loc, -1, p.reg, axis.reg, angle.reg);
        b.argBase = int(m_cs.args.size());
        b.nargs = 1;
        m_cs.args.push_back(category);
        int lDepth = m_frameDepth++;
        int saved = m_ctl;
        m_ctl = newCtl(-1, true);
        int ctl = m_ctl;
        int top = here();
        emit(Op::IllumNext, s.loc);
        genLoopRest(s, lDepth, ctl, saved, top, top, nullptr);
    }

    void genIlluminate(const Stmt& s) {
        bool solar = s.kind == Stmt::Solar;
        if (m_cs.kind != ShaderKind::Light) {
            error(s.loc, fmt::format("{} is only allowed in light shaders", solar ? "solar" : "illuminate"));
            return;
        }
        m_hasIlluminate = true;
        (solar ? m_hasSolar : m_hasIlluminateAt) = true;
        size_t n = s.exprs.size();
        bool ok = solar ? (n == 0 || n == 2) : (n == 1 || n == 3);
        if (!ok) {
            error(s.loc, solar ? "solar expects () or (axis, angle)" : "illuminate expects (position [, axis, angle])");
            return;
        }
        Val a, b, c;
        if (solar) {
            if (n == 2) {
                a = coerce(gen(*s.exprs[0], Ty::Vector), Ty::Vector, s.exprs[0]->loc);
                b = coerce(gen(*s.exprs[1], Ty::Float), Ty::Float, s.exprs[1]->loc);
            }
        } else {
            a = coerce(gen(*s.exprs[0], Ty::Point), Ty::Point, s.exprs[0]->loc);
            if (n == 3) {
                b = coerce(gen(*s.exprs[1], Ty::Vector), Ty::Vector, s.exprs[1]->loc);
                c = coerce(gen(*s.exprs[2], Ty::Float), Ty::Float, s.exprs[2]->loc);
            }
        }
        int at = here();
        emit(solar ? Op::Solar : Op::Illuminate, s.loc, -1, a.reg, b.reg, c.reg);
        ++m_frameDepth;
        int saved = m_ctl;
        m_ctl = newCtl(-1, true);
        genStmt(*s.body[0]);
        m_ctl = saved;
        m_cs.code[at].target = here();
        emit(Op::EndIf, s.loc);
        --m_frameDepth;
    }

public:
    bool hasIlluminate() const { return m_hasIlluminate; }
    bool hasSolar() const { return m_hasSolar; }
    bool hasIlluminateAt() const { return m_hasIlluminateAt; }

private:
    // --- expressions ---------------------------------------------------

    /// Converts `v` to type `to` with RenderMan's implicit conversions.
    Val coerce(Val v, Ty to, SrcLoc loc) {
        if (!v) return v;
        if (v.ty == to) return v;
        const RegInfo& r = m_cs.regs[v.reg];
        if (r.arrayLen > 0) {
            error(loc, fmt::format("cannot use array {} as {}", describe(v), tyName(to)));
            return {};
        }
        if (to == Ty::Float && v.ty == Ty::Bool) return {v.reg, Ty::Float};
        if (isTriple(to) && (v.ty == Ty::Tuple || (isSpatial(v.ty) && isSpatial(to)))) return {v.reg, to};
        if (v.ty == Ty::Float && isTriple(to)) {
            if (r.kind == RegKind::Const) {
                float x = m_cs.consts[r.constIndex];
                return {constT(to, x, x, x), to};
            }
            int t = temp(to);
            emit(Op::Promote3, loc, t, v.reg);
            return {t, to};
        }
        if (v.ty == Ty::Float && to == Ty::Matrix) {
            int t = temp(to);
            emit(Op::PromoteM, loc, t, v.reg);
            return {t, to};
        }
        error(loc, fmt::format("cannot convert {} to {}", tyName(v.ty), tyName(to)));
        return {};
    }

    /// Generates the value stored into register `dst`; while it is
    /// generated, m_uniformDest says whether `dst` is declared uniform.
    Val genStored(int dst, const Expr& e, Ty hint) {
        const RegInfo& d = m_cs.regs[dst];
        bool saved = m_uniformDest;
        m_uniformDest = d.fixed && !d.varying && d.kind != RegKind::Temp && d.kind != RegKind::Const;
        Val v = gen(e, hint);
        m_uniformDest = saved;
        return v;
    }

    /// Emits `dst = expr` for a scalar destination register.
    void assignTo(int dst, Ty dstTy, const Expr& e, SrcLoc loc) {
        int before = here();
        Val v = coerce(genStored(dst, e, dstTy), dstTy, loc);
        if (!v) return;
        if (m_cs.regs[v.reg].arrayLen > 0) {
            error(loc, "cannot assign an array to a scalar");
            return;
        }
        // Write straight into the destination when the value is a temporary
        // just computed by a simple point-wise instruction.
        if (here() > before && m_cs.code.back().dst == v.reg && m_cs.regs[v.reg].kind == RegKind::Temp &&
            retargetable(m_cs.code.back().op) && tyFloats(m_cs.regs[v.reg].ty) == tyFloats(dstTy)) {
            m_cs.code.back().dst = dst;
            m_cs.code.back().loc = loc;  // errors about the store point at the assignment
            return;
        }
        if (dstTy == Ty::String) emit(Op::MovS, loc, dst, v.reg);
        else emit(Op::Mov, loc, dst, v.reg);
    }
    static bool retargetable(Op op) {
        switch (op) {
        case Op::AddF: case Op::SubF: case Op::MulF: case Op::DivF: case Op::NegF: case Op::Add3: case Op::Sub3:
        case Op::Mul3: case Op::Div3: case Op::Neg3: case Op::Mul3F: case Op::Div3F: case Op::Dot: case Op::Cross:
        case Op::Make3: case Op::Promote3: case Op::Select: case Op::LoadElem: case Op::Comp:
            return true;
        default: return false;
        }
    }

    /// Generates an expression evaluated for its effects (a statement, a for
    /// loop's init or step): the one place where a void call may stand.
    void genEffect(const Expr& e) {
        const Expr* saved = m_effectExpr;
        m_effectExpr = &e;
        gen(e, Ty::Void);
        m_effectExpr = saved;
    }

    /// True when `name` calls a void user function, or a built-in whose
    /// every form is void.
    bool callIsVoid(const std::string& name) const {
        std::shared_ptr<Scope> where;
        if (auto f = lookupFunc(name, &where)) return f->ret.ty == Ty::Void;
        bool any = false;
        for (const BuiltinSig& sig : builtinTable()) {
            if (name != sig.name) continue;
            if (sig.ret[0] != 'v') return false;
            any = true;
        }
        return any;
    }

    Val gen(const Expr& e, Ty hint) {
        if (++m_exprDepth > 1200) {
            error(e.loc, "expression nested too deeply");
            --m_exprDepth;
            return {};
        }
        Val v = genInner(e, hint);
        --m_exprDepth;
        return v;
    }

    Val genInner(const Expr& e, Ty hint) {
        switch (e.kind) {
        case Expr::Num: return {constF(float(e.num)), Ty::Float};
        case Expr::Str: return {constS(e.name), Ty::String};
        case Expr::Var: {
            int r = lookupVar(e.name);
            if (r < 0) {
                error(e.loc, fmt::format("undefined variable '{}'", e.name));
                return {};
            }
            return {r, m_cs.regs[r].ty};
        }
        case Expr::Index: return genIndex(e);
        case Expr::Call:
            if (&e != m_effectExpr && callIsVoid(e.name)) {
                error(e.loc, fmt::format("'{}' returns no value (it is void) but its value is used", e.name));
                return {};
            }
            return genCall(e, hint);
        case Expr::Unary: return genUnary(e);
        case Expr::Binary: return genBinary(e);
        case Expr::Assign: return genAssign(e);
        case Expr::Ternary: return genTernary(e, hint);
        case Expr::Cast: return genCast(e);
        case Expr::Tuple: return genTuple(e, isTriple(hint) ? hint : Ty::Tuple);
        }
        return {};
    }

    Val genTuple(const Expr& e, Ty ty) {
        if (e.kids.size() == 16) {
            int t = temp(Ty::Matrix);
            std::vector<int> regs;
            for (auto& k : e.kids) {
                Val v = coerce(gen(*k, Ty::Float), Ty::Float, k->loc);
                if (!v) return {};
                regs.push_back(v.reg);
            }
            Instr& mk = emit(Op::MakeM, e.loc, t);
            mk.argBase = int(m_cs.args.size());
            mk.nargs = 16;
            m_cs.args.insert(m_cs.args.end(), regs.begin(), regs.end());
            return {t, Ty::Matrix};
        }
        if (e.kids.size() != 3) {
            error(e.loc, "a tuple needs 3 values");
            return {};
        }
        int r[3];
        bool allConst = true;
        float cv[3];
        for (int k = 0; k < 3; ++k) {
            Val v = coerce(gen(*e.kids[k], Ty::Float), Ty::Float, e.kids[k]->loc);
            if (!v) return {};
            r[k] = v.reg;
            if (m_cs.regs[v.reg].kind == RegKind::Const) cv[k] = m_cs.consts[m_cs.regs[v.reg].constIndex];
            else allConst = false;
        }
        if (allConst) return {constT(ty == Ty::Tuple ? Ty::Point : ty, cv[0], cv[1], cv[2]), ty};
        int t = temp(ty);
        emit(Op::Make3, e.loc, t, r[0], r[1], r[2]);
        return {t, ty};
    }

    Val genCast(const Expr& e) {
        Ty to = e.castTy;
        const Expr& k = *e.kids[0];
        Val v;
        if (k.kind == Expr::Tuple) v = genTuple(k, isTriple(to) ? to : Ty::Tuple);
        else v = gen(k, to);
        if (!v) return v;
        if (to == Ty::Matrix && v.ty == Ty::Matrix && e.name.empty()) return v;
        if (isTriple(to) && isTriple(v.ty) && m_cs.regs[v.reg].arrayLen == 0) v.ty = to;  // explicit casts between triples
        v = coerce(v, to, e.loc);
        if (!v || e.name.empty()) return v;
        int space = constS(e.name);
        if (to == Ty::Color) return callBuiltin(Bi::ColorFromSpace, Ty::Color, {space, v.reg}, e.loc);
        if (to == Ty::Point) return callBuiltin(Bi::TransformFT, to, {space, constS("current"), v.reg}, e.loc);
        if (to == Ty::Vector) return callBuiltin(Bi::VTransformFT, to, {space, constS("current"), v.reg}, e.loc);
        if (to == Ty::Normal) return callBuiltin(Bi::NTransformFT, to, {space, constS("current"), v.reg}, e.loc);
        if (to == Ty::Matrix) return callBuiltin(Bi::SpaceMatrix, to, {space, v.reg}, e.loc);
        error(e.loc, fmt::format("a space name is not allowed in a {} cast", tyName(to)));
        return {};
    }

    Val callBuiltin(Bi id, Ty ret, std::vector<int> args, SrcLoc loc, uint32_t outMask = 0) {
        int t = ret == Ty::Void ? -1 : temp(ret);
        Instr& in = emit(Op::Call, loc, t);
        in.sub = int16_t(id);
        in.argBase = int(m_cs.args.size());
        in.nargs = int(args.size());
        in.outMask = outMask;
        m_cs.args.insert(m_cs.args.end(), args.begin(), args.end());
        return {t, ret};
    }

    Val genIndex(const Expr& e) {
        Val base = gen(*e.kids[0], Ty::Void);
        if (!base) return {};
        Val idx = coerce(gen(*e.kids[1], Ty::Float), Ty::Float, e.kids[1]->loc);
        if (!idx) return {};
        // By value: temp() below adds a register and can move m_cs.regs.
        const Ty elemTy = m_cs.regs[base.reg].ty;
        if (m_cs.regs[base.reg].arrayLen > 0) {
            int t = temp(elemTy);
            emit(Op::LoadElem, e.loc, t, base.reg, idx.reg);
            return {t, elemTy};
        }
        if (isTriple(base.ty)) {
            int t = temp(Ty::Float);
            emit(Op::Comp, e.loc, t, base.reg, idx.reg);
            return {t, Ty::Float};
        }
        error(e.loc, fmt::format("cannot index a {}", tyName(base.ty)));
        return {};
    }

    Val genUnary(const Expr& e) {
        Val v = gen(*e.kids[0], Ty::Void);
        if (!v) return {};
        if (e.name == "!") {
            if (v.ty == Ty::Float) {
                int t = temp(Ty::Float);
                emit(Op::EqF, e.loc, t, v.reg, constF(0));
                return {t, Ty::Bool};
            }
            if (v.ty != Ty::Bool) {
                error(e.loc, fmt::format("'!' needs a boolean, not {}", tyName(v.ty)));
                return {};
            }
            int t = temp(Ty::Float);
            emit(Op::Not, e.loc, t, v.reg);
            return {t, Ty::Bool};
        }
        if (m_cs.regs[v.reg].arrayLen > 0) {
            error(e.loc, "cannot negate an array");
            return {};
        }
        if (v.ty == Ty::Float) {
            const RegInfo& r = m_cs.regs[v.reg];
            if (r.kind == RegKind::Const) return {constF(-m_cs.consts[r.constIndex]), Ty::Float};
            int t = temp(Ty::Float);
            emit(Op::NegF, e.loc, t, v.reg);
            return {t, Ty::Float};
        }
        if (isTriple(v.ty)) {
            int t = temp(v.ty);
            emit(Op::Neg3, e.loc, t, v.reg);
            return {t, v.ty};
        }
        error(e.loc, fmt::format("cannot negate a {}", tyName(v.ty)));
        return {};
    }

    static Ty tripleResult(const std::string& op, Ty a, Ty b) {
        if (a == Ty::Tuple) return b == Ty::Tuple ? Ty::Point : b;
        if (b == Ty::Tuple) return a;
        if (op == "-" && a == Ty::Point && b == Ty::Point) return Ty::Vector;
        if (a == Ty::Point || b == Ty::Point) return Ty::Point;
        return a;
    }

    Val binaryOp(const std::string& op, Val a, Val b, SrcLoc loc) {
        if (!a || !b) return {};
        if (m_cs.regs[a.reg].arrayLen > 0 || m_cs.regs[b.reg].arrayLen > 0) {
            error(loc, fmt::format("operator '{}' cannot be applied to arrays", op));
            return {};
        }
        auto bad = [&]() -> Val {
            error(loc, fmt::format("operator '{}' cannot be applied to {} and {}", op, tyName(a.ty), tyName(b.ty)));
            return {};
        };
        if (a.ty == Ty::Bool && (op == "&&" || op == "||")) a.ty = Ty::Bool;
        if (op == "&&" || op == "||") {
            auto asBool = [&](Val v) -> Val {
                if (v.ty == Ty::Bool) return v;
                if (v.ty != Ty::Float) return {};
                int t = temp(Ty::Float);
                emit(Op::NeF, loc, t, v.reg, constF(0));
                return {t, Ty::Bool};
            };
            Val x = asBool(a), y = asBool(b);
            if (!x || !y) return bad();
            int t = temp(Ty::Float);
            emit(op == "&&" ? Op::And : Op::Or, loc, t, x.reg, y.reg);
            return {t, Ty::Bool};
        }
        if (a.ty == Ty::Bool) a.ty = Ty::Float;
        if (b.ty == Ty::Bool) b.ty = Ty::Float;
        bool cmp = op == "<" || op == "<=" || op == ">" || op == ">=";
        bool eq = op == "==" || op == "!=";
        if (cmp) {
            if (a.ty != Ty::Float || b.ty != Ty::Float) return bad();
            int t = temp(Ty::Float);
            Op o = op == "<" ? Op::LtF : op == "<=" ? Op::LeF : op == ">" ? Op::GtF : Op::GeF;
            emit(o, loc, t, a.reg, b.reg);
            return {t, Ty::Bool};
        }
        if (eq) {
            bool ne = op == "!=";
            int t = temp(Ty::Float);
            if (a.ty == Ty::Float && b.ty == Ty::Float) emit(ne ? Op::NeF : Op::EqF, loc, t, a.reg, b.reg);
            else if (a.ty == Ty::String && b.ty == Ty::String) emit(ne ? Op::NeS : Op::EqS, loc, t, a.reg, b.reg);
            else if (a.ty == Ty::Matrix || b.ty == Ty::Matrix) {
                Val x = coerce(a, Ty::Matrix, loc), y = coerce(b, Ty::Matrix, loc);
                if (!x || !y) return {};
                emit(ne ? Op::NeM : Op::EqM, loc, t, x.reg, y.reg);
            } else if (isTriple(a.ty) || isTriple(b.ty)) {
                Ty tt = isTriple(a.ty) ? a.ty : b.ty;
                if ((a.ty == Ty::Color) != (b.ty == Ty::Color) && a.ty != Ty::Float && b.ty != Ty::Float && a.ty != Ty::Tuple && b.ty != Ty::Tuple) return bad();
                Val x = coerce(a, tt, loc), y = coerce(b, tt, loc);
                if (!x || !y) return {};
                emit(ne ? Op::Ne3 : Op::Eq3, loc, t, x.reg, y.reg);
            } else {
                return bad();
            }
            return {t, Ty::Bool};
        }
        if (a.ty == Ty::String || b.ty == Ty::String || a.ty == Ty::Void || b.ty == Ty::Void) return bad();
        if ((op == "." || op == "^") && (isTriple(a.ty) != isTriple(b.ty)) && (a.ty == Ty::Float || b.ty == Ty::Float)) {
            // RI Spec 3.2 section 13.1: a float with a triple is promoted by
            // duplicating it (v ^ 2, v . 0.1; both peers take them).
            const Ty tt = isTriple(a.ty) ? a.ty : b.ty;
            a = coerce(a, tt, loc);
            b = coerce(b, tt, loc);
            if (!a || !b) return {};
        }
        if (op == ".") {
            if (!isTriple(a.ty) || !isTriple(b.ty)) return bad();
            if ((a.ty == Ty::Color) != (b.ty == Ty::Color) && a.ty != Ty::Tuple && b.ty != Ty::Tuple) return bad();
            int t = temp(Ty::Float);
            emit(Op::Dot, loc, t, a.reg, b.reg);
            return {t, Ty::Float};
        }
        if (op == "^") {
            if (!isTriple(a.ty) || !isTriple(b.ty)) return bad();
            if ((a.ty == Ty::Color) != (b.ty == Ty::Color) && a.ty != Ty::Tuple && b.ty != Ty::Tuple) return bad();
            Ty rt = (a.ty == Ty::Color || b.ty == Ty::Color) ? Ty::Color : Ty::Vector;
            int t = temp(rt);
            emit(Op::Cross, loc, t, a.reg, b.reg);
            return {t, rt};
        }
        if (a.ty == Ty::Matrix || b.ty == Ty::Matrix) {
            if (op != "*" && op != "/") return bad();
            Val x = coerce(a, Ty::Matrix, loc), y = coerce(b, Ty::Matrix, loc);
            if (!x || !y) return {};
            int t = temp(Ty::Matrix);
            emit(op == "*" ? Op::MulM : Op::DivM, loc, t, x.reg, y.reg);
            return {t, Ty::Matrix};
        }
        if (a.ty == Ty::Float && b.ty == Ty::Float) {
            const RegInfo& ra = m_cs.regs[a.reg];
            const RegInfo& rb = m_cs.regs[b.reg];
            if (ra.kind == RegKind::Const && rb.kind == RegKind::Const) {  // constant folding
                float x = m_cs.consts[ra.constIndex], y = m_cs.consts[rb.constIndex];
                float r = op == "+" ? x + y : op == "-" ? x - y : op == "*" ? x * y : (y == 0 ? 0.f : x / y);
                return {constF(r), Ty::Float};
            }
            int t = temp(Ty::Float);
            Op o = op == "+" ? Op::AddF : op == "-" ? Op::SubF : op == "*" ? Op::MulF : Op::DivF;
            emit(o, loc, t, a.reg, b.reg);
            return {t, Ty::Float};
        }
        // At least one triple.
        if (isTriple(a.ty) && isTriple(b.ty) && (a.ty == Ty::Color) != (b.ty == Ty::Color) && a.ty != Ty::Tuple && b.ty != Ty::Tuple)
            return bad();
        if (op == "*" && (a.ty == Ty::Float || b.ty == Ty::Float)) {
            Val tr = a.ty == Ty::Float ? b : a, f = a.ty == Ty::Float ? a : b;
            Ty rt = tr.ty == Ty::Tuple ? Ty::Point : tr.ty;
            int t = temp(rt);
            emit(Op::Mul3F, loc, t, tr.reg, f.reg);
            return {t, rt};
        }
        if (op == "/" && b.ty == Ty::Float) {
            Ty rt = a.ty == Ty::Tuple ? Ty::Point : a.ty;
            int t = temp(rt);
            emit(Op::Div3F, loc, t, a.reg, b.reg);
            return {t, rt};
        }
        Ty rt = tripleResult(op, a.ty == Ty::Float ? b.ty : a.ty, b.ty == Ty::Float ? a.ty : b.ty);
        Val x = coerce(a, a.ty == Ty::Float ? rt : a.ty, loc), y = coerce(b, b.ty == Ty::Float ? rt : b.ty, loc);
        if (!x || !y) return {};
        int t = temp(rt);
        Op o = op == "+" ? Op::Add3 : op == "-" ? Op::Sub3 : op == "*" ? Op::Mul3 : Op::Div3;
        emit(o, loc, t, x.reg, y.reg);
        return {t, rt};
    }

    Val genBinary(const Expr& e) {
        Val a = gen(*e.kids[0], Ty::Void);
        Val b = gen(*e.kids[1], isTriple(a.ty) ? a.ty : Ty::Void);
        return binaryOp(e.name, a, b, e.loc);
    }

    Val genTernary(const Expr& e, Ty hint) {
        int cond = condition(*e.kids[0]);
        Val a = gen(*e.kids[1], hint), b = gen(*e.kids[2], hint);
        if (!a || !b) return {};
        if (a.ty == Ty::Bool) a.ty = Ty::Float;
        if (b.ty == Ty::Bool) b.ty = Ty::Float;
        Ty rt = a.ty;
        if (a.ty != b.ty) {
            if (a.ty == Ty::Float) rt = b.ty;
            else if (b.ty == Ty::Float || b.ty == Ty::Tuple) rt = a.ty;
            else if (a.ty == Ty::Tuple) rt = b.ty;
            else if (isSpatial(a.ty) && isSpatial(b.ty)) rt = a.ty;
            else {
                error(e.loc, fmt::format("the branches of '?:' have different types ({} and {})", tyName(a.ty), tyName(b.ty)));
                return {};
            }
        }
        // Strings are uniform: a string '?:' needs a uniform condition
        // (checked once varyingness is known, inferVaryingAndOptimize()).
        if (m_cs.regs[a.reg].arrayLen > 0 || m_cs.regs[b.reg].arrayLen > 0) {
            error(e.loc, fmt::format("'?:' cannot select between values of type {}", describe(a)));
            return {};
        }
        a = coerce(a, rt, e.loc);
        b = coerce(b, rt, e.loc);
        if (!a || !b) return {};
        int t = temp(rt);
        emit(Op::Select, e.loc, t, a.reg, b.reg, cond);
        return {t, rt};
    }

    Val genAssign(const Expr& e) {
        const Expr& lhs = *e.kids[0];
        const Expr& rhs = *e.kids[1];
        std::string op = e.name == "=" ? "" : e.name.substr(0, 1);
        if (lhs.kind == Expr::Var) {
            int r = lookupVar(lhs.name);
            if (r < 0) {
                error(lhs.loc, fmt::format("undefined variable '{}'", lhs.name));
                return {};
            }
            const RegInfo ri = m_cs.regs[r];
            if (ri.kind == RegKind::Const) {
                error(lhs.loc, fmt::format("cannot assign to constant '{}'", lhs.name));
                return {};
            }
            if (ri.kind == RegKind::Global && (ri.global == gE || ri.global == gDu || ri.global == gDv ||
                                               ri.global == gNcomps || ri.global == gTime)) {
                error(lhs.loc, fmt::format("cannot assign to read-only variable '{}'", lhs.name));
                return {};
            }
            if (m_readOnly.count(r)) {
                error(lhs.loc, fmt::format("cannot assign to '{}': it is not an output parameter of the function", lhs.name));
                return {};
            }
            if (ri.arrayLen > 0) {
                Val v = gen(rhs, ri.ty);
                if (!v) return {};
                if (!op.empty() || m_cs.regs[v.reg].arrayLen != ri.arrayLen || m_cs.regs[v.reg].ty != ri.ty) {
                    error(e.loc, fmt::format("cannot assign {} to array '{}'", describe(v), lhs.name));
                    return {};
                }
                emit(Op::MovArr, e.loc, r, v.reg);
                return {r, ri.ty};
            }
            if (op.empty()) {
                assignTo(r, ri.ty, rhs, e.loc);
            } else {
                Val v = binaryOp(op, {r, ri.ty}, genStored(r, rhs, ri.ty), e.loc);
                v = coerce(v, ri.ty, e.loc);
                if (!v) return {};
                if (m_cs.code.back().dst == v.reg && retargetable(m_cs.code.back().op)) m_cs.code.back().dst = r;
                else emit(ri.ty == Ty::String ? Op::MovS : Op::Mov, e.loc, r, v.reg);
            }
            return {r, ri.ty};
        }
        if (lhs.kind == Expr::Index) {
            if (lhs.kids[0]->kind != Expr::Var) {
                error(lhs.loc, "can only assign to an element of a named variable");
                return {};
            }
            int r = lookupVar(lhs.kids[0]->name);
            if (r < 0) {
                error(lhs.kids[0]->loc, fmt::format("undefined variable '{}'", lhs.kids[0]->name));
                return {};
            }
            if (m_readOnly.count(r) || m_cs.regs[r].kind == RegKind::Const) {
                error(lhs.loc, fmt::format("cannot assign to '{}'", lhs.kids[0]->name));
                return {};
            }
            const RegInfo ri = m_cs.regs[r];
            Val idx = coerce(gen(*lhs.kids[1], Ty::Float), Ty::Float, lhs.kids[1]->loc);
            if (!idx) return {};
            Ty et = ri.arrayLen > 0 ? ri.ty : Ty::Float;
            if (ri.arrayLen == 0 && !isTriple(ri.ty)) {
                error(lhs.loc, fmt::format("cannot index a {}", tyName(ri.ty)));
                return {};
            }
            Val v = gen(rhs, et);
            if (!op.empty()) {
                int cur = temp(et);
                emit(ri.arrayLen > 0 ? Op::LoadElem : Op::Comp, e.loc, cur, r, idx.reg);
                v = binaryOp(op, {cur, et}, v, e.loc);
            }
            v = coerce(v, et, e.loc);
            if (!v) return {};
            if (ri.arrayLen > 0) emit(Op::StoreElem, e.loc, r, idx.reg, v.reg);
            else emit(Op::SetComp, e.loc, r, idx.reg, v.reg);
            return v;
        }
        error(lhs.loc, "the left side of an assignment must be a variable or an array element");
        return {};
    }

    // --- calls -----------------------------------------------------------
    struct LoopInfo {
        int lDepth;
        int ctl;
    };
    struct FuncInfo {
        int result;
        Ty retTy;
        int frameDepth;  // -1: no frame (single tail return)
        int ctl;
        int loopsBase;
    };

    /// Cost of passing `v` where code `c` is wanted; -1 if impossible.
    int argCost(char c, Val v, Ty firstTriple) const {
        if (!v) return -1;
        const RegInfo& r = m_cs.regs[v.reg];
        Ty t = v.ty == Ty::Bool ? Ty::Float : v.ty;
        if (c == 'a') return 0;
        if (r.arrayLen > 0) return -1;
        switch (c) {
        case 'f': return t == Ty::Float ? 0 : -1;
        case 's': return t == Ty::String ? 0 : -1;
        case 'm': return t == Ty::Matrix ? 0 : t == Ty::Float ? 2 : -1;
        case 'c': return t == Ty::Color ? 0 : t == Ty::Tuple ? 1 : t == Ty::Float ? 2 : -1;
        case 'p': return isSpatial(t) ? (t == Ty::Tuple ? 1 : 0) : t == Ty::Float ? 3 : -1;
        case 't':
            if (isTriple(t)) {
                if (firstTriple != Ty::Void && firstTriple != t && (firstTriple == Ty::Color) != (t == Ty::Color) && t != Ty::Tuple && firstTriple != Ty::Tuple) return -1;
                return 0;
            }
            return t == Ty::Float ? 2 : -1;
        }
        return -1;
    }

    Val genCall(const Expr& e, Ty hint) {
        std::shared_ptr<Scope> where;
        if (const Overloads* all = lookupOverloads(e.name, &where)) {
            if (auto f = chooseOverload(e, *all)) return inlineCall(e, f, where);
            error(e.loc, fmt::format("no version of function '{}' takes these arguments", e.name));
            return {};
        }
        if (e.name == "texture" || e.name == "environment" || e.name == "shadow") return genTexture(e, hint);
        if (e.name == "spline") return genSpline(e, hint);
        if (e.name == "comp" && e.kids.size() == 2) {
            Val v = gen(*e.kids[0], Ty::Void);
            Val i = coerce(gen(*e.kids[1], Ty::Float), Ty::Float, e.kids[1]->loc);
            if (!v || !i) return {};
            if (!isTriple(v.ty)) {
                error(e.loc, fmt::format("comp() expects a color, point, vector or normal, not {}", tyName(v.ty)));
                return {};
            }
            int t = temp(Ty::Float);
            emit(Op::Comp, e.loc, t, v.reg, i.reg);
            return {t, Ty::Float};
        }
        if (e.name == "setcomp" && e.kids.size() == 3) {
            Val v = gen(*e.kids[0], Ty::Void);
            if (!v) return {};
            if (isTriple(v.ty)) {
                Val i = coerce(gen(*e.kids[1], Ty::Float), Ty::Float, e.kids[1]->loc);
                Val x = coerce(gen(*e.kids[2], Ty::Float), Ty::Float, e.kids[2]->loc);
                if (!i || !x) return {};
                checkWritable(e.kids[0]->loc, v.reg);
                emit(Op::SetComp, e.loc, v.reg, i.reg, x.reg);
                return {-1, Ty::Void};
            }
        }
        if ((e.name == "min" || e.name == "max") && e.kids.size() > 2) {
            Val acc = gen(*e.kids[0], hint);
            for (size_t k = 1; k < e.kids.size() && acc; ++k) {
                Val next = gen(*e.kids[k], hint);
                if (!next) return {};  // the argument's error is already reported
                acc = builtinCall(e, e.name, {acc, next}, hint);
            }
            return acc;
        }
        if (e.name == "concat" && e.kids.empty()) return {constS(""), Ty::String};
        if (e.name == "shadername" && e.kids.empty()) return {constS(m_cs.name), Ty::String};
        if (e.name == "arraylength") {
            Val a = e.kids.size() == 1 ? gen(*e.kids[0], Ty::Void) : Val{};
            if (e.kids.size() != 1 || (a && m_cs.regs[a.reg].arrayLen <= 0)) {
                error(e.loc, "arraylength() expects one array");
                return {};
            }
            if (!a) return {};
            return {constF(float(m_cs.regs[a.reg].arrayLen)), Ty::Float};
        }
        std::vector<Val> args;
        for (auto& k : e.kids) args.push_back(gen(*k, Ty::Void));
        for (auto& a : args)
            if (!a) return {};
        return builtinCall(e, e.name, args, hint);
    }

    void checkWritable(SrcLoc loc, int reg) {
        const RegInfo& r = m_cs.regs[reg];
        if (r.kind == RegKind::Const || r.kind == RegKind::Temp || m_readOnly.count(reg))
            error(loc, "output argument must be a writable variable");
    }

    /// Whether a built-in has a version returning the type its context
    /// asks for (return code 'h'), beside its float version.
    static bool hasContextTypedVersion(const std::string& name) {
        for (const BuiltinSig& sig : builtinTable())
            if (sig.ret[0] == 'h' && name == sig.name) return true;
        return false;
    }

    Val builtinCall(const Expr& e, const std::string& name, std::vector<Val> args, Ty hint) {
        const BuiltinSig* best = nullptr;
        int bestCost = 1 << 30;
        bool known = false;
        for (const BuiltinSig& sig : builtinTable()) {
            if (name != sig.name) continue;
            known = true;
            std::string codes;
            std::vector<bool> outs;
            bool variadic = false;
            for (const char* p = sig.args; *p; ++p) {
                if (*p == '&') {
                    outs.push_back(true);
                    codes += *++p;
                    continue;
                }
                if (*p == '*') {
                    variadic = true;
                    break;
                }
                outs.push_back(false);
                codes += *p;
            }
            if (args.size() < codes.size() || (!variadic && args.size() != codes.size())) continue;
            int cost = 0;
            Ty firstTriple = Ty::Void;
            for (size_t k = 0; k < codes.size(); ++k) {
                int c = argCost(codes[k], args[k], firstTriple);
                if (c < 0) {
                    cost = -1;
                    break;
                }
                if (codes[k] == 't' && firstTriple == Ty::Void && isTriple(args[k].ty)) firstTriple = args[k].ty;
                cost += c;
            }
            if (cost < 0) continue;
            // Of a fixed and a variadic version, the one naming more
            // arguments wins: filterstep(e, s1, s2, "width", w).
            if (variadic) cost += int(args.size() - codes.size());
            bool retTriple = sig.ret[0] == 'h' || sig.ret[0] == 't' || sig.ret[0] == 'c' || sig.ret[0] == 'p' || sig.ret[0] == 'n';
            if (isTriple(hint) != retTriple && hint != Ty::Void && sig.ret[0] != 'v' && (sig.ret[0] == 'h' || hint == Ty::Float)) cost += 5;
            if (sig.ret[0] == 'h' && !isTriple(hint)) cost += 5;
            // noise(), pnoise(), cellnoise() and random() return the type
            // their context asks for: `color noise(P)`, `color c = noise(P)`
            // or `P + noise(P)` take the three-channel version (RI Spec 3.2;
            // Pixie and Aqsis). Its float version promoted gave grey.
            if (sig.ret[0] == 'f' && isTriple(hint) && hint != Ty::Tuple && hasContextTypedVersion(name)) cost += 5;
            if (cost < bestCost) {
                bestCost = cost;
                best = &sig;
            }
        }
        if (!best) {
            if (!known) error(e.loc, fmt::format("undefined function '{}'", name));
            else {
                std::string types;
                for (auto& a : args) types += (types.empty() ? "" : ", ") + describe(a);
                error(e.loc, fmt::format("no version of '{}' takes ({})", name, types));
            }
            return {};
        }
        // Convert arguments and find the result type.
        std::vector<int> regs;
        uint32_t outMask = 0;
        Ty firstTriple = Ty::Void;
        size_t k = 0;
        for (const char* p = best->args; *p; ++p) {
            bool out = false;
            if (*p == '&') {
                out = true;
                ++p;
            }
            if (*p == '*') break;
            Val v = args[k];
            Ty want = v.ty;
            switch (*p) {
            case 'f': want = Ty::Float; break;
            case 's': want = Ty::String; break;
            case 'm': want = Ty::Matrix; break;
            case 'c': want = Ty::Color; break;
            case 'p': want = isSpatial(v.ty) ? (v.ty == Ty::Tuple ? Ty::Point : v.ty) : Ty::Point; break;
            case 't':
                if (isTriple(v.ty)) want = firstTriple != Ty::Void && v.ty == Ty::Tuple ? firstTriple : v.ty;
                else want = firstTriple != Ty::Void ? firstTriple : (isTriple(hint) ? hint : Ty::Point);
                if (firstTriple == Ty::Void) firstTriple = want;
                break;
            default: break;
            }
            if (out) {
                checkWritable(e.kids.size() > k ? e.kids[k]->loc : e.loc, v.reg);
                outMask |= 1u << k;
                regs.push_back(v.reg);
            } else {
                Val c = coerce(v, want, e.kids.size() > k ? e.kids[k]->loc : e.loc);
                if (!c) return {};
                regs.push_back(c.reg);
            }
            ++k;
        }
        for (; k < args.size(); ++k) regs.push_back(args[k].reg);  // variadic rest
        if (firstTriple == Ty::Tuple) firstTriple = Ty::Point;
        Ty ret;
        switch (best->ret[0]) {
        case 'f': ret = Ty::Float; break;
        case 'c': ret = Ty::Color; break;
        case 'p': ret = Ty::Point; break;
        case 'n': ret = Ty::Normal; break;
        case 'm': ret = Ty::Matrix; break;
        case 's': ret = Ty::String; break;
        case 'v': ret = Ty::Void; break;
        case 'h': ret = isTriple(hint) && hint != Ty::Tuple ? hint : Ty::Point; break;
        default: ret = firstTriple == Ty::Void ? Ty::Point : firstTriple; break;
        }
        if (best->usesLights) {
            m_cs.usesLights = true;
            if (m_cs.kind != ShaderKind::Surface && m_cs.kind != ShaderKind::Volume)
                error(e.loc, fmt::format("{}() is only allowed in surface and volume shaders", name));
        }
        if (best->id == Bi::Printf || best->id == Bi::Format || best->id == Bi::Concat) {
            if (best->id == Bi::Concat)
                for (size_t j = 0; j < args.size(); ++j)
                    if (args[j].ty != Ty::String) {
                        error(e.kids[j]->loc, "concat() expects strings");
                        return {};
                    }
        }
        Val r = callBuiltin(best->id, ret, regs, e.loc, outMask);
        // random() is polymorphic in storage class: stored into a uniform
        // variable it draws one value per grid; elsewhere one per point.
        bool random = best->id == Bi::RandomF || best->id == Bi::RandomT;
        if (best->alwaysVarying && !(random && m_uniformDest)) m_cs.code.back().varies = true;
        return r;
    }

    /// texture/environment/shadow(name[channel], coordinates..., "param", value, ...)
    Val genTexture(const Expr& e, Ty hint) {
        if (e.kids.empty()) {
            error(e.loc, fmt::format("{}() needs a map name", e.name));
            return {};
        }
        const Expr* nameE = e.kids[0].get();
        int channel = constF(0);
        if (nameE->kind == Expr::Index) {
            Val c = coerce(gen(*nameE->kids[1], Ty::Float), Ty::Float, nameE->loc);
            if (!c) return {};
            channel = c.reg;
            nameE = nameE->kids[0].get();
        }
        Val name = gen(*nameE, Ty::String);
        if (!name) return {};
        if (name.ty != Ty::String) {
            error(nameE->loc, fmt::format("{}() expects a map name string first", e.name));
            return {};
        }
        std::vector<Val> coords;
        size_t k = 1;
        std::vector<Val> rest;
        for (; k < e.kids.size(); ++k) {
            Val v = gen(*e.kids[k], Ty::Void);
            if (!v) return {};
            if (v.ty == Ty::String) break;
            coords.push_back(v);
        }
        std::vector<int> params;
        for (; k < e.kids.size(); ++k) {
            Val pn = gen(*e.kids[k], Ty::Void);
            if (!pn) return {};
            if (pn.ty != Ty::String || k + 1 >= e.kids.size()) {
                error(e.kids[k]->loc, fmt::format("{}() expects \"name\", value pairs after the coordinates", e.name));
                return {};
            }
            Val pv = gen(*e.kids[++k], Ty::Void);
            if (!pv) return {};
            params.push_back(pn.reg);
            params.push_back(pv.reg);
        }
        bool color = isTriple(hint) && e.name != "shadow";
        std::vector<int> regs{name.reg, channel};
        Bi id;
        if (e.name == "texture") {
            if (coords.empty()) {
                regs.push_back(m_cs.globalRegs[gS]);
                regs.push_back(m_cs.globalRegs[gT]);
                if (lookupVar("s") < 0) error(e.loc, "texture() without coordinates needs s and t");
                id = color ? Bi::TextureC : Bi::TextureF;
            } else if (coords.size() == 2 || coords.size() == 8) {
                for (Val c : coords) {
                    Val f = coerce(c, Ty::Float, e.loc);
                    if (!f) return {};
                    regs.push_back(f.reg);
                }
                id = coords.size() == 2 ? (color ? Bi::TextureC : Bi::TextureF) : (color ? Bi::TextureC4 : Bi::TextureF4);
            } else {
                error(e.loc, "texture() expects 0, 2 or 8 coordinates");
                return {};
            }
        } else {
            if (coords.size() != 1 && coords.size() != 4) {
                error(e.loc, fmt::format("{}() expects {}", e.name,
                                         e.name == "shadow" ? "a point or four points" : "a direction or four directions"));
                return {};
            }
            for (Val c : coords) {
                Val p = coerce(c, e.name == "shadow" ? Ty::Point : Ty::Vector, e.loc);
                if (!p) return {};
                regs.push_back(p.reg);
            }
            if (e.name == "shadow") {
                id = coords.size() == 1 ? Bi::Shadow : Bi::Shadow4;
                regs.push_back(lookupVar("N") >= 0 ? m_cs.globalRegs[gN] : constT(Ty::Normal, 0, 0, 0));
            } else {
                // Four directions (RI Spec 3.2): the corners of the region.
                if (coords.size() == 4) id = color ? Bi::EnvironmentC4 : Bi::EnvironmentF4;
                else id = color ? Bi::EnvironmentC : Bi::EnvironmentF;
            }
        }
        regs.push_back(int(params.size()) / 2);  // count of pairs, stored as a plain number
        int pairsAt = int(regs.size()) - 1;
        regs[pairsAt] = constF(float(params.size() / 2));
        regs.insert(regs.end(), params.begin(), params.end());
        Ty ret = color ? (hint == Ty::Tuple ? Ty::Color : hint) : Ty::Float;
        if (e.name == "shadow" && isTriple(hint)) ret = Ty::Float;  // promoted by the caller
        Val r = callBuiltin(id, ret, regs, e.loc);
        m_cs.code.back().varies = true;
        return r;
    }

    /// spline([basis,] t, v0, v1, v2, v3, ...) or spline([basis,] t, array)
    Val genSpline(const Expr& e, Ty hint) {
        std::vector<Val> args;
        for (auto& k : e.kids) {
            args.push_back(gen(*k, hint));
            if (!args.back()) return {};
        }
        size_t k = 0;
        int basis = -1;
        if (!args.empty() && args[0].ty == Ty::String) basis = args[k++].reg;
        if (args.size() < k + 2) {
            error(e.loc, "spline() expects ([basis,] t, values...)");
            return {};
        }
        Val t = coerce(args[k++], Ty::Float, e.loc);
        if (!t) return {};
        std::vector<int> regs;
        if (basis >= 0) regs.push_back(basis);
        regs.push_back(t.reg);
        Ty vt;
        if (args.size() == k + 1 && m_cs.regs[args[k].reg].arrayLen > 0) {
            vt = m_cs.regs[args[k].reg].ty;
            regs.push_back(args[k].reg);
        } else {
            if (args.size() - k < 4) {
                error(e.loc, "spline() needs at least four control values");
                return {};
            }
            vt = Ty::Float;
            for (size_t j = k; j < args.size(); ++j)
                if (isTriple(args[j].ty)) vt = args[j].ty == Ty::Tuple ? Ty::Point : args[j].ty;
            if (vt == Ty::Float && isTriple(hint)) vt = hint == Ty::Tuple ? Ty::Point : hint;
            for (size_t j = k; j < args.size(); ++j) {
                Val c = coerce(args[j], vt, e.kids[j]->loc);
                if (!c) return {};
                regs.push_back(c.reg);
            }
        }
        if (vt != Ty::Float && !isTriple(vt)) {
            error(e.loc, fmt::format("spline() cannot interpolate {}", tyName(vt)));
            return {};
        }
        Bi id = vt == Ty::Float ? (basis >= 0 ? Bi::SplineBasisF : Bi::SplineF) : (basis >= 0 ? Bi::SplineBasisT : Bi::SplineT);
        return callBuiltin(id, vt, regs, e.loc);
    }

    /// Inlines a user function: formals alias the arguments (RSL passes by
    /// reference; only output formals may be written).
    Val inlineCall(const Expr& e, const std::shared_ptr<FuncDef>& f, const std::shared_ptr<Scope>& defScope) {
        if (auto self = std::find(m_inlining.begin(), m_inlining.end(), f.get()); self != m_inlining.end()) {
            // Name the functions between, when the call comes back through others.
            std::string via;
            for (auto g = self + 1; g != m_inlining.end(); ++g) via += fmt::format("{}'{}'", via.empty() ? " through " : ", ", (*g)->name);
            error(e.loc, fmt::format("function '{}' calls itself{} (recursion is not allowed)", f->name, via));
            return {};
        }
        if (m_inlining.size() > 64) {
            error(e.loc, "function calls nested too deeply");
            return {};
        }
        if (e.kids.size() != f->formals.size()) {
            error(e.loc, fmt::format("function '{}' expects {} argument(s), got {}", f->name, f->formals.size(), e.kids.size()));
            return {};
        }
        checkReturns(*f);
        m_inlinedOnce.insert(f.get());
        auto scope = std::make_shared<Scope>();
        scope->parent = defScope;
        std::set<int> readOnly;
        for (size_t k = 0; k < f->formals.size(); ++k) {
            const VarDecl& fm = f->formals[k];
            const Expr& ae = *e.kids[k];
            Val v = gen(ae, fm.type.ty);
            if (!v) return {};
            const RegInfo& ar = m_cs.regs[v.reg];
            int wantArr = fm.type.arrayLen;
            if (wantArr != 0) {
                if (ar.arrayLen == 0 || ar.ty != fm.type.ty || (wantArr > 0 && wantArr != ar.arrayLen)) {
                    error(ae.loc, fmt::format("argument {} of '{}' must be {}[{}]", k + 1, f->name, tyName(fm.type.ty), wantArr > 0 ? std::to_string(wantArr) : ""));
                    return {};
                }
                scope->vars[fm.name] = v.reg;
                if (!fm.type.output) readOnly.insert(v.reg);
                continue;
            }
            if (fm.type.output) {
                if (ar.kind == RegKind::Const || ar.kind == RegKind::Temp || m_readOnly.count(v.reg)) {
                    error(ae.loc, fmt::format("argument {} of '{}' is an output and must be a variable", k + 1, f->name));
                    return {};
                }
                bool same = v.ty == fm.type.ty || (isSpatial(v.ty) && isSpatial(fm.type.ty));
                if (!same || ar.arrayLen > 0) {
                    error(ae.loc, fmt::format("output argument {} of '{}' must be a {}, not {}", k + 1, f->name, tyName(fm.type.ty), describe(v)));
                    return {};
                }
                scope->vars[fm.name] = v.reg;
                continue;
            }
            Val c = coerce(v, fm.type.ty, ae.loc);
            if (!c) return {};
            if (m_cs.regs[c.reg].ty != fm.type.ty && !(isSpatial(m_cs.regs[c.reg].ty) && isSpatial(fm.type.ty))) {
                int t = temp(fm.type.ty);
                emit(Op::Mov, ae.loc, t, c.reg);
                c.reg = t;
            }
            scope->vars[fm.name] = c.reg;
            readOnly.insert(c.reg);
        }
        // One variable given for an input and an output (f(r, r)): the
        // input reads a copy of its value at the call, as if passed by
        // value, and the output writes the variable (as Pixie and Aqsis).
        // It was refused: the shared register was read-only.
        std::set<int> outputRegs;
        for (const auto& fm : f->formals)
            if (fm.type.output && scope->vars.count(fm.name)) outputRegs.insert(scope->vars[fm.name]);
        for (const auto& fm : f->formals) {
            auto bound = scope->vars.find(fm.name);
            if (fm.type.output || fm.type.arrayLen != 0 || bound == scope->vars.end() || !outputRegs.count(bound->second))
                continue;
            const int copy = temp(m_cs.regs[bound->second].ty);
            emit(Op::Mov, e.loc, copy, bound->second);
            readOnly.erase(bound->second);
            readOnly.insert(copy);
            bound->second = copy;
        }
        // The result register, and a mask frame when `return` can happen
        // before the end of the body.
        int result = f->ret.ty == Ty::Void ? -1 : temp(f->ret.ty);
        bool needFrame = needsReturnFrame(*f->body);
        auto savedScope = m_scope;
        auto savedReadOnly = m_readOnly;
        for (int r : readOnly) m_readOnly.insert(r);
        for (auto& [n, r] : scope->vars)
            if (!readOnly.count(r)) m_readOnly.erase(r);
        m_scope = scope;
        m_inlining.push_back(f.get());
        int savedCtl = m_ctl;
        int frame = -1;
        if (needFrame) {
            emit(Op::LoopBegin, e.loc);
            frame = m_frameDepth++;
            m_ctl = newCtl(-1, false);
        }
        m_funcs.push_back({result, f->ret.ty, frame, m_ctl, int(m_loops.size())});
        genStmt(*f->body);
        m_funcs.pop_back();
        if (needFrame) {
            emit(Op::LoopEnd, e.loc);
            --m_frameDepth;
        }
        m_ctl = savedCtl;
        m_inlining.pop_back();
        m_scope = savedScope;
        m_readOnly = savedReadOnly;
        return {result, f->ret.ty};
    }

    /// A function with a value must have a return statement; without one
    /// its callers would read a result register nothing wrote.
    void checkReturns(const FuncDef& f) {
        if (f.ret.ty == Ty::Void) return;
        int count = 0;
        countReturns(*f.body, &count);
        if (count == 0) error(f.loc, fmt::format("function '{}' must return a {} but has no return statement", f.name, tyName(f.ret.ty)));
    }

    /// True unless the body's only return is its last statement.
    static bool needsReturnFrame(const Stmt& body) {
        int count = 0;
        countReturns(body, &count);
        if (count == 0) return false;
        if (count == 1 && body.kind == Stmt::Block && !body.body.empty() && body.body.back()->kind == Stmt::Return) return false;
        return true;
    }
    static void countReturns(const Stmt& s, int* n) {
        if (s.kind == Stmt::Return) ++*n;
        if (s.kind == Stmt::Func) return;
        for (auto& b : s.body) countReturns(*b, n);
    }

    void checkUncalled(const std::shared_ptr<FuncDef>& f, const std::shared_ptr<Scope>& globals) {
        // Bind each formal to a fresh variable of its type and generate the
        // body into throwaway code, only for its error messages.
        checkReturns(*f);
        size_t codeSize = m_cs.code.size(), argsSize = m_cs.args.size(), ctlSize = m_cs.ctls.size();
        auto saved = m_scope;
        m_scope = std::make_shared<Scope>();
        m_scope->parent = globals;
        for (const VarDecl& fm : f->formals) {
            int r = newReg(fm.type.ty, std::max(0, fm.type.arrayLen == -1 ? 1 : fm.type.arrayLen), RegKind::Local, fm.name, false, false);
            m_scope->vars[fm.name] = r;
            if (!fm.type.output) m_readOnly.insert(r);
        }
        // What the throwaway code does is not what the shader does: an
        // illuminate() there does not make a light non-ambient.
        const bool hadIlluminate = m_hasIlluminate, usedLights = m_cs.usesLights;
        const bool hadSolar = m_hasSolar, hadIlluminateAt = m_hasIlluminateAt;
        m_inlining.push_back(f.get());
        m_funcs.push_back({f->ret.ty == Ty::Void ? -1 : temp(f->ret.ty), f->ret.ty, -1, 0, int(m_loops.size())});
        genStmt(*f->body);
        m_funcs.pop_back();
        m_inlining.pop_back();
        m_scope = saved;
        m_cs.code.resize(codeSize);
        m_cs.args.resize(argsSize);
        m_cs.ctls.resize(ctlSize);
        m_hasIlluminate = hadIlluminate;
        m_hasSolar = hadSolar;
        m_hasIlluminateAt = hadIlluminateAt;
        m_cs.usesLights = usedLights;
    }

    CompiledShader& m_cs;
    CompileErrors& m_errs;
    std::shared_ptr<Scope> m_scope;
    std::map<uint32_t, int> m_constF;
    std::map<std::string, int> m_constS;
    std::vector<LoopInfo> m_loops;
    std::vector<FuncInfo> m_funcs;
    std::vector<const FuncDef*> m_inlining;  // the functions being inlined, outermost first
    std::set<const FuncDef*> m_inlinedOnce;
    std::set<int> m_readOnly;
    std::set<std::string> m_reported;
    int m_frameDepth = 0;
    int m_ctl = 0;
    int m_exprDepth = 0;
    bool m_uniformDest = false;  // generating a value stored into a uniform variable
    const Expr* m_effectExpr = nullptr;  // see genEffect()
    bool m_hasIlluminate = false;
    bool m_hasSolar = false, m_hasIlluminateAt = false;  // which of the two the light uses
};

}  // namespace

std::shared_ptr<CompiledShader> compileShaderSource(const std::string& text, const std::string& fileName,
                                                    const std::vector<std::string>& includePath,
                                                    Diagnostics& diag) {
    SourceSet src;
    int main = src.add(fileName, text);
    CompileErrors errs(src, diag);
    std::vector<Token> toks = preprocess(src, main, includePath, errs);
    if (errs.count()) return nullptr;
    Program prog = parse(toks, errs);
    if (errs.count()) return nullptr;
    if (prog.shaders.empty()) {
        errs.error(toks.back().loc, "no shader definition found (expected surface, light, displacement, volume or imager)");
        return nullptr;
    }
    if (prog.shaders.size() > 1) {
        errs.error(prog.shaders[1].loc, "more than one shader in a file");
        return nullptr;
    }
    auto cs = std::make_shared<CompiledShader>();
    cs->fileName = fileName;
    Codegen cg(*cs, errs);
    cg.run(prog, prog.shaders[0]);
    if (errs.count()) return nullptr;
    cs->isAmbientLight = cs->kind == ShaderKind::Light && !cg.hasIlluminate();
    cs->isSolarLight = cs->kind == ShaderKind::Light && cg.hasSolar() && !cg.hasIlluminateAt();
    if (!inferVaryingAndOptimize(*cs, errs)) return nullptr;
    return cs;
}

}  // namespace umbra::shading
