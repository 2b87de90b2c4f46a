// `umbra report`: the report of a real render's statistics, its HTML's
// internal links and self-containment, located errors on bad input, and a
// headless Chromium drawing the page. Every run is a child process; no test
// reads a clock.

#include "support/child_run.h"
#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

using umbra::test::Image;
using umbra::test::ChildRun;
using umbra::test::readFile;
using umbra::test::runIn;
using umbra::test::ScratchDir;
using umbra::test::writeFile;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

ChildRun runUmbra(const ScratchDir& dir, std::vector<std::string> args) {
    args.insert(args.begin(), "umbra");
    return runIn(dir, UMBRA_APP, std::move(args));
}

/// Three 64 x 48 frames of a sphere moving over a floor under a spotlight
/// with an automatic depth map: every frame has a first pass and one map,
/// written to out.000N.1.shd.
std::string threeFrames() {
    std::string rib = "Format 64 48 1\nPixelSamples 2 2\n";
    for (int n = 1; n <= 3; ++n)
        rib += fmt::format(R"(FrameBegin {}
Display "out.####.tif" "file" "rgba"
Projection "perspective" "fov" 40
Translate 0 0 5
WorldBegin
  LightSource "shadowspot" 1 "from" [0.5 4 0.3] "to" [0 0 0] "coneangle" [0.9] "intensity" [16] "shadowname" ["auto"]
  Surface "matte"
  AttributeBegin
    Translate {} 0.5 0
    Sphere 0.6 -0.6 0.6 360
  AttributeEnd
  Patch "bilinear" "P" [-3 -0.5 -3  3 -0.5 -3  -3 -0.5 3  3 -0.5 3]
WorldEnd
FrameEnd
)",
                           n, 0.2 * (n - 3));
    return rib;
}

/// Renders the three frames with --stats run.json in `dir`.
json renderThreeFrames(const ScratchDir& dir) {
    writeFile(dir.file("seq.rib"), threeFrames());
    const ChildRun run = runUmbra(dir, {"render", "--threads", "2", "--stats", "run.json", "seq.rib"});
    EXPECT_EQ(run.status, 0) << run.messages;
    return json::parse(readFile(dir.file("run.json")));
}

/// The same frames as JSON lines, each listing its map as `--stats X.jsonl`
/// does (schema 1), with the given light name.
void writeLines(const ScratchDir& dir, const json& doc, const std::string& name, const std::string& light) {
    std::string lines;
    for (json frame : doc["frames"]) {
        frame["schema"] = 1;
        const int n = frame["frame"].get<int>();
        frame["maps"] = json::array(
            {{{"light", light}, {"path", fmt::format("out.{:04d}.1.shd", n)}, {"reused", false},
              {"reason", n == 1 ? "first frame" : "caster changed"}}});
        lines += frame.dump() + "\n";
    }
    writeFile(dir.file(name), lines);
}

std::string camera(const json& frame) {
    double wall = 0;
    for (const auto& p : frame["passes"])
        if (p["name"] == "camera") wall += p["wall_seconds"].get<double>();
    return fmt::format("{:.4f}", wall);
}

std::vector<std::string> cells(const std::string& row) {
    std::vector<std::string> out;
    std::stringstream ss(row);
    std::string cell;
    std::getline(ss, cell, '|');  // before the first bar
    while (std::getline(ss, cell, '|')) {
        const size_t a = cell.find_first_not_of(' '), b = cell.find_last_not_of(' ');
        out.push_back(a == std::string::npos ? "" : cell.substr(a, b - a + 1));
    }
    return out;
}

/// The markdown rows of the table under heading `title`.
std::vector<std::vector<std::string>> tableRows(const std::string& md, const std::string& title) {
    std::vector<std::vector<std::string>> rows;
    const size_t at = md.find("## " + title);
    if (at == std::string::npos) return rows;
    std::stringstream ss(md.substr(at));
    std::string line;
    std::getline(ss, line);
    int lines = 0;
    while (std::getline(ss, line) && line.rfind("## ", 0) != 0)
        if (line.rfind("|", 0) == 0 && lines++ >= 2) rows.push_back(cells(line));  // past header and rule
    return rows;
}

}  // namespace

