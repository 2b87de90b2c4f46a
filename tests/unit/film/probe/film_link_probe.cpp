// A program linking only umbra::film: writes one small image per format into
// the directory named by argv[1]. Its CTest entry also checks (with ldd) that
// the film module pulls no OpenImageIO into a process: OIIO's library
// closure costs ~0.12 s of dynamic loading at every start.

#include "umbra/film/film.h"

#include <cstdio>
#include <string>

int main(int argc, char** argv) {
    using namespace umbra;
    if (argc != 2) {
        std::fprintf(stderr, "usage: film_link_probe DIR\n");
        return 2;
    }
    const float crop[4] = {0, 1, 0, 1};
    film::Film f(4, 4, crop, film::PixelFilter(film::FilterKind::Box, 1, 1));
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 4; ++x) {
            float* p = f.rgba(x, y);
            p[0] = p[1] = p[2] = 0.25f * float(x);
            p[3] = 1;
            f.z(x, y) = 1.0f + float(y);
        }
    Diagnostics diag;
    bool ok = true;
    const char* names[] = {"probe.exr", "probe.tif", "probe.png"};
    for (const char* name : names) {
        scene::DisplayRecord d;
        d.name = std::string(argv[1]) + "/" + name;
        d.driver = "file";
        d.mode = "rgba";
        ok = f.writeDisplay(d, scene::Options{}, {}, diag) && ok;
    }
    return ok ? 0 : 1;
}
