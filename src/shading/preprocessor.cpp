// Lexer and preprocessor of the shading language. The preprocessor works on
// tokens (not text), so every token keeps the location it came from and
// error carets point into the right file; tokens produced by a macro carry
// the location of the macro's use.

#include "slc.h"

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <string_view>

namespace umbra::shading {

namespace {
constexpr int kMaxIncludeDepth = 32;
constexpr int kMaxMacroDepth = 64;
constexpr size_t kMaxExpandedTokens = 1u << 20;
}  // namespace

int SourceSet::add(const std::string& name, std::string text) {
    files.push_back({std::make_shared<const std::string>(name), std::move(text)});
    return int(files.size()) - 1;
}

std::string SourceSet::lineText(int file, int line) const {
    if (file < 0 || file >= int(files.size()) || line <= 0) return {};
    const std::string& t = files[file].text;
    size_t pos = 0;
    for (int l = 1; l < line; ++l) {
        pos = t.find('\n', pos);
        if (pos == std::string::npos) return {};
        ++pos;
    }
    size_t end = t.find('\n', pos);
    std::string s = t.substr(pos, end == std::string::npos ? std::string::npos : end - pos);
    if (!s.empty() && s.back() == '\r') s.pop_back();
    return s;
}

FileLoc CompileErrors::fileLoc(const SrcLoc& loc) const {
    if (loc.file < 0 || loc.file >= int(m_src.files.size())) return {};
    return FileLoc(m_src.files[loc.file].name, loc.line, loc.col);
}

std::string CompileErrors::quote(const SrcLoc& loc) const {
    std::string line = m_src.lineText(loc.file, loc.line);
    if (line.empty()) return {};
    std::string caret;
    for (int i = 0; i + 1 < loc.col && i < int(line.size()); ++i) caret += line[i] == '\t' ? '\t' : ' ';
    return "\n    " + line + "\n    " + caret + "^";
}

void CompileErrors::error(const SrcLoc& loc, const std::string& msg) {
    ++m_count;
    m_diag.report(Severity::Error, fileLoc(loc), msg + quote(loc));
}

void CompileErrors::warning(const SrcLoc& loc, const std::string& msg) {
    m_diag.report(Severity::Warning, fileLoc(loc), msg + quote(loc));
}

namespace {

/// A file's text after C's translation phase 2, which removes every
/// backslash-newline before comments are recognised (phase 3): a `//`
/// comment ending in a backslash goes on over the next line, a directive
/// or a token may continue there. Maps offsets back to the lines and
/// columns as written, so that later errors keep their places.
class SplicedText {
public:
    explicit SplicedText(const std::string& written) {
        m_anchors.push_back({0, 0});
        size_t w = 0;
        while (w < written.size()) {
            if (written[w] == '\\') {
                size_t newline = w + 1;
                if (newline < written.size() && written[newline] == '\r') ++newline;
                if (newline < written.size() && written[newline] == '\n') {
                    w = newline + 1;
                    m_anchors.push_back({m_text.size(), w});
                    continue;
                }
            }
            m_text += written[w++];
        }
        m_lineStarts.push_back(0);
        for (size_t k = 0; k < written.size(); ++k)
            if (written[k] == '\n') m_lineStarts.push_back(k + 1);
    }

    const std::string& text() const { return m_text; }

