#include "umbra/ri/parser.h"

#include <gtest/gtest.h>
#include <zlib.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace umbra::ri {
namespace {

/// Records the requests the tests look at, as text.
struct Recorder : Target {
    std::vector<std::string> log;
    std::vector<RequestArgs> args;
    std::vector<ParamList> params;
    void unhandled(std::string_view request, const FileLoc& loc) override { log.push_back(std::string(request)); }
    void primitive(const std::string& type, RequestArgs a, ParamList p, const FileLoc& loc) override {
        log.push_back(fmt::format("{}@{}", type, loc.str()));
        args.push_back(std::move(a));
        params.push_back(std::move(p));
    }
    void surface(const std::string& name, ParamList p, const FileLoc& loc) override {
        log.push_back("Surface " + name);
        params.push_back(std::move(p));
    }
    void translate(const Vec3& d, const FileLoc& loc) override { log.push_back(fmt::format("Translate {} {} {}", d.x, d.y, d.z)); }
    void lightSource(const std::string& name, const std::string& handle, ParamList p, const FileLoc& loc) override {
        log.push_back("LightSource " + name + " " + handle);
    }
};

std::vector<std::string> messages(const Diagnostics& d) {
    std::vector<std::string> out;
    for (const Diagnostic& m : d.recorded()) out.push_back(m.str());
    return out;
}

struct Parsed {
    Recorder rec;
    Diagnostics diag;
    bool ok = false;
};

std::unique_ptr<Parsed> parse(std::string_view text) {
    auto p = std::make_unique<Parsed>();
    p->diag.setRecord(true);
    p->diag.setSink([](const Diagnostic&) {});
    p->ok = parseString(text, "t.rib", p->rec, p->diag);
    return p;
}

TEST(Parser, PositionalNumbersBareOrBracketed) {
    auto p = parse("Sphere 1 -1 1 360\nSphere [2 -2 2 180]\nSphere [3 -3] 3 [90]");
    ASSERT_TRUE(p->ok) << fmt::format("{}", fmt::join(messages(p->diag), "\n"));
    ASSERT_EQ(p->rec.args.size(), 3u);
    EXPECT_EQ(p->rec.args[0].floats, (std::vector<float>{1, -1, 1, 360}));
    EXPECT_EQ(p->rec.args[1].floats, (std::vector<float>{2, -2, 2, 180}));
    EXPECT_EQ(p->rec.args[2].floats, (std::vector<float>{3, -3, 3, 90}));
    EXPECT_EQ(p->rec.log[1], "Sphere@t.rib:2:1");
    // The third form is not RIB's (Pixie and Aqsis refuse it): read in
    // order, with a warning; the first two are not warned of.
    EXPECT_EQ(messages(p->diag),
              (std::vector<std::string>{"t.rib:3:1: warning: Sphere: numbers given partly in [ ] and partly loose, or in "
                                        "several [ ]; read in order (RIB gives them all loose or all in one [ ]; usage: "
                                        "Sphere radius zmin zmax thetamax)"}));
}

TEST(Parser, IntegerArraysGoToIntArrays) {
    auto p = parse("PointsGeneralPolygons [1 1] [3 3] [0 1 2 0 2 3] \"P\" [0 0 0 1 0 0 1 1 0 0 1 0]");
    ASSERT_TRUE(p->ok);
    const RequestArgs& a = p->rec.args.at(0);
    ASSERT_EQ(a.intArrays.size(), 3u);
    EXPECT_EQ(a.intArrays[2], (std::vector<int>{0, 1, 2, 0, 2, 3}));
    EXPECT_EQ(a.ints, (std::vector<int>{1, 1, 3, 3, 0, 1, 2, 0, 2, 3}));
    const Param* P = p->rec.params.at(0).find("P");
    ASSERT_NE(P, nullptr);
    EXPECT_EQ(P->decl.storage, StorageClass::Vertex);
    EXPECT_EQ(P->count(), 4u);
    EXPECT_EQ(P->floats[3], 1.0f);
}

TEST(Parser, WrongArgumentCountIsReportedAndSkipped) {
    auto p = parse("Sphere 1 -1 1\nTranslate 1 2 3");
    EXPECT_FALSE(p->ok);
    EXPECT_EQ(messages(p->diag), (std::vector<std::string>{
        "t.rib:1:1: error: Sphere: missing argument thetamax (usage: Sphere radius zmin zmax thetamax)"}));
    EXPECT_EQ(p->rec.log, (std::vector<std::string>{"Translate 1 2 3"}));
}

TEST(Parser, NumbersOutOfFloatRangeSkipTheirRequest) {
    // 1e39 would be infinity as a float: the request never reaches the
    // target, in positional arguments or in a parameter list alike.
    auto p = parse("Translate 1e39 0 0\nSphere 1 -1 1 360 \"Cs\" [nan 0 0]\nTranslate 1 2 3.4e38");
    EXPECT_FALSE(p->ok);
    EXPECT_EQ(messages(p->diag), (std::vector<std::string>{
        "t.rib:1:11: error: Translate: number out of range \"1e39\" (expected a magnitude of at most 3.4e38, the "
        "largest 32-bit float)",
        "t.rib:2:25: error: Sphere: not a finite number \"nan\" (expected a finite number)"}));
    EXPECT_EQ(p->rec.log, (std::vector<std::string>{"Translate 1 2 3.4e+38"}));
}

TEST(Parser, UnknownRequestSkipsItsArguments) {
    auto p = parse("Spher 1 2 [3] \"x\"\nTranslate 1 2 3");
    EXPECT_EQ(messages(p->diag), (std::vector<std::string>{
        "t.rib:1:1: error: Spher: unknown request (its arguments are skipped)"}));
    EXPECT_EQ(p->rec.log, (std::vector<std::string>{"Translate 1 2 3"}));
}

TEST(Parser, RequestsOfLaterRenderManVersionsWarnOnceAndAreSkipped) {
    // A RenderMan 19+ (RIS) file: its materials, patterns, lights and
    // integrator are warned once per request name and skipped, the rest
    // is read; a misspelt request is still an error.
    auto p = parse("Integrator \"PxrPathTracer\" \"i\" \"int maxPathLength\" [5]\n"
                   "Pattern \"PxrChecker\" \"c\" \"color colorA\" [1 0 0]\n"
                   "Bxdf \"PxrDiffuse\" \"d\" \"reference color diffuseColor\" [\"c:resultRGB\"]\n"
                   "Bxdf \"PxrDiffuse\" \"e\"\nTranslate 1 2 3\nBxdff \"x\"");
    EXPECT_EQ(messages(p->diag), (std::vector<std::string>{
        "t.rib:1:1: warning: Integrator: a RenderMan 19+ (RIS) integrator umbra does not have; the REYES hider "
        "renders the frame (its arguments are skipped)",
        "t.rib:2:1: warning: Pattern: a RenderMan 19+ (RIS) pattern node umbra does not have; ignored (its "
        "arguments are skipped)",
        "t.rib:3:1: warning: Bxdf: a RenderMan 19+ (RIS) material umbra does not have; the current Surface shades "
        "instead (its arguments are skipped)",
        "t.rib:6:1: error: Bxdff: unknown request (its arguments are skipped)"}));
    EXPECT_EQ(p->rec.log, (std::vector<std::string>{"Translate 1 2 3"}));
}

TEST(Parser, DeclarationsInlineAndDeclared) {
    auto p = parse("Declare \"myfloat\" \"uniform float[2]\"\n"
                   "Surface \"s\" \"myfloat\" [1 2] \"varying color Cq\" [1 0 0] \"Kd\" 0.5 \"texturename\" \"a.tx\"");
    ASSERT_TRUE(p->ok) << fmt::format("{}", fmt::join(messages(p->diag), "\n"));
    const ParamList& l = p->rec.params.at(0);
    ASSERT_EQ(l.size(), 4u);
    EXPECT_EQ(l.params()[0].decl.str(), "uniform float[2] myfloat");
    EXPECT_EQ(l.params()[1].decl.str(), "varying color Cq");
    EXPECT_EQ(l.getFloat("Kd", 0), 0.5f);
    EXPECT_EQ(l.getString("texturename", ""), "a.tx");
    EXPECT_EQ(l.params()[1].loc.str(), "t.rib:2:29");
}

TEST(Parser, DeclaredNamesLoseTheirBlanksAndNamesOfSeveralWordsAreWarnedAndIgnored) {
    // As a parser test of Aqsis's writes them; Aqsis and Pixie take both.
    auto p = parse("Declare \"  padded \" \"uniform float\"\n"
                   "Declare \"  two words  \" \"constant string\"\n"
                   "Declare \" \" \"uniform float\"\n"
                   "Surface \"s\" \"padded\" 2");
    EXPECT_TRUE(p->ok);
    EXPECT_EQ(messages(p->diag), (std::vector<std::string>{
        "t.rib:2:1: warning: Declare: parameter name \"  two words  \" is not one word; the declaration is ignored "
        "(no parameter list could name it)",
        "t.rib:3:1: warning: Declare: parameter name \" \" is not one word; the declaration is ignored (no "
        "parameter list could name it)"}));
    ASSERT_EQ(p->rec.params.size(), 1u);
    ASSERT_EQ(p->rec.params[0].size(), 1u);
    EXPECT_EQ(p->rec.params[0].params()[0].decl.str(), "uniform float padded");
    EXPECT_FALSE(p->rec.params[0].params()[0].decl.inferred);
}

TEST(Parser, ParameterErrorsDropOnlyTheParameter) {
    // A shader parameter with more values than fit keeps the leading ones,
    // with a warning (Pixie takes them silently, Aqsis warns); too few or
    // of the wrong type drop it.
    auto p = parse("Surface \"s\" \"Cs\" [1 0] \"Kd\" \"a\" \"constant float c\" [1 2] \"Ka\" 0.25 \"Ks\"\n"
                   "Surface \"t\" \"uniform float[2] f\" [1 .5 .25] \"constant string n\" [\"blue\" \"red\"]");
    EXPECT_EQ(messages(p->diag), (std::vector<std::string>{
        "t.rib:1:13: error: Surface: parameter \"Cs\" (varying color) expects a multiple of 3 values, got 2",
        "t.rib:1:24: error: Surface: parameter \"Kd\" (uniform float) expects numbers, got string \"a\"",
        "t.rib:1:33: warning: Surface: parameter \"c\" (constant float) expects 1 value, got 2; the first is used",
        "t.rib:1:68: error: Surface: parameter \"Ks\" has no value",
        "t.rib:2:13: warning: Surface: parameter \"f\" (uniform float[2]) expects a multiple of 2 values, got 3; the "
        "first 2 are used",
        "t.rib:2:45: warning: Surface: parameter \"n\" (constant string) expects 1 value, got 2; the first is "
        "used"}));
    ASSERT_EQ(p->rec.params.size(), 2u);
    EXPECT_EQ(p->rec.params[0].size(), 2u);
    EXPECT_EQ(p->rec.params[0].getFloat("Ka", 0), 0.25f);
    EXPECT_EQ(p->rec.params[0].getFloat("c", 0), 1.0f);
    const ParamList& t = p->rec.params[1];
    ASSERT_NE(t.find("f"), nullptr);
    EXPECT_EQ(t.find("f")->floats, (std::vector<float>{1, 0.5f}));
    ASSERT_NE(t.find("n"), nullptr);
    EXPECT_EQ(t.find("n")->strings, (std::vector<std::string>{"blue"}));
}

TEST(Parser, UndeclaredShaderParametersAreTypedByTheirValues) {
    // RenderMan types a shader request's own parameters from the shader's
    // declarations; the parser keeps them with an inferred type.
    auto p = parse("Surface \"s\" \"Kx\" 1 \"tint\" [1 0.5 0] \"map\" \"a.tx\"");
    EXPECT_TRUE(messages(p->diag).empty());
    ASSERT_EQ(p->rec.params.size(), 1u);
    const ParamList& l = p->rec.params[0];
    ASSERT_EQ(l.size(), 3u);
    EXPECT_TRUE(l.params()[0].decl.inferred);
    EXPECT_EQ(l.params()[1].floats, (std::vector<float>{1, 0.5f, 0}));
    EXPECT_EQ(l.params()[2].decl.type, ParamType::String);
}

TEST(Parser, UndeclaredGeometryParameterIsAnError) {
    auto p = parse("Sphere 1 -1 1 360 \"Kx\" 1");
    EXPECT_EQ(messages(p->diag), (std::vector<std::string>{
        "t.rib:1:19: error: Sphere: parameter \"Kx\" is not declared (use Declare or an inline declaration such as "
        "\"uniform float Kx\")"}));
}

TEST(Parser, HandlesMayBeIntegersOrStrings) {
    auto p = parse("LightSource \"pointlight\" 3\nLightSource \"spotlight\" \"key\"\nLightSource \"x\" 1.5");
    EXPECT_EQ(p->rec.log, (std::vector<std::string>{"LightSource pointlight 3", "LightSource spotlight key"}));
    ASSERT_EQ(messages(p->diag).size(), 1u);
    EXPECT_EQ(messages(p->diag)[0], "t.rib:3:17: error: LightSource: argument handle must be an integer or a "
                                    "string, got number 1.5 (usage: LightSource name handle)");
}

TEST(Parser, ALightWithoutAHandleSaysWhatWasTakenForIt) {
    auto p = parse("LightSource \"pointlight\" \"intensity\" [20] \"from\" [0 0 -3]");
    ASSERT_FALSE(messages(p->diag).empty());
    EXPECT_EQ(messages(p->diag)[0], "t.rib:1:38: error: LightSource: expected a parameter name string, got an array "
                                    "of 1 numbers: \"intensity\" was read as the light's handle (a number or string "
                                    "handle must follow the shader name)");
}

TEST(Parser, MissingBracketResynchronises) {
    auto p = parse("Sphere [1 -1 1 360\nTranslate 1 2 3\n] Translate 4 5 6");
    EXPECT_EQ(messages(p->diag), (std::vector<std::string>{
        "t.rib:1:8: error: Sphere: missing ']' to close this array",
        "t.rib:3:1: warning: Translate: skipped a ']' that closes no '['"}));
    EXPECT_EQ(p->rec.log, (std::vector<std::string>{"Translate 1 2 3", "Translate 4 5 6"}));
}

// Classic Mac OS files end their lines with a lone CR. A comment ends there
// (as Aqsis reads it): read to the next LF, the first comment swallowed
// every request after it and the render wrote nothing, silently.
TEST(Parser, CommentEndsAtALoneCarriageReturn) {
    auto p = parse("version 3.03\r# exported on a classic Mac\rTranslate 1 2 3\r#\rTranslate 4 5 6\r\n");
    EXPECT_EQ(p->rec.log, (std::vector<std::string>{"version", "Translate 1 2 3", "Translate 4 5 6"}));
    EXPECT_TRUE(messages(p->diag).empty()) << fmt::format("{}", fmt::join(messages(p->diag), "\n"));
}

// Jan Walter's Blender exporter writes a second ']' after every coloured
// polygon. Pixie and Aqsis skip it and keep the polygon; so does umbra, with
// one warning for the file.
TEST(Parser, StrayClosingBracketIsSkippedAndTheRequestKept) {
    auto p = parse("Polygon \"P\" [0 0 0 1 0 0 1 1 0] \"Cs\" [1 0 0 0 1 0 0 0 1]\n]\n"
                   "Color [1 0 0]\n]\nSphere 1 -1 1 360\n]\n");
    EXPECT_EQ(p->rec.log, (std::vector<std::string>{"Polygon@t.rib:1:1", "Color", "Sphere@t.rib:5:1"}));
    EXPECT_EQ(messages(p->diag), (std::vector<std::string>{
        "t.rib:2:1: warning: Polygon: skipped a ']' that closes no '['"}));
}

TEST(Parser, BytesThatAreNoRibAreStrayAndTheRequestBeforeThemKept) {
    // A control byte, a reserved binary byte or an undefined request code
    // after a finished request is reported where it stands; the request
    // is drawn (Pixie and Aqsis draw it too). A broken value inside the
    // request still costs the request.
    auto p = parse(std::string("Polygon \"P\" [0 0 0 1 0 0 1 1 0]\n\x01\nSphere 1 -1 1 360 \xf5\n"
                               "Sphere 2 -2 2 360\n\xa6\x05\nSphere 3 -3 3 1e39\n"));
    EXPECT_EQ(p->rec.log, (std::vector<std::string>{"Polygon@t.rib:1:1", "Sphere@t.rib:3:1", "Sphere@t.rib:4:1"}));
    const auto m = messages(p->diag);
    ASSERT_EQ(m.size(), 4u);
    EXPECT_EQ(m[0], "t.rib:2:1: error: RIB: unexpected control character 0x01 (not RIB)");
    EXPECT_EQ(m[1].rfind("t.rib:3:19: error: RIB: binary RIB: reserved byte", 0), 0u) << m[1];
    EXPECT_EQ(m[2].rfind("t.rib:5:1: error: RIB: binary RIB: request code 5 used before it was defined", 0), 0u) << m[2];
    EXPECT_EQ(m[3].rfind("t.rib:6:15: error: Sphere: number out of range", 0), 0u) << m[3];
}

std::string gzipBytes(const std::string& text) {
    z_stream zs{};
    EXPECT_EQ(deflateInit2(&zs, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY), Z_OK);
    std::string out(deflateBound(&zs, text.size()) + 64, '\0');
    zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(text.data()));
    zs.avail_in = static_cast<uInt>(text.size());
    zs.next_out = reinterpret_cast<Bytef*>(out.data());
    zs.avail_out = static_cast<uInt>(out.size());
    EXPECT_EQ(deflate(&zs, Z_FINISH), Z_STREAM_END);
    out.resize(zs.total_out);
    deflateEnd(&zs);
    return out;
}

