// The deterministic test pattern of the test kernels. Every value is a multiple of
// 2^-16 in [0, 1), so it survives float arithmetic on any device bit for bit;
// `reference_fill` in testkit/src/kernels.rs computes the same.
#ifndef PARALLAX_PATTERN_GLSL
#define PARALLAX_PATTERN_GLSL

#include "hash.glsl"

vec4 fill_pattern(uint x, uint y, uint view) {
    uint h = hash3(x, y, view);
    return vec4(float(h & 0xffffu), float(h >> 16u), float(view & 0xffffu), 65535.0) / 65536.0;
}

#endif
