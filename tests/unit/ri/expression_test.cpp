#include "umbra/ri/expression.h"

#include <gtest/gtest.h>

#include <map>

namespace umbra::ri {
namespace {

struct Eval {
    std::map<std::string, ExprValue> values{{"user:pass", {true, 0, "shadow"}}, {"Frame", {false, 3, ""}},
                                            {"user:lod", {false, 2.5, ""}}};
    std::vector<std::string> undefined;
    std::string error;
    bool operator()(const std::string& expr) {
        bool r = false;
        error.clear();
        ExprLookup lookup = [&](const std::string& n, ExprValue* v) {
            auto it = values.find(n);
            if (it == values.end()) return false;
            *v = it->second;
            return true;
        };
        EXPECT_TRUE(evaluateCondition(expr, lookup, &r, &error, &undefined)) << expr << ": " << error;
        return r;
    }
    std::string fails(const std::string& expr) {
        bool r;
        error.clear();
        EXPECT_FALSE(evaluateCondition(expr, nullptr, &r, &error, &undefined)) << expr;
        return error;
    }
};

TEST(Condition, ComparesStringsAndNumbers) {
    Eval e;
    EXPECT_TRUE(e("$user:pass == 'shadow'"));
    EXPECT_FALSE(e("$user:pass != 'shadow'"));
    EXPECT_TRUE(e("$user:pass == \"shadow\""));
    EXPECT_TRUE(e("${user:pass} == 'shadow'"));
    EXPECT_TRUE(e("$Frame == 3"));
    EXPECT_TRUE(e("$Frame > 2 && $Frame <= 3"));
    EXPECT_FALSE(e("$Frame < 3"));
    EXPECT_TRUE(e("$Frame >= 3"));
    EXPECT_TRUE(e("$user:lod > 2"));  // numbers, not "2.5" > "2" as text
    EXPECT_TRUE(e("10 > 9"));         // as numbers; as text "10" < "9"
    EXPECT_TRUE(e("'b' > 'a'"));
}

TEST(Condition, LogicPrecedenceAndParentheses) {
    Eval e;
    EXPECT_TRUE(e("1 || 0 && 0"));     // && binds tighter
    EXPECT_FALSE(e("(1 || 0) && 0"));
    EXPECT_TRUE(e("!($Frame == 4)"));
    EXPECT_TRUE(e("!0"));
    EXPECT_FALSE(e("!!0"));
    EXPECT_TRUE(e("true"));
    EXPECT_FALSE(e("false || ''"));
    EXPECT_TRUE(e("'x'"));
}

TEST(Condition, DefinedAndUndefinedReferences) {
    Eval e;
    EXPECT_TRUE(e("defined($user:pass)"));
    EXPECT_TRUE(e("defined(user:pass)"));
    EXPECT_FALSE(e("defined($user:nope)"));
    EXPECT_TRUE(e.undefined.empty());  // asking is not using
    EXPECT_TRUE(e("$user:nope == ''"));
    EXPECT_FALSE(e("$user:nope"));
    EXPECT_EQ(e.undefined, std::vector<std::string>{"user:nope"});
}

TEST(Condition, ArithmeticAsPixieReadsIt) {
    Eval e;
    EXPECT_TRUE(e("1 + 4 * 7.0 == 29"));      // * binds tighter than +
    EXPECT_TRUE(e("(1 + 4) * 7 == 35"));
    EXPECT_TRUE(e("$Frame - 1 == 2"));
    EXPECT_TRUE(e("$Frame/2 == 1.5"));
    EXPECT_TRUE(e("-$Frame == -3 && - -2 == 2 && +2 == 2"));
    EXPECT_TRUE(e("10 - 4 - 3 == 3"));          // left to right
    EXPECT_TRUE(e("$user:lod * 2 > $Frame + 1"));
    EXPECT_TRUE(e("'12' + 1 == 13"));           // a string that spells a number
    EXPECT_TRUE(e("1 + 4 * 7.0 == '29'"));      // compared as text, "29" == "29"
    EXPECT_FALSE(e("1 + 4 * 7.0 == '29' && false"));
    EXPECT_EQ(e.fails("'abc' + 1"), "arithmetic on the string 'abc' (concat() joins strings)");
}

TEST(Condition, ConcatMatchAndIndirectReferences) {
    Eval e;
    e.values["user:which"] = {true, 0, "pass"};
    EXPECT_TRUE(e("concat('sha', 'dow') == $user:pass"));
    EXPECT_TRUE(e("concat('frame', $Frame) == 'frame3'"));
    EXPECT_TRUE(e("$(concat('user:', $user:which)) == 'shadow'"));  // names what it spells
    EXPECT_TRUE(e("1 == $(Frame) - 2"));                           // $(name) as ${name}
    EXPECT_TRUE(e("$user:pass =~ '^sha'"));
    EXPECT_FALSE(e("$user:pass =~ '^dow'"));
    EXPECT_TRUE(e("'*abc\\'' =~ '\\*abc?' || 1 == $(Frame)"));  // \' is a quote, \* stays for the pattern
    EXPECT_EQ(e.fails("'x' =~ '('").substr(0, 24), "=~: '(' is not a regular");
    // Patterns that make a backtracking matcher take exponential time are
    // answered at once; too long a pattern is refused.
    EXPECT_FALSE(e("'aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa' =~ '^(a*)*b$'"));
    EXPECT_EQ(e.fails("'x' =~ '" + std::string(300, 'a') + "'"),
              "=~ takes a text and a pattern of at most 256 characters");
}

TEST(Condition, DeepNestingIsRefusedNotOverflowed) {
    Eval e;
    EXPECT_EQ(e.fails(std::string(100000, '(') + "1" + std::string(100000, ')')),
              "the expression is nested too deeply");
    EXPECT_EQ(e.fails(std::string(100000, '!') + "1"), "the expression is nested too deeply");
    EXPECT_EQ(e.fails(std::string(100000, '-') + "1"), "the expression is nested too deeply");
    EXPECT_TRUE(e(std::string(50, '(') + "1" + std::string(50, ')')));
}

TEST(Condition, MalformedExpressionsSayWhere) {
    Eval e;
    EXPECT_EQ(e.fails("$user:pass == "), "expected a value, got the end");
    EXPECT_EQ(e.fails("(1"), "expected ')', got the end");
    EXPECT_EQ(e.fails("pass == 'x'"), "unknown word \"pass\" (strings are quoted: 'pass')");
    EXPECT_EQ(e.fails("'open"), "unterminated string starting at character 1");
    EXPECT_EQ(e.fails("1 2"), "unexpected \"2\" at character 3");
    EXPECT_EQ(e.fails("$ == 1"), "expected a name after '$', got \"== 1\" at character 3");
}

}  // namespace
}  // namespace umbra::ri
