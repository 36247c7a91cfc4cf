#version 460
// Casts a batch of rays through the scene CWBVH: closest hit or any hit (alpha-mask aware).
// The kernel behind the GPU-vs-CPU traversal comparison and the rays/s benchmark; compile with
// `glslc -fshader-stage=compute --target-env=vulkan1.3`.
//
// Bindings: set 0 = the scene (pt_scene.glsl); set 1: 0 rays in, 1 hits out.

#extension GL_GOOGLE_include_directive : require

#include "pt_scene.glsl"
#define BVH_NODES scene_nodes.data
#define BVH_TRIS scene_triangles.data
#include "bvh_traverse.glsl"

#ifndef RAYCAST_GROUP_SIZE
#define RAYCAST_GROUP_SIZE 64
#endif
layout(local_size_x = RAYCAST_GROUP_SIZE) in;

struct RayIn {
    vec4 origin_tmin;
    vec4 dir_tmax;
};

struct HitOut {
    uint primitive; // BVH-ordered triangle index, 0xffffffff = miss
    float t;
    vec2 barycentrics;
};

layout(std430, set = 1, binding = 0) readonly buffer Rays { RayIn data[]; } rays;
layout(std430, set = 1, binding = 1) writeonly buffer Hits { HitOut data[]; } hits;

layout(push_constant) uniform Params {
    uint ray_count;
    uint any_hit; // 0: closest hit, 1: any hit (only `primitive` is meaningful)
} params;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= params.ray_count) {
        return;
    }
    RayIn r = rays.data[i];
    BvhRay ray = bvh_make_ray(r.origin_tmin.xyz, r.dir_tmax.xyz, r.origin_tmin.w, r.dir_tmax.w);
    BvhHit h = bvh_traverse(ray, params.any_hit != 0u);
    hits.data[i] = HitOut(h.primitive, h.t, h.barycentrics);
}
