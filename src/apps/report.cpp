#include "apps/report.h"

#include "umbra/shadow/shadow_map.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

namespace umbra::apps {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

/// Bad input, with where it is; reported once, before anything is written.
struct InputError {
    FileLoc loc;
    std::string message;
};

struct MapUse {
    std::string light, path, reason;
    bool reused = false;
};

struct Frame {
    std::string where;  // "file:line" or "file frames[i]": the slowest-frames table says where each came from
    int number = -1;
    bool skipped = false;
    int width = 0, height = 0, threads = 1;
    double wall = 0, cpu = 0, firstPass = 0, camera = 0, lookupSeconds = 0, peakMemoryMib = 0;
    bool hasCache = false;
    double cacheLookups = 0, cacheHits = 0, cacheMisses = 0, cacheEvictions = 0, cachePeakBytes = 0;
    std::vector<MapUse> maps;
    bool hasMaps = false;  // older statistics do not list the maps
    int depthPasses = 0;
    /// The maps the frame used: listed, or (older statistics) its depth passes.
    int mapCount() const { return hasMaps ? int(maps.size()) : depthPasses; }

    /// Output, setup and whatever else is neither the first pass nor the camera pass.
    double other() const { return std::max(0.0, wall - firstPass - camera); }
    /// Shadows' share of the frame, estimated from one shadowed run: the
    /// first pass plus the camera pass's map lookups (summed over threads,
    /// so divided by them).
    double shadowSeconds() const { return firstPass + lookupSeconds / std::max(1, threads); }
    double withoutShadows() const { return std::max(0.0, wall - shadowSeconds()); }
    double increasePercent() const {
        const double base = withoutShadows();
        return base > 0 ? 100.0 * shadowSeconds() / base : 0.0;
    }
};

/// Typed access to a frame object's fields: missing optional fields read as
/// absent, present ones of the wrong type are located errors.
class FieldReader {
public:
    FieldReader(FileLoc loc, std::string context) : m_loc(std::move(loc)), m_context(std::move(context)) {}