    /// The line and column as written of text()[at].
    SrcLoc loc(int file, size_t at) const {
        auto anchor = std::upper_bound(m_anchors.begin(), m_anchors.end(), at,
                                       [](size_t a, const Anchor& b) { return a < b.spliced; });
        --anchor;
        const size_t written = anchor->written + (at - anchor->spliced);
        const auto line = std::upper_bound(m_lineStarts.begin(), m_lineStarts.end(), written) - 1;
        return SrcLoc{file, int(line - m_lineStarts.begin()) + 1, int(written - *line) + 1};
    }

private:
    /// From text()[spliced] on, the text is the one written from [written].
    struct Anchor {
        size_t spliced, written;
    };
    std::string m_text;
    std::vector<Anchor> m_anchors;     // one per splice, by offset
    std::vector<size_t> m_lineStarts;  // offsets in the written text
};

}  // namespace

std::vector<Token> lexFile(const SourceSet& src, int file, CompileErrors& errs) {
    const SplicedText spliced(src.files[file].text);
    const std::string& s = spliced.text();
    std::vector<Token> out;
    size_t i = 0, n = s.size();
    bool lineStart = true, space = false;
    auto loc = [&](size_t at) { return spliced.loc(file, at); };
    while (i < n) {
        char c = s[i];
        if (c == '\n') {
            ++i;
            lineStart = true;
            continue;
        }
        if (std::isspace(static_cast<unsigned char>(c))) {
            ++i;
            space = true;
            continue;
        }
        if (c == '/' && i + 1 < n && s[i + 1] == '/') {
            while (i < n && s[i] != '\n') ++i;
            continue;
        }
        if (c == '/' && i + 1 < n && s[i + 1] == '*') {
            SrcLoc start = loc(i);
            i += 2;
            while (i + 1 < n && !(s[i] == '*' && s[i + 1] == '/')) ++i;
            if (i + 1 >= n) {
                errs.error(start, "unterminated comment");
                break;
            }
            i += 2;
            space = true;
            continue;
        }
        Token t;
        t.loc = loc(i);
        t.lineStart = lineStart;
        t.spaceBefore = space;
        lineStart = false;
        space = false;
        if (std::isalpha(static_cast<unsigned char>(c)) || c == '_') {
            size_t b = i;
            while (i < n && (std::isalnum(static_cast<unsigned char>(s[i])) || s[i] == '_')) ++i;
            t.kind = Tok::Ident;
            t.text = s.substr(b, i - b);
        } else if (std::isdigit(static_cast<unsigned char>(c)) || (c == '.' && i + 1 < n && std::isdigit(static_cast<unsigned char>(s[i + 1])))) {
            size_t b = i;
            while (i < n && std::isdigit(static_cast<unsigned char>(s[i]))) ++i;
            if (i < n && s[i] == '.') {
                ++i;
                while (i < n && std::isdigit(static_cast<unsigned char>(s[i]))) ++i;
            }
            if (i < n && (s[i] == 'e' || s[i] == 'E')) {
                size_t e = i + 1;
                if (e < n && (s[e] == '+' || s[e] == '-')) ++e;
                if (e < n && std::isdigit(static_cast<unsigned char>(s[e]))) {
                    i = e;
                    while (i < n && std::isdigit(static_cast<unsigned char>(s[i]))) ++i;
                }
            }
            t.kind = Tok::Number;
            t.text = s.substr(b, i - b);
            t.number = std::strtod(t.text.c_str(), nullptr);
            if (i < n && (s[i] == 'f' || s[i] == 'F')) ++i;
        } else if (c == '"') {
            const size_t open = i++;
            t.kind = Tok::String;
            bool closed = false;
            while (i < n && s[i] != '\n') {
                if (s[i] == '"') {
                    closed = true;
                    ++i;
                    break;
                }
                if (s[i] == '\\' && i + 1 < n) {
                    char e = s[i + 1];
                    t.text += e == 'n' ? '\n' : e == 't' ? '\t' : e == 'r' ? '\r' : e;
                    i += 2;
                    continue;
                }
                t.text += s[i++];
            }
            if (!closed) {
                t.kind = Tok::Other;
                t.text = s.substr(open, i - open);
            }
        } else if (c == '#') {
            ++i;
            t.kind = Tok::Hash;
            t.text = "#";
        } else {
            static const char* kTwo[] = {"==", "!=", "<=", ">=", "&&", "||", "+=", "-=", "*=", "/=", "++", "--"};
            t.kind = Tok::Punct;
            bool two = false;
            if (i + 1 < n)
                for (const char* p : kTwo)
                    if (s[i] == p[0] && s[i + 1] == p[1]) {
                        t.text = p;
                        i += 2;
                        two = true;
                        break;
                    }
            if (!two) {
                if (std::string_view("+-*/^.,;:?(){}[]=<>!").find(c) == std::string_view::npos) t.kind = Tok::Other;
                t.text = std::string(1, c);
                ++i;
            }
        }
        out.push_back(std::move(t));
    }
    return out;
}

namespace {

/// An integer of an #if expression: C's intmax_t, or uintmax_t for a `u`
/// suffix or a constant too large to be signed. Kept as its bits, so that
/// signed arithmetic wraps instead of being undefined behaviour.
struct IfValue {
    uint64_t bits = 0;
    bool isUnsigned = false;
    int64_t asSigned() const { return static_cast<int64_t>(bits); }
    bool isTrue() const { return bits != 0; }
    static IfValue ofBool(bool b) { return {b ? 1u : 0u, false}; }
};

/// The expression of an #if or #elif, its `defined` and macros already
/// replaced, evaluated with the grammar and arithmetic of the C
/// preprocessor (C99 6.10.1): the unary `+ - ~ !`, the binary
/// `* / % + - << >> < > <= >= == != & ^ | && ||`, `?:` and parentheses;
/// names left over are 0. Operands cpp does not evaluate (right of a false
/// `&&` or a true `||`, the branch `?:` does not take) may divide by zero.
class IfExpression {
public:
    IfExpression(const std::vector<Token>& toks, const SrcLoc& directive, CompileErrors& errs)
        : m_toks(joinSplitTokens(toks)), m_errs(errs), m_end(toks.empty() ? directive : toks.back().loc) {}

