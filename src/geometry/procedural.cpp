#include "umbra/geometry/procedural.h"

#include "geometry/ri_binding.h"
#include "umbra/geometry/ri.h"

#include "umbra/ri/parser.h"
#include "umbra/scene/builder.h"
#include "umbra/util/search_path.h"

#include <fmt/format.h>

#include <dlfcn.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <cmath>
#include <filesystem>
#include <sstream>
#include <thread>

extern char** environ;

namespace umbra::geometry {

namespace {

/// The directory of the RIB file a request came from ("" when unknown).
std::string directoryOf(const FileLoc& loc) {
    if (!loc.file) return {};
    return std::filesystem::path(*loc.file).parent_path().string();
}

/// `name` as found beside the RIB (`directory`), then in `searchPath`;
/// empty when it is in neither (absolute names are taken as they are).
std::string findFile(const std::string& name, const std::string& directory, const std::vector<std::string>& searchPath) {
    namespace fs = std::filesystem;
    std::error_code ec;
    if (fs::path(name).is_absolute()) return fs::exists(name, ec) ? name : std::string();
    std::vector<std::string> dirs;
    if (!directory.empty()) dirs.push_back(directory);
    dirs.insert(dirs.end(), searchPath.begin(), searchPath.end());
    dirs.push_back(".");
    for (const std::string& d : dirs) {
        fs::path p = fs::path(d) / name;
        if (fs::is_regular_file(p, ec)) return p.string();
    }
    return {};
}

std::vector<std::string> searchPathOf(const scene::Options& options, const char* kind) {
    auto it = options.searchPaths.find(kind);
    return it == options.searchPaths.end() ? std::vector<std::string>() : splitSearchPath(it->second);
}

std::vector<std::string> splitBlanks(const std::string& s) {
    std::istringstream in(s);
    std::vector<std::string> words;
    for (std::string w; in >> w;) words.push_back(w);
    return words;
}

/// Reports what a generator's RIB made wrong as warnings, at their places
/// in its output: the generator is at fault, not the scene, and the rest
/// of the frame renders.
class WarningsOnly {
public:
    explicit WarningsOnly(Diagnostics& to) : m_to(to) {
        m_local.setSink([this](const Diagnostic& d) {
            m_to.report(d.severity == Severity::Info ? Severity::Info : Severity::Warning, d.loc, d.message);
        });
    }
    Diagnostics& diag() { return m_local; }

private:
    Diagnostics& m_to;
    Diagnostics m_local;
};

/// Collects a builder's primitives and nothing else: a procedural's RIB
/// cannot end worlds or make files (the builder reports those requests).
class NoSink : public scene::SceneSink {
public:
    void renderWorld(const scene::WorldRecord&) override {}
    void make(const scene::MakeRecord&) override {}
};

}  // namespace

/// A running RunProgram generator: its input (a socket, so writing to a
/// program that died fails instead of raising SIGPIPE) and its output.
struct ProceduralContext::Program {
    pid_t pid = -1;
    int in = -1, out = -1;
    std::mutex mutex;  // one request at a time, answered in order
    bool dead = false;
    std::string deadWhy;  // why later requests get nothing, when it did not fail

    /// How the program ended, once its output closed: "" while it runs on
    /// (after a second's wait), else "exited with status 3", "was killed by
    /// signal 11" or "exited" (status 0).
    std::string ending() {
        for (int i = 0; i < 100 && pid > 0; ++i) {
            int status = 0;
            if (waitpid(pid, &status, WNOHANG) == pid) {
                pid = -1;
                if (WIFSIGNALED(status)) return fmt::format("was killed by signal {}", WTERMSIG(status));
                const int code = WIFEXITED(status) ? WEXITSTATUS(status) : 0;
                return code == 0 ? "exited" : fmt::format("exited with status {}", code);
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(10));
        }
        return "";
    }