    const json* find(const json& obj, const char* key, json::value_t kind, const char* expected) const {
        auto it = obj.find(key);
        if (it == obj.end() || it->is_null()) return nullptr;
        const bool ok = kind == json::value_t::number_float ? it->is_number() : it->type() == kind;
        if (!ok) fail(fmt::format("expected {} for \"{}\", got {}", expected, key, it->type_name()));
        return &*it;
    }
    double number(const json& obj, const char* key, double fallback = 0) const {
        const json* v = find(obj, key, json::value_t::number_float, "a number");
        return v ? v->get<double>() : fallback;
    }
    /// Frame numbers, thread counts and resolutions: whole numbers an int holds.
    int integer(const json& obj, const char* key, int fallback) const {
        const json* v = find(obj, key, json::value_t::number_float, "a whole number");
        if (!v) return fallback;
        return checkedInt(*v, key);
    }
    int checkedInt(const json& v, const char* key) const {
        if (!v.is_number_integer() || v.get<double>() < -2147483648.0 || v.get<double>() > 2147483647.0)
            fail(fmt::format("expected a whole number for \"{}\", got {}", key, v.dump()));
        return v.get<int>();
    }
    std::string string(const json& obj, const char* key) const {
        const json* v = find(obj, key, json::value_t::string, "a string");
        return v ? v->get<std::string>() : std::string();
    }
    bool boolean(const json& obj, const char* key) const {
        const json* v = find(obj, key, json::value_t::boolean, "true or false");
        return v && v->get<bool>();
    }
    const json* object(const json& obj, const char* key) const {
        return find(obj, key, json::value_t::object, "an object");
    }
    const json* array(const json& obj, const char* key) const { return find(obj, key, json::value_t::array, "an array"); }
    [[noreturn]] void fail(const std::string& message) const { throw InputError{m_loc, m_context + message}; }

private:
    FileLoc m_loc;
    std::string m_context;
};

Frame readFrame(const json& obj, const FieldReader& r, std::string where, int index) {
    if (!obj.is_object()) r.fail(fmt::format("expected a frame object, got {}", obj.type_name()));
    Frame f;
    f.where = std::move(where);
    f.number = r.integer(obj, "frame", index);
    f.skipped = r.boolean(obj, "skipped");
    if (f.skipped) return f;
    if (const json* res = r.array(obj, "resolution"); res && res->size() == 2) {
        f.width = r.checkedInt((*res)[0], "resolution");
        f.height = r.checkedInt((*res)[1], "resolution");
    }
    f.wall = r.number(obj, "wall_seconds");
    f.cpu = r.number(obj, "cpu_seconds");
    f.threads = std::max(1, r.integer(obj, "threads", 1));
    f.peakMemoryMib = r.number(obj, "peak_memory_mib");
    if (const json* fp = r.object(obj, "first_pass")) f.firstPass = r.number(*fp, "wall_seconds");
    if (const json* passes = r.array(obj, "passes"))
        for (const json& p : *passes) {
            if (!p.is_object()) r.fail("expected each of \"passes\" to be an object");
            const std::string name = r.string(p, "name");
            if (name == "camera") f.camera += r.number(p, "wall_seconds");
            if (name.rfind("depth:", 0) == 0) f.depthPasses++;
        }
    if (const json* shadow = r.object(obj, "shadow")) {
        f.lookupSeconds = r.number(*shadow, "lookup_seconds");
        if (const json* c = r.object(*shadow, "tile_cache")) {
            f.hasCache = true;
            f.cacheLookups = r.number(*c, "lookups");
            f.cacheHits = r.number(*c, "hits");
            f.cacheMisses = r.number(*c, "misses");
            f.cacheEvictions = r.number(*c, "evictions");
            f.cachePeakBytes = r.number(*c, "peak_bytes");
        }
    }
    if (const json* maps = r.array(obj, "maps")) {
        f.hasMaps = true;
        for (const json& m : *maps) {
            if (!m.is_object()) r.fail("expected each of \"maps\" to be an object");
            f.maps.push_back({r.string(m, "light"), r.string(m, "path"), r.string(m, "reason"), r.boolean(m, "reused")});
        }
    }
    return f;
}

/// nlohmann's message without its "[json.exception...] parse error at line L, column C: " prefix
/// (the location is ours to give, in the whole file's terms).
std::string parseMessage(const json::parse_error& e) {
    std::string what = e.what();
    const size_t column = what.find("column ");
    const size_t colon = column == std::string::npos ? what.find("]") : what.find(": ", column);
    return colon == std::string::npos ? what : what.substr(colon + 2);
}

/// The 1-based line and column of byte `offset` (1-based, as nlohmann counts) of `text`.
std::pair<int, int> lineColumn(const std::string& text, size_t offset) {
    int line = 1, column = 1;
    for (size_t i = 0; i + 1 < offset && i < text.size(); ++i) {
        if (text[i] == '\n') {
            ++line;
            column = 1;
        } else {
            ++column;
        }
    }
    return {line, column};
}

void readLines(const std::string& path, const std::string& text, std::vector<Frame>& frames) {
    std::istringstream in(text);
    std::string line;
    for (int lineNo = 1; std::getline(in, line); ++lineNo) {
        if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
        json obj;
        try {
            obj = json::parse(line);
        } catch (const json::parse_error& e) {
            throw InputError{FileLoc::inFile(path, lineNo, int(std::max<size_t>(1, e.byte))),
                             "expected one JSON object (a frame's statistics) per line: " + parseMessage(e)};
        }
        const FieldReader r(FileLoc::inFile(path, lineNo, 1), "");
        frames.push_back(readFrame(obj, r, fmt::format("{}:{}", path, lineNo), int(frames.size())));
    }
}

void readStats(const std::string& path, std::vector<Frame>& frames) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError{FileLoc::inFile(path), "cannot read the statistics file"};
    std::stringstream buf;
    buf << in.rdbuf();
    const std::string text = buf.str();
    if (text.find_first_not_of(" \t\r\n") == std::string::npos)
        throw InputError{FileLoc::inFile(path, 1, 1), "expected statistics (a JSON document with \"frames\", or "
                                                      "one JSON object per line), got an empty file"};
    if (fs::path(path).extension() == ".jsonl") return readLines(path, text, frames);
    json doc;
    try {
        doc = json::parse(text);
    } catch (const json::parse_error& e) {
        // Several lines that are each an object: JSON lines under another name.
        const std::string first = text.substr(0, text.find('\n'));
        if (json::accept(first) && json::parse(first).is_object()) return readLines(path, text, frames);
        const auto [line, column] = lineColumn(text, e.byte);
        throw InputError{FileLoc::inFile(path, line, column),
                         "expected a JSON document with a \"frames\" array: " + parseMessage(e)};
    }
    if (!doc.is_object())
        throw InputError{FileLoc::inFile(path, 1, 1),
                         fmt::format("expected a JSON object with a \"frames\" array, got {}", doc.type_name())};
    if (!doc.contains("frames")) return readLines(path, text, frames);  // a single JSON line
    const json& list = doc["frames"];
    if (!list.is_array())
        throw InputError{FileLoc::inFile(path), fmt::format("expected \"frames\" to be an array, got {}", list.type_name())};
    for (size_t i = 0; i < list.size(); ++i) {
        const FieldReader r(FileLoc::inFile(path), fmt::format("frames[{}]: ", i));
        frames.push_back(readFrame(list[i], r, fmt::format("{} frames[{}]", path, i), int(frames.size())));
    }
}

