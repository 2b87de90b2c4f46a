# Third-party packages, all from Debian's archive (see README "Setup").
find_package(Threads REQUIRED)
find_package(ZLIB REQUIRED)
find_package(fmt REQUIRED)
find_package(nlohmann_json REQUIRED)
find_package(CLI11 REQUIRED)
find_package(TBB REQUIRED)
find_package(Imath REQUIRED)
find_package(OpenEXR REQUIRED)
find_package(OpenImageIO CONFIG REQUIRED)
# libdeflate has no CMake package in Debian 12, only a pkg-config file.
find_package(PkgConfig REQUIRED)
pkg_check_modules(LIBDEFLATE REQUIRED IMPORTED_TARGET libdeflate)
# match() in shaders: a linear-time regular expression engine.
pkg_check_modules(RE2 REQUIRED IMPORTED_TARGET re2)

# Debian's OpenImageIO target names /usr/include/opencv4, which is not
# installed; the generate step fails unless that path is removed.
foreach(prop INTERFACE_INCLUDE_DIRECTORIES INTERFACE_SYSTEM_INCLUDE_DIRECTORIES)
  get_target_property(dirs OpenImageIO::OpenImageIO ${prop})
  if(dirs)
    list(FILTER dirs EXCLUDE REGEX "opencv4")
    set_target_properties(OpenImageIO::OpenImageIO PROPERTIES ${prop} "${dirs}")
  endif()
endforeach()

# OpenSubdiv: Debian's libosd-dev installs a CMake config naming static
# libraries it does not ship, and no pkg-config file; find the header and
# the CPU library directly and wrap them in an imported target.
find_path(OPENSUBDIV_INCLUDE_DIR opensubdiv/far/topologyRefiner.h REQUIRED)
find_library(OPENSUBDIV_CPU_LIBRARY osdCPU REQUIRED)
if(NOT TARGET OpenSubdiv::osdCPU)
  add_library(OpenSubdiv::osdCPU UNKNOWN IMPORTED)
  set_target_properties(OpenSubdiv::osdCPU PROPERTIES
    IMPORTED_LOCATION "${OPENSUBDIV_CPU_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${OPENSUBDIV_INCLUDE_DIR}")
endif()

if(UMBRA_TESTS)
  find_package(GTest REQUIRED)
endif()
if(UMBRA_BENCHMARKS)
  find_package(benchmark REQUIRED)
endif()

# umbra_module(NAME DEPS...): a static library umbra_NAME from src/NAME/*.cpp
# with public headers in include/umbra/NAME/.
function(umbra_module name)
  file(GLOB sources CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*.cpp)
  if(sources)
    add_library(umbra_${name} STATIC ${sources})
    target_include_directories(umbra_${name} PUBLIC ${PROJECT_SOURCE_DIR}/include)
    target_link_libraries(umbra_${name} PUBLIC ${ARGN})
  else()  # a module not yet written: headers only
    add_library(umbra_${name} INTERFACE)
    target_include_directories(umbra_${name} INTERFACE ${PROJECT_SOURCE_DIR}/include)
    target_link_libraries(umbra_${name} INTERFACE ${ARGN})
  endif()
  add_library(umbra::${name} ALIAS umbra_${name})
endfunction()

# umbra_test_program(TARGET): what every test program shares. Test code is
# compiled with -Og: its time goes into the renderer's libraries, which keep
# the build type's optimisation, while compiling the tests' own bodies at
# -O3 took two thirds of a clean build (a test file: 18 s of CPU at -O3,
# 10.5 s at -Og, most of it instantiating gtest, fmt and json templates).
function(umbra_test_program target)
  target_compile_options(${target} PRIVATE -Og)
endfunction()

# umbra_test(MODULE): one gtest binary per module from tests/unit/MODULE/*.cpp.
function(umbra_test module)
  file(GLOB sources CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*.cpp)
  if(NOT sources)
    return()
  endif()
  add_executable(test_${module} ${sources})
  umbra_test_program(test_${module})
  target_link_libraries(test_${module} PRIVATE umbra::${module} ${ARGN} GTest::gtest_main)
  # Shared test helpers: #include "support/..."
  target_include_directories(test_${module} PRIVATE ${PROJECT_SOURCE_DIR}/tests)
  target_compile_definitions(test_${module} PRIVATE
    UMBRA_SOURCE_DIR="${PROJECT_SOURCE_DIR}" UMBRA_BINARY_DIR="${PROJECT_BINARY_DIR}")
  include(GoogleTest)
  gtest_discover_tests(test_${module} DISCOVERY_TIMEOUT 60
    WORKING_DIRECTORY ${CMAKE_CURRENT_BINARY_DIR} PROPERTIES LABELS unit)
endfunction()