    /// The truth of the expression, or nothing after an error was reported.
    std::optional<bool> evaluate() {
        if (m_toks.empty()) {
            fail(m_end, "#if with no expression");
            return std::nullopt;
        }
        const IfValue v = conditional();
        if (!m_failed && m_pos < m_toks.size()) fail(m_toks[m_pos].loc, "malformed #if expression");
        if (m_failed) return std::nullopt;
        return v.isTrue();
    }

private:
    /// The shading language has no `<<`, `>>`, hexadecimal constants or
    /// integer suffixes, so its lexer splits them (`<` `<`, `0` `x1F`,
    /// `10` `u`); written without space between they are joined back here.
    static std::vector<Token> joinSplitTokens(const std::vector<Token>& in) {
        std::vector<Token> out;
        for (const Token& t : in) {
            if (!out.empty() && !t.spaceBefore) {
                Token& prev = out.back();
                const bool shift = prev.kind == Tok::Punct && (prev.text == "<" || prev.text == ">") &&
                                   t.kind == Tok::Punct && t.text == prev.text;
                const bool numberTail = prev.kind == Tok::Number && t.kind == Tok::Ident;
                if (shift || numberTail) {
                    prev.text += t.text;
                    continue;
                }
            }
            out.push_back(t);
        }
        return out;
    }

    bool isOperator(const std::string& op) const {
        if (m_pos >= m_toks.size()) return false;
        const Token& t = m_toks[m_pos];
        return (t.kind == Tok::Punct || t.kind == Tok::Other) && t.text == op;
    }
    SrcLoc here() const { return m_pos < m_toks.size() ? m_toks[m_pos].loc : m_end; }

    /// Reports the first error only; afterwards every rule returns at once.
    IfValue fail(const SrcLoc& loc, const std::string& msg) {
        if (!m_failed) m_errs.error(loc, msg);
        m_failed = true;
        return {};
    }

    /// Counts the nesting of conditional() and unary(), which every cycle
    /// of the recursion passes, so that garbage cannot overflow the stack.
    class Nesting {
    public:
        explicit Nesting(IfExpression& e) : m_e(e) { ++m_e.m_depth; }
        ~Nesting() { --m_e.m_depth; }
        bool tooDeep() const { return m_e.m_depth > kMaxMacroDepth; }

    private:
        IfExpression& m_e;
    };

    /// Marks an operand that cpp does not evaluate: dividing by zero there
    /// is no error.
    class Unevaluated {
    public:
        Unevaluated(IfExpression& e, bool skip) : m_e(e), m_skip(skip) { m_e.m_unevaluated += m_skip; }
        ~Unevaluated() { m_e.m_unevaluated -= m_skip; }

    private:
        IfExpression& m_e;
        int m_skip;
    };

    /// conditional: binary(1) [ '?' conditional ':' conditional ]
    IfValue conditional() {
        Nesting nesting(*this);
        if (nesting.tooDeep()) return fail(here(), "#if expression nested too deeply");
        const IfValue cond = binary(1);
        if (m_failed || !isOperator("?")) return cond;
        ++m_pos;
        IfValue first, second;
        {
            Unevaluated skip(*this, !cond.isTrue());
            first = conditional();
        }
        if (m_failed) return {};
        if (!isOperator(":")) return fail(here(), "expected ':' in #if expression");
        ++m_pos;
        {
            Unevaluated skip(*this, cond.isTrue());
            second = conditional();
        }
        // The result has the type both branches convert to.
        IfValue result = cond.isTrue() ? first : second;
        result.isUnsigned = first.isUnsigned || second.isUnsigned;
        return result;
    }

    /// The binding strength of a binary operator, from `||` (1) to `*` (10);
    /// 0 for any other token.
    static int precedence(const Token& t) {
        if (t.kind != Tok::Punct && t.kind != Tok::Other) return 0;
        static const std::pair<std::string_view, int> kLevels[] = {
            {"||", 1}, {"&&", 2}, {"|", 3},  {"^", 4},  {"&", 5},  {"==", 6}, {"!=", 6}, {"<", 7},  {">", 7},
            {"<=", 7}, {">=", 7}, {"<<", 8}, {">>", 8}, {"+", 9},  {"-", 9},  {"*", 10}, {"/", 10}, {"%", 10}};
        for (const auto& [op, level] : kLevels)
            if (t.text == op) return level;
        return 0;
    }

    /// binary(n): unary { operator of level >= n  binary(level + 1) },
    /// by precedence climbing; all binary operators associate to the left.
    IfValue binary(int minLevel) {
        IfValue lhs = unary();
        while (!m_failed && m_pos < m_toks.size()) {
            const int level = precedence(m_toks[m_pos]);
            if (level == 0 || level < minLevel) break;
            const Token& op = m_toks[m_pos++];
            const bool decided = (op.text == "&&" && !lhs.isTrue()) || (op.text == "||" && lhs.isTrue());
            Unevaluated skip(*this, decided);
            const IfValue rhs = binary(level + 1);
            if (m_failed) break;
            lhs = apply(op, lhs, rhs);
        }
        return lhs;
    }

