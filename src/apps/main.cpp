// The `umbra` command: render RIB files, compile shaders, inspect depth maps.
//
//   umbra render SCENE.rib [MORE.rib ...] [--threads N] [--progress]
//                [--stats FILE.json|FILE.jsonl] [--bucket-size N] [--quiet] [--no-shadows]
//                [--frames SPEC] [--resume] [--no-map-reuse] [--map-cache DIR] [--no-film-stream]
//   umbra SCENE.rib ...                      (same as `umbra render`)
//   umbra slc [--listing] [-I DIR] FILE.sl ... (compile shaders, report errors)
//   umbra info [--json] MAP                  (depth-map storage figures)
//   umbra txmake [--wrap M] [--swrap M] [--twrap M] [--filter F] [--width W] IN.tif OUT.tx
//   umbra txmake --shadow IN.z OUT.shd
//   umbra txmake --envlatl IN.tif OUT.env
//   umbra txmake --envcube PX NX PY NY PZ NZ OUT.env [--fov DEGREES]
//   umbra report STATS.json[l] ... -o DIR     (report.md and report.html of --stats files)
//   umbra farm submit [--frames SPEC] [--chunk N] [--partition P] [--retries N] [--cpus N]
//                     [--dry-run] SCENE.rib -o FARMDIR   (render on Slurm, docs/farm.md)

#include "umbra/render/make_files.h"
#include "umbra/render/renderer.h"
#include "umbra/util/error.h"
#include "umbra/util/frame_set.h"

#include "apps/commands.h"
#include "apps/farm.h"
#include "apps/report.h"
#include "umbra/util/interrupt.h"

#include <CLI/CLI.hpp>

#include <cstring>
#include <exception>
#include <new>
#include <string>
#include <vector>

