#include "umbra/ri/lexer.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace umbra::ri {
namespace {

struct Tok {
    TokenKind kind;
    int line, column;
    std::string text;
    double number;
    bool isInt;
};

std::vector<Tok> lexAll(std::string_view text) {
    Lexer lex(text);
    std::vector<Tok> out;
    for (;;) {
        Token t = lex.next();
        out.push_back({t.kind, t.line, t.column, std::string(t.text), t.number, t.isInt});
        if (t.kind == TokenKind::End) break;
    }
    return out;
}

TEST(Lexer, TokensAndLocations) {
    auto t = lexAll("Sphere 1 -2.5e1 [ \"a b\" ]\n  # comment\n\tWorldBegin ##RenderMan RIB\n+.5");
    ASSERT_EQ(t.size(), 9u);
    EXPECT_EQ(t[0].kind, TokenKind::Name);
    EXPECT_EQ(t[0].text, "Sphere");
    EXPECT_EQ(t[0].line, 1);
    EXPECT_EQ(t[0].column, 1);
    EXPECT_EQ(t[1].kind, TokenKind::Number);
    EXPECT_EQ(t[1].number, 1.0);
    EXPECT_TRUE(t[1].isInt);
    EXPECT_EQ(t[1].column, 8);
    EXPECT_EQ(t[2].number, -25.0);
    EXPECT_FALSE(t[2].isInt);
    EXPECT_EQ(t[2].column, 10);
    EXPECT_EQ(t[3].kind, TokenKind::ArrayBegin);
    EXPECT_EQ(t[3].column, 17);
    EXPECT_EQ(t[4].kind, TokenKind::String);
    EXPECT_EQ(t[4].text, "a b");
    EXPECT_EQ(t[4].column, 19);
    EXPECT_EQ(t[5].kind, TokenKind::ArrayEnd);
    EXPECT_EQ(t[6].kind, TokenKind::Name);
    EXPECT_EQ(t[6].text, "WorldBegin");
    EXPECT_EQ(t[6].line, 3);
    EXPECT_EQ(t[6].column, 2);
    EXPECT_EQ(t[7].kind, TokenKind::Number);
    EXPECT_EQ(t[7].number, 0.5);
    EXPECT_EQ(t[7].line, 4);
    EXPECT_EQ(t[8].kind, TokenKind::End);
}

TEST(Lexer, StringEscapes) {
    // a \n \t \\ \" octal 101 (A), octal 7 (BEL), then a line continuation.
    auto t = lexAll("\"a\\n\\t\\\\\\\"\\101\\7x\\\nb\" Next");
    ASSERT_EQ(t[0].kind, TokenKind::String);
    EXPECT_EQ(t[0].text, std::string("a\n\t\\\"A\x07xb"));
    EXPECT_EQ(t[1].kind, TokenKind::Name);
    EXPECT_EQ(t[1].line, 2);  // the continuation moved to line 2
    EXPECT_EQ(t[1].column, 4);
}

TEST(Lexer, BadNumberIsAnErrorNotAName) {
    auto t = lexAll("1.2.3 4x -");
    EXPECT_EQ(t[0].kind, TokenKind::Error);
    EXPECT_EQ(t[0].text, "bad number \"1.2.3\"");
    EXPECT_EQ(t[1].kind, TokenKind::Error);
    EXPECT_EQ(t[1].text, "bad number \"4x\"");
    EXPECT_EQ(t[1].column, 7);
    EXPECT_EQ(t[2].kind, TokenKind::Error);
}

TEST(Lexer, NumbersNoFloatHoldsAreErrors) {
    // 1e39 is a finite double but infinity as a float; 1e400 is not even a
    // double. Tiny values underflow to zero, which is fine.
    auto t = lexAll("1e39 -3.5e38 1e400 3.4e38 1e-400 nan -INF +inf Infinity");
    ASSERT_EQ(t.size(), 10u);
    EXPECT_EQ(t[0].kind, TokenKind::Error);
    EXPECT_EQ(t[0].text, "number out of range \"1e39\" (expected a magnitude of at most 3.4e38, the largest 32-bit "
                         "float)");
    EXPECT_EQ(t[0].column, 1);
    EXPECT_EQ(t[1].kind, TokenKind::Error);
    EXPECT_EQ(t[1].column, 6);
    EXPECT_EQ(t[2].kind, TokenKind::Error);
    EXPECT_EQ(t[2].text.find("number out of range \"1e400\""), 0u);
    EXPECT_EQ(t[3].kind, TokenKind::Number);
    EXPECT_EQ(t[4].kind, TokenKind::Number);
    EXPECT_EQ(t[4].number, 0.0);
    for (int k = 5; k < 9; ++k) {
        EXPECT_EQ(t[size_t(k)].kind, TokenKind::Error) << k;
        EXPECT_EQ(t[size_t(k)].text.find("not a finite number"), 0u) << k;
    }
    EXPECT_EQ(t[5].text, "not a finite number \"nan\" (expected a finite number)");
}

TEST(Lexer, UnterminatedStringResumesOnNextLine) {
    auto t = lexAll("Surface \"plastic\n WorldBegin");
    EXPECT_EQ(t[1].kind, TokenKind::Error);
    EXPECT_EQ(t[1].line, 1);
    EXPECT_EQ(t[1].column, 9);
    EXPECT_EQ(t[2].kind, TokenKind::Name);
    EXPECT_EQ(t[2].text, "WorldBegin");
    EXPECT_EQ(t[2].line, 2);
}

TEST(Lexer, IntegersOutOfRangeAreFloats) {
    auto t = lexAll("2147483647 4294967296 1e3");
    EXPECT_TRUE(t[0].isInt);
    EXPECT_FALSE(t[1].isInt);
    EXPECT_EQ(t[1].number, 4294967296.0);
    EXPECT_FALSE(t[2].isInt);
    EXPECT_EQ(t[2].number, 1000.0);
}

TEST(Lexer, BinaryBytesGiveOneError) {
    std::string s = "A \x81\x82\x83 B";
    auto t = lexAll(s);
    ASSERT_EQ(t.size(), 4u);
    EXPECT_EQ(t[1].kind, TokenKind::Error);
    EXPECT_EQ(t[2].text, "B");
}

}  // namespace
}  // namespace umbra::ri
