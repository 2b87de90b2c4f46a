#include "umbra/util/file.h"

#include <cerrno>
#include <cstdio>
#include <filesystem>
#include <sys/stat.h>
#include <unistd.h>

namespace umbra {

namespace fs = std::filesystem;

bool resolveOutputPath(const std::string& path, std::string* resolved, std::string* why) {
    // Follow symbolic links to the file they name (dangling ones too), as
    // every other program writing a file does; at most 40, as the kernel.
    fs::path p(path);
    for (int hops = 0;; ++hops) {
        struct stat st;
        if (::lstat(p.c_str(), &st) != 0) break;  // absent: written new
        if (S_ISLNK(st.st_mode)) {
            if (hops == 40) {
                *why = "too many levels of symbolic links";
                return false;
            }
            std::error_code ec;
            fs::path to = fs::read_symlink(p, ec);
            if (ec) {
                *why = ec.message();
                return false;
            }
            p = to.is_absolute() ? to : p.parent_path() / to;
            continue;
        }
        if (S_ISREG(st.st_mode)) break;
        *why = S_ISDIR(st.st_mode)    ? "it is a directory"
               : S_ISCHR(st.st_mode)  ? "it is a character device, not a file (umbra never replaces one)"
               : S_ISBLK(st.st_mode)  ? "it is a block device, not a file (umbra never replaces one)"
               : S_ISFIFO(st.st_mode) ? "it is a FIFO, not a file (umbra writes files whole, then renames them)"
                                      : "it is not a regular file";
        return false;
    }
    *resolved = p.string();
    return true;
}

bool moveIntoPlace(const std::string& tmp, const std::string& target) {
    // Never replace anything but a file (or a link, which the writers have
    // already followed): a special file named as an output is refused.
    struct stat st;
    if (::lstat(target.c_str(), &st) == 0 && !S_ISREG(st.st_mode) && !S_ISLNK(st.st_mode)) {
        errno = S_ISDIR(st.st_mode) ? EISDIR : EEXIST;
        return false;
    }
    ::unlink(target.c_str());  // absent is fine
    return std::rename(tmp.c_str(), target.c_str()) == 0;
}

}  // namespace umbra
