#pragma once
// The `umbra farm submit` command: a frame range rendered on Slurm as a
// maps job, a job array of frame chunks sharing its depth maps through a
// map cache, and a report job (docs/farm.md).

#include "umbra/util/error.h"

#include <string>

namespace umbra::apps {

/// What `umbra farm submit` was asked to do.
struct FarmArgs {
    std::string scene;        // the RIB file (or a #### pattern, with frames)
    std::string farmDir;      // scripts, maps, stats, logs, report, jobs.json
    std::string frames;       // a FrameSet spec; empty: every FrameBegin of the scene
    int chunk = 1;            // frames per array task
    std::string partition;    // empty: the cluster's default
    int retries = 2;          // attempts after a task's first failure
    int cpus = 1;             // CPUs per job, and umbra's --threads
    bool dryRun = false;      // print the scripts and sbatch commands only
};

/// Writes the jobs' scripts into args.farmDir and submits them with
/// `sbatch --parsable` (or prints them with dryRun); 0 on success.
int farmSubmit(const FarmArgs& args, Diagnostics& diag);

}  // namespace umbra::apps
