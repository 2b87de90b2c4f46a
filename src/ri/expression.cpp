#include "umbra/ri/expression.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <charconv>

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
            if (!parseNot(out)) return false;
            *out = number(!truth(*out));
            return true;
        }
        return parseCompare(out);
    }
    // compare := primary ( op primary )?
    bool parseCompare(ExprValue* out) {
        if (!parsePrimary(out)) return false;
        static const char* kOps[] = {"==", "!=", "<=", ">=", "<", ">"};
        for (const char* op : kOps) {
            if (!accept(op)) continue;
            ExprValue rhs;
            if (!parsePrimary(&rhs)) return false;
            int c;
            if (!out->isString && !rhs.isString)
                c = out->num < rhs.num ? -1 : out->num > rhs.num ? 1 : 0;
            else
                c = text(*out).compare(text(rhs)), c = c < 0 ? -1 : c > 0 ? 1 : 0;
            const std::string_view o = op;
            bool r = o == "==" ? c == 0 : o == "!=" ? c != 0 : o == "<=" ? c <= 0 : o == ">=" ? c >= 0
                   : o == "<"  ? c < 0  : c > 0;
            *out = number(r);
            return true;
        }
        return true;
    }
    // reference := '$' name | '${' name '}'
    bool parseReference(std::string* name) {
        if (!accept("$")) return fail(fmt::format("expected a $reference, got {}", where()));
        const bool braced = accept("{");
        size_t start = m_i;
        while (m_i < m_s.size() &&
               (std::isalnum(static_cast<unsigned char>(m_s[m_i])) || m_s[m_i] == '_' || m_s[m_i] == ':' ||
                m_s[m_i] == '.'))
            ++m_i;
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
            size_t end = m_s.find(c, m_i + 1);
            if (end == std::string_view::npos) return fail(fmt::format("unterminated string starting at character {}", m_i + 1));
            out->isString = true;
            out->str = std::string(m_s.substr(m_i + 1, end - m_i - 1));
            m_i = end + 1;
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
        if (std::isdigit(static_cast<unsigned char>(c)) || c == '-' || c == '+' || c == '.') {
            double d = 0;
            const char* b = m_s.data() + m_i + (c == '+' ? 1 : 0);
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
                    while (m_i < m_s.size() && (std::isalnum(static_cast<unsigned char>(m_s[m_i])) ||
                                                m_s[m_i] == '_' || m_s[m_i] == ':' || m_s[m_i] == '.'))
                        ++m_i;
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
};

}  // namespace

bool evaluateCondition(std::string_view expr, const ExprLookup& lookup, bool* result, std::string* error,
                       std::vector<std::string>* undefined) {
    std::vector<std::string> scratch;
    ConditionParser p(expr, lookup, undefined ? undefined : &scratch);
    return p.run(result, error);
}

}  // namespace umbra::ri
