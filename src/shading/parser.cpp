// Recursive-descent parser of the shading language (RI spec 3.2 part II).
// Each parse function starts with the grammar rule it implements.

#include "slc.h"

namespace umbra::shading {

namespace {

constexpr int kMaxNesting = 200;
constexpr int kMaxChain = 1000;

bool typeKeyword(const std::string& s, Ty* t) {
    static const std::pair<const char*, Ty> kTypes[] = {
        {"float", Ty::Float}, {"color", Ty::Color}, {"point", Ty::Point}, {"vector", Ty::Vector},
        {"normal", Ty::Normal}, {"matrix", Ty::Matrix}, {"string", Ty::String}, {"void", Ty::Void}};
    for (auto& [n, ty] : kTypes)
        if (s == n) {
            if (t) *t = ty;
            return true;
        }
    return false;
}

bool shaderKeyword(const std::string& s, ShaderKind* k) {
    static const std::pair<const char*, ShaderKind> kKinds[] = {
        {"surface", ShaderKind::Surface}, {"light", ShaderKind::Light}, {"displacement", ShaderKind::Displacement},
        {"volume", ShaderKind::Volume}, {"imager", ShaderKind::Imager}};
    for (auto& [n, kind] : kKinds)
        if (s == n) {
            if (k) *k = kind;
            return true;
        }
    return false;
}

class Parser {
public:
    Parser(const std::vector<Token>& toks, CompileErrors& errs) : m_t(toks), m_errs(errs) {}

    // program := { shader_definition | function_definition }
    Program program() {
        Program prog;
        while (!at(Tok::End) && m_errs.count() < 20) {
            size_t before = m_p;
            ShaderKind kind;
            if (peek().kind == Tok::Ident && shaderKeyword(peek().text, &kind)) {
                prog.shaders.push_back(shaderDef());
            } else if (isTypeStart()) {
                auto f = functionDef();
                if (f) prog.functions.push_back(std::move(f));
            } else {
                error(peek().loc, fmt::format("expected a shader or function definition, found {}", describe(peek())));
                ++m_p;
            }
            if (m_p == before) ++m_p;
        }
        return prog;
    }

private:
    const Token& peek(int k = 0) const { return m_t[std::min(m_p + size_t(k), m_t.size() - 1)]; }
    bool at(Tok k) const { return peek().kind == k; }
    bool isP(const char* s, int k = 0) const { return peek(k).kind == Tok::Punct && peek(k).text == s; }
    bool isId(const char* s, int k = 0) const { return peek(k).kind == Tok::Ident && peek(k).text == s; }
    const Token& next() {
        const Token& t = peek();
        if (m_p + 1 < m_t.size()) ++m_p;
        return t;
    }
    static std::string describe(const Token& t) {
        switch (t.kind) {
        case Tok::End: return "end of file";
        case Tok::Number: return fmt::format("'{}'", t.text);
        case Tok::String: return fmt::format("string \"{}\"", t.text);
        default: return fmt::format("'{}'", t.text);
        }
    }
    void error(const SrcLoc& loc, const std::string& msg) {
        if (m_panic) return;
        m_errs.error(loc, msg);
        m_panic = true;
    }
    bool expect(const char* p, const char* what = nullptr) {
        if (isP(p)) {
            next();
            return true;
        }
        error(peek().loc, fmt::format("expected '{}'{}{}, found {}", p, what ? " " : "", what ? what : "", describe(peek())));
        return false;
    }
    std::string expectIdent(const char* what) {
        if (at(Tok::Ident)) return next().text;
        error(peek().loc, fmt::format("expected {}, found {}", what, describe(peek())));
        return {};
    }
    /// Skips to the end of the current statement after an error.
    void recover() {
        int depth = 0;
        while (!at(Tok::End)) {
            if (isP("{")) ++depth;
            if (isP("}")) {
                if (depth == 0) break;
                --depth;
                if (depth == 0) {
                    next();
                    break;
                }
            }
            if (isP(";") && depth == 0) {
                next();
                break;
            }
            next();
        }
        m_panic = false;
    }
    bool isTypeStart(int k = 0) const {
        const Token& t = peek(k);
        if (t.kind != Tok::Ident) return false;
        return typeKeyword(t.text, nullptr) || t.text == "uniform" || t.text == "varying" || t.text == "output";
    }

