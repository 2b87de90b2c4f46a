#include "umbra/ri/lexer.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cfloat>
#include <charconv>
#include <climits>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <utility>

namespace umbra::ri {

namespace {
inline bool isSpace(unsigned char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v'; }
// Characters that end a bare word (a number or a request name).
// A byte >= 0200 is a binary token, which needs no space before it.
inline bool endsWord(unsigned char c) {
    return isSpace(c) || c == '[' || c == ']' || c == '"' || c == '#' || c >= 0200;
}
constexpr double kInfinityD = std::numeric_limits<double>::infinity();
// "nan", "inf" and "infinity" in any case: never a request name, always a
// number that is not one.
bool isNonFiniteName(std::string_view w) {
    auto is = [&](std::string_view name) {
        if (w.size() != name.size()) return false;
        for (size_t k = 0; k < w.size(); ++k)
            if (std::tolower(static_cast<unsigned char>(w[k])) != name[k]) return false;
        return true;
    };
    return is("nan") || is("inf") || is("infinity");
}
std::string notFinite(std::string_view word) {
    return fmt::format("not a finite number \"{}\" (expected a finite number)", word);
}
// An unsigned binary-RIB field, most significant byte first.
uint64_t bigEndian(const char* p, size_t count) {
    uint64_t v = 0;
    for (size_t k = 0; k < count; ++k) v = (v << 8) | static_cast<unsigned char>(p[k]);
    return v;
}
}  // namespace

Lexer::Lexer(std::string_view text, int firstLine) : m_s(text.data()), m_n(text.size()), m_line(firstLine) {}

Lexer::Lexer(ByteSource& source) : m_source(&source) {}

bool Lexer::refill(size_t keep) {
    if (!m_source || m_sourceDone) return false;
    if (m_n - keep >= kMaxTokenBytes) {
        m_overlong = true;
        return false;
    }
    if (m_capturing && m_captureFrom < m_base + keep) {
        const size_t from = m_captureFrom - m_base;
        m_capture.append(m_s + from, keep - from);
        m_captureFrom = m_base + keep;
    }
    m_buffer.erase(0, keep);
    m_base += keep;
    m_pos -= keep;
    const size_t held = m_buffer.size();
    m_buffer.resize(held + kChunkBytes);
    const size_t got = m_source->read(m_buffer.data() + held, kChunkBytes, &m_sourceError);
    m_buffer.resize(held + got);
    m_s = m_buffer.data();
    m_n = m_buffer.size();
    if (got == 0) m_sourceDone = true;
    return got != 0;
}

void Lexer::beginCapture(size_t offset) {
    m_capturing = true;
    m_capture.clear();
    m_captureFrom = std::max(offset, m_base);
}

std::string Lexer::endCapture(size_t offset) {
    if (offset > m_captureFrom)
        m_capture.append(m_s + (m_captureFrom - m_base), offset - m_captureFrom);
    else  // a refill copied past the end (the ArchiveEnd ended the file)
        m_capture.resize(m_capture.size() - (m_captureFrom - offset));
    m_capturing = false;
    return std::move(m_capture);
}

Token Lexer::makeError(int line, int column, std::string message) {
    m_scratch = std::move(message);
    Token t;
    t.kind = TokenKind::Error;
    t.line = line;
    t.column = column;
    t.text = m_scratch;
    return t;
}

Token Lexer::junkError(int line, int column, std::string message) {
    Token t = makeError(line, column, std::move(message));
    t.junk = true;
    return t;
}

Token Lexer::inputError(int line, int column) {
    Token t = makeError(line, column, std::exchange(m_sourceError, {}));
    t.inputFailed = true;
    return t;
}

Token Lexer::next() {
    for (;;) {
        bool definition = false;
        Token t = lexToken(&definition);
        if (!definition) return t;
    }
}

Token Lexer::lexToken(bool* definition) {
    if (m_inArray) return lexArrayElement();
    for (;;) {
        const char* s = m_s;
        const size_t n = m_n;
        size_t pos = m_pos;
        while (pos < n) {
            const char c = s[pos];
            if (c == '\n') {
                m_line += m_line < INT_MAX;  // saturates: 4 GiB of newlines is more lines than an int counts
                m_lineStart = m_base + pos + 1;
            } else if (!isSpace(static_cast<unsigned char>(c))) {
                break;
            }
            ++pos;
        }
        m_pos = pos;
        if (pos == n) {
            if (refill(pos)) continue;
            break;
        }
        if (s[pos] != '#') break;
        // A comment ends at the end of its line: LF, CR-LF, or a lone CR
        // (classic Mac OS files, as Aqsis reads them; read to the next LF,
        // one comment swallowed the whole file).
        for (;;) {
            while (m_pos < m_n && m_s[m_pos] != '\n' && m_s[m_pos] != '\r') ++m_pos;
            if (m_pos < m_n || !refill(m_pos)) break;
        }
    }
    Token t;
    t.line = m_line;
    t.column = columnAt(m_pos);
    t.offset = m_base + m_pos;
    if (m_pos >= m_n) {
        if (!m_sourceError.empty()) return inputError(t.line, t.column);
        return t;
    }

    unsigned char c = static_cast<unsigned char>(m_s[m_pos]);
    if (c == '[') {
        ++m_pos;
        t.kind = TokenKind::ArrayBegin;
        return t;
    }
    if (c == ']') {
        ++m_pos;
        t.kind = TokenKind::ArrayEnd;
        return t;
    }
    if (c == '"') return lexString(t.line, t.column);
    if (c >= 0200) return lexBinary(t.line, t.column, definition);
    if (c < 0x20 && !isSpace(c)) {
        // Skip the whole run so one stray stretch gives one message.
        for (;;) {
            while (m_pos < m_n) {
                unsigned char d = static_cast<unsigned char>(m_s[m_pos]);
                if (!(d < 0x20 && !isSpace(d))) break;
                ++m_pos;
            }
            if (m_pos < m_n || !refill(m_pos)) break;
        }
        return junkError(t.line, t.column, fmt::format("unexpected control character 0x{:02x} (not RIB)", c));
    }
    return lexWord(t.line, t.column);
}

bool Lexer::ensure(size_t count) {
    while (m_n - m_pos < count)
        if (!refill(m_pos)) {
            m_overlong = false;
            return false;
        }
    return true;
}

namespace {
// Binary RIB's first bytes (RI Spec 3.2, table C.1), in octal as the spec
// writes them.
constexpr unsigned kFixedFirst = 0200, kFixedLast = 0217;   // integers and fixed point
constexpr unsigned kShortString = 0220, kLongStringLast = 0243;  // 0220 + length, 0240 + bytes of length - 1
constexpr unsigned kLongString = 0240;
constexpr unsigned kFloat = 0244, kDouble = 0245, kRequest = 0246;
constexpr unsigned kFloatArray = 0310, kFloatArrayLast = 0313;  // 0310 + bytes of count - 1
constexpr unsigned kDefineRequest = 0314;
constexpr unsigned kDefineString = 0315, kDefineStringLast = 0316;  // 0315 + bytes of token - 1
constexpr unsigned kString = 0317, kStringLast = 0320;              // 0317 + bytes of token - 1
bool isReserved(unsigned c) {
    return (c > kRequest && c < kFloatArray) || c > kStringLast;
}
}  // namespace

bool Lexer::field(size_t bytes, uint64_t* value) {
    if (!ensure(1 + bytes)) return false;
    *value = bigEndian(m_s + m_pos + 1, bytes);
    m_pos += 1 + bytes;
    return true;
}

Lexer::Encoded Lexer::encodedString(std::string_view* out) {
    const unsigned c = static_cast<unsigned char>(m_s[m_pos]);
    uint64_t length = c - kShortString;
    if (c >= kLongString && !field(c - kLongString + 1, &length)) return Encoded::Cut;
    if (c < kLongString) ++m_pos;
    if (length >= kMaxTokenBytes - 8) return Encoded::Overlong;  // with its prefix, within what the buffer keeps
    if (!ensure(size_t(length))) return Encoded::Cut;
    *out = std::string_view(m_s + m_pos, size_t(length));
    m_pos += size_t(length);
    return Encoded::Ok;
}

bool Lexer::definedString(std::string* out, std::string* why) {
    if (!ensure(1)) {
        *why = "the input ends before its string";
        return false;
    }
    const unsigned c = static_cast<unsigned char>(m_s[m_pos]);
    if (c == '"') {
        const Token s = lexString(m_line, columnAt(m_pos));
        if (s.kind != TokenKind::String) {
            *why = std::string(s.text);
            return false;
        }
        out->assign(s.text);
        return true;
    }
    if (c < kShortString || c > kLongStringLast) {
        *why = fmt::format("expected a string after it, got byte 0{:o}", c);
        return false;
    }
    std::string_view text;
    switch (encodedString(&text)) {
    case Encoded::Ok: out->assign(text); return true;
    case Encoded::Cut: *why = "the input ends inside its string"; break;
    case Encoded::Overlong: *why = fmt::format("its string is longer than {} MiB", kMaxTokenBytes >> 20); break;
    }
    m_pos = m_n;
    return false;
}

Token Lexer::lexBinary(int line, int column, bool* definition) {
    const unsigned c = static_cast<unsigned char>(m_s[m_pos]);
    Token t;
    t.line = line;
    t.column = column;
    t.offset = m_base + m_pos;
    // The rest of the input is consumed: a cut token leaves nothing to
    // resynchronise on.
    auto truncated = [&]() {
        m_pos = m_n;
        if (!m_sourceError.empty()) return inputError(line, column);
        return makeError(line, column, fmt::format("binary RIB: the input ends inside an encoded token (byte 0{:o})", c));
    };
    auto number = [&](double v, bool isInt) {
        t.kind = TokenKind::Number;
        t.number = v;
        t.isInt = isInt;
        m_scratch = fmt::format("{}", v);
        t.text = m_scratch;
        return t;
    };
    uint64_t value = 0;
    if (c <= kFixedLast) {
        // 0200 + 4 d + w: a signed (w + 1)-byte integer, its bottom d bytes
        // after the point.
        const size_t bytes = (c - kFixedFirst) % 4 + 1, fraction = (c - kFixedFirst) / 4;
        if (!field(bytes, &value)) return truncated();
        const unsigned shift = unsigned(64 - 8 * bytes);
        const int64_t v = int64_t(value << shift) >> shift;
        return number(double(v) / double(uint64_t(1) << (8 * fraction)), fraction == 0);
    }
    if (c <= kLongStringLast) {
        switch (encodedString(&t.text)) {
        case Encoded::Ok: t.kind = TokenKind::String; return t;
        case Encoded::Cut: return truncated();
        case Encoded::Overlong:
            m_pos = m_n;
            return makeError(line, column, fmt::format("binary RIB: string longer than {} MiB", kMaxTokenBytes >> 20));
        }
    }
    if (c == kFloat || c == kDouble) {
        if (!field(c == kFloat ? 4 : 8, &value)) return truncated();
        const double v = c == kFloat ? double(std::bit_cast<float>(uint32_t(value))) : std::bit_cast<double>(value);
        if (!(std::fabs(v) <= double(FLT_MAX)))
            return makeError(line, column, fmt::format("binary RIB: number {} is not a finite 32-bit float", v));
        return number(v, false);
    }
    if (c == kRequest) {
        if (!field(1, &value)) return truncated();
        if (m_requests[value].empty())
            return junkError(line, column,
                             fmt::format("binary RIB: request code {} used before it was defined (0314)", value));
        t.kind = TokenKind::Name;
        t.text = m_requests[value];
        return t;
    }
    if (c >= kFloatArray && c <= kFloatArrayLast) {
        if (!field(c - kFloatArray + 1, &m_arrayLeft)) return truncated();
        m_inArray = true;
        t.kind = TokenKind::ArrayBegin;
        return t;
    }
    if (c == kDefineRequest || (c >= kDefineString && c <= kDefineStringLast)) {
        if (!field(c == kDefineRequest ? 1 : c - kDefineString + 1, &value)) return truncated();
        const uint32_t id = uint32_t(value);
        std::string defined, why;
        if (!definedString(&defined, &why))
            return junkError(line, column, fmt::format("binary RIB: {} definition 0{:o} {}: {}",
                                                       c == kDefineRequest ? "request" : "string", c, id, why));
        if (c == kDefineRequest) {
            const bool word = !defined.empty() && std::none_of(defined.begin(), defined.end(), [](char ch) {
                return endsWord(static_cast<unsigned char>(ch)) || static_cast<unsigned char>(ch) < 0x20;
            });
            if (!word)
                return junkError(line, column,
                                 fmt::format("binary RIB: request code {} defined as \"{}\" (expected a request name)",
                                             id, defined));
            m_requests[id] = std::move(defined);
        } else {
            m_strings[id] = std::move(defined);
        }
        *definition = true;
        return t;
    }
    if (c == kString || c == kStringLast) {
        if (!field(c - kString + 1, &value)) return truncated();
        const auto it = m_strings.find(uint32_t(value));
        if (it == m_strings.end())
            return makeError(line, column,
                             fmt::format("binary RIB: string token {} used before it was defined (0315)", value));
        t.kind = TokenKind::String;
        t.text = it->second;
        return t;
    }
    // Reserved bytes: the whole run, so a stretch of them gives one message.
    for (;;) {
        while (m_pos < m_n && isReserved(static_cast<unsigned char>(m_s[m_pos]))) ++m_pos;
        if (m_pos < m_n || !refill(m_pos)) break;
    }
    return junkError(line, column, fmt::format("binary RIB: reserved byte 0{:o} (not a RIB token)", c));
}

Token Lexer::lexArrayElement() {
    Token t;
    t.line = m_line;
    t.column = columnAt(m_pos);
    t.offset = m_base + m_pos;
    if (m_arrayLeft == 0) {
        m_inArray = false;
        t.kind = TokenKind::ArrayEnd;
        return t;
    }
    if (!ensure(4)) {
        m_inArray = false;
        m_arrayLeft = 0;
        m_pos = m_n;
        if (!m_sourceError.empty()) return inputError(t.line, t.column);
        return makeError(t.line, t.column, "binary RIB: the input ends inside an encoded float array");
    }
    --m_arrayLeft;
    const float v = std::bit_cast<float>(uint32_t(bigEndian(m_s + m_pos, 4)));
    m_pos += 4;
    if (!std::isfinite(v))
        return makeError(t.line, t.column, fmt::format("binary RIB: array element {} is not a finite number", v));
    t.kind = TokenKind::Number;
    t.number = v;
    m_scratch = fmt::format("{}", v);
    t.text = m_scratch;
    return t;
}

Token Lexer::lexWord(int line, int column) {
    size_t start = m_pos;
    for (;;) {
        const char* s = m_s;
        const size_t n = m_n;
        size_t pos = m_pos;
        while (pos < n && !endsWord(static_cast<unsigned char>(s[pos]))) ++pos;
        m_pos = pos;
        if (pos < n) break;
        const size_t base = m_base;
        const bool more = refill(start);
        start -= m_base - base;
        if (!more) break;
    }
    if (m_overlong) {
        // Read past the rest of the word without keeping it.
        m_overlong = false;
        for (;;) {
            while (m_pos < m_n && !endsWord(static_cast<unsigned char>(m_s[m_pos]))) ++m_pos;
            if (m_pos < m_n || !refill(m_pos)) break;
        }
        return makeError(line, column, fmt::format("word longer than {} MiB", kMaxTokenBytes >> 20));
    }
    // The input failed inside the word: report that rather than half a word.
    if (m_pos == m_n && !m_sourceError.empty()) return inputError(line, column);
    const char c = m_s[start];
    std::string_view word(m_s + start, m_pos - start);
    Token t;
    t.line = line;
    t.column = column;
    t.offset = m_base + start;
    bool numeric = (c >= '0' && c <= '9') || c == '+' || c == '-' || c == '.';
    if (!numeric) {
        if (isNonFiniteName(word)) return makeError(line, column, notFinite(word));
        t.kind = TokenKind::Name;
        t.text = word;
        return t;
    }
    std::string_view digits = word;
    if (!digits.empty() && digits[0] == '+') digits.remove_prefix(1);
    double v = 0;
    const char* end = digits.data() + digits.size();
    auto res = std::from_chars(digits.data(), end, v, std::chars_format::general);
    if (digits.empty() || res.ptr != end || (res.ec != std::errc() && res.ec != std::errc::result_out_of_range))
        return makeError(line, column, fmt::format("bad number \"{}\"", word));
    if (res.ec == std::errc::result_out_of_range) {
        // Too small for a double is zero; too large is an error below.
        size_t e = digits.find_first_of("eE");
        bool underflow = e != std::string_view::npos && e + 1 < digits.size() && digits[e + 1] == '-';
        v = underflow ? 0.0 : kInfinityD;
    }
    if (std::isnan(v) || (std::isinf(v) && res.ec == std::errc()))
        return makeError(line, column, notFinite(word));
    // Every value ends up in a 32-bit float (or int): beyond FLT_MAX it
    // would silently become infinity.
    if (!(std::fabs(v) <= double(FLT_MAX)))
        return makeError(line, column,
                         fmt::format("number out of range \"{}\" (expected a magnitude of at most 3.4e38, the "
                                     "largest 32-bit float)", word));
    bool integral = word.find_first_of(".eE") == std::string_view::npos;
    t.kind = TokenKind::Number;
    t.number = v;
    t.isInt = integral && v >= double(INT_MIN) && v <= double(INT_MAX);
    t.text = word;
    return t;
}

Token Lexer::lexString(int line, int column) {
    size_t quote = m_pos++;
    // Fast path: no escapes, the token points into the input.
    for (;;) {
        const char* s = m_s;
        const size_t n = m_n;
        size_t pos = m_pos;
        while (pos < n && s[pos] != '"' && s[pos] != '\\' && s[pos] != '\n') ++pos;
        m_pos = pos;
        if (pos < n) break;
        const size_t base = m_base;
        const bool more = refill(quote);
        quote -= m_base - base;
        if (!more) break;
    }
    const size_t start = quote + 1;
    if (m_pos < m_n && m_s[m_pos] == '"') {
        Token t;
        t.kind = TokenKind::String;
        t.line = line;
        t.column = column;
        t.text = std::string_view(m_s + start, m_pos - start);
        ++m_pos;
        return t;
    }
    m_scratch.assign(m_s + start, m_pos - start);
    // A string may span lines, as PRMan, Aqsis and Pixie read it; one that
    // never ends is reported at its quote and lexing resumes on the line
    // after it, so one missing quote costs one request. While streaming,
    // the input is kept from that first newline on (or from nothing: the
    // string so far is in m_scratch).
    bool sawNewline = false;
    size_t firstNewline = 0, lineStartAtNewline = 0;  // input offsets
    int lineAtNewline = 0;
    for (;;) {
        // Escapes look at most three bytes past the backslash.
        while (m_n - m_pos < 4 && !m_overlong && refill(sawNewline ? firstNewline - m_base : m_pos)) {
        }
        if (m_pos >= m_n || m_scratch.size() >= kMaxTokenBytes) break;
        const char* s = m_s;
        const size_t n = m_n;
        char ch = s[m_pos];
        if (ch == '\n') {
            if (!sawNewline) {
                sawNewline = true;
                firstNewline = m_base + m_pos;
                lineAtNewline = m_line;
                lineStartAtNewline = m_lineStart;
            }
            m_scratch.push_back(ch);
            ++m_pos;
            m_line += m_line < INT_MAX;
            m_lineStart = m_base + m_pos;
            continue;
        }
        if (ch == '"') {
            ++m_pos;
            Token t;
            t.kind = TokenKind::String;
            t.line = line;
            t.column = column;
            t.text = m_scratch;
            return t;
        }
        if (ch != '\\') {
            m_scratch.push_back(ch);
            ++m_pos;
            continue;
        }
        ++m_pos;
        if (m_pos >= n) break;
        char e = s[m_pos++];
        switch (e) {
        case 'n': m_scratch.push_back('\n'); break;
        case 't': m_scratch.push_back('\t'); break;
        case 'r': m_scratch.push_back('\r'); break;
        case 'b': m_scratch.push_back('\b'); break;
        case 'f': m_scratch.push_back('\f'); break;
        case '\r':
            // Line continuation with CR LF.
            if (m_pos < n && s[m_pos] == '\n') ++m_pos;
            m_line += m_line < INT_MAX;
            m_lineStart = m_base + m_pos;
            break;
        case '\n':
            // Line continuation: the backslash and newline vanish.
            m_line += m_line < INT_MAX;
            m_lineStart = m_base + m_pos;
            break;
        default:
            if (e >= '0' && e <= '7') {
                int v = e - '0';
                for (int k = 0; k < 2 && m_pos < n && s[m_pos] >= '0' && s[m_pos] <= '7'; ++k) v = v * 8 + (s[m_pos++] - '0');
                m_scratch.push_back(static_cast<char>(v & 0xff));
            } else {
                m_scratch.push_back(e);  // \\ \" \' and unknown escapes stand for the character
            }
        }
    }
    const bool overlong = m_overlong || m_scratch.size() >= kMaxTokenBytes;
    m_overlong = false;
    // Resume on the next line so the rest of the file still parses.
    if (sawNewline) {
        m_pos = firstNewline - m_base;
        m_line = lineAtNewline;
        m_lineStart = lineStartAtNewline;  // the newline itself is lexed next
    }
    if (!m_sourceError.empty() && !sawNewline) return inputError(line, column);
    if (overlong)
        return makeError(line, column, fmt::format("string longer than {} MiB (or no closing '\"')", kMaxTokenBytes >> 20));
    return makeError(line, column, "unterminated string (no closing '\"' before the end of the input)");
}

}  // namespace umbra::ri
