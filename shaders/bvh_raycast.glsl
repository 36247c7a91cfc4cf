// The `raycast` pass (parallax_passes::RaycastKernel): casts a batch of rays through the scene
// CWBVH, closest hit or any hit (alpha-mask aware). Behind the GPU-vs-CPU traversal test and
// the rays/s benchmark (`parallax bench-rays`). Included by bvh_raycast.comp (textures and
// alpha masks as the scene has them) and bvh_raycast_opaque.comp (PT_SCENE_NO_TEXTURES, for
// traversal benchmarks of opaque geometry).

#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "pt_types.glsl"

struct RayIn {
    vec4 origin_tmin;
    vec4 dir_tmax;
};

struct HitOut {
    uint primitive; // BVH-ordered triangle index, 0xffffffff = miss
    float t;
    vec2 barycentrics;
};

layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer Rays { RayIn data[]; };
layout(buffer_reference, std430, buffer_reference_align = 16) writeonly buffer Hits { HitOut data[]; };
// Per-frame data: which rays, which query (changes without re-recording).
layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer RaycastFrame {
    uint ray_count;
    uint any_hit; // 0: closest hit, 1: any hit (only `primitive` is meaningful)
};

// 72 bytes; parallax_passes::raycast::RaycastPush.
layout(push_constant, std430) uniform RaycastPush {
    SceneRefs scene;
    Rays rays;
    Hits hits;
    RaycastFrame frame;
} pc;

#define PT_SCENE pc.scene
#include "pt_scene.glsl"
#define BVH_NODES scene_nodes.data
#define BVH_TRIS scene_triangles.data
#include "bvh_traverse.glsl"

layout(local_size_x = 64) in;

void main() {
    // 1D over the rays, folded into 2D when it exceeds the 65535-group limit of one axis.
    uint i = gl_GlobalInvocationID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
    if (i >= pc.frame.ray_count) {
        return;
    }
    RayIn r = pc.rays.data[i];
    BvhRay ray = bvh_make_ray(r.origin_tmin.xyz, r.dir_tmax.xyz, r.origin_tmin.w, r.dir_tmax.w);
    BvhHit h = bvh_traverse(ray, pc.frame.any_hit != 0u);
    pc.hits.data[i] = HitOut(h.primitive, h.t, h.barycentrics);
}