    /// unary: ( '+' | '-' | '~' | '!' ) unary | '(' conditional ')' | integer | name
    IfValue unary() {
        Nesting nesting(*this);
        if (nesting.tooDeep()) return fail(here(), "#if expression nested too deeply");
        if (m_pos >= m_toks.size()) return fail(m_end, "missing operand at the end of the #if expression");
        const Token& t = m_toks[m_pos++];
        const bool op = t.kind == Tok::Punct || t.kind == Tok::Other;
        if (op && t.text == "+") return unary();
        if (op && t.text == "-") {
            IfValue v = unary();
            v.bits = 0 - v.bits;
            return v;
        }
        if (op && t.text == "~") {
            IfValue v = unary();
            v.bits = ~v.bits;
            return v;
        }
        if (op && t.text == "!") return IfValue::ofBool(!unary().isTrue());
        if (op && t.text == "(") {
            const IfValue v = conditional();
            if (m_failed) return {};
            if (!isOperator(")")) return fail(here(), "expected ')' in #if expression");
            ++m_pos;
            return v;
        }
        if (t.kind == Tok::Number) return integer(t);
        if (t.kind == Tok::Ident) return {};  // a name that is no macro is 0, as in C
        return fail(t.loc, "malformed #if expression");
    }

    /// A C integer constant: decimal, octal (a leading 0) or hexadecimal
    /// (0x), with an optional `u`, `l` or `ll` suffix.
    IfValue integer(const Token& t) {
        const std::string& x = t.text;
        const bool hex = x.size() > 1 && x[0] == '0' && (x[1] == 'x' || x[1] == 'X');
        if (!hex && x.find_first_of(".eE") != std::string::npos)
            return fail(t.loc, fmt::format("floating constant '{}' in #if expression", x));
        const uint64_t base = hex ? 16 : x[0] == '0' ? 8 : 10;
        size_t k = hex ? 2 : 0;
        uint64_t value = 0;
        bool tooLarge = false;
        for (; k < x.size(); ++k) {
            const char c = char(std::tolower(static_cast<unsigned char>(x[k])));
            const uint64_t digit = std::isdigit(static_cast<unsigned char>(c)) ? uint64_t(c - '0')
                                   : c >= 'a' && c <= 'f'                      ? uint64_t(c - 'a' + 10)
                                                                               : 99;
            if (digit >= base) break;
            tooLarge |= value > (UINT64_MAX - digit) / base;
            value = value * base + digit;
        }
        std::string suffix = x.substr(k);
        for (char& c : suffix) c = char(std::tolower(static_cast<unsigned char>(c)));
        static const std::set<std::string> kSuffixes = {"", "u", "l", "ul", "lu", "ll", "ull", "llu"};
        if ((hex && k == 2) || !kSuffixes.count(suffix))
            return fail(t.loc, fmt::format("invalid integer constant '{}' in #if expression", x));
        if (tooLarge) return fail(t.loc, fmt::format("integer constant '{}' too large in #if expression", x));
        // As in cpp, a decimal constant too large for intmax_t is unsigned.
        return {value, suffix.find('u') != std::string::npos || value > uint64_t(INT64_MAX)};
    }

    IfValue apply(const Token& op, const IfValue& a, const IfValue& b) {
        const std::string& o = op.text;
        if (o == "&&") return IfValue::ofBool(a.isTrue() && b.isTrue());
        if (o == "||") return IfValue::ofBool(a.isTrue() || b.isTrue());
        if (o == "<<" || o == ">>") return shift(a, b, o == "<<");
        // The usual arithmetic conversions: unsigned if either side is.
        const bool u = a.isUnsigned || b.isUnsigned;
        if (o == "==") return IfValue::ofBool(a.bits == b.bits);
        if (o == "!=") return IfValue::ofBool(a.bits != b.bits);
        if (o == "<") return IfValue::ofBool(u ? a.bits < b.bits : a.asSigned() < b.asSigned());
        if (o == ">") return IfValue::ofBool(u ? a.bits > b.bits : a.asSigned() > b.asSigned());
        if (o == "<=") return IfValue::ofBool(u ? a.bits <= b.bits : a.asSigned() <= b.asSigned());
        if (o == ">=") return IfValue::ofBool(u ? a.bits >= b.bits : a.asSigned() >= b.asSigned());
        IfValue r{0, u};
        if (o == "+") r.bits = a.bits + b.bits;
        else if (o == "-") r.bits = a.bits - b.bits;
        else if (o == "*") r.bits = a.bits * b.bits;
        else if (o == "&") r.bits = a.bits & b.bits;
        else if (o == "|") r.bits = a.bits | b.bits;
        else if (o == "^") r.bits = a.bits ^ b.bits;
        else if (b.bits == 0) {
            if (m_unevaluated == 0) fail(op.loc, "division by zero in #if expression");
        } else if (u) {
            r.bits = o == "/" ? a.bits / b.bits : a.bits % b.bits;
        } else if (a.asSigned() == INT64_MIN && b.asSigned() == -1) {
            r.bits = o == "/" ? a.bits : 0;  // overflows; wraps as the other operators do
        } else {
            r.bits = uint64_t(o == "/" ? a.asSigned() / b.asSigned() : a.asSigned() % b.asSigned());
        }
        return r;
    }

