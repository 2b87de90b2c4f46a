// `--frames` specs and frame-number patterns of file names.

#include "umbra/util/frame_set.h"

#include <gtest/gtest.h>

using umbra::FrameSet;

namespace {

std::vector<int> numbersOf(const std::string& spec) {
    FrameSet set;
    std::string error;
    EXPECT_TRUE(FrameSet::parse(spec, &set, &error)) << spec << ": " << error;
    return set.numbers();
}

std::string errorOf(const std::string& spec) {
    FrameSet set;
    std::string error;
    EXPECT_FALSE(FrameSet::parse(spec, &set, &error)) << spec;
    return error;
}

}  // namespace

TEST(FrameSet, Forms) {
    EXPECT_EQ(numbersOf("7"), (std::vector<int>{7}));
    EXPECT_EQ(numbersOf("1-5"), (std::vector<int>{1, 2, 3, 4, 5}));
    EXPECT_EQ(numbersOf("1-20x5"), (std::vector<int>{1, 6, 11, 16}));
    EXPECT_EQ(numbersOf("3,7,12"), (std::vector<int>{3, 7, 12}));
    EXPECT_EQ(numbersOf("1-3,20,30-36x2"), (std::vector<int>{1, 2, 3, 20, 30, 32, 34, 36}));
    EXPECT_EQ(numbersOf("0"), (std::vector<int>{0}));
    // Overlaps and any order: each number once, in order.
    EXPECT_EQ(numbersOf("5,1-3,2"), (std::vector<int>{1, 2, 3, 5}));
    EXPECT_EQ(numbersOf("4-4x3"), (std::vector<int>{4}));
}

TEST(FrameSet, Contains) {
    FrameSet set;
    std::string error;
    ASSERT_TRUE(FrameSet::parse("1-100x5,200", &set, &error));
    EXPECT_TRUE(set.contains(1));
    EXPECT_TRUE(set.contains(96));
    EXPECT_FALSE(set.contains(100));
    EXPECT_FALSE(set.contains(2));
    EXPECT_FALSE(set.contains(0));
    EXPECT_TRUE(set.contains(200));
    EXPECT_FALSE(set.contains(-1));
}

TEST(FrameSet, ErrorsSayWhatWasExpected) {
    EXPECT_NE(errorOf("").find("empty"), std::string::npos);
    EXPECT_NE(errorOf("a").find("expected a frame number"), std::string::npos);
    EXPECT_NE(errorOf("5-2").find("runs backwards"), std::string::npos);
    EXPECT_NE(errorOf("1-").find("last frame"), std::string::npos);
    EXPECT_NE(errorOf("1-10x0").find("step of 1 or more"), std::string::npos);
    EXPECT_NE(errorOf("1-10x").find("step of 1 or more"), std::string::npos);
    EXPECT_NE(errorOf("3x2").find("needs a range"), std::string::npos);
    EXPECT_NE(errorOf("1,,2").find("expected a frame number"), std::string::npos);
    EXPECT_NE(errorOf("1;2").find("unexpected ';'"), std::string::npos);
    EXPECT_NE(errorOf("-3").find("expected a frame number"), std::string::npos);
    EXPECT_NE(errorOf("99999999999").find("expected a frame number"), std::string::npos);
    // Every error shows the accepted forms.
    EXPECT_NE(errorOf("x").find("1-100x5"), std::string::npos);
}

TEST(FramePattern, Expands) {
    using umbra::expandFramePattern;
    using umbra::hasFramePattern;
    EXPECT_TRUE(hasFramePattern("shot.####.rib"));
    EXPECT_TRUE(hasFramePattern("shot.%04d.rib"));
    EXPECT_TRUE(hasFramePattern("shot.%d.rib"));
    EXPECT_FALSE(hasFramePattern("shot.rib"));
    EXPECT_FALSE(hasFramePattern("100%%.tif"));
    EXPECT_FALSE(hasFramePattern("50%.tif"));
    EXPECT_EQ(expandFramePattern("out.####.tif", 12), "out.0012.tif");
    EXPECT_EQ(expandFramePattern("out.#.tif", 12), "out.12.tif");
    EXPECT_EQ(expandFramePattern("out.%04d.tif", 12), "out.0012.tif");
    EXPECT_EQ(expandFramePattern("out.%d.tif", 7), "out.7.tif");
    EXPECT_EQ(expandFramePattern("out.%3d.tif", 7), "out.  7.tif");
    EXPECT_EQ(expandFramePattern("a##b.%02d", 3), "a03b.03");
    EXPECT_EQ(expandFramePattern("out.##.tif", 12345), "out.12345.tif");  // never cut
}
