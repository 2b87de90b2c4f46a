#include "umbra/ri/expression.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <regex>

namespace umbra::ri {

namespace {

std::string text(const ExprValue& v) {
    if (v.isString) return v.str;
    return fmt::format("{}", v.num);
}

bool truth(const ExprValue& v) { return v.isString ? !v.str.empty() : v.num != 0; }

ExprValue number(double d) {
    ExprValue v;
    v.num = d;
    return v;
}

/// Recursive descent over the grammar in expression.h; each parse
/// function is named after its rule.
class ConditionParser {
public:
    ConditionParser(std::string_view s, const ExprLookup& lookup, std::vector<std::string>* undefined)
        : m_s(s), m_lookup(lookup), m_undefined(undefined) {}

    bool run(bool* result, std::string* error) {
        ExprValue v;
        if (!parseOr(&v)) {
            *error = m_error;
            return false;
        }
        skipSpace();
        if (m_i < m_s.size()) {
            *error = fmt::format("unexpected \"{}\" at character {}", m_s.substr(m_i), m_i + 1);
            return false;
        }
        *result = truth(v);
        return true;
    }

private:
    void skipSpace() {
        while (m_i < m_s.size() && std::isspace(static_cast<unsigned char>(m_s[m_i]))) ++m_i;
    }
    bool accept(std::string_view tok) {
        skipSpace();
        if (m_s.substr(m_i, tok.size()) != tok) return false;
        m_i += tok.size();
        return true;
    }
    bool fail(std::string what) {
        if (m_error.empty()) m_error = std::move(what);
        return false;
    }
    static bool isNameChar(char c) {
        return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == ':' || c == '.';
    }
    std::string where() const {
        return m_i < m_s.size() ? fmt::format("\"{}\" at character {}", m_s.substr(m_i), m_i + 1) : "the end";
    }

