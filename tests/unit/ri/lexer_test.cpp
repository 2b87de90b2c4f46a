#include "umbra/ri/lexer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
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

// Binary RIB (RI Spec 3.2, appendix C): the bytes of a float, most
// significant first.
std::string floatBytes(float f) {
    uint32_t bits;
    std::memcpy(&bits, &f, 4);
    return {char(bits >> 24), char(bits >> 16), char(bits >> 8), char(bits)};
}

TEST(Lexer, BinaryTokensDecodeAsTheSpecEncodesThem) {
    using K = TokenKind;
    uint64_t quarter;
    const double q = 0.25;
    std::memcpy(&quarter, &q, 8);
    std::string d8(8, '\0');
    for (int k = 0; k < 8; ++k) d8[size_t(k)] = char(quarter >> (56 - 8 * k));
    const std::string s = std::string("\x80\x05") +       // 0200: one-byte integer 5
                          "\x81\xff\xfe" +                // 0201: two-byte integer -2
                          "\x85\x01\x80" +                // 0205: two bytes, one after the point: 1.5
                          "\x93" "abc" +                   // 0223: a 3-byte string
                          "\xa0\x03" "xyz" +               // 0240: a string with a one-byte length
                          "\xa4" + floatBytes(2.5f) +      // 0244: a float
                          "\xa5" + d8 +                    // 0245: a double
                          "\xcc\x07\x96" "Sphere" +        // 0314: request 7 is Sphere (no token)
                          "\xa6\x07" +                     // 0246: request 7
                          "\xcd\x02\"Cs\"" +               // 0315: string 2 is "Cs", given in ASCII
                          "\xcf\x02" +                     // 0317: string 2
                          "\xc8\x02" + floatBytes(1.0f) + floatBytes(-0.5f) +  // 0310: a two-float array
                          "Translate\x80\x01";             // ASCII and binary need no space between
    const auto t = lexAll(s);
    const std::vector<std::pair<K, std::string>> expected = {
        {K::Number, "5"},      {K::Number, "-2"},    {K::Number, "1.5"},      {K::String, "abc"},
        {K::String, "xyz"},    {K::Number, "2.5"},   {K::Number, "0.25"},     {K::Name, "Sphere"},
        {K::String, "Cs"},     {K::ArrayBegin, ""},  {K::Number, "1"},        {K::Number, "-0.5"},
        {K::ArrayEnd, ""},     {K::Name, "Translate"}, {K::Number, "1"},      {K::End, ""}};
    ASSERT_EQ(t.size(), expected.size());
    for (size_t k = 0; k < t.size(); ++k) {
        EXPECT_EQ(t[k].kind, expected[k].first) << "token " << k;
        EXPECT_EQ(t[k].text, expected[k].second) << "token " << k;
    }
    EXPECT_TRUE(t[0].isInt);
    EXPECT_EQ(t[1].number, -2.0);
    EXPECT_FALSE(t[2].isInt);
    EXPECT_EQ(t[2].number, 1.5);
    EXPECT_EQ(t[6].number, 0.25);
    EXPECT_EQ(t[11].number, -0.5);
}

TEST(Lexer, BadBinaryTokensAreErrorsAndLexingGoesOn) {
    using K = TokenKind;
    auto kinds = [](const std::vector<Tok>& t) {
        std::vector<K> k;
        for (const Tok& x : t) k.push_back(x.kind);
        return k;
    };
    // A request code never defined, a run of reserved bytes, a non-finite
    // float: one error each, then the next token.
    auto t = lexAll(std::string("\xa6\x09 A \xd1\xd2\xff B \xa4") + floatBytes(INFINITY) + " C");
    EXPECT_EQ(kinds(t), (std::vector<K>{K::Error, K::Name, K::Error, K::Name, K::Error, K::Name, K::End}));
    EXPECT_EQ(t[0].text, "binary RIB: request code 9 used before it was defined (0314)");
    EXPECT_EQ(t[2].text, "binary RIB: reserved byte 0321 (not a RIB token)");
    // A definition that names no request, and one without its string.
    t = lexAll(std::string("\xcc\x01\x93" "a b") + " D \xcc\x02 E");
    EXPECT_EQ(kinds(t), (std::vector<K>{K::Error, K::Name, K::Error, K::Name, K::End}));
    EXPECT_EQ(t[0].text, "binary RIB: request code 1 defined as \"a b\" (expected a request name)");
    // Cut short: a float, a string, an array.
    using namespace std::string_literals;  // "..."s keeps NUL bytes
    for (const std::string& cut : {"A \xa4\x40"s, "A \xa1\x00\x10xy"s, "A \xc8\x03"s + floatBytes(1.0f)}) {
        t = lexAll(cut);
        EXPECT_EQ(t.back().kind, K::End);
        EXPECT_EQ(t[t.size() - 2].kind, K::Error) << t[t.size() - 2].text;
    }
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
    const std::string alphabet = " \n\r\t\"\\#[]0123456789.eE+-naifSphere\x81\x01\x93\xa1\xa4\xa6\xc8\xcc\xcd\xcf\xd1";
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

/// Captures `text` from the token at `from` to the one at `to`, read a few
/// bytes at a time; `readOn` first reads the token after `to`, as the parser
/// does before it ends an archive's capture. Returns the capture and the
/// token read after it (its kind and text).
struct Captured {
    std::string text;
    TokenKind nextKind;
    std::string nextText;
};
Captured captureBetween(const std::string& text, size_t from, size_t to, bool readOn) {
    TrickleSource source(text);
    Lexer lex(source);
    Token t;
    do t = lex.next(); while (t.offset != from);
    lex.beginCapture(t.offset);
    do t = lex.next(); while (t.offset != to);
    Captured c;
    Token after;
    if (readOn) after = lex.next(), c.nextKind = after.kind, c.nextText = std::string(after.text);
    c.text = lex.endCapture(to);
    if (!readOn) after = lex.next(), c.nextKind = after.kind, c.nextText = std::string(after.text);
    return c;
}

TEST(Lexer, CaptureKeepsTheRawTextAcrossReads) {
    const std::string text = "ArchiveBegin \"a\"\n  Sphere 1 -1 1 360 # c\n \"s\\\"t\" ArchiveEnd rest";
    const size_t from = text.find("Sphere"), to = text.find("ArchiveEnd");
    const Captured c = captureBetween(text, from, to, false);
    EXPECT_EQ(c.text, text.substr(from, to - from));
    EXPECT_EQ(c.nextText, "rest");
}

// MayaMan's geometry files end "ArchiveEnd\n#\n": the parser ends the
// capture at the ArchiveEnd after it has read on to the end of the input,
// whose last read had already copied the ArchiveEnd into the capture.
TEST(Lexer, CaptureEndsAtItsOffsetAfterTheInputRanOut) {
    const std::string text = "ArchiveBegin \"a\"\n  Sphere 1 -1 1 360\nArchiveEnd\n#\n";
    const size_t from = text.find("Sphere"), to = text.find("ArchiveEnd");
    const Captured c = captureBetween(text, from, to, true);
    EXPECT_EQ(c.nextKind, TokenKind::End);
    EXPECT_EQ(c.text, text.substr(from, to - from));
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