TEST(Parser, BinaryRibReadsAsItsAsciiForm) {
    // As a RIB writer's binary mode writes it (RI Spec 3.2, appendix C):
    // requests defined once and referred to by code, parameter names as
    // defined string tokens, numbers as fixed point, floats and float
    // arrays; ASCII mixed in where the writer had no encoding.
    auto floatBytes = [](float f) {
        uint32_t bits;
        std::memcpy(&bits, &f, 4);
        return std::string{char(bits >> 24), char(bits >> 16), char(bits >> 8), char(bits)};
    };
    using namespace std::string_literals;  // "..."s keeps the NUL bytes of the encoding
    const std::string binary = "\xcc\x01\x99" "Translate" "\xcc\x02\x97" "Surface" "\xcc\x03\x96" "Sphere"s +
                               "\xcd\x00\x92" "Ks" "\xcd\x01\x92" "Kd"s +
                               "\xa6\x01" "\x80\x01" "\xa4"s + floatBytes(2.5f) + "\x81\xff\xfd"s +
                               "\xa6\x02" "\x97" "plastic" "\xcf\x00" "\xc8\x01"s + floatBytes(0.5f) +
                               "\xcf\x01" "\x85\x00\x40" "\n"s +
                               "\xa6\x03" "\x80\x01" "\x80\xff" "[1] " "\x81\x01\x68" "\n"s;
    auto fromBinary = parse(binary);
    ASSERT_TRUE(fromBinary->ok) << fmt::format("{}", fmt::join(messages(fromBinary->diag), "\n"));
    auto fromAscii = parse("Translate 1 2.5 -3\nSurface \"plastic\" \"Ks\" [0.5] \"Kd\" 0.25\nSphere 1 -1 [1] 360\n");
    ASSERT_TRUE(fromAscii->ok);
    EXPECT_TRUE(messages(fromBinary->diag).empty()) << fmt::format("{}", fmt::join(messages(fromBinary->diag), "\n"));
    ASSERT_EQ(fromBinary->rec.log.size(), 3u);
    EXPECT_EQ(fromBinary->rec.log[0], fromAscii->rec.log[0]);
    EXPECT_EQ(fromBinary->rec.log[1], fromAscii->rec.log[1]);
    EXPECT_EQ(fromBinary->rec.log[2].substr(0, 7), "Sphere@");
    ASSERT_EQ(fromBinary->rec.params.size(), 2u);
    for (size_t k = 0; k < 2; ++k) EXPECT_EQ(fromBinary->rec.params[k].size(), fromAscii->rec.params[k].size());
    EXPECT_EQ(fromBinary->rec.params[0].getFloat("Ks", 0), 0.5f);
    EXPECT_EQ(fromBinary->rec.params[0].getFloat("Kd", 0), 0.25f);
    EXPECT_EQ(fromBinary->rec.args.at(0).floats, (std::vector<float>{1, -1, 1, 360}));
}

