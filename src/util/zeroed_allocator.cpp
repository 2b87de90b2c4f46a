#include "umbra/util/zeroed_allocator.h"

#include <cstdint>

#include <sys/mman.h>

namespace umbra {

namespace {

constexpr size_t kHugePage = size_t(2) << 20;

size_t roundUp(size_t bytes, size_t to) { return (bytes + to - 1) / to * to; }

}  // namespace

void* allocateZeroed(size_t bytes) {
    if (bytes < kLargeZeroedBytes) return std::calloc(bytes ? bytes : 1, 1);
    // Whole huge pages, aligned: map one more and trim the ends, so every
    // 2 MiB of the block can be one huge page.
    const size_t size = roundUp(bytes, kHugePage);
    if (size < bytes || size > size_t(-1) - kHugePage) return nullptr;
    void* raw = ::mmap(nullptr, size + kHugePage, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (raw == MAP_FAILED) return nullptr;
    const uintptr_t begin = reinterpret_cast<uintptr_t>(raw);
    const uintptr_t aligned = roundUp(begin, kHugePage);
    if (aligned > begin) ::munmap(raw, aligned - begin);
    const uintptr_t tail = aligned + size, end = begin + size + kHugePage;
    if (end > tail) ::munmap(reinterpret_cast<void*>(tail), end - tail);
    void* p = reinterpret_cast<void*>(aligned);
    ::madvise(p, size, MADV_HUGEPAGE);  // a hint: without huge pages, ordinary ones
    return p;
}

void freeZeroed(void* p, size_t bytes) noexcept {
    if (!p) return;
    if (bytes < kLargeZeroedBytes) {
        std::free(p);
        return;
    }
    ::munmap(p, roundUp(bytes, kHugePage));
}

}  // namespace umbra
