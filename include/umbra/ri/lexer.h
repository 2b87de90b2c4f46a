#pragma once
// The RIB tokenizer (RI spec 3.2, appendix C "Language binding details"):
// ASCII RIB only. Tokens are request names, numbers, strings and the array
// brackets; `#` comments (including `##` structure comments) are skipped.

#include <cstddef>
#include <string>
#include <string_view>

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
};

/// Splits RIB text into tokens without allocating per token. Numbers are
/// read with std::from_chars; a word that starts like a number but is not
/// one ("1.2.3", "4x") is an Error token, so a typo never silently becomes
/// a request name. So is a number no 32-bit float holds (|x| > 3.4e38,
/// e.g. "1e39") and a non-finite one ("nan", "inf", "-inf" in any case):
/// every value ends up in a float, where it would silently become infinity.
class Lexer {
public:
    /// `text` must outlive the lexer; its first line is numbered `firstLine`
    /// (an inline archive replayed from the middle of its file).
    explicit Lexer(std::string_view text, int firstLine = 1);
    Token next();

private:
    Token makeError(int line, int column, std::string message);
    Token lexString(int line, int column);

    std::string_view m_text;
    size_t m_pos = 0;
    int m_line = 1;
    size_t m_lineStart = 0;
    std::string m_scratch;
};

}  // namespace umbra::ri