TEST(Parser, GzipRoundTrip) {
    std::string text = "Translate 1 2 3\nSphere 1 -1 1 360 \"Cs\" [1 0 0]\n";
    std::string gz = gzipBytes(text);
    ASSERT_TRUE(isGzip(gz));
    auto dir = std::filesystem::path(UMBRA_BINARY_DIR) / "test_ri_tmp";
    std::filesystem::create_directories(dir);
    std::string path = (dir / "scene.rib.gz").string();
    std::ofstream(path, std::ios::binary) << gz;

    Recorder fromGz, fromText;
    Diagnostics diag;
    diag.setRecord(true);
    ASSERT_TRUE(parseFile(path, fromGz, diag));
    ASSERT_TRUE(parseString(text, path, fromText, diag));
    EXPECT_EQ(fromGz.log, fromText.log);
    EXPECT_EQ(fromGz.log.at(1), "Sphere@" + path + ":2:1");

    // Truncated: the error is reported and parsing fails.
    std::string cut = gz.substr(0, gz.size() / 2);
    Recorder none;
    Diagnostics d2;
    d2.setRecord(true);
    d2.setSink([](const Diagnostic&) {});
    EXPECT_FALSE(parseString(cut, "cut.rib", none, d2));
    ASSERT_EQ(messages(d2).size(), 1u);
    // Read as a stream: located where the data stopped, and the request it
    // cut short (its arguments may go on) is not run.
    EXPECT_EQ(messages(d2)[0], "cut.rib:2:1: error: RIB: cannot decompress: gzip data is truncated");
    EXPECT_TRUE(none.log.empty());
}

