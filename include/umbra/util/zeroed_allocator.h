// Memory that starts as zeros without being written, shared by the film's
// planes and the depth images made from them, so a depth pass's plane can
// become its map's image without a copy.
#pragma once

#include <sys/mman.h>

#include <cstddef>
#include <cstdlib>
#include <new>
#include <utility>
#include <vector>

namespace umbra {

/// Fresh pages are zero already, so a frame's planes cost nothing until
/// the bucket workers first touch them, in parallel (zeroing 4.9 MB of
/// RGBA took 1.2 ms of every frame's serial start). Large blocks are their
/// own anonymous mappings, so a streamed film can give finished rows back
/// with madvise whatever malloc's thresholds are.
template <typename T>
struct ZeroedAllocator {
    static constexpr size_t kMappedBytes = size_t(64) << 10;
    using value_type = T;
    ZeroedAllocator() = default;
    template <typename U>
    ZeroedAllocator(const ZeroedAllocator<U>&) {}
    T* allocate(size_t n) {
        if (n * sizeof(T) >= kMappedBytes) {
            void* p = ::mmap(nullptr, n * sizeof(T), PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
            if (p == MAP_FAILED) throw std::bad_alloc();
            return static_cast<T*>(p);
        }
        if (void* p = std::calloc(n, sizeof(T))) return static_cast<T*>(p);
        throw std::bad_alloc();
    }
    void deallocate(T* p, size_t n) {
        if (n * sizeof(T) >= kMappedBytes)
            ::munmap(p, n * sizeof(T));
        else
            std::free(p);
    }
    template <typename U>
    void construct(U*) {}  // value-initialised elements: already zero
    template <typename U, typename... Args>
    void construct(U* p, Args&&... args) {
        ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
    }
    bool operator==(const ZeroedAllocator&) const { return true; }
    bool operator!=(const ZeroedAllocator&) const { return false; }
};

/// A plane of floats: a film's channel, a depth image.
using FloatPlane = std::vector<float, ZeroedAllocator<float>>;

}  // namespace umbra
