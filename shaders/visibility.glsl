// The visibility buffer of the `visibility` G-buffer (parallax_passes::visibility): one 64-bit
// key per pixel of a view, row-major, in a row buffer reset to zeros every frame.
//
// key = (~bits(t)) << 32 | primitive, where t >= 0 is the distance along the pixel's centre ray
// to the BVH triangle `primitive`. Float bits of t >= 0 grow with t, so the largest key is the
// nearest triangle and, at equal t, the larger primitive index (the one a traversal of one BVH
// leaf keeps: it tests a leaf's triangles highest first and keeps the first at equal t);
// atomicMax keeps it. 0 is no key at all (its t bits would be a NaN): the pixel saw nothing.

#ifndef VISIBILITY_GLSL
#define VISIBILITY_GLSL

#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require

layout(buffer_reference, std430, buffer_reference_align = 8) buffer VisibilityKeys {
    uint64_t data[];
};

const uint64_t VISIBILITY_EMPTY = 0ul;

uint64_t visibility_key(float t, uint primitive) {
    return (uint64_t(~floatBitsToUint(t)) << 32) | uint64_t(primitive);
}

uint visibility_primitive(uint64_t key) {
    return uint(key & 0xfffffffful);
}

float visibility_t(uint64_t key) {
    return uintBitsToFloat(~uint(key >> 32));
}

#endif