/// `text` deflated as gzip members of at most `memberBytes` each, one
/// after another (as `cat a.gz b.gz` makes).
std::string gzipMembers(const std::string& text, size_t memberBytes) {
    std::string out;
    for (size_t k = 0; k < text.size(); k += memberBytes) out += gzipBytes(text.substr(k, memberBytes));
    return out;
}

/// A Target with a small decompressed-byte budget.
struct BudgetRecorder : Recorder {
    uint64_t budget = 0;
    uint64_t decompressedByteBudget() const override { return budget; }
};

TEST(Parser, GzipIsReadAsAStreamOfMembersWithinTheBudget) {
    // Requests, a long run of whitespace and a comment split across
    // members, and an inline archive whose body crosses many reads.
    std::string text = "Translate 1 2 3\nArchiveBegin \"a\"\n  Sphere 1 -1 1 360\n";
    text += std::string(3 << 20, ' ') + "\n# " + std::string(1 << 20, 'c') + "\n";
    text += "ArchiveEnd\nReadArchive \"a\"\nTranslate 4 5 6\n";
    const std::string gz = gzipMembers(text, 100000);
    BudgetRecorder fromGz, fromText;
    fromGz.budget = text.size();  // exactly enough
    Diagnostics d;
    d.setRecord(true);
    d.setSink([](const Diagnostic&) {});
    ASSERT_TRUE(parseString(gz, "m.rib", fromGz, d)) << fmt::format("{}", fmt::join(messages(d), "\n"));
    ASSERT_TRUE(parseString(text, "m.rib", fromText, d));
    EXPECT_EQ(fromGz.log, fromText.log);
    EXPECT_EQ(fromGz.log, (std::vector<std::string>{"Translate 1 2 3", "ReadArchive", "Sphere@m.rib:3:3",
                                                    "Translate 4 5 6"}));
}

