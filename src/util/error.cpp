#include "umbra/util/error.h"

namespace umbra {

const std::string& FileLoc::fileName() const {
    static const std::string kUnknown;
    return file ? *file : kUnknown;
}

std::string FileLoc::str() const {
    if (!file || file->empty()) return line > 0 ? fmt::format("<input>:{}:{}", line, column) : std::string("<input>");
    if (line <= 0) return *file;
    if (column <= 0) return fmt::format("{}:{}", *file, line);
    return fmt::format("{}:{}:{}", *file, line, column);
}

const char* severityName(Severity s) {
    switch (s) {
    case Severity::Info: return "info";
    case Severity::Warning: return "warning";
    case Severity::Error: return "error";
    case Severity::Severe: return "severe error";
    }
    return "error";
}

std::string Diagnostic::str() const { return fmt::format("{}: {}: {}", loc.str(), severityName(severity), message); }

void Diagnostics::report(Severity s, const FileLoc& loc, std::string message) {
    Diagnostic d{s, loc, std::move(message)};
    if (s == Severity::Warning) ++m_warnings;
    if (s >= Severity::Error) {
        ++m_errors;
        if (s == Severity::Severe || m_policy == Policy::Abort) m_aborted = true;
    }
    std::lock_guard<std::mutex> lock(m_mutex);
    if (m_record) m_recorded.push_back(d);
    bool quietable = s < Severity::Error && m_quiet;
    if (m_policy == Policy::Ignore && s < Severity::Severe) return;
    if (quietable) return;
    if (m_sink)
        m_sink(d);
    else
        fmt::print(stderr, "{}\n", d.str());
}

void Diagnostics::setSink(std::function<void(const Diagnostic&)> sink) {
    std::lock_guard<std::mutex> lock(m_mutex);
    m_sink = std::move(sink);
}

std::vector<Diagnostic> Diagnostics::recorded() const {
    std::lock_guard<std::mutex> lock(m_mutex);
    return m_recorded;
}

bool Diagnostics::firstTime(const std::string& key) {
    std::lock_guard<std::mutex> lock(m_mutex);
    return m_seen.insert(key).second;
}

void checkFailed(const char* expr, const char* file, int line, const std::string& msg) {
    fmt::print(stderr, "umbra: internal error at {}:{}: check `{}` failed{}{}\n", file, line, expr,
               msg.empty() ? "" : ": ", msg);
    std::abort();
}

}  // namespace umbra