/// A map the sequence used: its storage figures when its file is still there.
struct MapStorage {
    std::string light, path;
    int frames = 0, rendered = 0;
    bool found = false;
    MapInfo info;
};

std::vector<MapStorage> mapStorage(const std::vector<Frame>& frames, const std::vector<std::string>& statsFiles,
                                   Diagnostics& diag) {
    std::vector<MapStorage> maps;
    std::map<std::string, size_t> index;
    for (const Frame& f : frames)
        for (const MapUse& m : f.maps) {
            if (m.path.empty()) continue;
            auto [it, added] = index.emplace(m.path, maps.size());
            if (added) {
                maps.emplace_back();
                maps.back().light = m.light;
                maps.back().path = m.path;
            }
            maps[it->second].frames++;
            if (!m.reused) maps[it->second].rendered++;
        }
    for (MapStorage& m : maps) {
        // Paths are as the render wrote them: relative to where it ran,
        // which is often beside the statistics.
        std::vector<fs::path> candidates{m.path};
        for (const auto& s : statsFiles)
            if (fs::path(m.path).is_relative()) candidates.push_back(fs::path(s).parent_path() / m.path);
        for (const auto& c : candidates) {
            std::error_code ec;
            if (!fs::is_regular_file(c, ec)) continue;
            Diagnostics quiet;
            quiet.setPolicy(Diagnostics::Policy::Ignore);
            if (auto map = ShadowMap::open(c.string(), quiet, FileLoc::inFile(c.string()))) {
                m.info = map->info();
                m.found = true;
                break;
            }
        }
        if (!m.found)
            diag.warning(FileLoc::inFile(m.path), "map not found or unreadable: its storage is left out of Table 2");
    }
    return maps;
}

std::string escapeHtml(const std::string& s) {
    std::string out;
    out.reserve(s.size());
    for (char c : s) switch (c) {
            case '&': out += "&amp;"; break;
            case '<': out += "&lt;"; break;
            case '>': out += "&gt;"; break;
            case '"': out += "&quot;"; break;
            case '\'': out += "&#39;"; break;
            default: out += c;
        }
    return out;
}

/// A markdown table cell: pipes and line breaks would end the cell or row.
std::string escapeMd(const std::string& s) {
    std::string out;
    for (char c : s) {
        if (c == '|') out += "\\|";
        else if (c == '\n' || c == '\r') out += ' ';
        else out += c;
    }
    return out;
}

std::string mb(double bytes) { return fmt::format("{:.3f}", bytes / 1e6); }
std::string pct(double part, double whole) { return whole > 0 ? fmt::format("{:.1f}", 100.0 * part / whole) : "—"; }

/// A table written once, as markdown and as HTML.
struct Table {
    std::vector<std::string> header;
    std::vector<bool> numeric;  // right-aligned columns
    std::vector<std::vector<std::string>> rows;