    /// `a << n` or `a >> n` as cpp computes it: a negative count shifts the
    /// other way; counts past the width leave 0, or -1 when a negative
    /// signed value is shifted right. The result has the type of `a`.
    static IfValue shift(const IfValue& a, const IfValue& n, bool left) {
        uint64_t count = n.bits;
        if (!n.isUnsigned && n.asSigned() < 0) {
            left = !left;
            count = 0 - n.bits;
        }
        IfValue r{0, a.isUnsigned};
        if (left) r.bits = count >= 64 ? 0 : a.bits << count;
        else if (!a.isUnsigned && a.asSigned() < 0) r.bits = count >= 64 ? ~uint64_t(0) : ~(~a.bits >> count);
        else r.bits = count >= 64 ? 0 : a.bits >> count;
        return r;
    }

    std::vector<Token> m_toks;
    CompileErrors& m_errs;
    SrcLoc m_end;  // where an expression that stops too early is reported
    size_t m_pos = 0;
    int m_depth = 0;
    int m_unevaluated = 0;
    bool m_failed = false;
};

struct Macro {
    bool function = false;
    std::vector<std::string> params;
    std::vector<Token> body;
};

/// Token-level preprocessor state.
class Preprocessor {
public:
    Preprocessor(SourceSet& src, const std::vector<std::string>& path, CompileErrors& errs)
        : m_src(src), m_path(path), m_errs(errs) {}

    void run(int file, int depth, std::vector<Token>& out) {
        std::vector<Token> toks = lexFile(m_src, file, m_errs);
        struct Cond {
            bool active;      // this branch is taken
            bool anyTaken;    // some branch of this #if was taken
            bool parentActive;
            SrcLoc loc;
        };
        std::vector<Cond> conds;
        auto active = [&] { return conds.empty() || conds.back().active; };
        size_t i = 0;
        std::vector<Token> pending;  // tokens of the active text to expand
        auto flush = [&] {
            const size_t first = out.size();
            expand(pending, 0, out);
            pending.clear();
            dropStrayText(out, first);
        };
        while (i < toks.size()) {
            if (toks[i].kind == Tok::Hash && toks[i].lineStart) {
                int line = toks[i].loc.line;
                SrcLoc hashLoc = toks[i].loc;
                ++i;
                std::vector<Token> dir;
                while (i < toks.size() && !(toks[i].lineStart && toks[i].loc.line != line)) {
                    if (toks[i].lineStart) break;
                    dir.push_back(toks[i++]);
                }
                flush();
                if (dir.empty()) continue;
                const std::string& d = dir[0].text;
                if (d == "ifdef" || d == "ifndef") {
                    bool def = dir.size() > 1 && isDefined(dir[1].text);
                    bool take = active() && (d == "ifdef" ? def : !def);
                    if (dir.size() < 2) m_errs.error(dir[0].loc, fmt::format("expected a macro name after #{}", d));
                    conds.push_back({take, take, active(), hashLoc});
                } else if (d == "if") {
                    bool take = active() && evalCondition(dir, 1);
                    conds.push_back({take, take, active(), hashLoc});
                } else if (d == "elif") {
                    if (conds.empty()) {
                        m_errs.error(dir[0].loc, "#elif without #if");
                        continue;
                    }
                    Cond& c = conds.back();
                    bool take = c.parentActive && !c.anyTaken && evalCondition(dir, 1);
                    c.active = take;
                    c.anyTaken |= take;
                } else if (d == "else") {
                    if (conds.empty()) {
                        m_errs.error(dir[0].loc, "#else without #if");
                        continue;
                    }
                    Cond& c = conds.back();
                    c.active = c.parentActive && !c.anyTaken;
                    c.anyTaken = true;
                } else if (d == "endif") {
                    if (conds.empty())
                        m_errs.error(dir[0].loc, "#endif without #if");
                    else
                        conds.pop_back();
                } else if (!active()) {
                    continue;
                } else if (d == "define") {
                    define(dir);
                } else if (d == "undef") {
                    if (dir.size() > 1) m_macros.erase(dir[1].text);
                } else if (d == "include") {
                    include(dir, file, depth, out);
                } else if (d == "pragma" || d == "line" || d == "error" || d == "warning") {
                    if (d == "error") m_errs.error(dir[0].loc, "#error");
                } else {
                    m_errs.error(dir[0].loc, fmt::format("unknown preprocessor directive '#{}'", d));
                }
                continue;
            }
            if (active()) pending.push_back(toks[i]);
            ++i;
        }
        flush();
        if (!conds.empty()) m_errs.error(conds.back().loc, "unterminated #if/#ifdef (expected #endif)");
    }

private:
    /// Reports and removes the `Tok::Other` tokens from out[first...]: text
    /// of an active group, or of a macro used there, that the shading
    /// language cannot read. Only here, as in cpp: skipped groups and
    /// unused macros may hold anything.
    void dropStrayText(std::vector<Token>& out, size_t first) {
        size_t kept = first;
        for (size_t k = first; k < out.size(); ++k) {
            if (out[k].kind == Tok::Other) {
                m_errs.error(out[k].loc, strayTextMessage(out[k]));
                continue;
            }
            if (kept != k) out[kept] = std::move(out[k]);
            ++kept;
        }
        out.resize(kept);
    }
    static std::string strayTextMessage(const Token& t) {
        const auto c = static_cast<unsigned char>(t.text[0]);
        if (c == '"') return "unterminated string";
        return fmt::format("unexpected character '{}'", std::isprint(c) ? t.text : fmt::format("\\x{:02x}", c));
    }