TEST(Parser, GzipPastTheBudgetStopsWithALocatedError) {
    std::string text = "Translate 1 2 3\nWorldBegin\n" + std::string(3 << 20, ' ') + "Translate 4 5 6\n";
    BudgetRecorder r;
    r.budget = 1 << 20;
    Diagnostics d;
    d.setRecord(true);
    d.setSink([](const Diagnostic&) {});
    EXPECT_FALSE(parseString(gzipBytes(text), "bomb.rib", r, d));
    // WorldBegin's arguments might have gone on past the budget: it is not run.
    EXPECT_EQ(r.log, (std::vector<std::string>{"Translate 1 2 3"}));
    // The error stands where the budget ran out: byte 2^20, on line 3.
    ASSERT_EQ(messages(d).size(), 1u);
    EXPECT_EQ(messages(d)[0], fmt::format("bomb.rib:3:{}: error: RIB: the decompressed RIB is larger than 1 MiB "
                                          "(Option \"limits\" \"decompressedmb\"); the rest of it is not read",
                                          (1 << 20) - 27 + 1));
}

TEST(Parser, MissingFileIsDetectable) {
    Recorder r;
    Diagnostics d;
    d.setRecord(true);
    d.setSink([](const Diagnostic&) {});
    EXPECT_FALSE(parseFile("/nonexistent/dir/x.rib", r, d));
    EXPECT_EQ(d.errorCount(), 1);
}

