#include "umbra/geometry/grid.h"

#include <gtest/gtest.h>

using namespace umbra;
using namespace umbra::geometry;

TEST(Grid, TransformMovesPointsVectorsAndNormalsEachTheirWay) {
    Grid g;
    g.nu = g.nv = 1;
    g.P = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
    g.N.assign(4, Vec3(0, 0, 1));
    auto add = [&](const char* name, ri::ParamType t, std::vector<float> d) {
        GridVar v;
        v.name = name;
        v.type = t;
        v.components = 3;
        v.perVertex = false;
        v.data = std::move(d);
        g.vars.push_back(v);
    };
    add("pt", ri::ParamType::Point, {1, 1, 1});
    add("vec", ri::ParamType::Vector, {1, 1, 1});
    add("nrm", ri::ParamType::Normal, {1, 1, 0});
    add("col", ri::ParamType::Color, {1, 1, 1});
    // Shear-free non-uniform scale, then a translation.
    const Mat4 M = Mat4::translate({5, 0, 0}) * Mat4::scale({2, 1, 4});
    g.transform(M, M.inverse());
    EXPECT_EQ(g.P[3], Vec3(7, 1, 0));
    EXPECT_EQ(normalize(g.N[0]), Vec3(0, 0, 1));
    EXPECT_EQ(g.find("pt")->data, (std::vector<float>{7, 1, 4}));
    EXPECT_EQ(g.find("vec")->data, (std::vector<float>{2, 1, 4}));
    // A normal stays perpendicular to transformed tangents: (1,1,0) is normal to (1,-1,0).
    const GridVar* n = g.find("nrm");
    const Vec3 tn(n->data[0], n->data[1], n->data[2]);
    EXPECT_FLOAT_EQ(dot(tn, M.vector(Vec3(1, -1, 0))), 0);
    EXPECT_EQ(g.find("col")->data, (std::vector<float>{1, 1, 1}));
    EXPECT_EQ(g.find("missing"), nullptr);
}
