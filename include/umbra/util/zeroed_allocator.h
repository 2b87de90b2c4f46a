// Memory that starts as zeros without being written, shared by the film's
// planes and the depth images made from them, so a depth pass's plane can
// become its map's image without a copy.
#pragma once

#include <cstddef>
#include <cstdlib>
#include <new>
#include <utility>
#include <vector>

namespace umbra {

/// Memory from calloc: fresh pages are zero already (calloc does not
/// clear what it takes fresh from the system), so a frame's planes cost
/// nothing until the bucket workers first touch them, in parallel (zeroing
/// 4.9 MB of RGBA took 1.2 ms of every frame's serial start); and memory a
/// finished pass gave back is taken again without new page faults (on
/// these hosts a page's first touch costs 11-12 us: a 2048^2 plane in
/// fresh pages costs 49 ms of faults). A streamed film gives finished rows
/// back with madvise (Film::releasePages), page-aligned inside the block.
template <typename T>
struct ZeroedAllocator {
    using value_type = T;
    ZeroedAllocator() = default;
    template <typename U>
    ZeroedAllocator(const ZeroedAllocator<U>&) {}
    T* allocate(size_t n) {
        if (void* p = std::calloc(n, sizeof(T))) return static_cast<T*>(p);
        throw std::bad_alloc();
    }
    void deallocate(T* p, size_t) { std::free(p); }
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