    // shader_definition := shader_type identifier '(' [formals] ')' block
    ShaderDef shaderDef() {
        ShaderDef d;
        shaderKeyword(peek().text, &d.kind);
        next();
        d.loc = peek().loc;
        d.name = expectIdent("a shader name");
        expect("(");
        d.params = formals(true);
        expect(")");
        d.body = block();
        if (m_panic) recover();
        return d;
    }

    // function_definition := [output] [detail] type identifier '(' [formals] ')' block
    std::shared_ptr<FuncDef> functionDef() {
        auto f = std::make_shared<FuncDef>();
        f->ret = typeSpec();
        f->loc = peek().loc;
        f->name = expectIdent("a function name");
        if (!expect("(")) {
            recover();
            return nullptr;
        }
        f->formals = formals(false);
        expect(")");
        f->body = block();
        if (m_panic) {
            recover();
            return nullptr;
        }
        return f;
    }

    // type_spec := [output] [uniform | varying] type
    TypeSpec typeSpec() {
        TypeSpec ts;
        for (;;) {
            if (isId("output")) ts.output = true;
            else if (isId("uniform")) ts.detail = Detail::Uniform;
            else if (isId("varying")) ts.detail = Detail::Varying;
            else break;
            next();
        }
        if (at(Tok::Ident) && typeKeyword(peek().text, &ts.ty)) {
            next();
        } else {
            error(peek().loc, fmt::format("expected a type, found {}", describe(peek())));
        }
        return ts;
    }

    // formals := formal { ';' formal } [';']
    // formal := type_spec declarator { ',' declarator }
    std::vector<VarDecl> formals(bool shaderParams) {
        std::vector<VarDecl> out;
        while (!isP(")") && !at(Tok::End) && !m_panic) {
            TypeSpec ts = typeSpec();
            if (m_panic) break;
            for (;;) {
                VarDecl d = declarator(ts, shaderParams);
                if (m_panic) return out;
                if (shaderParams && !d.init && !d.hasArrayInit) error(d.loc, fmt::format("shader parameter '{}' needs a default value", d.name));
                out.push_back(std::move(d));
                if (isP(",") && !(peek(1).kind == Tok::Ident && isTypeStart(1))) {
                    next();
                    continue;
                }
                break;
            }
            if (isP(";") || isP(",")) next();
            else if (!isP(")")) {
                error(peek().loc, fmt::format("expected ';' or ')' after parameter, found {}", describe(peek())));
                break;
            }
        }
        return out;
    }

    // declarator := identifier ['[' [number] ']'] ['=' (expr | '{' expr {',' expr} '}')]
    VarDecl declarator(TypeSpec ts, bool allowInit) {
        VarDecl d;
        d.loc = peek().loc;
        d.name = expectIdent("a variable name");
        if (isP("[")) {
            next();
            if (at(Tok::Number)) {
                double n = next().number;
                if (n < 1 || n > 1e6 || n != double(int(n))) error(d.loc, "array length must be a positive integer");
                ts.arrayLen = int(n);
            } else {
                ts.arrayLen = -1;
            }
            expect("]");
        }
        d.type = ts;
        if (isP("=")) {
            next();
            if (isP("{")) {
                next();
                d.hasArrayInit = true;
                while (!isP("}") && !m_panic) {
                    d.arrayInit.push_back(expr());
                    if (!isP(",")) break;
                    next();
                }
                expect("}");
                if (d.type.arrayLen == -1 && d.type.arrayLen != 0) d.type.arrayLen = int(d.arrayInit.size());
            } else {
                d.init = assignment();
            }
        }
        return d;
    }

    // declaration := type declarator { ',' declarator } ';'
    void declarations(Stmt& s, const char* endContext) {
        s.kind = Stmt::Decl;
        TypeSpec ts = typeSpec();
        for (;;) {
            s.decls.push_back(declarator(ts, true));
            if (m_panic || !isP(",")) break;
            next();
        }
        expect(";", endContext);
    }

    // block := '{' { statement } '}'
    StmtP block() {
        auto s = std::make_unique<Stmt>();
        s->kind = Stmt::Block;
        s->loc = peek().loc;
        if (!expect("{")) return s;
        while (!isP("}") && !at(Tok::End)) {
            size_t before = m_p;
            s->body.push_back(statement());
            if (m_panic) recover();
            if (m_p == before) next();
        }
        expect("}", "at end of block");
        return s;
    }

