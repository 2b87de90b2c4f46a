#pragma once
// User-facing diagnostics: one path for every error in user input.
//
// Every message names where it comes from as `file:line:column` and what was
// expected. Internal invariants use UMBRA_CHECK, which aborts with a message.

#include <fmt/format.h>

#include <atomic>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <memory>
#include <mutex>
#include <new>
#include <set>
#include <string>
#include <vector>

namespace umbra {

/// A place in an input file (RIB, shader source, map). Line and column are
/// 1-based; 0 means unknown.
struct FileLoc {
    std::shared_ptr<const std::string> file;  // shared: every token of a file points at one name
    int line = 0;
    int column = 0;

    FileLoc() = default;
    FileLoc(std::shared_ptr<const std::string> f, int l, int c) : file(std::move(f)), line(l), column(c) {}
    static FileLoc inFile(const std::string& name, int line = 0, int column = 0) {
        return FileLoc(std::make_shared<const std::string>(name), line, column);
    }
    const std::string& fileName() const;
    /// "file:line:column", or as much of it as is known.
    std::string str() const;
};

enum class Severity { Info, Warning, Error, Severe };
const char* severityName(Severity s);

/// One reported diagnostic.
struct Diagnostic {
    Severity severity;
    FileLoc loc;
    std::string message;
    /// "file:line:column: error: message"
    std::string str() const;
};

/// Collects and prints diagnostics; thread-safe. RenderMan's `ErrorHandler`
/// request selects the policy: "print" (default), "ignore" or "abort"
/// (stop at the first error).
class Diagnostics {
public:
    enum class Policy { Print, Ignore, Abort };

    void report(Severity s, const FileLoc& loc, std::string message);
    template <typename... Args>
    void error(const FileLoc& loc, fmt::format_string<Args...> f, Args&&... args) {
        report(Severity::Error, loc, fmt::format(f, std::forward<Args>(args)...));
    }
    template <typename... Args>
    void warning(const FileLoc& loc, fmt::format_string<Args...> f, Args&&... args) {
        report(Severity::Warning, loc, fmt::format(f, std::forward<Args>(args)...));
    }
    template <typename... Args>
    void info(const FileLoc& loc, fmt::format_string<Args...> f, Args&&... args) {
        report(Severity::Info, loc, fmt::format(f, std::forward<Args>(args)...));
    }
    /// Reports only the first time `key` is seen (e.g. "unsupported request X").
    template <typename... Args>
    void errorOnce(const std::string& key, const FileLoc& loc, fmt::format_string<Args...> f, Args&&... args) {
        if (firstTime(key)) report(Severity::Error, loc, fmt::format(f, std::forward<Args>(args)...));
    }
    template <typename... Args>
    void warningOnce(const std::string& key, const FileLoc& loc, fmt::format_string<Args...> f, Args&&... args) {
        if (firstTime(key)) report(Severity::Warning, loc, fmt::format(f, std::forward<Args>(args)...));
    }

    void setPolicy(Policy p) { m_policy = p; }
    Policy policy() const { return m_policy; }
    /// Where printed messages go (stderr by default); tests capture them.
    void setSink(std::function<void(const Diagnostic&)> sink);
    /// Keep a copy of every diagnostic (tests read them back).
    void setRecord(bool on) { m_record = on; }
    std::vector<Diagnostic> recorded() const;
    /// Suppress Info and Warning output (`--quiet`); errors still print.
    void setQuiet(bool q) { m_quiet = q; }

    int errorCount() const { return m_errors.load(); }
    int warningCount() const { return m_warnings.load(); }
    /// True once an error arrived under the Abort policy, or a Severe one.
    bool aborted() const { return m_aborted.load(); }

private:
    bool firstTime(const std::string& key);

    mutable std::mutex m_mutex;
    Policy m_policy = Policy::Print;
    bool m_record = false;
    bool m_quiet = false;
    std::function<void(const Diagnostic&)> m_sink;
    std::vector<Diagnostic> m_recorded;
    std::set<std::string> m_seen;
    std::atomic<int> m_errors{0}, m_warnings{0};
    std::atomic<bool> m_aborted{false};
};

[[noreturn]] void checkFailed(const char* expr, const char* file, int line, const std::string& msg);

/// Memory ran out while allocating something large for a request: says
/// what (`the 1920x1080 film with 16 samples per pixel`), for which request
/// (its location) and how many bytes, where a bare std::bad_alloc says
/// nothing. The `umbra` command reports it as its last error.
class OutOfMemory : public std::bad_alloc {
public:
    OutOfMemory(FileLoc loc, const std::string& what, uint64_t bytes)
        : m_loc(std::move(loc)), m_message(fmt::format("out of memory allocating {} ({} bytes)", what, bytes)) {}
    const FileLoc& loc() const { return m_loc; }
    /// "out of memory allocating <what> (<bytes> bytes)"
    const char* what() const noexcept override { return m_message.c_str(); }

private:
    FileLoc m_loc;
    std::string m_message;
};

/// Runs `allocate()`; a std::bad_alloc from it (not already an
/// OutOfMemory, which names something more precise) becomes an OutOfMemory
/// naming `what`, `bytes` and `loc`.
template <typename Allocate>
decltype(auto) allocating(const FileLoc& loc, uint64_t bytes, const std::string& what, Allocate&& allocate) {
    try {
        return allocate();
    } catch (const OutOfMemory&) {
        throw;
    } catch (const std::bad_alloc&) {
        throw OutOfMemory(loc, what, bytes);
    }
}

}  // namespace umbra

/// Internal invariant; aborts with a message when false. Not for user input.
#define UMBRA_CHECK(cond, ...)                                                          \
    do {                                                                                \
        if (!(cond)) ::umbra::checkFailed(#cond, __FILE__, __LINE__, fmt::format("" __VA_ARGS__)); \
    } while (0)