    void define(const std::vector<Token>& dir) {
        if (dir.size() < 2 || dir[1].kind != Tok::Ident) {
            m_errs.error(dir.size() > 1 ? dir[1].loc : dir[0].loc, "expected a macro name after #define");
            return;
        }
        Macro m;
        size_t k = 2;
        if (k < dir.size() && dir[k].text == "(" && dir[k].kind == Tok::Punct && !dir[k].spaceBefore) {
            m.function = true;
            ++k;
            while (k < dir.size() && dir[k].text != ")") {
                if (dir[k].kind == Tok::Ident) m.params.push_back(dir[k].text);
                else if (dir[k].text != ",") {
                    m_errs.error(dir[k].loc, "expected a parameter name in macro definition");
                    return;
                }
                ++k;
            }
            if (k >= dir.size()) {
                m_errs.error(dir[1].loc, "expected ')' in macro definition");
                return;
            }
            ++k;
        }
        m.body.assign(dir.begin() + std::ptrdiff_t(k), dir.end());
        m_macros[dir[1].text] = std::move(m);
    }

    void include(const std::vector<Token>& dir, int file, int depth, std::vector<Token>& out) {
        std::string name;
        if (dir.size() > 1 && dir[1].kind == Tok::String) {
            name = dir[1].text;
        } else if (dir.size() > 1 && dir[1].text == "<") {
            for (size_t k = 2; k < dir.size() && dir[k].text != ">"; ++k) name += dir[k].text;
        }
        if (name.empty()) {
            m_errs.error(dir[0].loc, "expected a file name after #include");
            return;
        }
        if (depth >= kMaxIncludeDepth) {
            m_errs.error(dir[0].loc, "#include nested too deeply");
            return;
        }
        namespace fs = std::filesystem;
        std::vector<std::string> dirs;
        dirs.push_back(fs::path(*m_src.files[file].name).parent_path().string());
        dirs.insert(dirs.end(), m_path.begin(), m_path.end());
        for (const std::string& d : dirs) {
            fs::path p = d.empty() ? fs::path(name) : fs::path(d) / name;
            std::error_code ec;
            if (!fs::is_regular_file(p, ec)) continue;
            std::ifstream in(p, std::ios::binary);
            std::stringstream ss;
            ss << in.rdbuf();
            int idx = m_src.add(p.string(), ss.str());
            run(idx, depth + 1, out);
            return;
        }
        m_errs.error(dir[1].loc, fmt::format("cannot find include file '{}'", name));
    }

    /// The truth of the #if or #elif `dir`, whose expression starts at
    /// dir[from]. As in cpp, `defined X` and `defined(X)` are replaced
    /// before macros are expanded. An erroneous expression is false.
    bool evalCondition(const std::vector<Token>& dir, size_t from) {
        std::vector<Token> toks;
        for (size_t k = from; k < dir.size(); ++k) {
            if (dir[k].kind != Tok::Ident || dir[k].text != "defined") {
                toks.push_back(dir[k]);
                continue;
            }
            const bool paren = k + 1 < dir.size() && dir[k + 1].kind == Tok::Punct && dir[k + 1].text == "(";
            const size_t name = k + 1 + (paren ? 1 : 0);
            if (name >= dir.size() || dir[name].kind != Tok::Ident) {
                m_errs.error(dir[k].loc, "expected a macro name after 'defined'");
                return false;
            }
            if (paren && (name + 1 >= dir.size() || dir[name + 1].text != ")")) {
                m_errs.error(dir[name].loc, fmt::format("expected ')' after 'defined({}'", dir[name].text));
                return false;
            }
            Token value = dir[k];
            value.kind = Tok::Number;
            value.text.assign(1, isDefined(dir[name].text) ? '1' : '0');
            toks.push_back(std::move(value));
            k = name + (paren ? 1 : 0);
        }
        std::vector<Token> expanded;
        expand(toks, 0, expanded);
        return IfExpression(expanded, dir[0].loc, m_errs).evaluate().value_or(false);
    }

