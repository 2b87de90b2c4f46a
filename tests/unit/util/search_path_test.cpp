// RenderMan search paths: '&' and '@', the defaults from the environment.

#include "umbra/util/search_path.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

using namespace umbra;

namespace {

/// Sets an environment variable for one scope, restoring it afterwards.
class ScopedEnv {
public:
    ScopedEnv(const char* name, const char* value) : m_name(name) {
        if (const char* old = std::getenv(name)) m_old = old, m_had = true;
        if (value) setenv(name, value, 1);
        else unsetenv(name);
    }
    ~ScopedEnv() {
        if (m_had) setenv(m_name, m_old.c_str(), 1);
        else unsetenv(m_name);
    }

private:
    const char* m_name;
    std::string m_old;
    bool m_had = false;
};

}  // namespace

TEST(SearchPath, AmpersandIsThePreviousValueAndAtTheDefault) {
    EXPECT_EQ(expandSearchPath("/a:&", "/p:/q", "/d"), "/a:/p:/q");
    EXPECT_EQ(expandSearchPath("@:/a", "/p", "/d1:/d2"), "/d1:/d2:/a");
    EXPECT_EQ(expandSearchPath("&:@:&", "/p", "/d"), "/p:/d");  // a directory is searched once, where it first comes
    EXPECT_EQ(expandSearchPath(".:@", "", ".:/d"), ".:/d");
    EXPECT_EQ(expandSearchPath("/only", "/p", "/d"), "/only");
}

// PRMan and Pixie expand environment variables in search paths
// ("${RMANTREE}/lib/shaders"; RenderMan for Maya writes "${RMSPROJ}").
TEST(SearchPath, EnvironmentVariablesAreExpanded) {
    ScopedEnv proj("UMBRA_TEST_PROJ", "/proj"), unset("UMBRA_TEST_UNSET", nullptr);
    EXPECT_EQ(expandSearchPath("${UMBRA_TEST_PROJ}/shaders:$UMBRA_TEST_PROJ/lib:&", "/p", "/d"),
              "/proj/shaders:/proj/lib:/p");
    EXPECT_EQ(expandSearchPath("${UMBRA_TEST_UNSET}/x:$:${:a$b", "", ""), "${UMBRA_TEST_UNSET}/x:$:${:a$b");
}

TEST(SearchPath, EmptyEntriesAndEmptyExpansionsVanish) {
    EXPECT_EQ(expandSearchPath("/a::/b:", "", ""), "/a:/b");
    EXPECT_EQ(expandSearchPath("&:/a:@", "", ""), "/a");
    EXPECT_EQ(expandSearchPath("", "/p", "/d"), "");
    EXPECT_EQ(splitSearchPath(":/x::y:"), (std::vector<std::string>{"/x", "y"}));
    EXPECT_EQ(joinSearchPath({"/x", "", "y"}), "/x:y");
}

TEST(SearchPath, AMarkerInsideAnEntryIsAMarkerToo) {
    // BMRT-era scenes write ".:../&" meaning ".:..:&"; Pixie and Aqsis both
    // find the standard shaders through it. The text beside the marker
    // stays an entry of its own.
    EXPECT_EQ(expandSearchPath(".:../&", "/p:/q", "/d"), ".:../:/p:/q");
    EXPECT_EQ(expandSearchPath("&dir:a@b", "/p", "/d"), "/p:dir:a:/d:b");
    EXPECT_EQ(expandSearchPath("x&&", "/p", "/d"), "x:/p");
}

TEST(SearchPath, BuiltinShadersOfABuildTreeAreTheSourceShaders) {
    // Test binaries do not live in an installed tree (no ../share/umbra).
    EXPECT_EQ(builtinShaderDir(), std::string(UMBRA_SOURCE_DIR) + "/shaders_dsl");
    EXPECT_FALSE(executableDirectory().empty());
}

TEST(SearchPath, ShaderPathFromTheEnvironment) {
    const std::string builtin = builtinShaderDir();
    {
        ScopedEnv env("UMBRA_SHADER_PATH", nullptr);
        EXPECT_EQ(defaultShaderPath(), builtin);
    }
    {
        ScopedEnv env("UMBRA_SHADER_PATH", "/studio/shaders:&");
        EXPECT_EQ(defaultShaderPath(), "/studio/shaders:" + builtin);
    }
    {
        ScopedEnv env("UMBRA_SHADER_PATH", "@:/late");
        EXPECT_EQ(defaultShaderPath(), builtin + ":/late");
    }
    {
        ScopedEnv env("UMBRA_SHADER_PATH", "/replaces/the/default");
        EXPECT_EQ(defaultShaderPath(), "/replaces/the/default");
    }
    {
        ScopedEnv env("UMBRA_SHADER_PATH", "");
        EXPECT_EQ(defaultShaderPath(), builtin);
    }
}

TEST(SearchPath, TexturePathFromTheEnvironment) {
    {
        ScopedEnv env("UMBRA_TEXTURE_PATH", nullptr);
        EXPECT_EQ(defaultTexturePath(), "");
    }
    {
        ScopedEnv env("UMBRA_TEXTURE_PATH", "/maps:&:/more:@");
        EXPECT_EQ(defaultTexturePath(), "/maps:/more");
    }
}
