#pragma once
// The RIB tokenizer (RI spec 3.2, appendix C "Language binding details"):
// ASCII RIB and the binary encoding, freely mixed. Tokens are request
// names, numbers, strings and the array brackets; `#` comments (including
// `##` structure comments) are skipped. Binary tokens (bytes 0200-0377)
// become the same tokens: an encoded request its name, an encoded float
// array its brackets and numbers; request and string definitions (0314,
// 0315-0316) give no token of their own.

#include <climits>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <unordered_map>

namespace umbra::ri {

enum class TokenKind {
    End,         // end of input
    Name,        // a request name (any bare word that is not a number)
    Number,      // integer or float
    String,      // a quoted string, escapes decoded
    ArrayBegin,  // [
    ArrayEnd,    // ]
    Error,       // malformed input; `text` holds the message
};

/// One token with its 1-based source position. `text` points into the
/// input or into the lexer's scratch buffer and stays valid only until the
/// next call to Lexer::next().
struct Token {
    TokenKind kind = TokenKind::End;
    int line = 0;
    int column = 0;
    std::string_view text;
    double number = 0;
    bool isInt = false;  // written without '.', exponent, and fits in int
    size_t offset = 0;   // byte offset of the token's first character in the input
    bool inputFailed = false;  // an Error because the input could not be read on (corrupt, truncated, over budget)
    /// An Error of bytes that are no RIB token at all (control characters,
    /// reserved or undefined binary codes): not part of the request being
    /// read, whose values go on (Pixie and Aqsis draw it too).
    bool junk = false;
};

/// Where a streaming Lexer reads its bytes from: a file, or a gzip
/// stream being inflated chunk by chunk.
class ByteSource {
public:
    virtual ~ByteSource() = default;
    /// Reads up to `capacity` bytes into `dst`. 0 means the end of the input,
    /// or a failure when `*error` was set (corrupt data, a refused budget).
    virtual size_t read(char* dst, size_t capacity, std::string* error) = 0;
};

/// Splits RIB text into tokens without allocating per token. Numbers are
/// read with std::from_chars; a word that starts like a number but is not
/// one ("1.2.3", "4x") is an Error token, so a typo never silently becomes
/// a request name. So is a number no 32-bit float holds (|x| > 3.4e38,
/// e.g. "1e39") and a non-finite one ("nan", "inf", "-inf" in any case):
/// every value ends up in a float, where it would silently become infinity.
///
/// The input is either all in memory or streamed from a ByteSource in
/// chunks of kChunkBytes: a streaming lexer keeps only the current token
/// (at most kMaxTokenBytes) and a captured inline archive, so a file of
/// gigabytes of comments or whitespace takes a few hundred KiB.
class Lexer {
public:
    static constexpr size_t kChunkBytes = size_t(256) << 10;
    /// Longest word or string: past it the token is an error and skipped,
    /// so one endless word or unterminated string cannot fill memory.
    static constexpr size_t kMaxTokenBytes = size_t(64) << 20;

    /// `text` must outlive the lexer; its first line is numbered `firstLine`
    /// (an inline archive replayed from the middle of its file).
    explicit Lexer(std::string_view text, int firstLine = 1);
    /// Streams from `source`, which must outlive the lexer. A read failure
    /// becomes an Error token (its message at the position reached), then End.
    explicit Lexer(ByteSource& source);
    Token next();

    /// Starts keeping the raw input from byte `offset` (the offset of the
    /// token last returned, or later) for endCapture().
    void beginCapture(size_t offset);
    /// The raw input from beginCapture's offset up to `offset` (the offset
    /// of the token last returned).
    std::string endCapture(size_t offset);

private:
    /// One token; *definition is set when the bytes read were a binary
    /// definition, which gives no token (next() reads on).
    Token lexToken(bool* definition);
    /// A binary token at m_pos (its first byte is >= 0200).
    Token lexBinary(int line, int column, bool* definition);
    /// The next element of an encoded float array, or its closing bracket.
    Token lexArrayElement();
    /// At least `count` bytes held from m_pos on (streaming: refills,
    /// keeping them); false when the input ends first.
    bool ensure(size_t count);
    /// A binary token's field of `bytes` bytes after its first byte (most
    /// significant first); m_pos moves past both. False when cut short.
    bool field(size_t bytes, uint64_t* value);
    /// An encoded string (its first byte 0220-0243 at m_pos); `out` views
    /// the held bytes until the next read.
    enum class Encoded { Ok, Cut, Overlong };
    Encoded encodedString(std::string_view* out);
    /// The string a binary definition names: an encoded string (0220-0243)
    /// or a quoted ASCII one, right after the definition's code.
    bool definedString(std::string* out, std::string* why);
    Token makeError(int line, int column, std::string message);
    Token junkError(int line, int column, std::string message);  // makeError, marked junk
    Token inputError(int line, int column);
    Token lexString(int line, int column);
    Token lexWord(int line, int column);
    /// Streaming: drops the buffer before index `keep` (the start of the
    /// token being read) and appends the next chunk. False at the end of
    /// the input, on a read failure, or when the kept token would exceed
    /// kMaxTokenBytes (m_overlong). Indices into the buffer shift by `keep`.
    bool refill(size_t keep);
    /// 1-based column of buffer index `index`; 0 (unknown: messages give
    /// the line alone) on a line longer than an int counts.
    int columnAt(size_t index) const {
        const size_t column = m_base + index - m_lineStart + 1;
        return column <= size_t(INT_MAX) ? static_cast<int>(column) : 0;
    }

    const char* m_s = nullptr;  // the bytes held: [0, m_n)
    size_t m_n = 0;
    size_t m_pos = 0;           // index of the next byte to read
    size_t m_base = 0;          // input offset of m_s[0]
    int m_line = 1;
    size_t m_lineStart = 0;     // input offset of the current line's first byte
    std::string m_scratch;

    ByteSource* m_source = nullptr;  // null: the whole input is in memory
    std::string m_buffer;            // streaming: the bytes held
    std::string m_sourceError;       // a read failure, reported once
    bool m_sourceDone = false;
    bool m_overlong = false;
    // Binary RIB: the requests (by code) and strings (by token) the stream
    // defined, and the floats still to come of an encoded array.
    std::string m_requests[256];
    std::unordered_map<uint32_t, std::string> m_strings;
    bool m_inArray = false;
    uint64_t m_arrayLeft = 0;
    bool m_capturing = false;
    size_t m_captureFrom = 0;  // input offset of the first byte not yet copied into m_capture
    std::string m_capture;
};

}  // namespace umbra::ri
