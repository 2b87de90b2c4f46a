// hider::CsgForest: the set expression of nested SolidBegin trees.

#include "umbra/hider/csg.h"

#include <gtest/gtest.h>

namespace umbra::hider {

TEST(CsgForest, EvaluatesNestedOperationsForEveryLeafState) {
    // 0: difference( 1: union(2: A, 3: B), 4: C ), and a second tree 5: intersection(6: D, 7: E).
    using Op = CsgForest::Op;
    CsgForest f;
    EXPECT_EQ(f.add(Op::Difference, -1), 0);
    EXPECT_EQ(f.add(Op::Union, 0), 1);
    EXPECT_EQ(f.add(Op::Primitive, 1), 2);
    EXPECT_EQ(f.add(Op::Primitive, 1), 3);
    EXPECT_EQ(f.add(Op::Primitive, 0), 4);
    EXPECT_EQ(f.add(Op::Intersection, -1), 5);
    EXPECT_EQ(f.add(Op::Primitive, 5), 6);
    EXPECT_EQ(f.add(Op::Primitive, 5), 7);
    for (int node : {0, 1, 2, 3, 4}) EXPECT_EQ(f.root(node), 0);
    for (int node : {5, 6, 7}) EXPECT_EQ(f.root(node), 5);
    for (int bits = 0; bits < 32; ++bits) {
        const bool a = bits & 1, b = bits & 2, c = bits & 4, d = bits & 8, e = bits & 16;
        const int32_t in[8] = {0, 0, a, b, c, 0, d, e};
        EXPECT_EQ(f.inside(0, in), (a || b) && !c) << bits;
        EXPECT_EQ(f.inside(1, in), a || b) << bits;
        EXPECT_EQ(f.inside(5, in), d && e) << bits;
    }
}

TEST(CsgForest, NestedPrimitiveIsPartOfItsParentAndEmptyOperationsAreEmpty) {
    using Op = CsgForest::Op;
    CsgForest f;
    f.add(Op::Primitive, -1);     // 0
    f.add(Op::Primitive, 0);      // 1: inside 0
    f.add(Op::Intersection, -1);  // 2: no children
    f.add(Op::Difference, -1);    // 3: no children
    const int32_t inner[4] = {0, 1, 0, 0};
    EXPECT_TRUE(f.inside(0, inner));
    const int32_t none[4] = {0, 0, 0, 0};
    EXPECT_FALSE(f.inside(0, none));
    EXPECT_FALSE(f.inside(2, none));
    EXPECT_FALSE(f.inside(3, none));
}

}  // namespace umbra::hider