// MayaMan writes every shape as an inline archive in one geometry file,
// which it ends "ArchiveEnd\n#\n"; the last archive was recorded with its
// ArchiveEnd and replaying it reported an unmatched ArchiveEnd.
TEST(Parser, InlineArchiveLastInAReadFile) {
    auto dir = std::filesystem::path(UMBRA_BINARY_DIR) / "test_ri_tmp";
    std::filesystem::create_directories(dir);
    std::ofstream(dir / "defs.rib") << "ArchiveBegin \"a\"\nTranslate 1 2 3\nArchiveEnd\n#\n";
    std::ofstream(dir / "uses.rib") << "ReadArchive \"defs.rib\"\nReadArchive \"a\"\n";
    Recorder r;
    Diagnostics d;
    d.setRecord(true);
    d.setSink([](const Diagnostic&) {});
    EXPECT_TRUE(parseFile((dir / "uses.rib").string(), r, d)) << fmt::format("{}", fmt::join(messages(d), "\n"));
    EXPECT_EQ(r.log, (std::vector<std::string>{"ReadArchive", "ReadArchive", "Translate 1 2 3"}));
    EXPECT_TRUE(messages(d).empty());
}

// Exporters (BlenderMan) name every archive from the project directory the
// render runs in, also inside archives read from a subdirectory; Pixie and
// Aqsis find them there, after the including file's directory and the path.
TEST(Parser, ReadArchiveFallsBackOnTheCurrentDirectory) {
    namespace fs = std::filesystem;
    auto dir = fs::path(UMBRA_BINARY_DIR) / "test_ri_tmp" / "project";
    fs::create_directories(dir / "sub");
    std::ofstream(dir / "sub" / "geom.rib") << "Translate 1 2 3\n";
    const std::string fromHere = fs::relative(dir / "sub" / "geom.rib", fs::current_path()).string();
    std::ofstream(dir / "sub" / "obj.rib") << "ReadArchive \"" << fromHere << "\"\n";
    std::ofstream(dir / "main.rib") << "ReadArchive \"sub/obj.rib\"\n";
    Recorder r;
    Diagnostics d;
    d.setRecord(true);
    d.setSink([](const Diagnostic&) {});
    EXPECT_TRUE(parseFile((dir / "main.rib").string(), r, d)) << fmt::format("{}", fmt::join(messages(d), "\n"));
    EXPECT_EQ(r.log, (std::vector<std::string>{"ReadArchive", "ReadArchive", "Translate 1 2 3"}));
}