    /// cpp's predefined macros that shaders use: `__LINE__`, the line of
    /// its use (of the outermost macro's use inside an expansion), and
    /// `__FILE__`, the name of the file as a string literal. A #define of
    /// the same name overrides them.
    static bool isPredefined(const Token& t) {
        return t.kind == Tok::Ident && (t.text == "__LINE__" || t.text == "__FILE__");
    }
    Token predefinedValue(const Token& use) const {
        Token value = use;
        if (use.text == "__LINE__") {
            value.kind = Tok::Number;
            value.number = use.loc.line;
            value.text = std::to_string(use.loc.line);
        } else {
            value.kind = Tok::String;
            value.text = *m_src.files[size_t(use.loc.file)].name;
        }
        return value;
    }
    bool isDefined(const std::string& name) const {
        return m_macros.count(name) || name == "__LINE__" || name == "__FILE__";
    }

    /// Expands macros in `in`, appending to `out`. `depth` bounds nesting;
    /// a macro is not re-expanded inside its own expansion.
    void expand(const std::vector<Token>& in, int depth, std::vector<Token>& out) {
        // `carried`: the last token of an expansion that names a
        // function-like macro, looked at again with the tokens after the
        // expansion (cpp's rescan: GLUE(TW, ICE)(x) calls TWICE(x)).
        std::optional<Token> carried;
        for (size_t k = 0; k < in.size() || carried; ++k) {
            const Token t = carried ? *carried : in[k];
            if (carried) --k;  // `in[k]` is the token after the carried one
            carried.reset();
            if (m_expanded > kMaxExpandedTokens) {
                if (!m_reportedBlowup) m_errs.error(t.loc, "macro expansion too large");
                m_reportedBlowup = true;
                return;
            }
            auto it = t.kind == Tok::Ident ? m_macros.find(t.text) : m_macros.end();
            if (it == m_macros.end() && isPredefined(t)) {
                out.push_back(predefinedValue(t));
                continue;
            }
            if (it == m_macros.end() || m_active.count(t.text)) {
                out.push_back(t);
                continue;
            }
            if (depth >= kMaxMacroDepth) {
                if (!m_reportedBlowup) m_errs.error(t.loc, "macro expansion nested too deeply");
                m_reportedBlowup = true;
                out.push_back(t);
                continue;
            }
            const Macro& m = it->second;
            std::vector<Token> body;
            if (m.function) {
                if (k + 1 >= in.size() || in[k + 1].text != "(" || in[k + 1].kind != Tok::Punct) {
                    out.push_back(t);  // a function-like macro name without arguments is left alone
                    continue;
                }
                std::vector<std::vector<Token>> argsv(1);
                size_t j = k + 2;
                int level = 0;
                for (; j < in.size(); ++j) {
                    const Token& a = in[j];
                    if (a.kind == Tok::Punct && a.text == "(") ++level;
                    if (a.kind == Tok::Punct && a.text == ")") {
                        if (level == 0) break;
                        --level;
                    }
                    if (a.kind == Tok::Punct && a.text == "," && level == 0) {
                        argsv.emplace_back();
                        continue;
                    }
                    argsv.back().push_back(a);
                }
                if (j >= in.size()) {
                    m_errs.error(t.loc, fmt::format("unterminated argument list of macro '{}'", t.text));
                    return;
                }
                if (argsv.size() == 1 && argsv[0].empty() && m.params.empty()) argsv.clear();
                if (argsv.size() != m.params.size()) {
                    m_errs.error(t.loc, fmt::format("macro '{}' expects {} arguments, got {}", t.text, m.params.size(), argsv.size()));
                    k = j;
                    continue;
                }
                substitute(m, &argsv, depth, body);
                k = j;
            } else {
                substitute(m, nullptr, depth, body);
            }
            for (Token& b : body) {
                b.loc = t.loc;  // errors inside an expansion point at the use
                b.lineStart = false;
            }
            m_expanded += body.size();
            m_active.insert(t.text);
            const size_t first = out.size();
            expand(body, depth + 1, out);
            m_active.erase(t.text);
            if (out.size() > first && k + 1 < in.size() && in[k + 1].kind == Tok::Punct && in[k + 1].text == "(") {
                const Token& last = out.back();
                const auto call = last.kind == Tok::Ident ? m_macros.find(last.text) : m_macros.end();
                // A macro's own name in its expansion stays unexpanded, as in cpp.
                if (call != m_macros.end() && call->second.function && last.text != t.text && !m_active.count(last.text)) {
                    carried = last;
                    out.pop_back();
                }
            }
        }
    }