    std::string markdown() const {
        std::string s = "|";
        for (const auto& h : header) s += fmt::format(" {} |", escapeMd(h));
        s += "\n|";
        for (size_t i = 0; i < header.size(); ++i) s += numeric[i] ? "---:|" : "---|";
        s += "\n";
        for (const auto& row : rows) {
            s += "|";
            for (const auto& cell : row) s += fmt::format(" {} |", escapeMd(cell));
            s += "\n";
        }
        return s;
    }
    std::string html() const {
        std::string s = "<table>\n<thead><tr>";
        for (size_t i = 0; i < header.size(); ++i)
            s += fmt::format("<th{}>{}</th>", numeric[i] ? " class=\"num\"" : "", escapeHtml(header[i]));
        s += "</tr></thead>\n<tbody>\n";
        for (const auto& row : rows) {
            s += "<tr>";
            for (size_t i = 0; i < row.size(); ++i)
                s += fmt::format("<td{}>{}</td>", numeric[i] ? " class=\"num\"" : "", escapeHtml(row[i]));
            s += "</tr>\n";
        }
        return s + "</tbody>\n</table>\n";
    }
};

struct Series {
    std::string name, color;
    std::vector<double> values;
};

/// A step of 1, 2 or 5 times a power of ten giving about five ticks up to `top`.
double tickStep(double top) {
    const double raw = top / 5;
    const double power = std::pow(10.0, std::floor(std::log10(raw)));
    for (double m : {1.0, 2.0, 5.0})
        if (m * power >= raw) return m * power;
    return 10 * power;
}

/// A bar chart in SVG: one slot per label, the series stacked or side by side.
std::string barChart(const std::string& title, const std::string& unit, const std::vector<std::string>& labels,
                     const std::vector<Series>& series, bool stacked) {
    constexpr double kWidth = 1100, kHeight = 280, kLeft = 80, kRight = 20, kTop = 40, kBottom = 50;
    const double plotW = kWidth - kLeft - kRight, plotH = kHeight - kTop - kBottom;
    const size_t n = labels.size();
    double top = 0;
    for (size_t i = 0; i < n; ++i) {
        double sum = 0;
        for (const auto& s : series) sum = stacked ? sum + s.values[i] : std::max(sum, s.values[i]);
        top = std::max(top, sum);
    }
    std::string svg = fmt::format(
        "<svg width=\"{0}\" height=\"{1}\" viewBox=\"0 0 {0} {1}\" "
        "role=\"img\" aria-label=\"{2}\" shape-rendering=\"crispEdges\" font-family=\"sans-serif\" font-size=\"12\">\n"
        "<rect x=\"0\" y=\"0\" width=\"{0}\" height=\"{1}\" fill=\"#ffffff\"/>\n"
        "<text x=\"{3}\" y=\"18\" font-size=\"14\" font-weight=\"bold\">{2}</text>\n",
        kWidth, kHeight, escapeHtml(title), kLeft);
    // Legend, right-aligned in the title row.
    double lx = kWidth - kRight;
    for (auto it = series.rbegin(); it != series.rend(); ++it) {
        lx -= 7.5 * double(it->name.size()) + 30;
        svg += fmt::format("<rect x=\"{:.1f}\" y=\"8\" width=\"12\" height=\"12\" fill=\"{}\"/>"
                           "<text x=\"{:.1f}\" y=\"18\">{}</text>\n",
                           lx, it->color, lx + 16, escapeHtml(it->name));
    }
    // Sums past the largest double (absurd statistics) have no scale to draw.
    if (n == 0 || top <= 0 || !std::isfinite(top)) {
        svg += fmt::format("<text x=\"{:.0f}\" y=\"{:.0f}\" fill=\"#666666\">{}</text>\n", kLeft + plotW / 2 - 25,
                           kTop + plotH / 2, n == 0 || top <= 0 ? "no data" : "values too large to plot");
        return svg + "</svg>\n";
    }
    const double step = tickStep(top);
    const double yMax = std::ceil(top / step) * step;
    auto y = [&](double v) { return kTop + plotH * (1 - v / yMax); };
    for (int k = 0; k * step <= yMax + step / 2; ++k) {
        const double v = k * step;
        svg += fmt::format("<line x1=\"{}\" y1=\"{:.1f}\" x2=\"{}\" y2=\"{:.1f}\" stroke=\"#e0e0e0\"/>"
                           "<text x=\"{}\" y=\"{:.1f}\" text-anchor=\"end\">{:g}</text>\n",
                           kLeft, y(v), kLeft + plotW, y(v), kLeft - 6, y(v) + 4, v);
    }
    svg += fmt::format("<text x=\"16\" y=\"{:.0f}\" transform=\"rotate(-90 16 {:.0f})\" text-anchor=\"middle\">{}</text>\n",
                       kTop + plotH / 2, kTop + plotH / 2, escapeHtml(unit));
    const double slot = plotW / double(n);
    const double barW = std::max(slot * (n > 200 ? 1.0 : 0.8), 0.5);
    const size_t labelEvery = (n + 19) / 20;
    for (size_t i = 0; i < n; ++i) {
        const double x0 = kLeft + slot * double(i) + (slot - barW) / 2;
        double base = 0;
        for (size_t k = 0; k < series.size(); ++k) {
            const double v = series[k].values[i];
            if (v <= 0) continue;
            const double w = stacked ? barW : barW / double(series.size());
            const double x = stacked ? x0 : x0 + w * double(k);
            const double lo = stacked ? base : 0;
            svg += fmt::format("<rect x=\"{:.2f}\" y=\"{:.2f}\" width=\"{:.2f}\" height=\"{:.2f}\" fill=\"{}\"/>\n", x,
                               y(lo + v), w, y(lo) - y(lo + v), series[k].color);
            if (stacked) base += v;
        }
        if (i % labelEvery == 0)
            svg += fmt::format("<text x=\"{:.1f}\" y=\"{:.0f}\" text-anchor=\"middle\">{}</text>\n",
                               kLeft + slot * (double(i) + 0.5), kTop + plotH + 16, escapeHtml(labels[i]));
    }
    svg += fmt::format("<line x1=\"{0}\" y1=\"{1}\" x2=\"{2}\" y2=\"{1}\" stroke=\"#000000\"/>"
                       "<line x1=\"{0}\" y1=\"{3}\" x2=\"{0}\" y2=\"{1}\" stroke=\"#000000\"/>\n",
                       kLeft, kTop + plotH, kLeft + plotW, kTop);
    return svg + "</svg>\n";
}