TEST(Report, TablesHoldTheNumbersOfARealRendersStatistics) {
    ScratchDir dir("report-real");
    const json doc = renderThreeFrames(dir);
    const ChildRun run = runUmbra(dir, {"report", "run.json", "-o", "rep"});
    ASSERT_EQ(run.status, 0) << run.messages;
    const std::string md = readFile(dir.file("rep/report.md"));

    // Table 1, one row per frame then the sequence: first pass, second pass
    // (the rest of the frame) and total, from the statistics themselves.
    const auto t1 = tableRows(md, "Table 1");
    ASSERT_EQ(t1.size(), 4u) << md;
    double first = 0, total = 0;
    for (int i = 0; i < 3; ++i) {
        const json& f = doc["frames"][i];
        const double fp = f["first_pass"]["wall_seconds"].get<double>(), wall = f["wall_seconds"].get<double>();
        EXPECT_EQ(t1[i][0], std::to_string(f["frame"].get<int>()));
        EXPECT_EQ(t1[i][1], "1") << "one depth pass per frame";
        EXPECT_EQ(t1[i][2], fmt::format("{:.4f}", fp));
        EXPECT_EQ(t1[i][3], fmt::format("{:.4f}", wall - fp));
        EXPECT_EQ(t1[i][4], fmt::format("{:.4f}", wall));
        first += fp;
        total += wall;
    }
    EXPECT_EQ(t1[3][0], "all");
    EXPECT_EQ(t1[3][2], fmt::format("{:.4f}", first));
    EXPECT_EQ(t1[3][4], fmt::format("{:.4f}", total));

    // The slowest frames, slowest first, with their camera pass.
    const auto slow = tableRows(md, "Slowest frames");
    ASSERT_EQ(slow.size(), 3u) << md;
    std::vector<json> frames(doc["frames"].begin(), doc["frames"].end());
    std::stable_sort(frames.begin(), frames.end(), [](const json& a, const json& b) {
        return a["wall_seconds"].get<double>() > b["wall_seconds"].get<double>();
    });
    for (int i = 0; i < 3; ++i) {
        EXPECT_EQ(slow[i][0], std::to_string(frames[i]["frame"].get<int>()));
        EXPECT_EQ(slow[i][3], camera(frames[i]));
        EXPECT_EQ(slow[i][7], "64x48");
    }

    // The tile cache's sequence totals.
    double lookups = 0, hits = 0;
    for (const auto& f : doc["frames"]) {
        lookups += f["shadow"]["tile_cache"]["lookups"].get<double>();
        hits += f["shadow"]["tile_cache"]["hits"].get<double>();
    }
    const auto cache = tableRows(md, "Tile cache");
    ASSERT_EQ(cache.size(), 1u) << md;
    EXPECT_EQ(cache[0][0], fmt::format("{:.0f}", lookups));
    EXPECT_EQ(cache[0][1], fmt::format("{:.0f}", hits));
}

TEST(Report, JsonLinesGiveStoragePerMapAndReuse) {
    ScratchDir dir("report-lines");
    const json doc = renderThreeFrames(dir);
    writeLines(dir, doc, "run.jsonl", "key");
    const ChildRun run = runUmbra(dir, {"report", "run.jsonl", "-o", "rep"});
    ASSERT_EQ(run.status, 0) << run.messages;
    const std::string md = readFile(dir.file("rep/report.md"));

    // Table 2: each map's storage, from its file; raw is width x height x 4
    // bytes, the bounding box and the tiles at most that.
    const auto t2 = tableRows(md, "Table 2");
    ASSERT_EQ(t2.size(), 4u) << md;
    double rawSum = 0;
    for (int i = 0; i < 3; ++i) {
        const auto& row = t2[i];
        EXPECT_EQ(row[0], "key");
        EXPECT_EQ(row[1], fmt::format("out.{:04d}.1.shd", i + 1));
        EXPECT_EQ(row[2], "1");
        int w = 0, h = 0;
        ASSERT_EQ(std::sscanf(row[4].c_str(), "%dx%d", &w, &h), 2) << row[4];
        EXPECT_EQ(row[5], fmt::format("{:.3f}", w * h * 4 / 1e6));
        EXPECT_LE(std::stod(row[6]), std::stod(row[5]));
        EXPECT_LE(std::stod(row[8]), std::stod(row[5]));
        EXPECT_GT(std::stod(row[8]), 0.0) << "the floor and sphere fill some tiles";
        rawSum += w * h * 4 / 1e6;
    }
    EXPECT_EQ(t2[3][0], "all");
    EXPECT_NEAR(std::stod(t2[3][5]), rawSum, 0.002);

    // Reuse: every map rendered, for the reasons the lines give.
    EXPECT_NE(md.find("3 maps rendered, 0 reused"), std::string::npos) << md;
    const auto reasons = tableRows(md, "Map reuse");
    ASSERT_EQ(reasons.size(), 2u) << md;
    EXPECT_EQ(reasons[0], (std::vector<std::string>{"caster changed", "2"}));
    EXPECT_EQ(reasons[1], (std::vector<std::string>{"first frame", "1"}));
}

