#include "umbra/ri/lexer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <random>
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
    size_t offset;
    bool operator==(const Tok&) const = default;
};

std::vector<Tok> lexAll(Lexer& lex) {
    std::vector<Tok> out;
    for (;;) {
        Token t = lex.next();
        out.push_back({t.kind, t.line, t.column, std::string(t.text), t.number, t.isInt, t.offset});
        if (t.kind == TokenKind::End) break;
    }
    return out;
}

std::vector<Tok> lexAll(std::string_view text) {
    Lexer lex(text);
    return lexAll(lex);
}

/// Hands out `text` a few bytes at a time (1, 2, 3, 1, ...), so every
/// token and escape crosses a read boundary somewhere; then fails with
/// `failure` when that is not empty.
class TrickleSource : public ByteSource {
public:
    explicit TrickleSource(std::string text, std::string failure = {})
        : m_text(std::move(text)), m_failure(std::move(failure)) {}
    size_t read(char* dst, size_t capacity, std::string* error) override {
        const size_t n = std::min({capacity, m_text.size() - m_pos, size_t(1 + m_reads++ % 3)});
        std::memcpy(dst, m_text.data() + m_pos, n);
        m_pos += n;
        if (n == 0) *error = m_failure;
        return n;
    }

private:
    std::string m_text, m_failure;
    size_t m_pos = 0, m_reads = 0;
};

/// A word of `length` letters, then " Sphere", generated as it is read.
class LongWordSource : public ByteSource {
public:
    explicit LongWordSource(size_t length) : m_left(length) {}
    size_t read(char* dst, size_t capacity, std::string*) override {
        const size_t n = std::min(capacity, m_left);
        std::memset(dst, 'a', n);
        m_left -= n;
        if (n > 0 || m_tailDone) return n;
        m_tailDone = true;
        std::memcpy(dst, " Sphere", 7);
        return 7;
    }

private:
    size_t m_left;
    bool m_tailDone = false;
};

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

TEST(Lexer, StreamingGivesTheSameTokensWhereverTheReadsEnd) {
    const std::string text =
        "##RenderMan RIB\nversion 3.04 # comment\r\n"
        "Surface \"plastic\" \"Ks\" [.5] \"s\" \"a\\tb\\101\\\\\\\"c\\\nd\"\n"
        "  Polygon \"P\" [0 0 0  1 0 0  1 1 0] 1.2.3 1e39 nan \x81\x82 B\n"
        "Attribute \"two\nlines\" \"x\" \"never closed\nSphere 1 -1 1 360\n# the end";
    TrickleSource source(text);
    Lexer streamed(source);
    EXPECT_EQ(lexAll(streamed), lexAll(text));
}

TEST(Lexer, StreamingMatchesInMemoryOnRandomText) {
    // 3000 strings over RIB's awkward characters (quotes, escapes,
    // comments, brackets, number-like words, binary bytes), fixed seed.
    const std::string alphabet = " \n\r\t\"\\#[]0123456789.eE+-naifSphere\x81\x01";
    std::mt19937 rng(3);
    std::uniform_int_distribution<size_t> pick(0, alphabet.size() - 1), length(0, 120);
    for (int round = 0; round < 3000; ++round) {
        std::string text(length(rng), ' ');
        for (char& c : text) c = alphabet[pick(rng)];
        TrickleSource source(text);
        Lexer streamed(source);
        ASSERT_EQ(lexAll(streamed), lexAll(text)) << "text: " << text;
    }
}

TEST(Lexer, CaptureKeepsTheRawTextAcrossReads) {
    const std::string text = "ArchiveBegin \"a\"\n  Sphere 1 -1 1 360 # c\n \"s\\\"t\" ArchiveEnd rest";
    const size_t from = text.find("Sphere"), to = text.find("ArchiveEnd");
    TrickleSource source(text);
    Lexer lex(source);
    Token t;
    do t = lex.next(); while (t.offset != from);
    lex.beginCapture(t.offset);
    do t = lex.next(); while (t.offset != to);
    EXPECT_EQ(lex.endCapture(t.offset), text.substr(from, to - from));
    EXPECT_EQ(lex.next().text, "rest");
}

TEST(Lexer, ReadFailureIsAnErrorWhereTheInputStopped) {
    TrickleSource source("Translate 1 2\n  3", "cannot decompress: gzip data is truncated");
    Lexer lex(source);
    auto t = lexAll(lex);
    ASSERT_EQ(t.size(), 5u);
    EXPECT_EQ(t[2].text, "2");
    // The last number may be cut short: the failure stands in its place.
    EXPECT_EQ(t[3].kind, TokenKind::Error);
    EXPECT_EQ(t[3].text, "cannot decompress: gzip data is truncated");
    EXPECT_EQ(t[3].line, 2);
    EXPECT_EQ(t[3].column, 3);
    EXPECT_EQ(t[4].kind, TokenKind::End);
}

TEST(Lexer, OverlongWordIsOneErrorAndIsNotKept) {
    LongWordSource source(Lexer::kMaxTokenBytes + 10);
    Lexer lex(source);
    Token t = lex.next();
    EXPECT_EQ(t.kind, TokenKind::Error);
    EXPECT_EQ(t.text, "word longer than 64 MiB");
    t = lex.next();
    EXPECT_EQ(t.kind, TokenKind::Name);
    EXPECT_EQ(t.text, "Sphere");
    EXPECT_EQ(t.column, int(Lexer::kMaxTokenBytes + 12));
}

}  // namespace
}  // namespace umbra::ri