int main(int argc, char** argv) {
    // `umbra scene.rib` is `umbra render scene.rib`.
    std::vector<std::string> args(argv, argv + argc);
    static const char* kCommands[] = {"render", "slc", "info", "txmake", "report", "farm", "-h", "--help", "--version"};
    bool hasCommand = false;
    if (args.size() > 1)
        for (const char* c : kCommands) hasCommand |= args[1] == c;
    if (args.size() > 1 && !hasCommand) args.insert(args.begin() + 1, "render");

    CLI::App app{"umbra: a REYES renderer with depth-map shadows"};
    app.set_version_flag("--version", "umbra 0.1.0");
    app.require_subcommand(1);

    umbra::render::RenderSettings settings;
    std::vector<std::string> ribFiles;
    std::string statsPath;
    auto* render = app.add_subcommand("render", "Render RIB files (ASCII or gzip-compressed)");
    render->add_option("files", ribFiles, "RIB files, rendered in order")->required();
    render->add_option("--threads", settings.threads, "Worker threads (default: all cores)")->check(CLI::NonNegativeNumber);
    render->add_flag("--progress", settings.progress, "Show progress: buckets done, elapsed, ETA");
    render->add_option("--stats", statsPath, "Write statistics as JSON (FILE.json: one document at the end; FILE.jsonl: a line per frame as it ends)");
    render->add_option("--bucket-size", settings.bucketSize,
                       "Bucket size in pixels (default 32 for camera passes, 64 for depth passes)")
        ->check(CLI::Range(1, 4096));
    render->add_flag("--quiet", settings.quiet, "Print errors only");
    render->add_flag("--no-shadows", settings.noShadows, "Turn every depth pass and shadow() lookup off");
    bool noFilmStream = false;
    render->add_flag("--no-film-stream", noFilmStream,
                     "Keep the whole film and write the images at the end, instead of writing TIFF strips as "
                     "bucket rows finish (the same files; more memory)");
    bool noMapReuse = false;
    render->add_flag("--no-map-reuse", noMapReuse,
                     "Render every automatic depth map again, even when an earlier frame's has the same content");
    render->add_option("--map-cache", settings.mapCache,
                       "Directory of automatic depth maps shared between processes by their content digest "
                       "(read instead of rendered when present; rendered ones are added)");
    render->add_flag("--resume,--skip-existing", settings.resume,
                     "Skip frames whose every Display file is a complete image (truncated ones are rendered again)");
    std::string framesSpec;
    render->add_option("--frames", framesSpec,
                       "FrameBegin numbers to render: 1-100, 1-100x5 (every 5th), 3,7,12, 1-10,20,30-40x2; "
                       "a file name with #### or %04d is one RIB per frame")
        ->check(CLI::Validator(
            [](std::string& spec) {
                umbra::FrameSet frames;
                std::string error;
                return umbra::FrameSet::parse(spec, &frames, &error) ? std::string() : error;
            },
            "SPEC"));

    std::vector<std::string> slcFiles;
    std::vector<std::string> slcIncludes;
    bool listing = false;
    auto* slc = app.add_subcommand("slc", "Compile shading-language shaders and report errors");
    slc->add_option("files", slcFiles, "Shader sources (.sl)")->required();
    slc->add_flag("--listing", listing, "Print the bytecode listing");
    slc->add_option("-I,--include", slcIncludes, "Directory searched for #include files (after the including file's own)");

    std::string mapPath;
    bool json = false;
    auto* info = app.add_subcommand("info", "Describe a depth map: resolution, bounds, tiles, storage");
    info->add_option("map", mapPath, "Depth map (.shd / .exr)")->required();
    info->add_flag("--json", json, "Print JSON");

    umbra::apps::TxmakeArgs tx;
    auto* txmake = app.add_subcommand(
        "txmake", "Make a texture, environment or shadow map, as MakeTexture, MakeLatLongEnvironment, "
                  "MakeCubeFaceEnvironment and MakeShadow do");
    txmake->add_option("files", tx.files, "Input file(s), then the output file")->required();
    txmake->add_flag("--shadow", tx.shadow, "Make a shadow map from a zfile or OpenEXR depth image (MakeShadow)");
    txmake->add_flag("--envlatl", tx.envLatl, "Make a lat-long environment map (MakeLatLongEnvironment)");
    txmake->add_flag("--envcube", tx.envCube,
                     "Make an environment map from six faces px nx py ny pz nz (MakeCubeFaceEnvironment)");
    const std::vector<std::string> wraps{"periodic", "black", "clamp"};
    txmake->add_option("--wrap", tx.wrap, "Wrap mode in s and t (default black)")->check(CLI::IsMember(wraps));
    txmake->add_option("--swrap", tx.swrap, "Wrap mode in s")->check(CLI::IsMember(wraps));
    txmake->add_option("--twrap", tx.twrap, "Wrap mode in t")->check(CLI::IsMember(wraps));
    txmake->add_option("--filter", tx.filter,
                       std::string("Filter for the MIP levels (default gaussian): ") + umbra::render::makeFilterNames());
    txmake->add_option("--width", tx.width, "Filter width in s and t (default 2)")->check(CLI::PositiveNumber);
    txmake->add_option("--swidth", tx.swidth, "Filter width in s")->check(CLI::PositiveNumber);
    txmake->add_option("--twidth", tx.twidth, "Filter width in t")->check(CLI::PositiveNumber);
    txmake->add_option("--fov", tx.fov, "Cube faces' full field of view, degrees (default 90)");

    std::vector<std::string> reportFiles;
    std::string reportDir;
    auto* report = app.add_subcommand("report", "Write a profiling report (report.md, report.html) of --stats files");
    report->add_option("files", reportFiles, "Statistics: .json documents or JSON lines, in frame order")->required();
    report->add_option("-o,--output", reportDir, "Directory the report is written to")->required();

    umbra::apps::FarmArgs farmArgs;
    auto* farm = app.add_subcommand("farm", "Render frames on a Slurm cluster (docs/farm.md)");
    farm->require_subcommand(1);
    auto* farmSubmit = farm->add_subcommand(
        "submit", "Submit a maps job (the first frame), a job array of frame chunks sharing its depth maps, "
                  "and a report job");
    farmSubmit->add_option("scene", farmArgs.scene, "The RIB file (or shot.####.rib with --frames)")->required();
    farmSubmit->add_option("-o,--output", farmArgs.farmDir,
                           "Farm directory (on a filesystem every node sees): scripts, logs, maps, stats, report")
        ->required();
    farmSubmit->add_option("--frames", farmArgs.frames, "FrameBegin numbers to render (default: all the scene's)");
    farmSubmit->add_option("--chunk", farmArgs.chunk, "Frames per array task (default 1)")->check(CLI::PositiveNumber);
    farmSubmit->add_option("--partition", farmArgs.partition, "Slurm partition (default: the cluster's)");
    farmSubmit->add_option("--retries", farmArgs.retries, "Attempts after a task's first failure (default 2)")
        ->check(CLI::NonNegativeNumber);
    farmSubmit->add_option("--cpus", farmArgs.cpus, "CPUs per job, umbra's --threads (default 1)")
        ->check(CLI::PositiveNumber);
    farmSubmit->add_flag("--dry-run", farmArgs.dryRun, "Print the job scripts and sbatch commands; submit nothing");

    std::vector<char*> cargs;
    for (auto& a : args) cargs.push_back(a.data());
    try {
        app.parse(int(cargs.size()), cargs.data());
    } catch (const CLI::ParseError& e) {
        return app.exit(e);
    }

    if (*render && !framesSpec.empty()) {
        umbra::FrameSet frames;
        std::string error;
        umbra::FrameSet::parse(framesSpec, &frames, &error);  // checked above
        settings.frames = frames;
    }
    settings.reuseMaps = !noMapReuse;
    settings.filmStream = !noFilmStream;

    umbra::Diagnostics diag;
    diag.setQuiet(settings.quiet);
    // A frame larger than the machine's memory (Format, PixelSamples,
    // shadowmapsize) ends here: the outputs are written to temporary names
    // and renamed, so none is left half-written.
    try {
        if (*render) {
            umbra::installInterruptHandlers();
            int status = umbra::render::renderFiles(ribFiles, settings, statsPath, diag);
            // Stopped by a signal: the shell's convention, 128 + its number.
            return umbra::interrupted() ? 128 + umbra::interruptSignal() : status;
        }
        if (*slc) return umbra::apps::compileShaders(slcFiles, slcIncludes, listing, diag);
        if (*info) return umbra::apps::describeMap(mapPath, json, diag);
        if (*txmake) return umbra::apps::txmake(tx, diag);
        if (*report) return umbra::apps::writeReport(reportFiles, reportDir, diag);
        if (*farmSubmit) return umbra::apps::farmSubmit(farmArgs, diag);
    } catch (const umbra::OutOfMemory& e) {
        // What was being allocated, for which request: the render stops
        // here, its outputs unwritten.
        diag.error(e.loc(), "{}; nothing was written for this frame", e.what());
    } catch (const std::bad_alloc&) {
        fmt::print(stderr, "umbra: out of memory: the frame needs more memory than this machine has "
                           "(check Format, PixelSamples and shadowmapsize)\n");
    } catch (const std::exception& e) {
        // A fault of umbra's own: reported, not an abort (and never a
        // hang: the bucket scheduler publishes a node however its work ends).
        fmt::print(stderr, "umbra: internal error: {}; the render stopped (please report it with the input)\n",
                   e.what());
    }
    return 1;
}