TEST(Report, HtmlLinksResolveAndNothingIsFetchedOrUnescaped) {
    ScratchDir dir("report-html");
    const json doc = renderThreeFrames(dir);
    writeLines(dir, doc, "run.jsonl", "<b>\"key\" & 'fill'</b>");
    const ChildRun run = runUmbra(dir, {"report", "run.jsonl", "-o", "rep"});
    ASSERT_EQ(run.status, 0) << run.messages;
    const std::string html = readFile(dir.file("rep/report.html"));

    std::set<std::string> ids, targets;
    const std::regex id(R"re(\bid="([^"]*)")re"), href(R"re(\bhref="([^"]*)")re");
    for (auto it = std::sregex_iterator(html.begin(), html.end(), id); it != std::sregex_iterator(); ++it)
        EXPECT_TRUE(ids.insert((*it)[1]).second) << "duplicate id " << (*it)[1];
    for (auto it = std::sregex_iterator(html.begin(), html.end(), href); it != std::sregex_iterator(); ++it) {
        const std::string target = (*it)[1];
        ASSERT_EQ(target.rfind("#", 0), 0u) << "a link out of the page: " << target;
        targets.insert(target.substr(1));
    }
    EXPECT_GE(targets.size(), 8u) << "the navigation links every section";
    for (const auto& t : targets) EXPECT_TRUE(ids.count(t)) << "#" << t << " has no element";

    // Self-contained: no URL, script, or external resource of any kind.
    for (const char* banned : {"http:", "https:", "<script", "src=", "<link", "@import", "url("})
        EXPECT_EQ(html.find(banned), std::string::npos) << banned;
    // Balanced elements, the plots drawn by the report itself.
    auto count = [&](const std::string& s) {
        size_t n = 0;
        for (size_t at = html.find(s); at != std::string::npos; at = html.find(s, at + 1)) ++n;
        return n;
    };
    for (const char* tag : {"section", "svg", "table", "figure"})
        EXPECT_EQ(count(fmt::format("<{}", tag)), count(fmt::format("</{}>", tag))) << tag;
    EXPECT_EQ(count("<svg"), 5u);
    // The light's name is text, never markup.
    EXPECT_EQ(html.find("<b>"), std::string::npos);
    EXPECT_NE(html.find("&lt;b&gt;&quot;key&quot; &amp; &#39;fill&#39;&lt;/b&gt;"), std::string::npos);
}