    // statement := block | declaration ';' | function_definition | if | while | for
    //            | break [n] ';' | continue [n] ';' | return [expr] ';'
    //            | illuminance '(' args ')' statement | illuminate '(' args ')' statement
    //            | solar '(' [args] ')' statement | extern declaration ';' | expr ';' | ';'
    StmtP statement() {
        m_chain = 0;
        auto s = std::make_unique<Stmt>();
        s->loc = peek().loc;
        if (++m_depth > kMaxNesting) {
            error(peek().loc, "statements nested too deeply");
            --m_depth;
            s->kind = Stmt::Empty;
            return s;
        }
        struct Guard {
            int& d;
            ~Guard() { --d; }
        } guard{m_depth};
        if (isP("{")) return block();
        if (isP(";")) {
            next();
            s->kind = Stmt::Empty;
            return s;
        }
        if (isId("extern")) {
            next();
            s->kind = Stmt::Extern;
            TypeSpec ts = typeSpec();
            for (;;) {
                s->decls.push_back(declarator(ts, false));
                if (!isP(",")) break;
                next();
            }
            expect(";");
            return s;
        }
        if (isTypeStart()) {
            // A function definition has '(' after the name.
            int k = 0;
            while (isId("output", k) || isId("uniform", k) || isId("varying", k)) ++k;
            if (peek(k + 1).kind == Tok::Ident && peek(k + 2).kind == Tok::Punct && peek(k + 2).text == "(") {
                s->kind = Stmt::Func;
                s->func = functionDef();
                if (!s->func) s->kind = Stmt::Empty;
                return s;
            }
            declarations(*s, "after declaration");
            return s;
        }
        if (isId("if")) {
            next();
            s->kind = Stmt::If;
            expect("(");
            s->exprs.push_back(expr());
            expect(")");
            s->body.push_back(statement());
            if (isId("else")) {
                next();
                s->body.push_back(statement());
            }
            return s;
        }
        if (isId("while")) {
            next();
            s->kind = Stmt::While;
            expect("(");
            s->exprs.push_back(expr());
            expect(")");
            s->body.push_back(statement());
            return s;
        }
        if (isId("for")) {
            next();
            s->kind = Stmt::For;
            expect("(");
            if (isTypeStart()) {
                // for (float i = 0; ...): Aqsis's compiler takes a
                // declaration here (Pixie's does not); it is read as a
                // block of the declaration and the loop, so `i` is the
                // loop's own. umbra said "the left side of an assignment
                // must be a variable".
                auto decl = std::make_unique<Stmt>();
                decl->loc = peek().loc;
                declarations(*decl, "after the loop's declaration");
                s->exprs.push_back(nullptr);
                s->exprs.push_back(isP(";") ? nullptr : expr());
                expect(";");
                s->exprs.push_back(isP(")") ? nullptr : expr());
                expect(")");
                s->body.push_back(statement());
                auto scope = std::make_unique<Stmt>();
                scope->kind = Stmt::Block;
                scope->loc = s->loc;
                scope->body.push_back(std::move(decl));
                scope->body.push_back(std::move(s));
                return scope;
            }
            s->exprs.push_back(isP(";") ? nullptr : expr());
            expect(";");
            s->exprs.push_back(isP(";") ? nullptr : expr());
            expect(";");
            s->exprs.push_back(isP(")") ? nullptr : expr());
            expect(")");
            s->body.push_back(statement());
            return s;
        }
        if (isId("break") || isId("continue")) {
            s->kind = peek().text == "break" ? Stmt::Break : Stmt::Continue;
            next();
            if (at(Tok::Number)) {
                double n = next().number;
                if (n < 1 || n != double(int(n)) || n > 1000) error(s->loc, "break/continue level must be a positive integer");
                else s->level = int(n);
            }
            expect(";");
            return s;
        }
        if (isId("return")) {
            next();
            s->kind = Stmt::Return;
            if (!isP(";")) s->exprs.push_back(expr());
            expect(";");
            return s;
        }
        if (isId("illuminance") || isId("illuminate") || isId("solar")) {
            std::string w = next().text;
            s->kind = w == "illuminance" ? Stmt::Illuminance : w == "illuminate" ? Stmt::Illuminate : Stmt::Solar;
            expect("(");
            while (!isP(")") && !m_panic) {
                s->exprs.push_back(assignment());
                if (!isP(",")) break;
                next();
            }
            expect(")");
            s->body.push_back(statement());
            return s;
        }
        s->kind = Stmt::ExprS;
        s->exprs.push_back(expr());
        expect(";", "after expression");
        return s;
    }