/// One section of the report: heading, prose, plot, tables, in both forms.
struct Section {
    Section(std::string i, std::string t, std::string x) : id(std::move(i)), title(std::move(t)), text(std::move(x)) {}
    std::string id, title, text, svg;
    std::vector<std::pair<std::string, Table>> tables;  // caption, table
};

std::string fmtSeconds(double s) { return fmt::format("{:.4f}", s); }

std::vector<Section> buildSections(const std::vector<Frame>& all, const std::vector<MapStorage>& maps) {
    std::vector<const Frame*> frames;
    for (const Frame& f : all)
        if (!f.skipped) frames.push_back(&f);
    std::vector<std::string> labels;
    for (const Frame* f : frames) labels.push_back(std::to_string(f->number));
    auto values = [&](auto get) {
        std::vector<double> v;
        for (const Frame* f : frames) v.push_back(get(*f));
        return v;
    };
    std::vector<Section> sections;

    // Time per frame, stacked by pass.
    {
        Section s{"time", "Time per frame", ""};
        double wall = 0, first = 0, camera = 0, cpu = 0;
        for (const Frame* f : frames) {
            wall += f->wall;
            first += f->firstPass;
            camera += f->camera;
            cpu += f->cpu;
        }
        s.text = fmt::format(
            "{} frames rendered, {} skipped; {} s of wall time ({} s CPU). The first pass (making the depth maps) "
            "took {}% of it, the camera pass {}%, the rest (setup, output) {}%.",
            frames.size(), all.size() - frames.size(), fmtSeconds(wall), fmtSeconds(cpu), pct(first, wall),
            pct(camera, wall), pct(std::max(0.0, wall - first - camera), wall));
        s.svg = barChart("Wall time per frame, by pass", "seconds", labels,
                         {{"first pass (depth maps)", "#d62728", values([](const Frame& f) { return f.firstPass; })},
                          {"camera pass", "#1f77b4", values([](const Frame& f) { return f.camera; })},
                          {"other (setup, output)", "#9e9e9e", values([](const Frame& f) { return f.other(); })}},
                         true);
        sections.push_back(std::move(s));
    }
    // Shadow overhead per frame.
    {
        Section s{"overhead", "Shadow overhead per frame",
                  "The time shadows added to each frame, as a percentage of the frame without them, estimated "
                  "from the shadowed run: the first pass plus the camera pass's map lookups (their time summed "
                  "over threads, divided by the threads). Render with --no-shadows for the exact figure."};
        s.svg = barChart("Shadow overhead per frame (estimated)", "% of the frame without shadows", labels,
                         {{"% increase", "#ff7f0e", values([](const Frame& f) { return f.increasePercent(); })}},
                         true);
        sections.push_back(std::move(s));
    }
    // Storage per map.
    {
        Section s{"storage", "Storage per map", ""};
        std::vector<std::string> mapLabels;
        Series raw{"raw", "#8c564b", {}}, box{"bounding box", "#e377c2", {}}, tile{"tile scheme", "#bcbd22", {}};
        for (const MapStorage& m : maps) {
            if (!m.found) continue;
            mapLabels.push_back(fs::path(m.path).filename().string());
            raw.values.push_back(double(m.info.rawBytes) / 1e6);
            box.values.push_back(double(m.info.bboxBytes) / 1e6);
            tile.values.push_back(double(m.info.tileBytes) / 1e6);
        }
        s.text = maps.empty() ? "The statistics list no maps (statistics without \"maps\", or no automatic maps)."
                              : "Each map the sequence read, from its file (as umbra info reports it).";
        s.svg = barChart("Storage per map", "megabytes", mapLabels, {raw, box, tile}, false);
        sections.push_back(std::move(s));
    }
    // Cache behaviour.
    {
        Section s{"cache", "Tile cache", ""};
        double lookups = 0, hits = 0, misses = 0, evictions = 0, peak = 0;
        int withCache = 0;
        for (const Frame* f : frames) {
            if (!f->hasCache) continue;
            ++withCache;
            lookups += f->cacheLookups;
            hits += f->cacheHits;
            misses += f->cacheMisses;
            evictions += f->cacheEvictions;
            peak = std::max(peak, f->cachePeakBytes);
        }
        s.text = fmt::format("Tile cache of the shadow-map lookups, over the {} frames that used it.", withCache);
        s.svg = barChart("Tile cache hits and misses per frame", "lookups", labels,
                         {{"hits", "#2ca02c", values([](const Frame& f) { return f.cacheHits; })},
                          {"misses", "#7f3b08", values([](const Frame& f) { return f.cacheMisses; })}},
                         true);
        Table t{{"lookups", "hits", "misses", "hit rate %", "evictions", "largest peak (MB)"},
                {true, true, true, true, true, true},
                {{fmt::format("{:.0f}", lookups), fmt::format("{:.0f}", hits), fmt::format("{:.0f}", misses),
                  pct(hits, lookups), fmt::format("{:.0f}", evictions), mb(peak)}}};
        s.tables.push_back({"Sequence totals", std::move(t)});
        sections.push_back(std::move(s));
    }
    // Map reuse.
    {
        Section s{"reuse", "Map reuse", ""};
        std::map<std::string, int> reasons;
        int rendered = 0, reused = 0;
        for (const Frame* f : frames)
            for (const MapUse& m : f->maps) {
                (m.reused ? reused : rendered)++;
                reasons[m.reason.empty() ? "(no reason recorded)" : m.reason]++;
            }
        const bool listed = std::any_of(frames.begin(), frames.end(), [](const Frame* f) { return f->hasMaps; });
        s.text = listed ? fmt::format("{} maps rendered, {} reused from an earlier frame.", rendered, reused)
                        : "The statistics do not list the maps (written before map reuse was recorded).";
        auto count = [](bool wantReused) {
            return [wantReused](const Frame& f) {
                return double(std::count_if(f.maps.begin(), f.maps.end(),
                                            [&](const MapUse& m) { return m.reused == wantReused; }));
            };
        };
        s.svg = barChart("Maps per frame: rendered and reused", "maps", labels,
                         {{"rendered", "#9467bd", values(count(false))}, {"reused", "#17becf", values(count(true))}},
                         true);
        Table t{{"reason", "maps"}, {false, true}, {}};
        for (const auto& [reason, n] : reasons) t.rows.push_back({reason, std::to_string(n)});
        if (!reasons.empty()) s.tables.push_back({"Why each map was rendered or reused", std::move(t)});
        sections.push_back(std::move(s));
    }
    // The slowest frames.
    {
        Section s{"slowest", "Slowest frames", "The ten frames with the most wall time."};
        std::vector<const Frame*> sorted = frames;
        std::stable_sort(sorted.begin(), sorted.end(), [](const Frame* a, const Frame* b) { return a->wall > b->wall; });
        sorted.resize(std::min<size_t>(sorted.size(), 10));
        Table t{{"frame", "wall (s)", "first pass (s)", "camera pass (s)", "other (s)", "CPU (s)", "peak memory (MiB)",
                 "resolution", "statistics"},
                {true, true, true, true, true, true, true, false, false},
                {}};
        for (const Frame* f : sorted)
            t.rows.push_back({std::to_string(f->number), fmtSeconds(f->wall), fmtSeconds(f->firstPass),
                              fmtSeconds(f->camera), fmtSeconds(f->other()), fmtSeconds(f->cpu),
                              fmt::format("{:.1f}", f->peakMemoryMib),
                              f->width > 0 ? fmt::format("{}x{}", f->width, f->height) : "—", f->where});
        s.tables.push_back({"", std::move(t)});
        sections.push_back(std::move(s));
    }
    // Reeves, Salesin & Cook 1987, Table 1.
    {
        Section s{"table1", "Table 1: time cost of shadows",
                  "Reeves, Salesin & Cook 1987, Table 1, for each frame: the first pass makes the depth maps, the "
                  "second pass is the rest of the frame. Without shadows and % increase are estimated as in the "
                  "overhead plot."};
        Table t{{"frame", "maps", "first pass (s)", "second pass (s)", "total (s)", "lookups (s per thread)",
                 "without shadows, est. (s)", "% increase, est."},
                {true, true, true, true, true, true, true, true},
                {}};
        double first = 0, total = 0, lookups = 0, without = 0;
        for (const Frame* f : frames) {
            const double lookup = f->lookupSeconds / std::max(1, f->threads);
            t.rows.push_back({std::to_string(f->number), std::to_string(f->mapCount()), fmtSeconds(f->firstPass),
                              fmtSeconds(f->wall - f->firstPass), fmtSeconds(f->wall), fmtSeconds(lookup),
                              fmtSeconds(f->withoutShadows()), fmt::format("{:.1f}", f->increasePercent())});
            first += f->firstPass;
            total += f->wall;
            lookups += lookup;
            without += f->withoutShadows();
        }
        t.rows.push_back({"all", "", fmtSeconds(first), fmtSeconds(total - first), fmtSeconds(total),
                          fmtSeconds(lookups), fmtSeconds(without),
                          without > 0 ? fmt::format("{:.1f}", 100.0 * (total - without) / without) : "—"});
        s.tables.push_back({"", std::move(t)});
        sections.push_back(std::move(s));
    }
    // Reeves, Salesin & Cook 1987, Table 2.
    {
        Section s{"table2", "Table 2: depth map storage",
                  "Reeves, Salesin & Cook 1987, Table 2, for each map of the sequence, in megabytes (10^6 bytes): "
                  "raw is width x height x 4 bytes; bounding box stores only the box of finite depths; tile scheme "
                  "only the tiles holding a finite depth; on disk is the file."};
        Table t{{"light", "map", "frames", "rendered", "resolution", "raw", "bounding box", "bbox % of raw", "tile scheme",
                 "tile % of raw", "on disk"},
                {false, false, true, true, false, true, true, true, true, true, true},
                {}};
        double raw = 0, box = 0, tile = 0, disk = 0;
        for (const MapStorage& m : maps) {
            if (!m.found) {
                t.rows.push_back({m.light, m.path, std::to_string(m.frames), std::to_string(m.rendered), "not found",
                                  "—", "—", "—", "—", "—", "—"});
                continue;
            }
            const MapInfo& i = m.info;
            t.rows.push_back({m.light, m.path, std::to_string(m.frames), std::to_string(m.rendered),
                              fmt::format("{}x{}", i.width, i.height), mb(double(i.rawBytes)), mb(double(i.bboxBytes)),
                              pct(double(i.bboxBytes), double(i.rawBytes)), mb(double(i.tileBytes)),
                              pct(double(i.tileBytes), double(i.rawBytes)), mb(double(i.fileBytes))});
            raw += double(i.rawBytes);
            box += double(i.bboxBytes);
            tile += double(i.tileBytes);
            disk += double(i.fileBytes);
        }
        t.rows.push_back({"all", "", "", "", "", mb(raw), mb(box), pct(box, raw), mb(tile), pct(tile, raw), mb(disk)});
        s.tables.push_back({"", std::move(t)});
        sections.push_back(std::move(s));
    }
    return sections;
}

