#pragma once
// The RIB parser: reads ASCII RIB (plain or gzip-compressed), checks each
// request's positional arguments and parameter list, and calls the
// matching ri::Target method. Malformed requests are reported with
// `file:line:column: error: <Request>: <what was expected>` and skipped;
// parsing resumes at the next request name.

#include "umbra/ri/declarations.h"
#include "umbra/ri/lexer.h"
#include "umbra/ri/target.h"
#include "umbra/util/error.h"

#include <map>
#include <memory>
#include <string>
#include <string_view>

namespace umbra::ri {

/// Parses RIB streams into a Target. One Parser keeps its `Declare` table
/// across the files it reads (archives included), as one RenderMan
/// session does.
class Parser {
public:
    Parser(Target& target, Diagnostics& diag);

    /// Reads and parses a file; gzip input is detected by its magic bytes.
    /// False when the file cannot be read or any error was reported.
    bool parseFile(const std::string& path);
    /// Parses RIB held in memory (plain or gzip bytes). `name` is used in
    /// messages; `directory` is where relative ReadArchive names are looked
    /// for first (empty: the directory part of `name`).
    bool parseString(std::string_view text, const std::string& name, const std::string& directory = {});

    /// Deepest ReadArchive nesting accepted (guards against recursion).
    static constexpr int kMaxArchiveDepth = 32;
    /// After this many errors in one stream the rest of it is skipped.
    static constexpr int kMaxErrorsPerStream = 100;

    Declarations& declarations() { return m_decls; }

private:
    friend class StreamParser;
    /// An `ArchiveBegin "name"` ... `ArchiveEnd` body (RenderMan 13+),
    /// kept as text and parsed again by each `ReadArchive "name"`.
    struct InlineArchive {
        std::string text;                         // from the body's line start, earlier columns blanked
        std::shared_ptr<const std::string> file;  // where it was written, for messages
        int firstLine = 1;
        std::string directory;                    // for ReadArchive requests inside it
    };

    /// Parses a file or gzip data read chunk by chunk.
    bool parseStream(ByteSource& source, bool gzip, const std::string& name, const std::string& directory, int depth);
    bool readArchive(const std::string& name, const FileLoc& loc, const std::string& directory, int depth);

    Target& m_target;
    Diagnostics& m_diag;
    Declarations m_decls;
    std::map<std::string, InlineArchive> m_inlineArchives;
};

/// Convenience wrappers around a fresh Parser.
bool parseFile(const std::string& path, Target& target, Diagnostics& diag);
bool parseString(std::string_view text, const std::string& name, Target& target, Diagnostics& diag);

/// True when `bytes` starts with the gzip magic number 1f 8b.
inline bool isGzip(std::string_view bytes) {
    return bytes.size() >= 2 && static_cast<unsigned char>(bytes[0]) == 0x1f && static_cast<unsigned char>(bytes[1]) == 0x8b;
}

}  // namespace umbra::ri
