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

/// Zeroed memory for a plane of `bytes`: from calloc when small; from the
/// system in 2 MiB-aligned blocks the kernel is asked to back with huge
/// pages from kLargeZeroedBytes up. Null when there is no memory.
///
/// Why: on these hosts (a paravirtualised VM) the first touch of a 4 KiB
/// page costs 11-12 us, so a 2048^2 plane in fresh small pages costs 49 ms
/// of faults and a 1080p RGBA film 90 ms. A huge page is one fault and
/// its zeroing (about 0.2 us per 4 KiB), 50 times less. Where the kernel
/// has no huge pages to give (or transparent huge pages are off) the
/// block is ordinary pages, as calloc's would be.
void* allocateZeroed(size_t bytes);
/// Gives back a block allocateZeroed(bytes) returned.
void freeZeroed(void* p, size_t bytes) noexcept;
/// Planes from this size up take the huge-page path.
inline constexpr size_t kLargeZeroedBytes = size_t(1) << 20;

/// Memory from allocateZeroed: fresh pages are zero already, so a frame's
/// planes cost nothing until the bucket workers first touch them, in
/// parallel (zeroing 4.9 MB of RGBA took 1.2 ms of every frame's serial
/// start). A streamed film gives finished rows back with madvise
/// (Film::releasePages), page-aligned inside the block.
template <typename T>
struct ZeroedAllocator {
    using value_type = T;
    ZeroedAllocator() = default;
    template <typename U>
    ZeroedAllocator(const ZeroedAllocator<U>&) {}
    T* allocate(size_t n) {
        if (n > size_t(-1) / sizeof(T)) throw std::bad_alloc();
        if (void* p = allocateZeroed(n * sizeof(T))) return static_cast<T*>(p);
        throw std::bad_alloc();
    }
    void deallocate(T* p, size_t n) { freeZeroed(p, n * sizeof(T)); }
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

/// Memory for blocks of exactly kPooledBytes (a 32x32 tile of depths),
/// carved from 2 MiB slabs of allocateZeroed and kept for reuse once given
/// back; other sizes come from malloc. Thread-safe.
///
/// Why: a frame makes and frees its maps' tiles by the thousand, each a
/// fresh 4 KiB of heap the first time, 11-12 us of page fault apiece on
/// these hosts (a desk-lamp frame's 463 tiles: 5 ms); a slab is one huge
/// page. Slabs are never unmapped: the pool keeps the most tiles ever held
/// at once (the tile cache's bound, plus tiles in use), ready for the next
/// frame. Under AddressSanitizer every block comes from malloc, so its
/// bounds stay checked.
inline constexpr size_t kPooledBytes = 4096;
void* allocatePooled(size_t bytes);
void freePooled(void* p, size_t bytes) noexcept;

template <typename T>
struct PooledAllocator {
    using value_type = T;
    PooledAllocator() = default;
    template <typename U>
    PooledAllocator(const PooledAllocator<U>&) {}
    T* allocate(size_t n) {
        if (n > size_t(-1) / sizeof(T)) throw std::bad_alloc();
        if (void* p = allocatePooled(n * sizeof(T))) return static_cast<T*>(p);
        throw std::bad_alloc();
    }
    void deallocate(T* p, size_t n) { freePooled(p, n * sizeof(T)); }
    bool operator==(const PooledAllocator&) const { return true; }
    bool operator!=(const PooledAllocator&) const { return false; }
};

}  // namespace umbra