TEST(Parser, ReadArchiveBesideTheIncludingFile) {
    auto dir = std::filesystem::path(UMBRA_BINARY_DIR) / "test_ri_tmp";
    std::filesystem::create_directories(dir);
    std::ofstream(dir / "inner.rib") << "Translate 7 8 9\n";
    std::ofstream(dir / "self.rib") << "ReadArchive \"self.rib\"\n";
    std::ofstream(dir / "outer.rib") << "ReadArchive \"inner.rib\"\nTranslate 1 1 1\n";
    Recorder r;
    Diagnostics d;
    d.setRecord(true);
    d.setSink([](const Diagnostic&) {});
    EXPECT_TRUE(parseFile((dir / "outer.rib").string(), r, d));
    EXPECT_EQ(r.log, (std::vector<std::string>{"ReadArchive", "Translate 7 8 9", "Translate 1 1 1"}));
    Recorder r2;
    EXPECT_FALSE(parseFile((dir / "self.rib").string(), r2, d));
    ASSERT_GE(messages(d).size(), 1u);
    EXPECT_NE(messages(d).back().find("ReadArchive: archives nested more than 32 deep"), std::string::npos);
}

TEST(Parser, MillionPolygonMeshParses) {
    // 1M quads on a 1000x1000 grid of points: about 30 MB of RIB text
    // (a smaller grid in unoptimised, e.g. sanitizer, builds). Only the
    // result is checked; speed is for the benchmarks, not a clock here.
#ifdef NDEBUG
    const int n = 1000;
#else
    const int n = 250;
#endif
    std::string rib = "PointsPolygons [";
    rib.reserve(40 << 20);
    for (int i = 0; i < n * n; ++i) rib += "4 ";
    rib += "] [";
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            int v = y * (n + 1) + x;
            rib += fmt::format("{} {} {} {} ", v, v + 1, v + n + 2, v + n + 1);
        }
    rib += "] \"P\" [";
    for (int y = 0; y <= n; ++y)
        for (int x = 0; x <= n; ++x) rib += fmt::format("{} {} 0 ", x * 0.001, y * 0.001);
    rib += "]\n";
    Recorder r;
    Diagnostics d;
    ASSERT_TRUE(parseString(rib, "big.rib", r, d));
    ASSERT_EQ(r.args.size(), 1u);
    EXPECT_EQ(r.args[0].intArrays[1].size(), size_t(4 * n * n));
    EXPECT_EQ(r.args[0].intArrays[1][4 * n * n - 1], (n - 1) * (n + 1) + (n - 1) + n + 1);
    EXPECT_EQ(r.params[0].find("P")->count(), size_t((n + 1) * (n + 1)));
}