    /// The body of macro `m` with its parameters replaced by the
    /// arguments `args` (null: an object-like macro), as cpp does: `# p`
    /// becomes the argument's spelling as a string, `a ## b` one token
    /// glued from both sides (arguments next to `##` unexpanded), any other
    /// parameter its fully expanded argument. 3Delight's XSI library names
    /// each colour's alpha `n##_a`.
    void substitute(const Macro& m, const std::vector<std::vector<Token>>* args, int depth, std::vector<Token>& out) {
        const std::vector<Token>& mb = m.body;
        auto param = [&](const Token& b) -> int {
            if (!args || b.kind != Tok::Ident) return -1;
            for (size_t pi = 0; pi < m.params.size(); ++pi)
                if (b.text == m.params[pi]) return int(pi);
            return -1;
        };
        auto pasteAt = [&](size_t bi) { return bi + 1 < mb.size() && mb[bi].kind == Tok::Hash && mb[bi + 1].kind == Tok::Hash && !mb[bi + 1].spaceBefore; };
        for (size_t bi = 0; bi < mb.size(); ++bi) {
            const Token& b = mb[bi];
            if (pasteAt(bi)) {
                bi += 2;
                if (bi >= mb.size() || out.empty()) {
                    m_errs.error(b.loc, "'##' needs a token on each side");
                    return;
                }
                const int pi = param(mb[bi]);
                std::vector<Token> right = pi >= 0 ? (*args)[size_t(pi)] : std::vector<Token>{mb[bi]};
                if (right.empty()) continue;
                Token& left = out.back();
                left.text = spelling(left) + spelling(right[0]);
                classify(left);
                for (size_t r = 1; r < right.size(); ++r) out.push_back(right[r]);
                continue;
            }
            if (args && b.kind == Tok::Hash && bi + 1 < mb.size() && param(mb[bi + 1]) >= 0) {
                Token str = b;
                str.kind = Tok::String;
                str.text.clear();
                for (const Token& a : (*args)[size_t(param(mb[bi + 1]))])
                    str.text += (str.text.empty() || !a.spaceBefore ? "" : " ") + spelling(a);
                out.push_back(std::move(str));
                ++bi;
                continue;
            }
            const int pi = param(b);
            if (pi < 0) {
                out.push_back(b);
                continue;
            }
            if (pasteAt(bi + 1)) {  // an argument glued on its right is not expanded
                for (Token a : (*args)[size_t(pi)]) out.push_back(std::move(a));
                continue;
            }
            std::vector<Token> argEx;
            expand((*args)[size_t(pi)], depth + 1, argEx);
            for (Token a : argEx) {
                a.lineStart = false;
                out.push_back(std::move(a));
            }
        }
    }
    /// A token as written (strings in quotes).
    static std::string spelling(const Token& t) {
        return t.kind == Tok::String ? "\"" + t.text + "\"" : t.text;
    }
    /// The kind of a token glued by `##`: a name, a number or punctuation.
    static void classify(Token& t) {
        const std::string& x = t.text;
        const bool name = !x.empty() && (std::isalpha(static_cast<unsigned char>(x[0])) || x[0] == '_') &&
                          std::all_of(x.begin(), x.end(), [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; });
        if (name) {
            t.kind = Tok::Ident;
        } else if (!x.empty() && (std::isdigit(static_cast<unsigned char>(x[0])) || x[0] == '.')) {
            t.kind = Tok::Number;
            t.number = std::strtod(x.c_str(), nullptr);
        } else if (t.kind != Tok::String) {
            t.kind = Tok::Punct;
        }
    }

    SourceSet& m_src;
    const std::vector<std::string>& m_path;
    CompileErrors& m_errs;
    std::map<std::string, Macro> m_macros;
    std::set<std::string> m_active;
    size_t m_expanded = 0;
    bool m_reportedBlowup = false;
};

}  // namespace

std::vector<Token> preprocess(SourceSet& src, int mainFile, const std::vector<std::string>& includePath,
                              CompileErrors& errs) {
    Preprocessor pp(src, includePath, errs);
    std::vector<Token> out;
    pp.run(mainFile, 0, out);
    Token end;
    end.kind = Tok::End;
    if (!out.empty()) end.loc = out.back().loc;
    else end.loc = SrcLoc{mainFile, 1, 1};
    out.push_back(end);
    return out;
}

}  // namespace umbra::shading
