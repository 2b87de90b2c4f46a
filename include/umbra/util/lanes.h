#pragma once
// Four lanes of floats or integers in one SSE register (GCC/Clang vector
// extensions; SSE2, the x86-64 baseline): the hider tests samples and the
// shadow lookups project points and draw samples four at a time.
//
// Lane arithmetic is IEEE float arithmetic, lane by lane, so code written
// with these types gives the bits the same scalar expressions give.

#include <cstdint>
#include <cstring>
#include <limits>

namespace umbra {

typedef float F4 __attribute__((vector_size(16)));
typedef int32_t I4 __attribute__((vector_size(16)));
typedef uint32_t U4 __attribute__((vector_size(16)));

inline F4 toF4(I4 v) { return __builtin_convertvector(v, F4); }

/// floor() of each lane as an int, for lanes within the int range (callers
/// bound their values first).
inline I4 floorX4(F4 v) {
    const I4 i = __builtin_convertvector(v, I4);
    return i + (toF4(i) > v);  // a true comparison is -1
}

/// |v| of each lane (the sign bit cleared, as std::abs does).
inline F4 abs4(F4 v) { return F4(U4(v) & 0x7fffffffu); }

/// Lanes that are finite numbers: -1, else 0 (infinities and NaN).
inline I4 finite4(F4 v) { return abs4(v) <= std::numeric_limits<float>::max(); }

/// Four lanes from memory, and back, without alignment requirements.
inline F4 load4(const float* p) {
    F4 v;
    std::memcpy(&v, p, sizeof v);
    return v;
}
inline I4 load4(const int32_t* p) {
    I4 v;
    std::memcpy(&v, p, sizeof v);
    return v;
}
inline void store4(float* p, F4 v) { std::memcpy(p, &v, sizeof v); }
inline void store4(int32_t* p, I4 v) { std::memcpy(p, &v, sizeof v); }

}  // namespace umbra
