#include "umbra/util/error.h"

#include <gtest/gtest.h>

using namespace umbra;

TEST(Diagnostics, MessageNamesFileLineColumn) {
    Diagnostics d;
    d.setRecord(true);
    d.setSink([](const Diagnostic&) {});
    d.error(FileLoc::inFile("a.rib", 3, 7), "Sphere: expected {} numbers", 4);
    auto r = d.recorded();
    ASSERT_EQ(r.size(), 1u);
    EXPECT_EQ(r[0].str(), "a.rib:3:7: error: Sphere: expected 4 numbers");
    EXPECT_EQ(d.errorCount(), 1);
    EXPECT_FALSE(d.aborted());
}

TEST(Diagnostics, WarningOnceReportsOnce) {
    Diagnostics d;
    d.setRecord(true);
    d.setSink([](const Diagnostic&) {});
    for (int i = 0; i < 3; ++i) d.warningOnce("k", FileLoc(), "unsupported");
    EXPECT_EQ(d.recorded().size(), 1u);
}

TEST(Diagnostics, AbortPolicyStopsAtFirstError) {
    Diagnostics d;
    d.setSink([](const Diagnostic&) {});
    d.setPolicy(Diagnostics::Policy::Abort);
    d.warning(FileLoc(), "w");
    EXPECT_FALSE(d.aborted());
    d.error(FileLoc(), "e");
    EXPECT_TRUE(d.aborted());
}