TEST(Parser, StringsMaySpanLinesAndAnUnendedOneCostsOneRequest) {
    // PRMan, Aqsis and Pixie read a newline inside a string as part of it.
    auto p = parse("Surface \"two\nlines\"\nSphere 1 -1 1 360\n");
    ASSERT_TRUE(p->ok) << fmt::format("{}", fmt::join(messages(p->diag), "\n"));
    ASSERT_EQ(p->rec.log.size(), 2u);
    EXPECT_EQ(p->rec.log[0], "Surface two\nlines");
    EXPECT_EQ(p->rec.log[1], "Sphere@t.rib:3:1");  // lines still count
    // A quote never closed: reported at the quote, and the next lines parse.
    auto q = parse("Surface \"plastic\nSphere 1 -1 1 360\nTranslate 1 2 3\n");
    EXPECT_FALSE(q->ok);
    ASSERT_EQ(messages(q->diag).size(), 1u);
    EXPECT_EQ(messages(q->diag)[0],
              "t.rib:1:9: error: Surface: unterminated string (no closing '\"' before the end of the input)");
    ASSERT_EQ(q->rec.log.size(), 2u);
    EXPECT_EQ(q->rec.log[0], "Sphere@t.rib:2:1");
    EXPECT_EQ(q->rec.log[1], "Translate 1 2 3");
}

}  // namespace
}  // namespace umbra::ri
