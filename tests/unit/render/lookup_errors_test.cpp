// Shadow maps, textures and environment maps that cannot be read follow one
// rule (issue 20): one error per file, located at the RIB primitive whose
// shader asked and naming the shader's call; the frame is still rendered,
// with the map's lookups lit and the texture's reading 0.

#include "support/render_harness.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

namespace umbra {
namespace {

TEST(LookupErrors, UnreadableMapsAndTexturesAreOneLocatedErrorEach) {
    test::ScratchDir dir("lookup-errors");
    const std::string image = dir.file("out.tif");
    const std::string missingMap = dir.file("missing.shd"), missingTexture = dir.file("missing.tx");
    const std::string rib = fmt::format(R"(Format 32 24 1
Display "{}" "file" "rgba"
Projection "perspective" "fov" 40
WorldBegin
LightSource "shadowspot" 1 "from" [0 0 -5] "to" [0 0 0] "shadowname" ["{}"]
Translate 0 0 5
Surface "paintedplastic" "texturename" ["{}"]
  Sphere 1 -1 1 360
WorldEnd
)",
                                        image, missingMap, missingTexture);
    Diagnostics diag;
    diag.setQuiet(true);
    diag.setRecord(true);
    const test::Image img = test::renderImage(rib, image, diag, 2);
    std::vector<Diagnostic> errors;
    for (const Diagnostic& d : diag.recorded())
        if (d.severity == Severity::Error) errors.push_back(d);
    ASSERT_EQ(errors.size(), 2u) << (errors.empty() ? "" : errors[0].str());
    int map = 0, texture = 0;
    for (const Diagnostic& d : errors) {
        // At the Sphere (line 8, column 3), whichever grid asked first.
        EXPECT_EQ(d.loc.str(), "test.rib:8:3") << d.str();
        if (d.message.find(missingMap) != std::string::npos) {
            ++map;
            EXPECT_NE(d.message.find("(shadow() at "), std::string::npos) << d.str();
            EXPECT_NE(d.message.find("shadowspot.sl:"), std::string::npos) << d.str();
            EXPECT_NE(d.message.find("its lookups are lit"), std::string::npos) << d.str();
        } else if (d.message.find(missingTexture) != std::string::npos) {
            ++texture;
            EXPECT_NE(d.message.find("texture(): cannot read"), std::string::npos) << d.str();
            EXPECT_NE(d.message.find("paintedplastic.sl:"), std::string::npos) << d.str();
        }
    }
    EXPECT_EQ(map, 1);
    EXPECT_EQ(texture, 1);
    // Still rendered: the sphere covers the middle of the frame.
    ASSERT_EQ(img.width, 32);
    EXPECT_GT(img.at(16, 12, 3), 0.99f);
}

}  // namespace
}  // namespace umbra
