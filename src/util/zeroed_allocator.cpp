#include "umbra/util/zeroed_allocator.h"

#include <cstdint>
#include <cstdlib>
#include <mutex>

#include <sys/mman.h>
#include <unistd.h>

namespace umbra {

namespace {

constexpr size_t kHugePage = size_t(2) << 20;

// Under AddressSanitizer every plane comes from calloc, whose blocks it
// guards: an index past a plane's end inside a mapping's last page would
// go unseen.
#if defined(__SANITIZE_ADDRESS__)
constexpr bool kHeapOnly = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kHeapOnly = true;
#else
constexpr bool kHeapOnly = false;
#endif
#else
constexpr bool kHeapOnly = false;
#endif

bool fromHeap(size_t bytes) { return kHeapOnly || bytes < kLargeZeroedBytes; }

size_t roundUp(size_t bytes, size_t to) { return (bytes + to - 1) / to * to; }

size_t smallPage() {
    static const size_t page = size_t(::sysconf(_SC_PAGESIZE));
    return page;
}

/// The mapped size of a large block of `bytes`: whole small pages, and a
/// last partial 2 MiB more than half used made whole (at most 1 MiB more
/// resident: a 640^2 depth film's 1.6 MB was 400 small-page faults
/// otherwise); one less than half used stays in small pages. Less than
/// `bytes` when it overflows.
size_t blockSize(size_t bytes) {
    size_t size = roundUp(bytes, smallPage());
    if (size % kHugePage > kHugePage / 2) size = roundUp(size, kHugePage);
    return size;
}

}  // namespace

void* allocateZeroed(size_t bytes) {
    if (fromHeap(bytes)) return std::calloc(bytes ? bytes : 1, 1);
    // Aligned to a huge page, so every whole 2 MiB of the block can be one:
    // map a huge page more than needed and trim both ends.
    const size_t size = blockSize(bytes);
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

namespace {

/// The pool behind allocatePooled: free blocks linked through their first
/// bytes, refilled a slab at a time.
struct BlockPool {
    std::mutex mutex;
    void* free = nullptr;

    void* take() {
        std::lock_guard<std::mutex> lock(mutex);
        if (!free) {
            auto* slab = static_cast<char*>(allocateZeroed(kHugePage));
            if (!slab) return nullptr;
            // Linked back to front, so blocks are handed out in address order.
            for (size_t at = kHugePage; at >= kPooledBytes; at -= kPooledBytes) {
                void* block = slab + at - kPooledBytes;
                *static_cast<void**>(block) = free;
                free = block;
            }
        }
        void* block = free;
        free = *static_cast<void**>(block);
        return block;
    }
    void give(void* block) noexcept {
        std::lock_guard<std::mutex> lock(mutex);
        *static_cast<void**>(block) = free;
        free = block;
    }
};

BlockPool& blockPool() {
    static BlockPool* pool = new BlockPool();  // never destroyed: blocks may be given back during exit
    return *pool;
}

bool pooled(size_t bytes) { return !kHeapOnly && bytes == kPooledBytes; }

}  // namespace

void* allocatePooled(size_t bytes) {
    if (!pooled(bytes)) return std::malloc(bytes ? bytes : 1);
    return blockPool().take();
}

void freePooled(void* p, size_t bytes) noexcept {
    if (!p) return;
    if (!pooled(bytes)) {
        std::free(p);
        return;
    }
    blockPool().give(p);
}

void freeZeroed(void* p, size_t bytes) noexcept {
    if (!p) return;
    if (fromHeap(bytes)) {
        std::free(p);
        return;
    }
    ::munmap(p, blockSize(bytes));
}

}  // namespace umbra