TEST(Report, BadInputIsALocatedErrorAndLeavesTheOldReport) {
    ScratchDir dir("report-bad");
    writeFile(dir.file("good.jsonl"), "{\"frame\": 1, \"wall_seconds\": 0.5}\n{\"frame\": 2, \"skipped\": true}\n");
    ASSERT_EQ(runUmbra(dir, {"report", "good.jsonl", "-o", "rep"}).status, 0);
    const std::string before = readFile(dir.file("rep/report.html"));
    ASSERT_FALSE(before.empty());

    struct Case {
        std::string file, text, where, expected;
    };
    const std::vector<Case> cases{
        {"syntax.jsonl", "{\"frame\": 1, \"wall_seconds\": 0.5}\n\n{\"frame\": 3, \"wall_seconds\": }\n", "syntax.jsonl:3:",
         "expected one JSON object (a frame's statistics) per line"},
        {"type.jsonl", "{\"frame\": 1}\n{\"frame\": 2, \"wall_seconds\": \"slow\"}\n", "type.jsonl:2:1",
         "expected a number for \"wall_seconds\", got string"},
        {"nested.jsonl", "{\"frame\": 1, \"shadow\": {\"tile_cache\": [1, 2]}}\n", "nested.jsonl:1:1",
         "expected an object for \"tile_cache\""},
        {"doc.json", "{\n  \"frames\": [\n    {\"frame\": 1,,}\n  ]\n}\n", "doc.json:3:", "expected a JSON document"},
        {"frames.json", "{\"frames\": 3}", "frames.json", "expected \"frames\" to be an array, got number"},
        {"frame.json", "{\"frames\": [{\"frame\": 1}, 7]}", "frame.json", "frames[1]: expected a frame object"},
        {"empty.json", "\n", "empty.json:1:1", "got an empty file"},
        {"huge.jsonl", "{\"frame\": 1e300}\n", "huge.jsonl:1:1", "expected a whole number for \"frame\", got 1e+300"},
    };
    for (const Case& c : cases) {
        writeFile(dir.file(c.file), c.text);
        const ChildRun run = runUmbra(dir, {"report", "good.jsonl", c.file, "-o", "rep"});
        EXPECT_NE(run.status, 0) << c.file;
        EXPECT_NE(run.messages.find(c.where), std::string::npos) << c.file << ": " << run.messages;
        EXPECT_NE(run.messages.find(c.expected), std::string::npos) << c.file << ": " << run.messages;
        EXPECT_EQ(readFile(dir.file("rep/report.html")), before) << c.file;
    }
    std::vector<std::string> left;
    for (const auto& e : fs::directory_iterator(dir.file("rep"))) left.push_back(e.path().filename().string());
    std::sort(left.begin(), left.end());
    EXPECT_EQ(left, (std::vector<std::string>{"report.html", "report.md"})) << "no temporary left behind";
    // A missing file is an error too.
    const ChildRun missing = runUmbra(dir, {"report", "absent.jsonl", "-o", "rep"});
    EXPECT_NE(missing.status, 0);
    EXPECT_NE(missing.messages.find("absent.jsonl: error: cannot read the statistics file"), std::string::npos)
        << missing.messages;
}

TEST(Report, ThousandFramesOfSparseStatistics) {
    // The scale of a production sequence, with frames missing every optional
    // field: the slowest frame and every Table 1 row are still found.
    ScratchDir dir("report-many");
    std::string lines;
    for (int n = 1; n <= 1000; ++n) {
        json f = {{"schema", 1}, {"frame", n}, {"wall_seconds", 1.0 + (n * 37 % 1000) / 1000.0}};
        if (n % 3 == 0) f["first_pass"] = {{"wall_seconds", 0.25}};
        if (n % 5 == 0)
            f["maps"] = json::array({{{"light", "key"}, {"path", "gone.shd"}, {"reused", n % 10 == 0}, {"reason", "x"}}});
        lines += f.dump() + "\n";
    }
    writeFile(dir.file("many.jsonl"), lines);
    const ChildRun run = runUmbra(dir, {"report", "many.jsonl", "-o", "rep"});
    ASSERT_EQ(run.status, 0) << run.messages;
    EXPECT_NE(run.messages.find("gone.shd"), std::string::npos) << "a map file that is gone is a warning";
    const std::string md = readFile(dir.file("rep/report.md"));
    EXPECT_EQ(tableRows(md, "Table 1").size(), 1001u);
    const auto slow = tableRows(md, "Slowest frames");
    ASSERT_EQ(slow.size(), 10u);
    EXPECT_EQ(slow[0][0], "27") << "27 * 37 = 999 (mod 1000): the longest frame";
    EXPECT_EQ(slow[0][1], "1.9990");
    EXPECT_NE(md.find("100 maps rendered, 100 reused"), std::string::npos);
}

