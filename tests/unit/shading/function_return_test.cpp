// User functions: their inlining, `return` (early, varying, of calls, in
// loops and lighting loops), output parameters and globals read inside
// them. Each shader is checked against the same sum written here in C++,
// on grids where the points differ, so a point that runs under the wrong
// run mask shows.

#include "shading_test_util.h"

#include <cmath>

using namespace umbra;
using namespace umbra::shading;
using namespace umbra::shading::testing;

namespace {

/// Six points at z = 1 around the origin (where the test lights stand),
/// with normals that lean differently at each point; some face away from
/// the origin.
ShadingGrid leaningGrid() {
    ShadingGrid g = makeGrid(6, 1, [](float u, float) { return Vec3(2 * u - 1, 0.5f * u, 1); });
    for (size_t i = 0; i < 6; ++i) {
        const float u = g.u[i];
        g.N[i] = g.Ng[i] = normalize(Vec3(u - 0.5f, 0.2f, i % 3 == 2 ? 1.0f : -1.0f));
    }
    return g;
}

/// The diffuse sum of a point light of colour `cl` at the origin, over the
/// hemisphere about faceforward(normalize(N), I), as an illuminance loop
/// about that normal with angle PI/2 computes it.
Vec3 pointLightDiffuse(const ShadingGrid& g, size_t i, const Vec3& cl) {
    Vec3 Nn = normalize(g.N[i]);
    if (dot(g.I[i], Nn) > 0) Nn = -Nn;  // faceforward(Nn, I)
    const Vec3 L = -g.P[i];              // from the surface to the light
    const float c = dot(normalize(L), Nn);
    if (c < 0) return Vec3(0.f);
    return cl * c;
}

const char* kPointLight = "light pt(color c = color(1, 0.5, 0.25)) { illuminate(point(0, 0, 0)) Cl = c; }";

}  // namespace

// The report: returning a call to a function that holds an illuminance loop.
TEST(FunctionReturn, ReturnOfACallHoldingIlluminance) {
    Harness h;
    h.svc.spaces["world"] = Mat4::identity();
    auto light = h.instance(kPointLight);
    const std::string lib =
        "color lit(normal Nf) { color c = 0; illuminance(P, Nf, PI/2) { c += Cl * (normalize(L).Nf); } return c; }\n";
    for (const char* direct : {"color direct(normal Nf) { return lit(Nf); }",
                               "color direct(normal Nf) { color r = lit(Nf); return r; }"}) {
        ShadingGrid g = leaningGrid();
        h.surface(lib + direct + "\nsurface s() { normal Nf = faceforward(normalize(N), I); Ci = direct(Nf); Oi = 1; }", g,
                  {light.get()});
        for (size_t i = 0; i < 6; ++i) expectNear(g.Ci[i], pointLightDiffuse(g, i, Vec3(1, 0.5f, 0.25f)), 1e-5f);
    }
}