    ExprP make(Expr::Kind k, SrcLoc loc) {
        auto e = std::make_unique<Expr>();
        e->kind = k;
        e->loc = loc;
        return e;
    }

    // expr := assignment
    ExprP expr() { return assignment(); }

    // assignment := ternary [('=' | '+=' | '-=' | '*=' | '/=') assignment]
    ExprP assignment() {
        if (++m_depth > kMaxNesting) {
            error(peek().loc, "expression nested too deeply");
            --m_depth;
            return make(Expr::Num, peek().loc);
        }
        ExprP lhs = ternary();
        if (isP("=") || isP("+=") || isP("-=") || isP("*=") || isP("/=")) {
            const Token& op = next();
            auto e = make(Expr::Assign, op.loc);
            e->name = op.text;
            e->kids.push_back(std::move(lhs));
            e->kids.push_back(assignment());
            --m_depth;
            return e;
        }
        --m_depth;
        return lhs;
    }

    // ternary := or ['?' expr ':' ternary]
    ExprP ternary() {
        ExprP c = logicalOr();
        if (!isP("?")) return c;
        auto e = make(Expr::Ternary, next().loc);
        e->kids.push_back(std::move(c));
        e->kids.push_back(assignment());
        expect(":");
        if (++m_depth > kMaxNesting) {
            error(peek().loc, "expression nested too deeply");
            --m_depth;
            return e;
        }
        e->kids.push_back(ternary());
        --m_depth;
        return e;
    }

    ExprP binary(ExprP lhs, const Token& op, ExprP rhs) {
        // Left-associative chains nest to the left; bound them so that the
        // tree (and the recursion over it) stays shallow.
        if (++m_chain > kMaxChain) error(op.loc, "expression too long");
        auto e = make(Expr::Binary, op.loc);
        e->name = op.text;
        e->kids.push_back(std::move(lhs));
        e->kids.push_back(std::move(rhs));
        return e;
    }

    // or := and { '||' and }
    ExprP logicalOr() {
        ExprP l = logicalAnd();
        while (!m_panic && isP("||")) {
            const Token& op = next();
            l = binary(std::move(l), op, logicalAnd());
        }
        return l;
    }
    // and := equality { '&&' equality }
    ExprP logicalAnd() {
        ExprP l = equality();
        while (!m_panic && isP("&&")) {
            const Token& op = next();
            l = binary(std::move(l), op, equality());
        }
        return l;
    }
    // equality := relational { ('==' | '!=') relational }
    ExprP equality() {
        ExprP l = relational();
        while (!m_panic && (isP("==") || isP("!="))) {
            const Token& op = next();
            l = binary(std::move(l), op, relational());
        }
        return l;
    }
    // relational := additive { ('<' | '<=' | '>' | '>=') additive }
    ExprP relational() {
        ExprP l = additive();
        while (!m_panic && (isP("<") || isP("<=") || isP(">") || isP(">="))) {
            const Token& op = next();
            l = binary(std::move(l), op, additive());
        }
        return l;
    }
    // additive := crossExpr { ('+' | '-') crossExpr }
    ExprP additive() {
        ExprP l = crossExpr();
        while (!m_panic && (isP("+") || isP("-"))) {
            const Token& op = next();
            l = binary(std::move(l), op, crossExpr());
        }
        return l;
    }
    // crossExpr := multiplicative { '^' multiplicative }
    ExprP crossExpr() {
        ExprP l = multiplicative();
        while (!m_panic && isP("^")) {
            const Token& op = next();
            l = binary(std::move(l), op, multiplicative());
        }
        return l;
    }
    // multiplicative := dotExpr { ('*' | '/') dotExpr }
    ExprP multiplicative() {
        ExprP l = dotExpr();
        while (!m_panic && (isP("*") || isP("/"))) {
            const Token& op = next();
            l = binary(std::move(l), op, dotExpr());
        }
        return l;
    }
    // dotExpr := unary { '.' unary }
    ExprP dotExpr() {
        ExprP l = unary();
        while (!m_panic && isP(".")) {
            const Token& op = next();
            l = binary(std::move(l), op, unary());
        }
        return l;
    }

