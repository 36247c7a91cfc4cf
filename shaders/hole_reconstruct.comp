#version 460
// The two passes of the reconstruction of subsampled hole filling
// (parallax_passes::hole_subsample): one invocation per entry of the band's
// `hole_reconstruct_list` (dispatched indirectly on the list's own header), so both cost per
// reconstructed pixel.
//
// `hole_reconstruct` (stage GATHER) writes each listed pixel's value to
// `hole_reconstructed`: the G-buffer-weighted mean (hole_similarity) of the traced hole pixels
// among its 8 neighbours, which compact_holes_subsampled.comp made sure includes one with a
// positive weight. Under `--denoise samples` (accum given) a pixel with a running mean of its
// own traced frames (its history carried by hole_temporal) shows that mean instead: a
// reconstructed value is never a sample, and a pixel's own samples beat its neighbours'.
// `hole_reconstruct_apply` (stage APPLY) copies them into the radiance in place. Two passes
// because the gather reads the radiance 1 row beyond its band, which another band's apply
// would be writing (the graph orders a read before the next version's write, as for the
// firefly passes).
#extension GL_EXT_buffer_reference : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "pixel_list.glsl"
#include "hole_subsample.glsl"

layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer HoleList {
    uint groups_x;
    uint groups_y;
    uint groups_z;
    uint count;
    uint data[];
};

const uint GATHER = 0u;
const uint APPLY = 1u;
const uint NO_IMAGE = 0xffffffffu;

// 40 bytes; parallax_passes::shaders::HoleReconstructPush, generated from this block.
layout(push_constant, std430) uniform HoleReconstructPush {
    HoleList list;        // the band's section of `hole_reconstruct_list`
    uint radiance;        // Rgba32f: read 1 row beyond the band (GATHER), written (APPLY)
    uint sampling;        // R32u `hole_sampling`, 1 row beyond the band
    uint position_depth;  // G-buffer layers, 1 row beyond the band
    uint normal_metallic;
    uint accum;           // this frame's `hole_accum` (--denoise samples), or NO_IMAGE
    uint reconstructed;   // Rgba32f `hole_reconstructed`
    uint stage;
    uint pad;
} pc;

layout(local_size_x = 64) in;

vec4 gather(ivec2 p) {
    ivec2 size = imageSize(uimages[pc.sampling]);
    vec4 position = imageLoad(images[pc.position_depth], p);
    vec3 normal = imageLoad(images[pc.normal_metallic], p).xyz;
    vec4 sum = vec4(0.0);
    float weights = 0.0;
    for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
            ivec2 q = p + ivec2(dx, dy);
            if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, size))
                || imageLoad(uimages[pc.sampling], q).x != HOLE_TRACED) {
                continue;
            }
            vec4 position_q = imageLoad(images[pc.position_depth], q);
            vec3 normal_q = imageLoad(images[pc.normal_metallic], q).xyz;
            float w = hole_similarity(position, normal, position_q, normal_q);
            sum += w * imageLoad(images[pc.radiance], q);
            weights += w;
        }
    }
    return sum / weights;
}

void main() {
    uint entry = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * PIXEL_LIST_GROUP
        + gl_LocalInvocationID.x;
    if (entry >= pc.list.count) {
        return;
    }
    uint packed = pc.list.data[entry];
    ivec2 p = ivec2(packed & 0xffffu, packed >> 16u);
    if (pc.stage == APPLY) {
        imageStore(images[pc.radiance], p, imageLoad(images[pc.reconstructed], p));
        return;
    }
    if (pc.accum != NO_IMAGE) {
        vec4 own = imageLoad(images[pc.accum], p);
        if (own.a >= 1.0) {
            imageStore(images[pc.reconstructed], p, vec4(own.rgb, 1.0));
            return;
        }
    }
    imageStore(images[pc.reconstructed], p, gather(p));
}
