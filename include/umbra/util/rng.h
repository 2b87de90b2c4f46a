#pragma once
// Deterministic random numbers. Every random choice in a render is seeded
// from *what* is being computed (frame, grid id, pixel, point), never from
// which thread computes it or when, so images do not depend on thread count
// or bucket order.

#include <cstdint>

namespace umbra {

/// hash32's mixing of every lane of `x`: a uint32_t, or a vector of them
/// (GCC/Clang vector extensions), so vectorised code draws the same numbers.
template <typename U>
inline U hash32Lanes(U x) {
    x ^= x >> 16;
    x *= 0x7feb352dU;
    x ^= x >> 15;
    x *= 0x846ca68bU;
    x ^= x >> 16;
    return x;
}
/// A 32-bit integer hash with good avalanche (Wellons' "lowbias32").
inline uint32_t hash32(uint32_t x) { return hash32Lanes(x); }
/// Combines several keys into one seed.
inline uint32_t hashCombine(uint32_t seed, uint32_t v) { return hash32(seed ^ (v + 0x9e3779b9U + (seed << 6) + (seed >> 2))); }
inline uint32_t hashKeys(uint32_t a, uint32_t b) { return hashCombine(hash32(a), b); }
inline uint32_t hashKeys(uint32_t a, uint32_t b, uint32_t c) { return hashCombine(hashKeys(a, b), c); }
inline uint32_t hashKeys(uint32_t a, uint32_t b, uint32_t c, uint32_t d) { return hashCombine(hashKeys(a, b, c), d); }

/// A float in [0,1) from the top 24 bits of a hash.
inline float hashToUnit(uint32_t h) { return float(h >> 8) * (1.0f / 16777216.0f); }

/// PCG32 (O'Neill 2014): a small, fast generator for a stream of numbers
/// from one seed, e.g. the samples of one shadow lookup.
class Rng {
public:
    explicit Rng(uint64_t seed = 0x853c49e6748fea9bULL, uint64_t stream = 0xda3e39cb94b95bdbULL) {
        m_inc = (stream << 1u) | 1u;
        m_state = 0;
        next();
        m_state += seed;
        next();
    }
    uint32_t next() {
        uint64_t old = m_state;
        m_state = old * 6364136223846793005ULL + m_inc;
        uint32_t xorshifted = uint32_t(((old >> 18u) ^ old) >> 27u);
        uint32_t rot = uint32_t(old >> 59u);
        return (xorshifted >> rot) | (xorshifted << ((32 - rot) & 31));
    }
    /// Uniform in [0,1).
    float uniform() { return hashToUnit(next()); }

private:
    uint64_t m_state, m_inc;
};

}  // namespace umbra
