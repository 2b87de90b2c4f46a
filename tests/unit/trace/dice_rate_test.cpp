#include "umbra/trace/occlusion_scene.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <vector>

using namespace umbra;
using namespace umbra::trace;

namespace {

std::vector<Vec3> lattice(int m, const std::function<Vec3(double, double)>& f) {
    std::vector<Vec3> P;
    for (int j = 0; j <= m; ++j)
        for (int i = 0; i <= m; ++i) P.push_back(f(double(i) / m, double(j) / m));
    return P;
}

// Sagitta of a chord spanning `angle` radians of a circle of radius R.
double sagitta(double R, double angle) { return R * (1 - std::cos(angle / 2)); }

}  // namespace

TEST(DiceRate, PlaneNeedsOneMicropolygon) {
    const int m = 16;
    auto P = lattice(m, [](double u, double v) { return Vec3(float(3 * u - 1), 2.0f, float(5 * v + 2)); });
    const DiceRate r = chooseDiceRate(P.data(), m, 1e-4f);
    EXPECT_EQ(r.nu, 1);
    EXPECT_EQ(r.nv, 1);
    EXPECT_EQ(r.chordError, 0.0f);
}

TEST(DiceRate, CylinderArcMeetsToleranceAndIsNotWasteful) {
    // A cylinder of radius R swept by thetaMax around z: curved along u only.
    const double R = 2.5, thetaMax = 1.5 * M_PI, L = 4;
    const float tol = 1e-3f;
    const int m = 16;
    auto P = lattice(m, [&](double u, double v) {
        return Vec3(float(R * std::cos(thetaMax * u)), float(R * std::sin(thetaMax * u)), float(L * v));
    });
    const DiceRate r = chooseDiceRate(P.data(), m, tol);
    EXPECT_EQ(r.nv, 1);
    // The u budget is a third of the tolerance; the lattice's second
    // difference underestimates the curvature by about (thetaMax/m)^2/12.
    const double exact = sagitta(R, thetaMax / r.nu);
    EXPECT_LE(exact, tol / 3.0 * 1.02);
    EXPECT_GT(sagitta(R, thetaMax / (r.nu - 1)), tol / 3.0 * 0.98);
    EXPECT_NEAR(r.chordError, exact, 0.02 * exact);
    // Halving the rate would break the tolerance itself.
    EXPECT_GT(sagitta(R, thetaMax / (r.nu / 2)), tol);
}

TEST(DiceRate, TwistedQuadIsDicedUntilCellCentresAreWithinBudget) {
    // The hyperbolic paraboloid z = c u v: a cell of a x b has its bilinear
    // centre c a b / 4 away from the midpoint of the diagonal both triangles share.
    const double c = 1.0;
    const float tol = 1e-3f;
    const int m = 8;
    auto P = lattice(m, [&](double u, double v) { return Vec3(float(u), float(v), float(c * u * v)); });
    const DiceRate r = chooseDiceRate(P.data(), m, tol);
    const int expected = int(std::ceil(std::sqrt(3 * c / (4 * tol))));
    EXPECT_EQ(r.nu, expected);
    EXPECT_EQ(r.nv, expected);
    // Measured along the normal, which tilts slightly away from z over the patch.
    EXPECT_NEAR(r.chordError, c / (4.0 * r.nu * r.nv), 0.01 * c / (4.0 * r.nu * r.nv));
    EXPECT_LE(c / (4.0 * r.nu * r.nv), tol / 3.0);
}

TEST(DiceRate, SphereRowsAreCurvedBothWays) {
    // Unit sphere parametrised like RenderMan's: theta = 2 pi u, phi from -pi/2 to pi/2.
    const int m = 16;
    const float tol = 2e-4f;
    auto P = lattice(m, [](double u, double v) {
        const double th = 2 * M_PI * u, ph = M_PI * (v - 0.5);
        return Vec3(float(std::cos(ph) * std::cos(th)), float(std::cos(ph) * std::sin(th)), float(std::sin(ph)));
    });
    const DiceRate r = chooseDiceRate(P.data(), m, tol);
    // Equator chords and meridian chords each within a third of the budget.
    EXPECT_LE(sagitta(1, 2 * M_PI / r.nu), tol / 3.0 * 1.02);
    EXPECT_LE(sagitta(1, M_PI / r.nv), tol / 3.0 * 1.02);
    // Along u the angle step is twice that along v, so about twice the cells.
    EXPECT_NEAR(double(r.nu) / r.nv, 2.0, 0.05);
    EXPECT_LE(r.chordError, tol * 1.02f);
}
