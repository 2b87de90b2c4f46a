#pragma once
// Internals of the shading-language compiler and VM: source files and
// tokens, the AST, types, and the bytecode shared by codegen and the
// interpreter. Not installed; the public API is in include/umbra/shading/.

#include "umbra/shading/shading_system.h"

#include <cstdint>
#include <atomic>
#include <memory>
#include <string>
#include <vector>

namespace umbra::shading {

/// Source texts of one compilation (the main file and its #includes), kept
/// so that error messages can quote the offending line.
struct SourceSet {
    struct File {
        std::shared_ptr<const std::string> name;
        std::string text;
    };
    std::vector<File> files;
    int add(const std::string& name, std::string text);
    std::string lineText(int file, int line) const;
};

/// A position in a SourceSet (file index, 1-based line and column).
struct SrcLoc {
    int file = -1, line = 0, col = 0;
};

/// Reports compile errors as "file:line:col: error: msg" followed by the
/// source line and a caret under the column; counts them.
class CompileErrors {
public:
    CompileErrors(const SourceSet& src, Diagnostics& diag) : m_src(src), m_diag(diag) {}
    void error(const SrcLoc& loc, const std::string& msg);
    void warning(const SrcLoc& loc, const std::string& msg);
    int count() const { return m_count; }
    FileLoc fileLoc(const SrcLoc& loc) const;

private:
    std::string quote(const SrcLoc& loc) const;
    const SourceSet& m_src;
    Diagnostics& m_diag;
    int m_count = 0;
};

/// Token kinds. `Other` is what the shading language has no use for: a
/// character such as `@` or `%`, or a string without its closing quote
/// (`text` then starts with the quote). cpp lexes such text too, and
/// complains only where it reaches the compiler: skipped #if groups, #if
/// expressions (`% & | ~`) and unused macro bodies may hold it.
enum class Tok : uint8_t { End, Ident, Number, String, Punct, Hash, Other };

/// A lexical token; `text` is the identifier, string contents or punctuator.
struct Token {
    Tok kind = Tok::End;
    std::string text;
    double number = 0;
    SrcLoc loc;
    bool lineStart = false;  // first token on its line (for # directives)
    bool spaceBefore = false;
};

/// Splits one file into tokens. An unterminated comment is reported; stray
/// characters and unterminated strings become `Tok::Other` tokens, which
/// preprocess() reports where they reach the shading-language text.
std::vector<Token> lexFile(const SourceSet& src, int file, CompileErrors& errs);

/// Runs the preprocessor (#include, #define, #undef, #ifdef, #ifndef, #if,
/// #elif, #else, #endif) over the tokens of `mainFile`, resolving includes
/// relative to the including file and then `includePath`.
std::vector<Token> preprocess(SourceSet& src, int mainFile, const std::vector<std::string>& includePath,
                              CompileErrors& errs);

// ---------------------------------------------------------------------------
// Types.

/// Language types. Bool is the result of comparisons (not storable);
/// Tuple is an untyped parenthesised triple that becomes whichever triple
/// type it is assigned to.
enum class Ty : uint8_t { Void, Float, Color, Point, Vector, Normal, Matrix, String, Bool, Tuple };

/// The public value type of a language type (Float for the internal ones).
inline ValueType valueTypeOf(Ty t) {
    switch (t) {
    case Ty::Color: return ValueType::Color;
    case Ty::Point: return ValueType::Point;
    case Ty::Vector: return ValueType::Vector;
    case Ty::Normal: return ValueType::Normal;
    case Ty::Matrix: return ValueType::Matrix;
    case Ty::String: return ValueType::String;
    default: return ValueType::Float;
    }
}
const char* tyName(Ty t);
inline bool isTriple(Ty t) { return t == Ty::Color || t == Ty::Point || t == Ty::Vector || t == Ty::Normal || t == Ty::Tuple; }
inline bool isSpatial(Ty t) { return t == Ty::Point || t == Ty::Vector || t == Ty::Normal || t == Ty::Tuple; }
/// Floats per value of a type (1, 3, 16; 0 for strings and void).
inline int tyFloats(Ty t) {
    switch (t) {
    case Ty::Float: case Ty::Bool: return 1;
    case Ty::Color: case Ty::Point: case Ty::Vector: case Ty::Normal: case Ty::Tuple: return 3;
    case Ty::Matrix: return 16;
    default: return 0;
    }
}

enum class Detail : uint8_t { Default, Uniform, Varying };

/// A declared type: base type, array length (0 scalar, -1 unsized formal),
/// uniform/varying and output qualifiers.
struct TypeSpec {
    Ty ty = Ty::Float;
    int arrayLen = 0;
    Detail detail = Detail::Default;
    bool output = false;
};

// ---------------------------------------------------------------------------
// AST.

struct Expr;
struct Stmt;
using ExprP = std::unique_ptr<Expr>;
using StmtP = std::unique_ptr<Stmt>;

struct Expr {
    enum Kind { Num, Str, Var, Index, Call, Unary, Binary, Assign, Ternary, Cast, Tuple };
    Kind kind;
    SrcLoc loc;
    std::string name;   // variable/function name, operator, cast space
    double num = 0;
    Ty castTy = Ty::Void;
    std::vector<ExprP> kids;
};

struct VarDecl {
    TypeSpec type;
    std::string name;
    SrcLoc loc;
    ExprP init;                    // scalar initialiser
    std::vector<ExprP> arrayInit;  // {a, b, c}
    bool hasArrayInit = false;
};

struct FuncDef;

struct Stmt {
    enum Kind { Block, ExprS, Decl, If, While, For, Break, Continue, Return, Illuminance, Illuminate, Solar, Func, Extern, Empty };
    Kind kind;
    SrcLoc loc;
    std::vector<StmtP> body;     // Block; If: then [else]; loops: body
    std::vector<ExprP> exprs;    // ExprS; If cond; For init/cond/step (may be null); Return; Illum* args
    std::vector<VarDecl> decls;  // Decl, Extern
    int level = 1;               // Break/Continue
    std::shared_ptr<FuncDef> func;
};

struct FuncDef {
    TypeSpec ret;
    std::string name;
    std::vector<VarDecl> formals;
    StmtP body;
    SrcLoc loc;
};

struct ShaderDef {
    ShaderKind kind = ShaderKind::Surface;
    std::string name;
    std::vector<VarDecl> params;
    StmtP body;
    SrcLoc loc;
};

struct Program {
    std::vector<std::shared_ptr<FuncDef>> functions;
    std::vector<ShaderDef> shaders;
};

/// Parses preprocessed tokens. Errors are reported; the result holds what
/// could be parsed.
Program parse(const std::vector<Token>& toks, CompileErrors& errs);

// ---------------------------------------------------------------------------
// Bytecode.

/// Opcodes. Operands are register numbers (dst, a, b, c), extra operands
/// live in CompiledShader::args[argBase .. argBase+nargs), jumps in `target`.
/// Every op runs over all active points of the grid (once for uniform dst).
enum class Op : uint8_t {
    Nop,        // nothing
    Mov,        // dst = a (float/triple/matrix, broadcasting uniform to varying)
    MovS,       // dst = a (string)
    MovArr,     // dst[] = a[] (whole array)
    Promote3,   // dst(triple) = (a, a, a)
    PromoteM,   // dst(matrix) = a * identity
    Make3,      // dst(triple) = (a, b, c)
    MakeM,      // dst(matrix) = 16 floats from args
    LoadElem,   // dst = a[b]   (index clamped to the array)
    StoreElem,  // dst[a] = b
    Comp,       // dst = component b (float index) of triple a
    SetComp,    // component a of triple dst = b
    AddF,       // dst = a + b (float)
    SubF,       // dst = a - b
    MulF,       // dst = a * b
    DivF,       // dst = a / b, 0 where b == 0
    NegF,       // dst = -a
    Add3,       // dst = a + b (triples, per component)
    Sub3,       // dst = a - b
    Mul3,       // dst = a * b
    Div3,       // dst = a / b, 0 where b == 0
    Neg3,       // dst = -a
    Mul3F,      // dst(triple) = a(triple) * b(float)
    Div3F,      // dst(triple) = a(triple) / b(float)
    Dot,        // dst = a . b
    Cross,      // dst = a ^ b
    MulM,       // dst = a * b (matrices, RSL row-vector order)
    DivM,       // dst = a * inverse(b)
    LtF,        // dst = a < b
    LeF,        // dst = a <= b
    GtF,        // dst = a > b
    GeF,        // dst = a >= b
    EqF,        // dst = a == b (float)
    NeF,        // dst = a != b
    Eq3,        // dst = a == b (triples)
    Ne3,        // dst = a != b
    EqS,        // dst = a == b (strings)
    NeS,        // dst = a != b
    EqM,        // dst = a == b (matrices)
    NeM,        // dst = a != b
    And,        // dst = a && b
    Or,         // dst = a || b
    Not,        // dst = !a
    Select,     // dst = c ? a : b
    Call,       // dst = builtin `sub`(args...)
    Jump,       // goto target
    IfBegin,    // push mask & a; if no point is active goto target
    Else,       // mask = enclosing & !a; if none active goto target
    EndIf,      // pop mask
    LoopBegin,  // push a copy of the mask (points still in the loop)
    LoopCond,   // loop mask &= a; if none left goto target; push body mask
    LoopCont,   // pop the body mask (end of an iteration)
    LoopEnd,    // pop the loop mask
    Break,      // remove active points from mask frames c and above
    IllumBegin, // start illuminance: a=P, b=axis, c=angle (or -1), args: category
    IllumNext,  // next light with active points: set L, Cl, push body mask; none left: goto target
    Illuminate, // light: L = Ps - a; push mask of points inside cone (b axis, c angle); goto target if none
    Solar,      // light: L = a (or -N); push mask; goto target if none
    ParamInit,  // if the instance or a primvar gives param dst a value, load it and goto target
};
const char* opName(Op op);

/// One instruction.
struct Instr {
    Op op = Op::Nop;
    int16_t sub = 0;     // builtin id for Call
    int dst = -1, a = -1, b = -1, c = -1;
    int argBase = 0, nargs = 0;
    uint32_t outMask = 0;  // Call: which args are written
    int target = -1;
    int ctl = 0;         // control context (see CtlCtx)
    bool varies = false; // Call: result differs per point even for uniform arguments
    SrcLoc loc;
};

enum class RegKind : uint8_t { Global, Param, Local, Temp, Const };

/// A register: one variable or temporary, uniform (one value) or varying
/// (one value per grid point), possibly a fixed-size array.
struct RegInfo {
    Ty ty = Ty::Float;
    int arrayLen = 0;
    bool varying = false;
    bool fixed = false;  // varyingness declared, not inferred
    RegKind kind = RegKind::Temp;
    std::string name;
    int constIndex = -1;  // Const: floats at consts[constIndex] or strings at constStrings[constIndex]
    int param = -1;       // Param: index in params
    int global = -1;      // Global: GlobalId
    SrcLoc loc;
    int floatsPerValue() const { return tyFloats(ty) * (arrayLen > 0 ? arrayLen : 1); }
};

/// A control-flow region for uniform/varying inference: code in it runs
/// under a varying mask if `cond` is varying, if it is always varying
/// (illuminance, illuminate, solar), if a break/return out of it happens
/// under varying control, or if its parent is varying.
struct CtlCtx {
    int parent = -1;
    int cond = -1;
    bool alwaysVarying = false;
    std::vector<int> breakers;
};

/// Shader globals.
enum GlobalId : int {
    gP, gN, gNg, gI, gE, gS, gT, gU, gV, gDu, gDv, gDPdu, gDPdv, gCs, gOs, gCi, gOi, gL, gCl, gOl, gPs,
    gNcomps, gTime, gAlpha, gNs, gDtime, gDPdtime, gGlobalCount
};

/// The output of the compiler for one shader.
struct CompiledShader {
    std::string name;
    ShaderKind kind = ShaderKind::Surface;
    std::string fileName;
    std::vector<ShaderParamInfo> params;
    std::vector<int> paramRegs;    // register of each param
    std::vector<RegInfo> regs;
    std::vector<Instr> code;
    std::vector<int> args;
    std::vector<CtlCtx> ctls;
    std::vector<float> consts;
    std::vector<std::string> constStrings;
    int globalRegs[gGlobalCount];
    bool isAmbientLight = false;   // light without illuminate/solar
    bool isSolarLight = false;     // light with solar() and no illuminate(): a distant light
    bool usesLights = false;

    std::string listing() const;
};

/// Compiles source text (with #include search path) to one shader; null
/// after reporting errors.
std::shared_ptr<CompiledShader> compileShaderSource(const std::string& text, const std::string& fileName,
                                                    const std::vector<std::string>& includePath,
                                                    Diagnostics& diag);

/// Post-codegen passes (bytecode.cpp): uniform/varying inference (reports
/// varying values assigned to uniform variables) and dead-code removal.
bool inferVaryingAndOptimize(CompiledShader& cs, CompileErrors& errs);

}  // namespace umbra::shading