TEST(Report, ChromiumDrawsEveryPlot) {
    // A real browser opens the page: each plot's bars must be drawn, in the
    // order of the page. Times are fixed here so the bars' sizes are known.
    ScratchDir dir("report-browser");
    std::string chromium;
    for (const char* name : {"chromium", "chromium-browser"})
        for (const char* bin : {"/usr/bin/", "/usr/local/bin/"})
            if (chromium.empty() && fs::exists(std::string(bin) + name)) chromium = std::string(bin) + name;
    ASSERT_FALSE(chromium.empty())
        << "headless Chromium is needed for this test: apt-get install chromium (scripts/install-deps.sh lists it)";

    renderThreeFrames(dir);  // for its depth maps
    std::string lines;
    for (int n = 1; n <= 3; ++n) {
        const json f = {
            {"schema", 1},
            {"frame", n},
            {"wall_seconds", 1.0},
            {"threads", 2},
            {"first_pass", {{"wall_seconds", 0.3}}},
            {"passes", json::array({{{"name", "depth:1"}, {"wall_seconds", 0.3}}, {{"name", "camera"}, {"wall_seconds", 0.6}}})},
            {"shadow", {{"lookup_seconds", 0.2}, {"tile_cache", {{"lookups", 100}, {"hits", 90}, {"misses", 10}}}}},
            {"maps", json::array({{{"light", "1"}, {"path", fmt::format("out.{:04d}.1.shd", n)}, {"reused", n > 1}}})}};
        lines += f.dump() + "\n";
    }
    writeFile(dir.file("fixed.jsonl"), lines);
    const ChildRun report = runUmbra(dir, {"report", "fixed.jsonl", "-o", "rep"});
    ASSERT_EQ(report.status, 0) << report.messages;

    const ChildRun shot = runIn(dir, chromium,
                           {chromium, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                            "--user-data-dir=" + dir.file("profile"), "--screenshot=" + dir.file("shot.png"),
                            "--window-size=1200,2400", "file://" + dir.file("rep/report.html")});
    ASSERT_EQ(shot.status, 0) << shot.messages;
    Image img;
    ASSERT_TRUE(umbra::test::readImage(dir.file("shot.png"), &img)) << shot.messages;
    ASSERT_EQ(img.width, 1200);
    ASSERT_EQ(img.height, 2400);

    // A series colour of each plot, in page order: pixels of it and the
    // mean row where they are.
    struct Colour {
        const char* series;
        int r, g, b;
    };
        // The camera pass is stacked on the first pass: above it on the page.
    const std::vector<Colour> colours{{"camera pass", 0x1f, 0x77, 0xb4}, {"first pass", 0xd6, 0x27, 0x28},
                                      {"overhead", 0xff, 0x7f, 0x0e},   {"raw storage", 0x8c, 0x56, 0x4b},
                                      {"cache hits", 0x2c, 0xa0, 0x2c}, {"maps rendered", 0x94, 0x67, 0xbd}};
    double lastRow = 0;
    for (const Colour& c : colours) {
        size_t pixels = 0;
        double rows = 0;
        for (int y = 0; y < img.height; ++y)
            for (int x = 0; x < img.width; ++x) {
                auto near = [&](int ch, int v) { return std::abs(img.at(x, y, ch) * 255.0f - float(v)) < 1.5f; };
                if (near(0, c.r) && near(1, c.g) && near(2, c.b)) {
                    ++pixels;
                    rows += y;
                }
            }
        // A legend swatch is 144 pixels; a bar is thousands.
        EXPECT_GT(pixels, 2000u) << c.series << " bars not drawn";
        if (pixels == 0) continue;
        const double row = rows / double(pixels);
        EXPECT_GT(row, lastRow) << c.series << " plot out of the page's order";
        lastRow = row;
    }
}

TEST(Report, NumbersPastTheLargestDoubleStillGiveAReport) {
    // Hits and misses that sum past the largest double once made the plot's
    // tick loop step by infinity forever.
    ScratchDir dir("report-huge");
    writeFile(dir.file("huge.jsonl"),
              "{\"frame\": 1, \"wall_seconds\": 1.5e308, \"shadow\": {\"tile_cache\": {\"hits\": 1e308, \"misses\": 1e308}}}\n"
              "{\"frame\": 2, \"wall_seconds\": 1e308}\n");
    const ChildRun run = runUmbra(dir, {"report", "huge.jsonl", "-o", "rep"});
    ASSERT_EQ(run.status, 0) << run.messages;
    EXPECT_NE(readFile(dir.file("rep/report.html")).find("values too large to plot"), std::string::npos);
}