    // or := and ( '||' and )*
    bool parseOr(ExprValue* out) {
        if (!parseAnd(out)) return false;
        while (accept("||")) {
            ExprValue rhs;
            if (!parseAnd(&rhs)) return false;
            *out = number(truth(*out) || truth(rhs));
        }
        return true;
    }
    // and := not ( '&&' not )*
    bool parseAnd(ExprValue* out) {
        if (!parseNot(out)) return false;
        while (accept("&&")) {
            ExprValue rhs;
            if (!parseNot(&rhs)) return false;
            *out = number(truth(*out) && truth(rhs));
        }
        return true;
    }
    // not := '!' not | compare
    bool parseNot(ExprValue* out) {
        skipSpace();
        if (m_s.substr(m_i, 2) != "!=" && accept("!")) {
            if (++m_depth > kMaxDepth) return fail("the expression is nested too deeply");
            const bool ok = parseNot(out);
            --m_depth;
            if (!ok) return false;
            *out = number(!truth(*out));
            return true;
        }
        return parseCompare(out);
    }
    // compare := sum ( op sum )?
    bool parseCompare(ExprValue* out) {
        if (!parseSum(out)) return false;
        static const char* kOps[] = {"==", "!=", "=~", "<=", ">=", "<", ">"};
        for (const char* op : kOps) {
            if (!accept(op)) continue;
            ExprValue rhs;
            if (!parseSum(&rhs)) return false;
            const std::string_view o = op;
            if (o == "=~") return match(text(*out), text(rhs), out);
            int c;
            if (!out->isString && !rhs.isString)
                c = out->num < rhs.num ? -1 : out->num > rhs.num ? 1 : 0;
            else
                c = text(*out).compare(text(rhs)), c = c < 0 ? -1 : c > 0 ? 1 : 0;
            bool r = o == "==" ? c == 0 : o == "!=" ? c != 0 : o == "<=" ? c <= 0 : o == ">=" ? c >= 0
                   : o == "<"  ? c < 0  : c > 0;
            *out = number(r);
            return true;
        }
        return true;
    }
    // `text =~ pattern`: true when the ECMAScript regular expression
    // matches somewhere in the text (as Perl's =~). A condition is input:
    // libstdc++'s polynomial executor (no back-references) keeps a
    // pattern such as (a*)*b from taking exponential time, its state limit
    // bounds a pattern's size, and both strings are kept short.
    bool match(const std::string& subject, const std::string& pattern, ExprValue* out) {
        constexpr size_t kMaxLength = 256;
        if (subject.size() > kMaxLength || pattern.size() > kMaxLength)
            return fail(fmt::format("=~ takes a text and a pattern of at most {} characters", kMaxLength));
#ifdef __GLIBCXX__
        const auto flags = std::regex::ECMAScript | std::regex_constants::__polynomial;
#else
        const auto flags = std::regex::ECMAScript;
#endif
        try {
            *out = number(std::regex_search(subject, std::regex(pattern, flags)));
        } catch (const std::regex_error& e) {
            return fail(fmt::format("=~: '{}' is not a regular expression ({})", pattern, e.what()));
        }
        return true;
    }
    // A number from an arithmetic operand: a number, or a string that is
    // one (a reference's value may be either).
    bool numeric(const ExprValue& v, double* d) {
        if (!v.isString) {
            *d = v.num;
            return true;
        }
        const char* b = v.str.data();
        const char* e = b + v.str.size();
        auto r = std::from_chars(b, e, *d);
        if (r.ec == std::errc() && r.ptr == e && b != e) return true;
        return fail(fmt::format("arithmetic on the string '{}' (concat() joins strings)", v.str));
    }
    // sum := product ( ( '+' | '-' ) product )*
    bool parseSum(ExprValue* out) { return parseArithmetic(out, "+-", &ConditionParser::parseProduct); }
    // product := unary ( ( '*' | '/' ) unary )*
    bool parseProduct(ExprValue* out) { return parseArithmetic(out, "*/", &ConditionParser::parseUnary); }
    // operand ( op operand )*, left to right, op one of `ops`.
    bool parseArithmetic(ExprValue* out, std::string_view ops, bool (ConditionParser::*operand)(ExprValue*)) {
        if (!(this->*operand)(out)) return false;
        for (;;) {
            skipSpace();
            if (m_i >= m_s.size() || ops.find(m_s[m_i]) == std::string_view::npos) return true;
            const char op = m_s[m_i++];
            ExprValue rhs;
            double a, b;
            if (!(this->*operand)(&rhs) || !numeric(*out, &a) || !numeric(rhs, &b)) return false;
            *out = number(op == '+' ? a + b : op == '-' ? a - b : op == '*' ? a * b : a / b);
        }
    }
    // unary := ( '-' | '+' ) unary | primary
    bool parseUnary(ExprValue* out) {
        if (++m_depth > kMaxDepth) return fail("the expression is nested too deeply");
        skipSpace();
        bool ok;
        if (m_i < m_s.size() && (m_s[m_i] == '-' || m_s[m_i] == '+')) {
            const bool minus = m_s[m_i++] == '-';
            double d;
            ok = parseUnary(out) && numeric(*out, &d);
            if (ok) *out = number(minus ? -d : d);
        } else {
            ok = parsePrimary(out);
        }
        --m_depth;
        return ok;
    }
    // reference := '$' name | '${' name '}' | '$(' name ')' | '$(' or ')'
    // (the last names what the expression's value spells)
    bool parseReference(std::string* name) {
        if (!accept("$")) return fail(fmt::format("expected a $reference, got {}", where()));
        if (m_s.substr(m_i, 1) == "(") {
            ++m_i;
            const size_t start = m_i;
            skipSpace();
            const size_t nameStart = m_i;
            while (m_i < m_s.size() && isNameChar(m_s[m_i])) ++m_i;
            const size_t nameEnd = m_i;
            if (nameEnd > nameStart && accept(")")) {
                *name = std::string(m_s.substr(nameStart, nameEnd - nameStart));
                return true;
            }
            m_i = start;
            ExprValue v;
            if (!parseOr(&v)) return false;
            if (!accept(")")) return fail(fmt::format("expected ')' after \"$(\", got {}", where()));
            *name = text(v);
            if (name->empty()) return fail("$(...) names nothing (its value is the empty string)");
            return true;
        }
        const bool braced = accept("{");
        size_t start = m_i;
        while (m_i < m_s.size() && isNameChar(m_s[m_i])) ++m_i;
        if (m_i == start) return fail(fmt::format("expected a name after '$', got {}", where()));
        *name = std::string(m_s.substr(start, m_i - start));
        if (braced && !accept("}")) return fail(fmt::format("expected '}}' after \"${{{}\"", *name));
        return true;
    }
    // primary := number | string | reference | defined(reference) | true | false | ( or )
    bool parsePrimary(ExprValue* out) {
        skipSpace();
        if (m_i >= m_s.size()) return fail("expected a value, got the end");
        const char c = m_s[m_i];
        if (c == '(') {
            ++m_i;
            if (!parseOr(out)) return false;
            if (!accept(")")) return fail(fmt::format("expected ')', got {}", where()));
            return true;
        }
        if (c == '\'' || c == '"') {
            // A backslash before the quote or another backslash escapes
            // it; any other backslash stays (a pattern's "\*").
            std::string str;
            size_t k = m_i + 1;
            for (; k < m_s.size() && m_s[k] != c; ++k) {
                if (m_s[k] == '\\' && k + 1 < m_s.size() && (m_s[k + 1] == c || m_s[k + 1] == '\\')) ++k;
                str += m_s[k];
            }
            if (k >= m_s.size()) return fail(fmt::format("unterminated string starting at character {}", m_i + 1));
            out->isString = true;
            out->str = std::move(str);
            m_i = k + 1;
            return true;
        }
        if (c == '$') {
            std::string name;
            if (!parseReference(&name)) return false;
            if (!m_lookup || !m_lookup(name, out)) {
                *out = ExprValue{true, 0, ""};
                if (std::find(m_undefined->begin(), m_undefined->end(), name) == m_undefined->end())
                    m_undefined->push_back(name);
            }
            return true;
        }
        if (std::isdigit(static_cast<unsigned char>(c)) || c == '.') {
            double d = 0;
            const char* b = m_s.data() + m_i;
            auto r = std::from_chars(b, m_s.data() + m_s.size(), d);
            if (r.ec != std::errc()) return fail(fmt::format("expected a number, got {}", where()));
            m_i = size_t(r.ptr - m_s.data());
            *out = number(d);
            return true;
        }
        if (std::isalpha(static_cast<unsigned char>(c))) {
            size_t start = m_i;
            while (m_i < m_s.size() && (std::isalnum(static_cast<unsigned char>(m_s[m_i])) || m_s[m_i] == '_')) ++m_i;
            const std::string_view word = m_s.substr(start, m_i - start);
            if (word == "true" || word == "false") {
                *out = number(word == "true");
                return true;
            }
            if (word == "defined") {
                if (!accept("(")) return fail(fmt::format("expected '(' after defined, got {}", where()));
                std::string name;
                skipSpace();
                if (m_i < m_s.size() && m_s[m_i] != '$') {
                    // defined(user:pass) as well as defined($user:pass).
                    size_t s0 = m_i;
                    while (m_i < m_s.size() && isNameChar(m_s[m_i])) ++m_i;
                    name = std::string(m_s.substr(s0, m_i - s0));
                    if (name.empty()) return fail(fmt::format("expected a name in defined(), got {}", where()));
                } else if (!parseReference(&name)) {
                    return false;
                }
                if (!accept(")")) return fail(fmt::format("expected ')' after defined({}, got {}", name, where()));
                ExprValue ignored;
                *out = number(m_lookup && m_lookup(name, &ignored));
                return true;
            }
            if (word == "concat") {
                // concat(a, b, ...): the texts of its arguments, joined.
                if (!accept("(")) return fail(fmt::format("expected '(' after concat, got {}", where()));
                std::string joined;
                do {
                    ExprValue part;
                    if (!parseOr(&part)) return false;
                    joined += text(part);
                    if (joined.size() > kMaxString) return fail("concat() makes a string too long");
                } while (accept(","));
                if (!accept(")")) return fail(fmt::format("expected ',' or ')' in concat(), got {}", where()));
                *out = ExprValue{true, 0, std::move(joined)};
                return true;
            }
            m_i = start;
            return fail(fmt::format("unknown word \"{}\" (strings are quoted: '{}')", word, word));
        }
        return fail(fmt::format("expected a value, got {}", where()));
    }

    std::string_view m_s;
    const ExprLookup& m_lookup;
    std::vector<std::string>* m_undefined;
    size_t m_i = 0;
    std::string m_error;
    // Nesting is recursion: bounded so a hostile condition cannot exhaust
    // the stack; strings are bounded so concat() cannot double one forever.
    static constexpr int kMaxDepth = 200;
    static constexpr size_t kMaxString = 1 << 16;
    int m_depth = 0;
};

}  // namespace

bool evaluateCondition(std::string_view expr, const ExprLookup& lookup, bool* result, std::string* error,
                       std::vector<std::string>* undefined) {
    std::vector<std::string> scratch;
    ConditionParser p(expr, lookup, undefined ? undefined : &scratch);
    return p.run(result, error);
}

}  // namespace umbra::ri