    void stop(bool force) {
        if (in >= 0) close(in);
        if (out >= 0) close(out);
        in = out = -1;
        if (pid <= 0) return;
        // Closing its input is the RI spec's way of ending a generator; one
        // that does not exit within a second is killed.
        if (force) ::kill(pid, SIGKILL);
        for (int i = 0; i < 100; ++i) {
            if (waitpid(pid, nullptr, WNOHANG) != 0) {
                pid = -1;
                return;
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(10));
        }
        ::kill(pid, SIGKILL);
        waitpid(pid, nullptr, 0);
        pid = -1;
    }
};

ProceduralContext::ProceduralContext(const scene::WorldRecord& world, const Mat4& cameraFromWorld,
                                     const Mat4& rasterFromCamera, bool perspective, Diagnostics& diag)
    : m_world(world), m_cameraFromWorld(cameraFromWorld), m_rasterFromCamera(rasterFromCamera),
      m_perspective(perspective), m_diag(diag), m_budget(kMaxExpansions) {
    if (auto it = world.options.user.find("limits:proceduraltime"); it != world.options.user.end()) {
        const double s = !it->second.floats.empty() ? double(it->second.floats[0])
                         : !it->second.ints.empty() ? double(it->second.ints[0]) : -1.0;
        if (s > 0)
            m_programSeconds = s;
        else
            diag.error(it->second.loc, "Option: limits \"proceduraltime\" expects a positive number of seconds");
    }
}

ProceduralContext::~ProceduralContext() {
    for (auto& [command, program] : m_programs) program->stop(false);
}

float ProceduralContext::detail(const Bound3& objectBound, const Mat4& worldFromObject) const {
    const Mat4 cameraFromObject = m_cameraFromWorld * worldFromObject;
    Bound3 raster;
    for (int c = 0; c < 8; ++c) {
        const Vec3 p{c & 1 ? objectBound.max.x : objectBound.min.x, c & 2 ? objectBound.max.y : objectBound.min.y,
                     c & 4 ? objectBound.max.z : objectBound.min.z};
        const Vec3 q = cameraFromObject.point(p);
        if (m_perspective && !(q.z > 1e-6f)) return kInfinity;
        raster.extend(m_rasterFromCamera.point(q));
    }
    return (raster.max.x - raster.min.x) * (raster.max.y - raster.min.y);
}

bool ProceduralContext::chargeExpansion(const FileLoc& loc) {
    if (m_budget.fetch_sub(1) > 0) return true;
    if (!m_budgetReported.exchange(true))
        m_diag.error(loc, "Procedural: more than {} expansions in one frame (procedurals that make more of "
                     "themselves?); this and the frame's further procedurals are skipped", kMaxExpansions);
    return false;
}

bool ProceduralContext::runProgram(const std::string& command, const std::string& directory,
                                   const std::string& request, const FileLoc& loc, std::string* rib) {
    Program* program = nullptr;
    {
        std::lock_guard<std::mutex> lock(m_programsMutex);
        std::unique_ptr<Program>& slot = m_programs[command];
        if (!slot) {
            slot = std::make_unique<Program>();
            std::vector<std::string> argv = splitBlanks(command);
            if (argv.empty()) {
                m_diag.error(loc, "Procedural \"RunProgram\": no program named (skipped)");
                slot->dead = true;
            } else {
                // Beside the RIB, on the "procedural" search path, else $PATH.
                const std::string found = argv[0].find('/') == std::string::npos
                                              ? findFile(argv[0], directory, searchPathOf(m_world.options, "procedural"))
                                              : findFile(argv[0], directory, {});
                if (!found.empty()) argv[0] = found;
                int toChild[2], fromChild[2];
                if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, toChild) != 0 ||
                    pipe2(fromChild, O_CLOEXEC) != 0) {
                    m_diag.error(loc, "Procedural \"RunProgram\": cannot make pipes for \"{}\" (skipped)", command);
                    slot->dead = true;
                } else {
                    posix_spawn_file_actions_t actions;
                    posix_spawn_file_actions_init(&actions);
                    posix_spawn_file_actions_adddup2(&actions, toChild[1], 0);
                    posix_spawn_file_actions_adddup2(&actions, fromChild[1], 1);
                    std::vector<char*> args;
                    for (std::string& a : argv) args.push_back(a.data());
                    args.push_back(nullptr);
                    pid_t pid = -1;
                    const int rc = posix_spawnp(&pid, args[0], &actions, nullptr, args.data(), environ);
                    posix_spawn_file_actions_destroy(&actions);
                    close(toChild[1]);
                    close(fromChild[1]);
                    slot->in = toChild[0];
                    slot->out = fromChild[0];
                    if (rc != 0) {
                        m_diag.error(loc, "Procedural \"RunProgram\": cannot run \"{}\": {} (skipped)", argv[0],
                                       std::strerror(rc));
                        slot->stop(false);
                        slot->dead = true;
                    } else {
                        slot->pid = pid;
                    }
                }
            }
        }
        program = slot.get();
    }

    std::lock_guard<std::mutex> lock(program->mutex);
    if (program->dead) {
        if (!program->deadWhy.empty())
            m_diag.error(loc, "Procedural \"RunProgram\": \"{}\" {}; this request's geometry is skipped", command,
                         program->deadWhy);
        return false;
    }
    auto fail = [&](const std::string& why) {
        m_diag.error(loc, "Procedural \"RunProgram\": \"{}\" {}; its geometry is skipped", command, why);
        program->stop(true);
        program->dead = true;
        return false;
    };
    for (size_t sent = 0; sent < request.size();) {
        const ssize_t n = send(program->in, request.data() + sent, request.size() - sent, MSG_NOSIGNAL);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) {
            const std::string ending = program->ending();
            return fail(ending.empty() ? std::string("stopped reading its input")
                                       : fmt::format("{} before reading its request", ending));
        }
        sent += size_t(n);
    }
    // Read up to the 0xFF that ends an answer, within the time budget.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(m_programSeconds);
    rib->clear();
    char buffer[65536];
    for (;;) {
        const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
        if (left.count() <= 0 && rib->empty())
            return fail(fmt::format("did not answer within {} s (Option \"limits\" \"proceduraltime\")", m_programSeconds));
        if (left.count() <= 0)
            return fail(fmt::format("wrote {} bytes of RIB but not, within {} s, the byte 0xFF that ends an answer (RI "
                                    "Spec 3.2: a generator writes it after each answer; Option \"limits\" "
                                    "\"proceduraltime\")", rib->size(), m_programSeconds));
        pollfd pfd{program->out, POLLIN, 0};
        const int ready = poll(&pfd, 1, int(std::min<int64_t>(left.count(), 1000)));
        if (ready < 0 && errno == EINTR) continue;
        if (ready <= 0) continue;
        const ssize_t n = read(program->out, buffer, sizeof buffer);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) {
            const std::string ending = program->ending();
            // A program that writes its RIB and exits, without the 0xFF:
            // its answer is plain (Pixie takes it; Aqsis draws nothing).
            if (ending == "exited" && !rib->empty()) {
                m_diag.warningOnce("runprogram-exit:" + command, loc,
                                   "Procedural \"RunProgram\": \"{}\" ended its answer by exiting, without the byte "
                                   "0xFF (RI Spec 3.2); its RIB is taken as the answer",
                                   command);
                program->stop(false);
                program->dead = true;
                program->deadWhy = "exited after answering an earlier request";
                return true;
            }
            return fail(ending.empty() || ending == "exited"
                            ? std::string("ended without finishing its answer (no byte 0xFF)")
                            : fmt::format("{} before finishing its answer", ending));
        }
        const char* end = static_cast<const char*>(memchr(buffer, '\xff', size_t(n)));
        rib->append(buffer, end ? size_t(end - buffer) : size_t(n));
        if (end) {
            if (end + 1 != buffer + n) return fail("wrote more than its answer after the byte 0xFF");
            return true;
        }
        if (rib->size() > kMaxAnswerBytes) return fail(fmt::format("answered more than {} bytes", kMaxAnswerBytes));
    }
}

