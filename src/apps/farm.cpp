#include "apps/farm.h"

#include "umbra/ri/parser.h"
#include "umbra/scene/builder.h"
#include "umbra/util/frame_set.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

namespace umbra::apps {

namespace fs = std::filesystem;

namespace {

const FileLoc kWhere = FileLoc::inFile("umbra farm submit");

/// `text` as one word of a POSIX shell.
std::string shellWord(const std::string& text) {
    std::string out = "'";
    for (char c : text) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return out + "'";
}

/// Records the FrameBegin numbers of a RIB; renders nothing.
struct FrameScan : scene::SceneSink {
    std::vector<int> frames;
    std::set<int> seen;
    int unnumberedWorlds = 0;
    void renderWorld(const scene::WorldRecord& world) override {
        if (world.frameNumber < 0) ++unnumberedWorlds;
    }
    void make(const scene::MakeRecord&) override {}
    void frameBegin(int n, const FileLoc&) override {
        if (seen.insert(n).second) frames.push_back(n);
    }
};

/// The full path of `program` on $PATH, or empty.
std::string onPath(const std::string& program) {
    const char* path = std::getenv("PATH");
    std::stringstream dirs(path ? path : "");
    for (std::string dir; std::getline(dirs, dir, ':');) {
        const fs::path candidate = fs::path(dir.empty() ? "." : dir) / program;
        if (::access(candidate.c_str(), X_OK) == 0 && !fs::is_directory(candidate)) return candidate.string();
    }
    return {};
}

/// Runs `args` (args[0] found on $PATH); its exit status (-1: did not run
/// or was killed), standard output and error.
int capture(const std::vector<std::string>& args, std::string* out, std::string* err) {
    int outPipe[2], errPipe[2];
    if (::pipe(outPipe) != 0) return -1;
    if (::pipe(errPipe) != 0) {
        ::close(outPipe[0]);
        ::close(outPipe[1]);
        return -1;
    }
    const pid_t pid = ::fork();
    if (pid == 0) {
        ::dup2(outPipe[1], 1);
        ::dup2(errPipe[1], 2);
        ::close(outPipe[0]);
        ::close(errPipe[0]);
        std::vector<char*> argv;
        for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
        argv.push_back(nullptr);
        ::execvp(argv[0], argv.data());
        std::fprintf(stderr, "cannot run %s: %s\n", argv[0], std::strerror(errno));
        ::_exit(127);
    }
    ::close(outPipe[1]);
    ::close(errPipe[1]);
    auto drain = [](int fd, std::string* to) {
        char buffer[4096];
        for (ssize_t n; (n = ::read(fd, buffer, sizeof buffer)) != 0;) {
            if (n < 0 && errno == EINTR) continue;
            if (n < 0) break;
            to->append(buffer, size_t(n));
        }
        ::close(fd);
    };
    // sbatch writes a line or two: the pipes never fill while the other is read.
    drain(outPipe[0], out);
    drain(errPipe[0], err);
    int status = 0;
    if (pid < 0) return -1;
    while (::waitpid(pid, &status, 0) < 0)
        if (errno != EINTR) return -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string trimmed(std::string s) {
    while (!s.empty() && std::isspace((unsigned char)s.back())) s.pop_back();
    size_t a = 0;
    while (a < s.size() && std::isspace((unsigned char)s[a])) ++a;
    return s.substr(a);
}

/// What every job's script starts with.
std::string header(const FarmArgs& a, const std::string& name, const std::string& log, const std::string& cwd) {
    std::string h = "#!/bin/bash\n";
    h += fmt::format("#SBATCH --job-name=umbra-{}\n", name);
    h += fmt::format("#SBATCH --output={}\n", log);
    h += "#SBATCH --open-mode=append\n";
    h += "#SBATCH --nodes=1\n#SBATCH --ntasks=1\n";
    h += fmt::format("#SBATCH --cpus-per-task={}\n", a.cpus);
    h += fmt::format("#SBATCH --chdir={}\n", cwd);
    if (!a.partition.empty()) h += fmt::format("#SBATCH --partition={}\n", a.partition);
    return h;
}

/// The part of a render job that renders `$frames` with up to 1 + retries
/// attempts, each starting its statistics afresh (a requeued or retried
/// task leaves one line per frame).
std::string renderLoop(const FarmArgs& a, const std::string& umbra, const std::string& scene,
                       const std::string& farm) {
    return fmt::format(R"SH(attempt=0
while :; do
  : > "$stats"
  rm -f "$failed"
  {umbra} render --threads {cpus} --frames "$frames" --map-cache {maps} --stats "$stats" {scene} && exit 0
  status=$?
  attempt=$((attempt + 1))
  if [ "$attempt" -gt {retries} ]; then
    echo "umbra farm: frames $frames failed $attempt times (last exit status $status)" >&2
    echo "$frames" > "$failed"
    exit "$status"
  fi
  echo "umbra farm: frames $frames failed (exit status $status); attempt $((attempt + 1)) of {attempts}" >&2
done
)SH",
                       fmt::arg("umbra", shellWord(umbra)), fmt::arg("cpus", a.cpus),
                       fmt::arg("maps", shellWord(farm + "/maps")), fmt::arg("scene", shellWord(scene)),
                       fmt::arg("retries", a.retries), fmt::arg("attempts", a.retries + 1));
}

}  // namespace

int farmSubmit(const FarmArgs& a, Diagnostics& diag) {
    if (a.chunk < 1 || a.retries < 0 || a.cpus < 1) {
        diag.error(kWhere, "--chunk and --cpus must be at least 1, --retries at least 0");
        return 1;
    }
    // The frames: --frames, kept to those the scene has; else every
    // FrameBegin of the scene. A #### pattern names one RIB per frame.
    std::vector<int> frames;
    FrameSet selected;
    if (!a.frames.empty()) {
        std::string error;
        if (!FrameSet::parse(a.frames, &selected, &error)) {
            diag.error(kWhere, "--frames \"{}\": {}", a.frames, error);
            return 1;
        }
    }
    if (hasFramePattern(a.scene) && !fs::exists(a.scene)) {
        if (a.frames.empty()) {
            diag.error(FileLoc::inFile(a.scene),
                       "\"{}\" names one RIB file per frame: give the frames with --frames (e.g. --frames 1-100)",
                       a.scene);
            return 1;
        }
        frames = selected.numbers();
    } else {
        if (!fs::exists(a.scene)) {
            diag.error(FileLoc::inFile(a.scene), "cannot open the scene \"{}\"", a.scene);
            return 1;
        }
        FrameScan scan;
        {
            scene::Builder builder(scan, diag);
            if (!ri::parseFile(a.scene, builder, diag)) return 1;
        }
        if (scan.frames.empty()) {
            diag.error(FileLoc::inFile(a.scene),
                       "the scene has no FrameBegin: a farm renders numbered frames (wrap each world in "
                       "FrameBegin n / FrameEnd)");
            return 1;
        }
        for (int n : scan.frames)
            if (a.frames.empty() || selected.contains(n)) frames.push_back(n);
        if (frames.empty()) {
            diag.error(kWhere, "--frames \"{}\": none of the scene's frames ({}) is selected", a.frames,
                       fmt::join(scan.frames, ","));
            return 1;
        }
    }

    std::error_code ec;
    const std::string cwd = fs::current_path(ec).string();
    const std::string farm = fs::weakly_canonical(fs::absolute(a.farmDir), ec).string();
    const std::string scene = fs::absolute(a.scene).lexically_normal().string();
    std::string umbra = fs::read_symlink("/proc/self/exe", ec).string();
    if (ec || umbra.empty()) {
        diag.error(kWhere, "cannot find the umbra program's own path (/proc/self/exe): {}", ec.message());
        return 1;
    }
    std::string sbatch;
    if (!a.dryRun) {
        sbatch = onPath("sbatch");
        if (sbatch.empty()) {
            diag.error(kWhere, "sbatch is not on PATH: is Slurm installed on this machine? (--dry-run prints the "
                               "scripts and commands without it)");
            return 1;
        }
    }

    // The first frame is the maps job's; the others go to the array, in
    // chunks of consecutive frames.
    const int first = frames.front();
    std::vector<std::string> chunks;
    for (size_t i = 1; i < frames.size(); i += size_t(a.chunk)) {
        std::vector<int> c(frames.begin() + long(i), frames.begin() + long(std::min(frames.size(), i + size_t(a.chunk))));
        chunks.push_back(fmt::format("{}", fmt::join(c, ",")));
    }
    const std::string stats = farm + "/stats", logs = farm + "/logs", scripts = farm + "/scripts";

    std::string maps = header(a, "maps", logs + "/maps.log", cwd);
    maps += fmt::format(
        "# umbra farm: renders frame {0}, the first; its automatic depth maps enter the\n"
        "# map cache {1}/maps, where the frame jobs read them.\nset -u\n"
        "frames={0}\nstats={2}\nfailed={3}\n",
        first, farm, shellWord(stats + "/maps.jsonl"), shellWord(stats + "/maps.failed"));
    maps += renderLoop(a, umbra, scene, farm);

    std::string array;
    if (!chunks.empty()) {
        std::vector<std::string> q;
        for (const auto& c : chunks) q.push_back(shellWord(c));
        array = header(a, "frames", logs + "/task.%a.log", cwd);
        array += fmt::format(
            "# umbra farm: array task N renders chunk N of the frames, reading the maps\n"
            "# job's depth maps from the map cache {0}/maps (rendering any it lacks).\nset -u\n"
            ": \"${{SLURM_ARRAY_TASK_ID:?this script runs as a task of a Slurm job array}}\"\n"
            "chunks=({1})\nframes=${{chunks[$SLURM_ARRAY_TASK_ID]}}\n"
            "stats={2}/task.$SLURM_ARRAY_TASK_ID.jsonl\nfailed={2}/task.$SLURM_ARRAY_TASK_ID.failed\n",
            farm, fmt::join(q, " "), shellWord(stats));
        array += renderLoop(a, umbra, scene, farm);
    }

    std::vector<std::string> names{"maps"}, described{shellWord(std::to_string(first))};
    for (size_t i = 0; i < chunks.size(); ++i) {
        names.push_back(fmt::format("task.{}", i));
        described.push_back(shellWord(chunks[i]));
    }
    std::string report = header(a, "report", logs + "/report.log", cwd);
    report += fmt::format(
        R"SH(# umbra farm: the report of every job's statistics, naming the jobs that
# left none or failed after their retries.
set -u
umbra={umbra}
stats={stats}
out={out}
names=({names})
frames=({frames})
files=()
missing=()
failed=()
for i in "${{!names[@]}}"; do
  name=${{names[$i]}}
  if [ -s "$stats/$name.jsonl" ]; then files+=("$stats/$name.jsonl"); else missing+=("$name (frames ${{frames[$i]}})"); fi
  if [ -e "$stats/$name.failed" ]; then failed+=("$name (frames ${{frames[$i]}})"); fi
done
mkdir -p "$out"
status=0
if [ ${{#files[@]}} -gt 0 ]; then
  "$umbra" report "${{files[@]}}" -o "$out" || status=$?
else
  echo "umbra farm: no job left statistics" >&2
  status=1
fi
# Each list appears whole (renamed into place); failed.txt last.
printf '%s\n' "${{missing[@]}}" | sed '/^$/d' > "$out/missing.txt.tmp" && mv "$out/missing.txt.tmp" "$out/missing.txt"
printf '%s\n' "${{failed[@]}}" | sed '/^$/d' > "$out/failed.txt.tmp" && mv "$out/failed.txt.tmp" "$out/failed.txt"
if [ ${{#missing[@]}} -gt 0 ]; then
  echo "umbra farm: no statistics from: ${{missing[*]}}" >&2
  status=1
fi
if [ ${{#failed[@]}} -gt 0 ]; then
  echo "umbra farm: failed after their retries: ${{failed[*]}}" >&2
  status=1
fi
exit $status
)SH",
        fmt::arg("umbra", shellWord(umbra)), fmt::arg("stats", shellWord(stats)), fmt::arg("out", shellWord(farm + "/report")),
        fmt::arg("names", fmt::join(names, " ")), fmt::arg("frames", fmt::join(described, " ")));

    const std::string mapsScript = scripts + "/maps.sh", arrayScript = scripts + "/frames.sh",
                      reportScript = scripts + "/report.sh";
    const std::vector<std::string> mapsCmd{"sbatch", "--parsable", mapsScript};
    auto arrayCmd = [&](const std::string& mapsJob) {
        return std::vector<std::string>{"sbatch",
                                        "--parsable",
                                        "--requeue",
                                        "--dependency=afterany:" + mapsJob,
                                        fmt::format("--array=0-{}", chunks.size() - 1),
                                        arrayScript};
    };
    auto reportCmd = [&](const std::string& after) {
        return std::vector<std::string>{"sbatch", "--parsable", "--dependency=afterany:" + after, reportScript};
    };
    auto shellLine = [](const std::vector<std::string>& cmd) {
        std::vector<std::string> words;
        for (const auto& w : cmd)
            words.push_back(w.rfind("--dependency=", 0) == 0 || w.find_first_of(" '\"$\\") == std::string::npos
                                ? w
                                : shellWord(w));
        return fmt::format("{}", fmt::join(words, " "));
    };

    if (a.dryRun) {
        fmt::print("# umbra farm submit --dry-run: {} frames ({} first, then {} array task{} of up to {})\n",
                   frames.size(), first, chunks.size(), chunks.size() == 1 ? "" : "s", a.chunk);
        fmt::print("# ---- {}\n{}\n", mapsScript, maps);
        if (!chunks.empty()) fmt::print("# ---- {}\n{}\n", arrayScript, array);
        fmt::print("# ---- {}\n{}\n", reportScript, report);
        fmt::print("# ---- commands\nmkdir -p {}\n", shellLine({stats, logs, scripts, farm + "/maps"}));
        fmt::print("MAPS_JOB=$({})\n", shellLine(mapsCmd));
        if (!chunks.empty()) fmt::print("FRAMES_JOB=$({})\n", shellLine(arrayCmd("$MAPS_JOB")));
        fmt::print("REPORT_JOB=$({})\n", shellLine(reportCmd(chunks.empty() ? "$MAPS_JOB" : "$FRAMES_JOB")));
        return 0;
    }

    // The farm directory: scripts, logs, the map cache, statistics (those
    // of an earlier submission removed, so the report is this one's).
    for (const std::string& dir : {farm, stats, logs, scripts, farm + "/maps"}) {
        fs::create_directories(dir, ec);
        if (ec || ::access(dir.c_str(), W_OK | X_OK) != 0) {
            diag.error(FileLoc::inFile(a.farmDir), "cannot use \"{}\" as the farm directory: {}", dir,
                       ec ? ec.message() : std::string(std::strerror(errno)));
            return 1;
        }
    }
    for (const auto& entry : fs::directory_iterator(stats, ec)) fs::remove(entry.path(), ec);
    auto writeScript = [&](const std::string& path, const std::string& text) {
        std::ofstream out(path, std::ios::binary | std::ios::trunc);
        out << text;
        out.close();
        if (!out) {
            diag.error(FileLoc::inFile(path), "cannot write the job script: {}", std::strerror(errno));
            return false;
        }
        fs::permissions(path, fs::perms::owner_exec | fs::perms::group_exec | fs::perms::others_exec,
                        fs::perm_options::add, ec);
        return true;
    };
    if (!writeScript(mapsScript, maps) || (!chunks.empty() && !writeScript(arrayScript, array)) ||
        !writeScript(reportScript, report))
        return 1;

    // Submits one job; its id, or empty (with an error naming the command).
    auto submit = [&](std::vector<std::string> cmd) -> std::string {
        cmd[0] = sbatch;
        std::string out, err;
        const int status = capture(cmd, &out, &err);
        const std::string id = trimmed(out.substr(0, out.find(';')));  // "id" or "id;cluster"
        if (status != 0 || id.empty() || id.find_first_not_of("0123456789") != std::string::npos) {
            diag.error(kWhere, "{} failed (exit status {}): {}", shellLine(cmd), status,
                       trimmed(err.empty() ? out : err));
            return {};
        }
        if (!trimmed(err).empty()) fmt::print(stderr, "{}\n", trimmed(err));
        return id;
    };
    nlohmann::json jobs = {{"scene", scene},          {"frames", frames}, {"first_frame", first},
                           {"chunks", chunks},        {"umbra", umbra},   {"farm_dir", farm}};
    const std::string mapsJob = submit(mapsCmd);
    if (mapsJob.empty()) return 1;
    jobs["maps"] = mapsJob;
    std::string last = mapsJob;
    if (!chunks.empty()) {
        const std::string arrayJob = submit(arrayCmd(mapsJob));
        if (arrayJob.empty()) return 1;
        jobs["frames_array"] = arrayJob;
        last = arrayJob;
    }
    const std::string reportJob = submit(reportCmd(last));
    if (reportJob.empty()) return 1;
    jobs["report"] = reportJob;
    {
        const std::string path = farm + "/jobs.json", tmp = path + ".tmp";
        std::ofstream out(tmp);
        out << jobs.dump(2) << "\n";
        out.close();
        if (!out || std::rename(tmp.c_str(), path.c_str()) != 0) {
            diag.error(FileLoc::inFile(path), "cannot write the job ids: {}", std::strerror(errno));
            return 1;
        }
    }
    fmt::print("umbra farm: {} frames submitted: maps job {}, {}report job {}; jobs in {}/jobs.json\n",
               frames.size(), mapsJob,
               chunks.empty() ? std::string()
                              : fmt::format("array job {} ({} tasks), ", jobs["frames_array"].get<std::string>(),
                                            chunks.size()),
               reportJob, farm);
    return 0;
}

}  // namespace umbra::apps
