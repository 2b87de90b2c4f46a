// libFuzzer entry point: any bytes, parsed as RIB (plain or gzip) into the
// scene builder. Must never crash, hang or leak, whatever the input.

#include "umbra/ri/parser.h"
#include "umbra/scene/builder.h"

#include <cstddef>
#include <cstdint>
#include <string_view>

namespace {

struct Discard : umbra::scene::SceneSink {
    void renderWorld(const umbra::scene::WorldRecord&) override {}
    void make(const umbra::scene::MakeRecord&) override {}
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    Discard sink;
    umbra::Diagnostics diag;
    diag.setSink([](const umbra::Diagnostic&) {});
    umbra::scene::Builder builder(sink, diag);
    umbra::ri::Parser parser(builder, diag);
    // No directory: ReadArchive looks only beside "fuzz.rib" in the current
    // directory, where the fuzzer's inputs are not RIB files.
    parser.parseString(std::string_view(reinterpret_cast<const char*>(data), size), "fuzz.rib",
                       "/nonexistent-umbra-fuzz-dir");
    return 0;
}