std::string markdown(const std::vector<Section>& sections, const std::vector<std::string>& files) {
    std::string md = "# umbra profiling report\n\nStatistics: ";
    for (size_t i = 0; i < files.size(); ++i) {
        if (i) md += ", ";
        md += escapeMd(files[i]);
    }
    md += "\n";
    for (const Section& s : sections) {
        md += fmt::format("\n## {}\n\n{}\n", s.title, s.text);
        for (const auto& [caption, table] : s.tables) {
            md += "\n";
            if (!caption.empty()) md += caption + ":\n\n";
            md += table.markdown();
        }
    }
    return md;
}

std::string html(const std::vector<Section>& sections, const std::vector<std::string>& files) {
    std::string page =
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>umbra profiling report</title>\n"
        "<style>\nbody{font-family:sans-serif;margin:20px;color:#222222;}\n"
        "table{border-collapse:collapse;margin:8px 0 16px 0;}\n"
        "th,td{border:1px solid #cccccc;padding:3px 8px;}\nth{background:#f0f0f0;}\n.num{text-align:right;}\n"
        "nav a{margin-right:14px;}\nsection{margin-top:18px;}\n</style>\n</head>\n<body>\n"
        "<h1>umbra profiling report</h1>\n<p>Statistics: ";
    for (size_t i = 0; i < files.size(); ++i) {
        if (i) page += ", ";
        page += escapeHtml(files[i]);
    }
    page += "</p>\n<nav>";
    for (const Section& s : sections) page += fmt::format("<a href=\"#{}\">{}</a>", s.id, escapeHtml(s.title));
    page += "</nav>\n";
    for (const Section& s : sections) {
        page += fmt::format("<section id=\"{}\">\n<h2>{}</h2>\n<p>{}</p>\n", s.id, escapeHtml(s.title), escapeHtml(s.text));
        if (!s.svg.empty()) page += "<figure id=\"plot-" + s.id + "\">\n" + s.svg + "</figure>\n";
        for (const auto& [caption, table] : s.tables) {
            if (!caption.empty()) page += "<h3>" + escapeHtml(caption) + "</h3>\n";
            page += table.html();
        }
        page += "</section>\n";
    }
    return page + "</body>\n</html>\n";
}

}  // namespace