struct Procedural::Expansion {
    std::once_flag once;
    std::vector<std::shared_ptr<const scene::PrimitiveRecord>> records;
    /// For each record that is itself a procedural, its own expansion.
    std::vector<std::shared_ptr<Expansion>> nested;
};

bool isProceduralRecord(const scene::PrimitiveRecord& record) { return record.type == "Procedural"; }

Procedural::Procedural(std::shared_ptr<const scene::PrimitiveRecord> record, std::shared_ptr<ProceduralContext> context,
                       std::shared_ptr<Expansion> expansion, int depth)
    : Primitive(std::move(record)), m_context(std::move(context)),
      m_expansion(expansion ? std::move(expansion) : std::make_shared<Expansion>()), m_depth(depth) {}

Procedural::~Procedural() = default;

Bound3 Procedural::bound() const {
    const std::vector<float>& b = record().floatArgs;
    if (b.size() != 6) return {};
    return {{b[0], b[2], b[4]}, {b[1], b[3], b[5]}};
}

Grid Procedural::dice(int, int) const { return {}; }

void Procedural::split(bool, std::vector<PrimitivePtr>& out) const {
    std::call_once(m_expansion->once, [this] { expand(); });
    // A generator's malformed primitives were reported when it was expanded.
    Diagnostics quiet;
    quiet.setSink([](const Diagnostic&) {});
    const Expansion& e = *m_expansion;
    for (size_t i = 0; i < e.records.size(); ++i) {
        if (e.nested[i]) {
            out.push_back(std::make_unique<Procedural>(e.records[i], m_context, e.nested[i], m_depth + 1));
            continue;
        }
        for (PrimitivePtr& p : makePrimitives(e.records[i], quiet)) out.push_back(std::move(p));
    }
}

