// Types shared by the BVH traversal and the scene buffers.

#ifndef BVH_TYPES_GLSL
#define BVH_TYPES_GLSL

// Mirrors parallax_scene::gpu::GpuTriangle (48 bytes).
struct BvhTriangle {
    vec3 v0;
    uint material;
    vec3 v1;
    uint scene_triangle;
    vec3 v2;
    uint flags;
};

const uint TRI_ALPHA_MASK = 1u;
const uint TRI_DOUBLE_SIDED = 2u;
const uint TRI_EMISSIVE = 4u;

#endif
