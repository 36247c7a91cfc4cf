// The `raycast` pass (parallax_passes::RaycastKernel): casts a batch of rays through the scene
// CWBVH, closest hit or any hit (alpha-mask aware). Behind the GPU-vs-CPU traversal test and
// the rays/s benchmark (`parallax bench-rays`). Included by bvh_raycast.comp (textures and
// alpha masks as the scene has them) and bvh_raycast_opaque.comp (PT_SCENE_NO_TEXTURES, for
// traversal benchmarks of opaque geometry).

#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_KHR_shader_subgroup_vote : require
#extension GL_KHR_shader_subgroup_shuffle : require
#extension GL_KHR_shader_subgroup_shuffle_relative : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_EXT_shader_explicit_arithmetic_types_int8 : require
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

// Work queue of the persistent schedule: the next ray to hand out, and how many workgroups
// have finished. Zero before a dispatch; the last workgroup to finish zeroes it again.
layout(buffer_reference, std430, buffer_reference_align = 4) coherent buffer RaycastWork {
    uint next_ray;
    uint groups_done;
};

// 84 bytes; parallax_passes::raycast (RaycastKernel::record).
layout(push_constant, std430) uniform RaycastPush {
    SceneRefs scene;
    Rays rays;
    Hits hits;
    RaycastFrame frame;
    RaycastWork work;
    // 0: one ray per invocation. Otherwise persistent invocations that fetch new rays for
    // their idle lanes once at least this many lanes of the subgroup are idle.
    uint fetch_threshold;
    uint pad; // rounds the block to its 8-byte alignment, as the Rust struct is
} pc;

#define PT_SCENE pc.scene
#include "pt_scene.glsl"
#define BVH_NODES scene_nodes.data
#define BVH_TRIS scene_triangle_words.data
#define BVH_COOPERATIVE
#define BVH_BYTES_FROM_INT8
#include "bvh_traverse.glsl"

layout(local_size_x = 64) in;

void cast_one_ray_per_invocation() {
    // 1D over the rays, folded into 2D when it exceeds the 65535-group limit of one axis.
    uint i = gl_GlobalInvocationID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
    if (i >= pc.frame.ray_count) {
        return;
    }
    RayIn r = pc.rays.data[i];
    BvhHit h = bvh_traverse(bvh_make_ray(r.origin_tmin.xyz, r.dir_tmax.xyz, r.origin_tmin.w, r.dir_tmax.w),
                            pc.frame.any_hit != 0u);
    pc.hits.data[i] = HitOut(h.primitive, h.t, h.barycentrics);
}

// Persistent invocations with dynamic ray fetch (Aila and Laine 2009; Ylitie et al. 2017): a
// subgroup keeps stepping its rays and, once enough of its lanes have finished, takes a batch
// of new rays for exactly those lanes from a global counter. Incoherent rays differ widely in
// length; without refills a subgroup runs at the pace of its longest ray with the other lanes
// idle. Each ray is traced by the same code whichever lane gets it, so hits do not depend on
// the schedule. Correct under any reconvergence: a ballot only involves the lanes that reach it
// together, and a group of lanes that is all idle always fetches.
void cast_persistent() {
    uint ray_count = pc.frame.ray_count;
    bool any_hit = pc.frame.any_hit != 0u;
    uint threshold = min(max(pc.fetch_threshold, 1u), gl_SubgroupSize);
    bool tracing = false;
    bool exhausted = false;
    uint ray_index = 0u;
    for (;;) {
        uvec4 idle = subgroupBallot(!tracing);
        uint idle_count = subgroupBallotBitCount(idle);
        bool all_idle = idle_count == subgroupBallotBitCount(subgroupBallot(true));
        if (!exhausted && (idle_count >= threshold || all_idle)) {
            uint base = 0u;
            if (subgroupElect()) {
                base = atomicAdd(pc.work.next_ray, idle_count);
            }
            base = subgroupBroadcastFirst(base);
            exhausted = base + idle_count >= ray_count;
            if (!tracing) {
                ray_index = base + subgroupBallotExclusiveBitCount(idle);
                if (ray_index < ray_count) {
                    RayIn r = pc.rays.data[ray_index];
                    bvh_begin(bvh_make_ray(r.origin_tmin.xyz, r.dir_tmax.xyz, r.origin_tmin.w, r.dir_tmax.w),
                              any_hit);
                    tracing = true;
                }
            }
        } else if (exhausted && all_idle) {
            break;
        }
        // Step until enough lanes are idle to be worth a refill (all of them once the rays
        // are exhausted).
        for (;;) {
            bool ended = bvh_test_pending_triangles_together(tracing);
            bool going = tracing && !ended && bvh_visit_node();
            if (tracing && !going) {
                pc.hits.data[ray_index] = HitOut(bvh_hit.primitive, bvh_hit.t, bvh_hit.barycentrics);
                tracing = false;
            }
            uint idle_now = subgroupBallotBitCount(subgroupBallot(!tracing));
            if (subgroupAll(!tracing) || (!exhausted && idle_now >= threshold)) {
                break;
            }
        }
    }

    // The last workgroup out resets the queue for the next dispatch. Every fetch of this
    // workgroup returned before the barrier, so the count only reaches the total after all.
    barrier();
    if (gl_LocalInvocationIndex == 0u) {
        uint groups = gl_NumWorkGroups.x * gl_NumWorkGroups.y * gl_NumWorkGroups.z;
        if (atomicAdd(pc.work.groups_done, 1u) == groups - 1u) {
            atomicExchange(pc.work.next_ray, 0u);
            atomicExchange(pc.work.groups_done, 0u);
        }
    }
}

void main() {
    if (pc.fetch_threshold == 0u) {
        cast_one_ray_per_invocation();
    } else {
        cast_persistent();
    }
}
