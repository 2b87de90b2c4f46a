#include "umbra/util/file.h"

#include <cstdio>
#include <unistd.h>

namespace umbra {

bool moveIntoPlace(const std::string& tmp, const std::string& target) {
    ::unlink(target.c_str());  // absent is fine; a directory makes rename fail below
    return std::rename(tmp.c_str(), target.c_str()) == 0;
}

}  // namespace umbra
