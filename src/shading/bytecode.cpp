// Bytecode passes after code generation: uniform/varying inference, dead
// code removal, and the human-readable listing.

#include "builtins.h"

#include <map>
#include <set>

namespace umbra::shading {

namespace {
const char* const kOpNames[] = {
    "nop", "mov", "movs", "movarr", "promote3", "promotem", "make3", "makem", "loadelem", "storeelem", "comp",
    "setcomp", "addf", "subf", "mulf", "divf", "negf", "add3", "sub3", "mul3", "div3", "neg3", "mul3f", "div3f",
    "dot", "cross", "mulm", "divm", "ltf", "lef", "gtf", "gef", "eqf", "nef", "eq3", "ne3", "eqs", "nes", "eqm", "nem",
    "and", "or", "not", "select", "call", "jump", "ifbegin", "else", "endif", "loopbegin", "loopcond", "loopcont",
    "loopend", "break", "illumbegin", "illumnext", "illuminate", "solar", "paraminit"};
static_assert(sizeof(kOpNames) / sizeof(kOpNames[0]) == size_t(Op::ParamInit) + 1, "one name per opcode");

bool isControl(Op op) {
    switch (op) {
    case Op::Jump: case Op::IfBegin: case Op::Else: case Op::EndIf: case Op::LoopBegin: case Op::LoopCond:
    case Op::LoopCont: case Op::LoopEnd: case Op::Break: case Op::IllumBegin: case Op::IllumNext:
    case Op::Illuminate: case Op::Solar: case Op::ParamInit:
        return true;
    default: return false;
    }
}

/// Registers an instruction reads and writes.
void operands(const CompiledShader& cs, const Instr& in, std::vector<int>* reads, std::vector<int>* writes) {
    reads->clear();
    writes->clear();
    if (in.op == Op::ParamInit) {
        writes->push_back(in.dst);
        return;
    }
    if (in.dst >= 0) writes->push_back(in.dst);
    if (in.op == Op::StoreElem || in.op == Op::SetComp) reads->push_back(in.dst);
    for (int r : {in.a, in.b, in.c})
        if (r >= 0) reads->push_back(r);
    for (int k = 0; k < in.nargs; ++k) {
        int r = cs.args[size_t(in.argBase + k)];
        if (r < 0) continue;
        if (k < 32 && (in.outMask >> k) & 1u) writes->push_back(r);
        else reads->push_back(r);
    }
    if (in.op == Op::IllumNext) {
        writes->push_back(cs.globalRegs[gL]);
        writes->push_back(cs.globalRegs[gCl]);
        if (cs.globalRegs[gOl] >= 0) writes->push_back(cs.globalRegs[gOl]);
    }
    if (in.op == Op::Illuminate || in.op == Op::Solar) writes->push_back(cs.globalRegs[gL]);
}

/// A call that reads another shader's or the renderer's value into its
/// output argument (RI Spec 3.2 §15.8 "message passing and information").
bool messagePassing(const Instr& in) {
    if (in.op != Op::Call) return false;
    switch (Bi(in.sub)) {
    case Bi::LightSource:
    case Bi::SurfaceMsg:
    case Bi::DisplacementMsg:
    case Bi::AtmosphereMsg:
    case Bi::Incident:
    case Bi::Opposite:
    case Bi::Attribute:
    case Bi::Option:
    case Bi::RendererInfo:
    case Bi::TextureInfo: return true;
    default: return false;
    }
}

bool pure(const CompiledShader& cs, const Instr& in) {
    if (isControl(in.op) || in.op == Op::Nop) return false;
    if (in.op == Op::StoreElem || in.op == Op::SetComp) return false;
    if (in.op == Op::Call) {
        if (in.outMask) return false;
        Bi id = Bi(in.sub);
        if (id == Bi::Printf) return false;
    }
    return in.dst >= 0 && cs.regs[size_t(in.dst)].kind == RegKind::Temp;
}

void removeDeadCode(CompiledShader& cs) {
    std::vector<int> reads, writes;
    for (;;) {
        std::vector<int> readCount(cs.regs.size(), 0);
        for (const Instr& in : cs.code) {
            operands(cs, in, &reads, &writes);
            for (int r : reads) ++readCount[size_t(r)];
        }
        std::vector<bool> keep(cs.code.size(), true);
        bool any = false;
        for (size_t i = 0; i < cs.code.size(); ++i)
            if (pure(cs, cs.code[i]) && readCount[size_t(cs.code[i].dst)] == 0) {
                keep[i] = false;
                any = true;
            }
        if (!any) return;
        std::vector<int> newIndex(cs.code.size() + 1);
        int n = 0;
        for (size_t i = 0; i < cs.code.size(); ++i) {
            newIndex[i] = n;
            if (keep[i]) ++n;
        }
        newIndex[cs.code.size()] = n;
        std::vector<Instr> code;
        for (size_t i = 0; i < cs.code.size(); ++i)
            if (keep[i]) {
                Instr in = cs.code[i];
                if (in.target >= 0) in.target = newIndex[size_t(in.target)];
                code.push_back(in);
            }
        cs.code = std::move(code);
    }
}

}  // namespace

const char* opName(Op op) { return kOpNames[size_t(op)]; }

bool inferVaryingAndOptimize(CompiledShader& cs, CompileErrors& errs) {
    std::vector<int> reads, writes;
    std::vector<bool> ctlVarying(cs.ctls.size(), false);
    std::set<int> reported;
    // Whether a register's value varies in the language's sense: read from
    // something varying. A variable declared uniform that is made varying
    // below (a uniform value stored under varying control) holds, on every
    // point that stored it, the same uniform value, so values computed from
    // it stay uniform in this sense and may be stored into other uniform
    // variables, as both peers' compilers allow.
    std::vector<bool> valueVarying(cs.regs.size());
    for (size_t r = 0; r < cs.regs.size(); ++r) valueVarying[r] = cs.regs[r].varying;
    bool ok = true;
    for (bool changed = true; changed;) {
        changed = false;
        for (size_t c = 0; c < cs.ctls.size(); ++c) {
            const CtlCtx& ctx = cs.ctls[c];
            bool v = ctx.alwaysVarying || (ctx.cond >= 0 && cs.regs[size_t(ctx.cond)].varying) ||
                     (ctx.parent >= 0 && ctlVarying[size_t(ctx.parent)]);
            for (int b : ctx.breakers) v = v || ctlVarying[size_t(b)];
            if (v && !ctlVarying[c]) {
                ctlVarying[c] = true;
                changed = true;
            }
        }
        for (const Instr& in : cs.code) {
            if (in.op == Op::ParamInit) continue;
            operands(cs, in, &reads, &writes);
            bool valueVaries = in.varies && !messagePassing(in), storageVaries = false;
            for (int r : reads) {
                valueVaries = valueVaries || valueVarying[size_t(r)];
                storageVaries = storageVaries || cs.regs[size_t(r)].varying;
            }
            const bool v = valueVaries || storageVaries || ctlVarying[size_t(in.ctl)] || in.varies;
            if (!v) continue;
            for (int w : writes) {
                RegInfo& r = cs.regs[size_t(w)];
                if (valueVaries && !r.fixed && !valueVarying[size_t(w)] && r.ty != Ty::String) {
                    valueVarying[size_t(w)] = true;
                    changed = true;
                }
                if (r.varying || r.ty == Ty::String) continue;
                // A variable declared uniform that is given a uniform value
                // under a varying condition (in an illuminance loop, say), or
                // another shader's value by message passing (lightsource(name,
                // uniformVar), whose storage is the light's business), becomes
                // varying: each point keeps what its own path stored. Pixie's
                // and Aqsis's compilers take such shaders and run them so
                // (docs/shading-language.md); a varying value stays an error,
                // as in both.
                if (r.fixed && valueVaries) {
                    if (reported.insert(w).second) {
                        errs.error(in.loc, fmt::format("cannot assign a varying value to uniform {} '{}'",
                                                       r.kind == RegKind::Param ? "parameter" : "variable", r.name));
                        ok = false;
                    }
                    continue;
                }
                r.varying = true;
                changed = true;
            }
        }
    }
    // Strings have one value per grid (as in PRMan before RSL 2, and
    // Pixie). A condition computed under a varying if is stored varying but
    // may still be uniform in value: the VM reads it at the first active
    // point, so only a value that differs between points is refused.
    for (const Instr& in : cs.code)
        if (in.op == Op::Select && cs.regs[size_t(in.dst)].ty == Ty::String && valueVarying[size_t(in.c)]) {
            errs.error(in.loc, "'?:' between strings needs a uniform condition: a string has one value for all points");
            ok = false;
        }
    // A string given a value that differs between points, or stored under
    // a condition that differs (an if, a loop; not an illuminance loop, whose
    // points see the same light), ends up with the last value stored on
    // every point. Pixie does the same silently; umbra says so.
    std::vector<bool> ctlDiverges(cs.ctls.size(), false);
    for (size_t c = 0; c < cs.ctls.size(); ++c) {  // parents come first
        const CtlCtx& ctx = cs.ctls[c];
        ctlDiverges[c] = (ctx.cond >= 0 && valueVarying[size_t(ctx.cond)]) ||
                         (ctx.parent >= 0 && ctlDiverges[size_t(ctx.parent)]);
    }
    // A string written in one place only (a local of the branch) is the
    // same on every point that reads it; one written in two places, one of
    // them under a condition that differs, is not.
    std::map<int, std::set<int>> stringWriteCtls;
    for (const Instr& in : cs.code) {
        if (in.op == Op::ParamInit) continue;
        operands(cs, in, &reads, &writes);
        for (int w : writes)
            if (cs.regs[size_t(w)].ty == Ty::String) stringWriteCtls[w].insert(in.ctl);
    }
    std::set<int> warnedStrings;
    std::vector<bool> stringVaries(cs.regs.size(), false);  // through temporaries: q = format("%f", s)
    for (const Instr& in : cs.code) {
        if (in.op == Op::ParamInit || in.op == Op::Select) continue;
        operands(cs, in, &reads, &writes);
        bool valueVaries = false;
        for (int r : reads)
            valueVaries = valueVaries || stringVaries[size_t(r)] ||
                          (valueVarying[size_t(r)] && cs.regs[size_t(r)].ty != Ty::String);
        for (int w : writes) {
            const RegInfo& r = cs.regs[size_t(w)];
            if (r.ty != Ty::String) continue;
            if (valueVaries) stringVaries[size_t(w)] = true;
            const bool divergentStore = ctlDiverges[size_t(in.ctl)] && stringWriteCtls[w].size() > 1;
            if (r.kind == RegKind::Temp || !(valueVaries || divergentStore)) continue;
            if (warnedStrings.insert(w).second)
                errs.warning(in.loc, fmt::format("string '{}' is given {} here, but a string holds one value for all "
                                                 "points of a grid: every point gets the last value stored",
                                                 r.name, valueVaries ? "a value that differs between points"
                                                                     : "a value under a condition that differs "
                                                                       "between points"));
        }
    }
    if (!ok) return false;
    removeDeadCode(cs);
    return true;
}

namespace {

std::string regText(const CompiledShader& cs, int r) {
    if (r < 0) return "-";
    const RegInfo& ri = cs.regs[size_t(r)];
    if (ri.kind == RegKind::Const) {
        if (ri.ty == Ty::String) return fmt::format("\"{}\"", cs.constStrings[size_t(ri.constIndex)]);
        if (ri.ty == Ty::Float) return fmt::format("{:g}", cs.consts[size_t(ri.constIndex)]);
        const float* f = &cs.consts[size_t(ri.constIndex)];
        return fmt::format("({:g},{:g},{:g})", f[0], f[1], f[2]);
    }
    if (ri.kind == RegKind::Temp) return fmt::format("%{}", r);
    return ri.name;
}

}  // namespace

std::string CompiledShader::listing() const {
    std::string out = fmt::format("{} {}\n", shaderKindName(kind), name);
    for (size_t p = 0; p < params.size(); ++p) {
        const RegInfo& r = regs[size_t(paramRegs[p])];
        out += fmt::format("param {}{} {}{} {}\n", params[p].output ? "output " : "", r.varying ? "varying" : "uniform",
                           tyName(r.ty), r.arrayLen ? fmt::format("[{}]", r.arrayLen) : "", r.name);
    }
    std::vector<bool> used(regs.size(), false);
    std::vector<int> reads, writes;
    for (const Instr& in : code) {
        operands(*this, in, &reads, &writes);
        for (int r : reads) used[size_t(r)] = true;
        for (int r : writes) used[size_t(r)] = true;
    }
    for (size_t i = 0; i < regs.size(); ++i) {
        const RegInfo& r = regs[i];
        if ((r.kind != RegKind::Temp && r.kind != RegKind::Local) || !used[i]) continue;
        out += fmt::format("reg {} {} {}{}\n", regText(*this, int(i)), r.varying ? "varying" : "uniform", tyName(r.ty),
                           r.arrayLen ? fmt::format("[{}]", r.arrayLen) : "");
    }
    for (size_t i = 0; i < code.size(); ++i) {
        const Instr& in = code[i];
        std::string line = fmt::format("{:4} {:<10}", i, opName(in.op));
        std::vector<std::string> ops;
        if (in.op == Op::Call) {
            const BuiltinSig* sig = nullptr;
            for (const BuiltinSig& s : builtinTable())
                if (s.id == Bi(in.sub)) sig = &s;
            std::string argText;
            for (int k = 0; k < in.nargs; ++k) argText += (k ? ", " : "") + regText(*this, args[size_t(k + in.argBase)]);
            std::string fn = sig ? sig->name : Bi(in.sub) == Bi::ColorFromSpace ? "colorfromspace" : fmt::format("builtin{}", in.sub);
            line += fmt::format(" {}{}({})", in.dst >= 0 ? regText(*this, in.dst) + " = " : "", fn, argText);
        } else if (in.op == Op::Break) {
            line += fmt::format(" frame {}", in.c);
        } else {
            for (int r : {in.dst, in.a, in.b, in.c})
                if (r >= 0) ops.push_back(regText(*this, r));
            for (int k = 0; k < in.nargs; ++k) ops.push_back(regText(*this, args[size_t(k + in.argBase)]));
            for (size_t k = 0; k < ops.size(); ++k) line += (k ? ", " : " ") + ops[k];
        }
        if (in.target >= 0) line += fmt::format(" -> {}", in.target);
        while (!line.empty() && line.back() == ' ') line.pop_back();
        out += line + "\n";
    }
    return out;
}

}  // namespace umbra::shading