    // unary := ('-' | '+' | '!') unary | type [string] unary | '(' type ')' unary | postfix
    ExprP unary() {
        if (++m_depth > kMaxNesting) {
            error(peek().loc, "expression nested too deeply");
            --m_depth;
            return make(Expr::Num, peek().loc);
        }
        struct Guard {
            int& d;
            ~Guard() { --d; }
        } guard{m_depth};
        if (isP("-") || isP("!") || isP("+")) {
            const Token& op = next();
            ExprP operand = unary();
            if (op.text == "+") return operand;
            auto e = make(Expr::Unary, op.loc);
            e->name = op.text;
            e->kids.push_back(std::move(operand));
            return e;
        }
        Ty ty;
        if (at(Tok::Ident) && typeKeyword(peek().text, &ty) && ty != Ty::Void) {
            auto e = make(Expr::Cast, next().loc);
            e->castTy = ty;
            if (at(Tok::String)) e->name = next().text;
            e->kids.push_back(unary());
            return e;
        }
        if (isP("(") && peek(1).kind == Tok::Ident && typeKeyword(peek(1).text, &ty) && ty != Ty::Void && isP(")", 2)) {
            auto e = make(Expr::Cast, next().loc);
            next();
            next();
            e->castTy = ty;
            e->kids.push_back(unary());
            return e;
        }
        return postfix();
    }

    // postfix := primary { '[' expr ']' }
    ExprP postfix() {
        ExprP e = primary();
        while (!m_panic && isP("[")) {
            if (++m_chain > kMaxChain) error(peek().loc, "expression too long");
            auto ix = make(Expr::Index, next().loc);
            ix->kids.push_back(std::move(e));
            ix->kids.push_back(expr());
            expect("]");
            e = std::move(ix);
        }
        return e;
    }

    // primary := number | string | identifier | identifier '(' [args] ')'
    //          | '(' expr ')' | '(' expr ',' expr ',' expr ')' | '(' 16 exprs ')'
    ExprP primary() {
        const Token& t = peek();
        if (t.kind == Tok::Number) {
            auto e = make(Expr::Num, t.loc);
            e->num = t.number;
            next();
            return e;
        }
        if (t.kind == Tok::String) {
            auto e = make(Expr::Str, t.loc);
            e->name = t.text;
            next();
            // Adjacent string literals concatenate, as in C.
            while (at(Tok::String)) e->name += next().text;
            return e;
        }
        if (t.kind == Tok::Ident) {
            if (isP("(", 1)) {
                auto e = make(Expr::Call, t.loc);
                e->name = t.text;
                next();
                next();
                while (!isP(")") && !m_panic && !at(Tok::End)) {
                    e->kids.push_back(assignment());
                    if (!isP(",")) break;
                    next();
                }
                expect(")", "after function arguments");
                return e;
            }
            auto e = make(Expr::Var, t.loc);
            e->name = t.text;
            next();
            return e;
        }
        if (isP("(")) {
            SrcLoc loc = next().loc;
            ExprP first = expr();
            if (isP(",")) {
                auto e = make(Expr::Tuple, loc);
                e->kids.push_back(std::move(first));
                while (isP(",") && !m_panic) {
                    next();
                    e->kids.push_back(expr());
                }
                expect(")");
                if (e->kids.size() != 3 && e->kids.size() != 16)
                    error(loc, fmt::format("a parenthesised tuple needs 3 or 16 values, not {}", e->kids.size()));
                return e;
            }
            expect(")");
            return first;
        }
        error(t.loc, fmt::format("expected an expression, found {}", describe(t)));
        return make(Expr::Num, t.loc);
    }

    const std::vector<Token>& m_t;
    CompileErrors& m_errs;
    size_t m_p = 0;
    int m_depth = 0;
    int m_chain = 0;  // binary/index nodes in the current statement
    bool m_panic = false;
};

}  // namespace

Program parse(const std::vector<Token>& toks, CompileErrors& errs) {
    Parser p(toks, errs);
    return p.program();
}

}  // namespace umbra::shading