bool Procedural::runDso(const std::string& name, const std::string& data, const std::string& directory,
                        ri::Target& target, Diagnostics& generatorDiag) const {
    ProceduralContext& ctx = *m_context;
    const FileLoc& loc = record().loc;
    // Beside the RIB, then on the "procedural" search path; "name" may omit ".so".
    const std::vector<std::string> path = searchPathOf(ctx.world().options, "procedural");
    std::string found = findFile(name, directory, path);
    if (found.empty()) found = findFile(name + ".so", directory, path);
    if (found.empty()) {
        ctx.diag().error(loc, "Procedural \"DynamicLoad\": cannot find \"{}\" (beside the RIB file or on the "
                           "\"procedural\" search path); its geometry is skipped", name);
        return false;
    }
    if (found.find('/') == std::string::npos) found = "./" + found;  // not a library name for dlopen's search
    void* dso = dlopen(found.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!dso) {
        ctx.diag().error(loc, "Procedural \"DynamicLoad\": cannot load \"{}\": {}; its geometry is skipped", found,
                           dlerror());
        return false;
    }
    using Convert = RtPointer (*)(RtString);
    using Subdivide = RtVoid (*)(RtPointer, RtFloat);
    using Free = RtVoid (*)(RtPointer);
    auto convert = reinterpret_cast<Convert>(dlsym(dso, "ConvertParameters"));
    auto subdivide = reinterpret_cast<Subdivide>(dlsym(dso, "Subdivide"));
    auto release = reinterpret_cast<Free>(dlsym(dso, "Free"));
    if (!convert || !subdivide || !release) {
        ctx.diag().error(loc, "Procedural \"DynamicLoad\": \"{}\" lacks {} (the RI spec's entry points are "
                           "ConvertParameters, Subdivide and Free, with C linkage); its geometry is skipped", found,
                           !convert ? "ConvertParameters" : !subdivide ? "Subdivide" : "Free");
        dlclose(dso);
        return false;
    }
    std::string block = data;  // the DSO may write into it
    RtPointer converted = convert(block.data());
    {
        RiCallbackScope scope(target, generatorDiag, loc);
        subdivide(converted, std::min(ctx.detail(bound(), record().worldFromObject), 3.0e38f));
    }
    release(converted);
    ++ctx.dsoCalls;
    dlclose(dso);
    return true;
}

void Procedural::expand() const {
    ProceduralContext& ctx = *m_context;
    const scene::PrimitiveRecord& rec = record();
    const FileLoc& loc = rec.loc;
    const std::string& kind = rec.stringArgs.at(0);
    const std::string first = rec.stringArgs.size() > 1 ? rec.stringArgs[1] : std::string();
    const std::string data = rec.stringArgs.size() > 2 ? rec.stringArgs[2] : std::string();
    if (m_depth >= ProceduralContext::kMaxDepth) {
        // Once a request: an archive naming itself twice reaches the limit
        // on thousands of branches.
        ctx.diag().errorOnce("procedural-depth:" + loc.str(), loc,
                             "Procedural \"{}\": nested more than {} deep (an archive or program that makes itself?); "
                             "not expanded", kind, ProceduralContext::kMaxDepth);
        ++ctx.failures;
        return;
    }
    if (!ctx.chargeExpansion(loc)) return;
    ++ctx.expanded;

    NoSink sink;
    WarningsOnly generatorDiag(ctx.diag());
    // Errors in an archive are the scene's, as ReadArchive's are; those in
    // a program's or DSO's output are the generator's: warnings.
    Diagnostics& diag = kind == "DelayedReadArchive" ? ctx.diag() : generatorDiag.diag();
    scene::Builder builder(sink, diag);
    builder.beginProcedural(ctx.world(), rec);
    ri::Parser parser(builder, diag);
    const std::string directory = directoryOf(loc);

    if (kind == "DelayedReadArchive") {
        const std::string path = findFile(first, directory, searchPathOf(ctx.world().options, "archive"));
        if (path.empty()) {
            ctx.diag().error(loc, "Procedural \"DelayedReadArchive\": cannot find \"{}\" (beside the RIB file or on the "
                             "\"archive\" search path); its geometry is skipped", first);
            ++ctx.failures;
            return;
        }
        ++ctx.archivesRead;
        parser.parseFile(path);
    } else if (kind == "RunProgram") {
        const float detail = ctx.detail(bound(), rec.worldFromObject);
        const std::string request = fmt::format("{:g} {}\n", std::min(detail, 3.0e38f), data);
        std::string rib;
        if (!ctx.runProgram(first, directory, request, loc, &rib)) {
            ++ctx.failures;
            return;
        }
        ++ctx.programRequests;
        parser.parseString(rib, fmt::format("RunProgram \"{}\" \"{}\"", first, data), directory);
    } else if (!runDso(first, data, directory, builder, generatorDiag.diag())) {
        ++ctx.failures;
        return;
    }

    Expansion& e = *m_expansion;
    for (scene::PrimitiveRecord& r : builder.takePrimitives()) {
        auto shared = std::make_shared<const scene::PrimitiveRecord>(std::move(r));
        if (isProceduralRecord(*shared)) {
            e.nested.push_back(std::make_shared<Expansion>());
        } else {
            // Malformed primitives are reported once, here.
            if (makePrimitives(shared, diag).empty()) continue;
            e.nested.push_back(nullptr);
        }
        e.records.push_back(std::move(shared));
    }
    ctx.primitivesMade += e.records.size();
}

}  // namespace umbra::geometry
