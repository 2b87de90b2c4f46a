#include "umbra/util/math.h"
#include "umbra/util/rng.h"

#include <gtest/gtest.h>

using namespace umbra;

TEST(Mat4, InverseOfComposedTransformIsIdentity) {
    Mat4 m = Mat4::translate({1, 2, 3}) * Mat4::rotate(30, {1, 1, 0}) * Mat4::scale({2, 3, 4});
    Mat4 p = m * m.inverse();
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) EXPECT_NEAR(p.m[i][j], i == j ? 1.0f : 0.0f, 1e-5f);
}

TEST(Mat4, SingularInverseReportsFailure) {
    bool ok = true;
    Mat4::scale({1, 0, 1}).inverse(&ok);
    EXPECT_FALSE(ok);
}

TEST(Mat4, RotateZByNinetyTakesXToY) {
    Vec3 p = Mat4::rotate(90, {0, 0, 1}).point({1, 0, 0});
    EXPECT_NEAR(p.x, 0, 1e-6);
    EXPECT_NEAR(p.y, 1, 1e-6);
}

TEST(Mat4, RibOrderPutsTranslationInLastRow) {
    float rib[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 5, 6, 7, 1};
    Vec3 p = Mat4::fromRib(rib).point({0, 0, 0});
    EXPECT_EQ(p, Vec3(5, 6, 7));
    float back[16];
    Mat4::fromRib(rib).toRib(back);
    for (int i = 0; i < 16; ++i) EXPECT_EQ(back[i], rib[i]);
}

TEST(Mat4, NormalsStayPerpendicularUnderNonUniformScale) {
    Mat4 m = Mat4::scale({4, 1, 1});
    Vec3 tangent = m.vector({1, -1, 0});
    Vec3 n = Mat4::normal(m.inverse(), {1, 1, 0});
    EXPECT_NEAR(dot(tangent, n), 0, 1e-6);
}

TEST(Bound3, TransformBoundContainsTransformedCorners) {
    Bound3 b({-1, -1, -1}, {1, 1, 1});
    Mat4 m = Mat4::rotate(45, {0, 0, 1});
    Bound3 t = transformBound(m, b);
    EXPECT_NEAR(t.max.x, std::sqrt(2.0f), 1e-5);
    EXPECT_NEAR(t.min.y, -std::sqrt(2.0f), 1e-5);
}

TEST(Rng, SameSeedSameStreamDifferentSeedDifferentStream) {
    Rng a(42), b(42), c(43);
    int differ = 0;
    for (int i = 0; i < 100; ++i) {
        uint32_t x = a.next();
        EXPECT_EQ(x, b.next());
        differ += x != c.next();
    }
    EXPECT_GT(differ, 95);
}

TEST(Rng, UniformMeanAndRange) {
    Rng r(7);
    double sum = 0;
    const int n = 100000;
    for (int i = 0; i < n; ++i) {
        float u = r.uniform();
        ASSERT_GE(u, 0.0f);
        ASSERT_LT(u, 1.0f);
        sum += u;
    }
    // The mean of n uniforms has standard deviation 1/sqrt(12 n) ~ 0.0009.
    EXPECT_NEAR(sum / n, 0.5, 0.005);
}

TEST(Math, SmallestSingularValueOfTheLinearPart) {
    // A rotation keeps lengths; a scale's least factor is its least
    // stretch, whichever side the rotation is on; a translation does not
    // count; a flat (singular) one gives 0.
    EXPECT_NEAR(smallestSingularValue3(Mat4::rotate(37, normalize(Vec3(1, 2, 3)))), 1.0f, 1e-5f);
    const Mat4 s = Mat4::scale({0.5f, 2.0f, 0.7f}), r = Mat4::rotate(30, normalize(Vec3(1, -1, 2)));
    EXPECT_NEAR(smallestSingularValue3(r * s), 0.5f, 1e-5f);
    EXPECT_NEAR(smallestSingularValue3(s * r), 0.5f, 1e-5f);
    EXPECT_NEAR(smallestSingularValue3(Mat4::translate({4, 5, 6}) * Mat4::scale({3, 3, 3})), 3.0f, 1e-5f);
    EXPECT_NEAR(smallestSingularValue3(Mat4::scale({1, 0, 1})), 0.0f, 1e-6f);
}