int writeReport(const std::vector<std::string>& statsFiles, const std::string& outDir, Diagnostics& diag) {
    std::vector<Frame> frames;
    try {
        for (const auto& file : statsFiles) readStats(file, frames);
    } catch (const InputError& e) {
        diag.error(e.loc, "{}", e.message);
        return 1;
    }
    const std::vector<MapStorage> maps = mapStorage(frames, statsFiles, diag);
    const std::vector<Section> sections = buildSections(frames, maps);

    const FileLoc outLoc = FileLoc::inFile(outDir);
    std::error_code ec;
    fs::create_directories(outDir, ec);
    if (ec) {
        diag.error(outLoc, "cannot make the report directory: {}", ec.message());
        return 1;
    }
    const std::vector<std::pair<std::string, std::string>> outputs{
        {"report.md", markdown(sections, statsFiles)}, {"report.html", html(sections, statsFiles)}};
    std::vector<fs::path> temps;
    auto removeTemps = [&] {
        for (const auto& t : temps) fs::remove(t, ec);
    };
    for (const auto& [name, text] : outputs) {
        const fs::path temp = fs::path(outDir) / (name + ".tmp");
        temps.push_back(temp);
        std::ofstream out(temp, std::ios::binary);
        out << text;
        out.close();
        if (!out) {
            diag.error(FileLoc::inFile(temp.string()), "cannot write the report");
            removeTemps();
            return 1;
        }
    }
    for (size_t i = 0; i < outputs.size(); ++i) {
        fs::rename(temps[i], fs::path(outDir) / outputs[i].first, ec);
        if (ec) {
            diag.error(FileLoc::inFile(temps[i].string()), "cannot rename the report into place: {}", ec.message());
            removeTemps();
            return 1;
        }
    }
    return 0;
}

}  // namespace umbra::apps
