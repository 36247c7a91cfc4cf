#version 460
// The `path_trace` pass (parallax_passes::PathTraceKernel): traces a row band of a view or a
// compacted list of its pixels with shaders/pt_trace.glsl and stores radiance and first-hit
// data into the view's images. Every pixel's value is a function of (pixel, view, frame,
// settings) only, so any split of a view into bands, lists or devices gives the same pixels.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int8 : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "pt_types.glsl"

// Pixel list (list mode): one band's section of a pixel list (parallax_passes::pixel_list): a
// header ending in `count`, then `count` entries of x | y << 16. The dispatch covers the
// section's capacity; invocations past `count` return.
layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer PixelList {
    uint groups_x;
    uint groups_y;
    uint groups_z;
    uint count;
    uint data[];
};

const uint NO_IMAGE = 0xffffffffu;

// 96 bytes; parallax_passes::shaders::PathTracePush, generated from this block.
layout(push_constant, std430) uniform PathTracePush {
    SceneRefs scene;
    TraceParamsRef trace; // this view's TraceParams in the per-frame data
    PixelList pixel_list; // list mode only: the band's section (header first)
    uint radiance;        // image indices (images[] of bindless.glsl), NO_IMAGE: not written
    uint albedo_roughness;
    uint normal_metallic;
    uint position_depth;
    uint y0; // rows mode: the instance's band
    uint y1;
    uint width;
    uint list_mode; // 1: trace pixel_list instead of rows y0..y1
} pc;

#define PT_SCENE pc.scene
#define params (pc.trace.p)
#include "pt_trace.glsl"

layout(local_size_x = 64) in;

void main() {
    uint x;
    uint y;
    if (pc.list_mode == 1u) {
        // 1D over the list, folded into 2D when the capacity exceeds the 65535-group limit of
        // one axis (parallax_passes::list_groups); the groups past the count return.
        uint i = gl_GlobalInvocationID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
        if (i >= pc.pixel_list.count) {
            return;
        }
        uint entry = pc.pixel_list.data[i];
        x = entry & 0xffffu;
        y = entry >> 16u;
    } else {
        // One workgroup per 8x8-pixel tile, so that a subgroup of 32 covers 8x4 pixels rather
        // than 32x1: nearby rays traverse the same nodes (1.5 % faster on an H100 on Sponza,
        // docs/RESULTS.md).
        uint local = gl_LocalInvocationIndex;
        x = gl_WorkGroupID.x * 8u + (local & 7u);
        y = pc.y0 + gl_WorkGroupID.y * 8u + (local >> 3u);
        if (x >= pc.width || y >= pc.y1) {
            return;
        }
    }
    PixelOut g = trace_pixel(x, y);
    ivec2 at = ivec2(x, y);
    if (pc.radiance != NO_IMAGE) {
        imageStore(images[pc.radiance], at, g.radiance);
    }
    if (pc.albedo_roughness != NO_IMAGE) {
        imageStore(images[pc.albedo_roughness], at, g.albedo_roughness);
    }
    if (pc.normal_metallic != NO_IMAGE) {
        imageStore(images[pc.normal_metallic], at, g.normal_metallic);
    }
    if (pc.position_depth != NO_IMAGE) {
        imageStore(images[pc.position_depth], at, g.position_depth);
    }
}
