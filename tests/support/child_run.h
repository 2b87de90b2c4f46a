#pragma once
// Running a program (usually the `umbra` command) as a child process in a
// test's scratch directory, and the small file helpers such tests share.
// Needs UMBRA_SOURCE_DIR (the standard shaders are found from it).

#include "support/render_harness.h"

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace umbra::test {

struct ChildRun {
    int status = -1;       // exit status; -1: killed or not started
    std::string messages;  // stdout and stderr
};

inline std::string readFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

inline void writeFile(const std::string& path, const std::string& text) {
    std::ofstream out(path, std::ios::binary);
    out << text;
}

/// Starts `program args...` (args[0] is the program's name for itself) in
/// `dir`, with the standard shaders on UMBRA_SHADER_PATH and `env` added
/// (NAME=VALUE), its output going to dir/`logName`; its pid, or -1.
inline pid_t startIn(const ScratchDir& dir, const std::string& program, std::vector<std::string> args,
                     const std::vector<std::string>& env = {}, const std::string& logName = "run.log") {
    const std::string log = dir.file(logName);
    const pid_t pid = fork();
    if (pid == 0) {
        if (chdir(dir.file("").c_str()) != 0) _exit(126);
        const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fd >= 0) {
            dup2(fd, 1);
            dup2(fd, 2);
        }
        setenv("UMBRA_SHADER_PATH", UMBRA_SOURCE_DIR "/shaders_dsl", 1);
        for (const std::string& e : env) putenv(strdup(e.c_str()));
        std::vector<char*> argv;
        for (auto& a : args) argv.push_back(a.data());
        argv.push_back(nullptr);
        execvp(program.c_str(), argv.data());
        _exit(127);
    }
    return pid;
}

/// Waits for a child startIn() started; its status and dir/`logName`.
inline ChildRun finish(const ScratchDir& dir, pid_t pid, const std::string& logName = "run.log") {
    ChildRun run;
    int status = 0;
    if (pid < 0 || waitpid(pid, &status, 0) != pid) return run;
    if (WIFEXITED(status)) run.status = WEXITSTATUS(status);
    run.messages = readFile(dir.file(logName));
    return run;
}

/// Runs `program args...` in `dir` as startIn() does and waits for it.
inline ChildRun runIn(const ScratchDir& dir, const std::string& program, std::vector<std::string> args,
                      const std::vector<std::string>& env = {}) {
    return finish(dir, startIn(dir, program, std::move(args), env));
}

}  // namespace umbra::test
