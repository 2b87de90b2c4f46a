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
    // Every leaf state, reached by setting the leaves one at a time: the
    // nodes' answers are the boolean expressions, and setLeaf reports
    // exactly the changes of its root's answer.
    auto expectTrees = [&](const CsgRayState& st, bool a, bool b, bool c, bool d, bool e, int bits) {
        EXPECT_EQ(bool(st.in[0]), (a || b) && !c) << bits;
        EXPECT_EQ(bool(st.in[1]), a || b) << bits;
        EXPECT_EQ(bool(st.in[5]), d && e) << bits;
    };
    for (int bits = 0; bits < 32; ++bits) {
        const bool want[5] = {bool(bits & 1), bool(bits & 2), bool(bits & 4), bool(bits & 8), bool(bits & 16)};
        const int leaf[5] = {2, 3, 4, 6, 7};
        CsgRayState st;
        st.reset(size_t(f.size()));
        bool set[5] = {false, false, false, false, false};
        for (int k = 0; k < 5; ++k) {
            const bool rootBefore = st.in[size_t(f.root(leaf[k]))];
            set[k] = want[k];
            const bool changed = f.setLeaf(leaf[k], want[k], st);
            EXPECT_EQ(changed, rootBefore != bool(st.in[size_t(f.root(leaf[k]))])) << bits;
            expectTrees(st, set[0], set[1], set[2], set[3], set[4], bits);
        }
        // Back out in another order: all outside again.
        for (int k = 4; k >= 0; --k) {
            set[k] = false;
            f.setLeaf(leaf[k], false, st);
            expectTrees(st, set[0], set[1], set[2], set[3], set[4], bits);
        }
        for (int k = 0; k < 5; ++k) f.clearPath(leaf[k], st);
        for (int n = 0; n < f.size(); ++n) EXPECT_EQ(st.count[size_t(n)], 0);
    }
}

TEST(CsgForest, NestedPrimitiveIsPartOfItsParentAndEmptyOperationsAreEmpty) {
    using Op = CsgForest::Op;
    CsgForest f;
    f.add(Op::Primitive, -1);     // 0
    f.add(Op::Primitive, 0);      // 1: inside 0
    f.add(Op::Intersection, -1);  // 2: no children
    f.add(Op::Difference, -1);    // 3: no children
    CsgRayState st;
    st.reset(4);
    EXPECT_TRUE(f.setLeaf(1, true, st));  // inside the nested block: inside the solid
    EXPECT_TRUE(st.in[0]);
    EXPECT_TRUE(f.setLeaf(1, false, st));
    EXPECT_FALSE(st.in[0]);
    EXPECT_FALSE(st.in[2]);
    EXPECT_FALSE(st.in[3]);
}

}  // namespace umbra::hider
