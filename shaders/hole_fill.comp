#version 460
// Second dispatch of a `hole_fill` op (parallax_passes::hole_fill::HoleFillKernel): one
// indirect dispatch path traces the listed holes of every target band of the op, so hole
// filling of many targets fills the GPU as tracing one large view does. Workgroup g traces
// HOLE_FILL_GROUP consecutive entries of the one target whose workgroups hold g
// (hole_fill_prefix.comp numbered them): neighbouring invocations trace neighbouring pixels of
// one view (compact_holes.comp keeps a tile's holes together), and the target, so its camera
// and image index, is the same in the whole workgroup. Each pixel's path is a function of
// (pixel, view, frame, settings) only, the same trace_pixel_from as pt_trace.comp, so a hole
// gets the bits that path tracing its whole view gives it; the primitive the G-buffer's centre
// ray hit (`first_hit`, when the pipeline has one) only bounds the camera rays' traversals.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int8 : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "hole_fill.glsl"

// 64 bytes; parallax_passes::shaders::HoleFillPush, generated from this block.
layout(push_constant, std430) uniform HoleFillPush {
    SceneRefs scene;
    HoleFillTable table;
    uint target_count;
    uint pad;
} pc;

// The TraceParams of the pixel's view: what pt_trace.glsl reads as `params`.
TraceParamsRef view_params;
#define PT_SCENE pc.scene
#define params (view_params.p)
#include "pt_trace.glsl"

layout(local_size_x = HOLE_FILL_GROUP) in;

void main() {
    uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (group >= pc.table.groups) {
        return;
    }
    // The last target whose first workgroup is at most `group`: a target without holes shares
    // its first workgroup with the next one, and the one found has `group` among its own.
    uint lo = 0u;
    uint hi = pc.target_count;
    while (hi - lo > 1u) {
        uint mid = (lo + hi) / 2u;
        if (pc.table.targets[mid].first_group <= group) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    HoleFillTarget band = pc.table.targets[lo];
    uint entry = (group - band.first_group) * HOLE_FILL_GROUP + gl_LocalInvocationIndex;
    if (entry >= band.count) {
        return;
    }
    uint packed = band.list.data[entry];
    uint x = packed & 0xffffu;
    uint y = packed >> 16u;
    view_params = band.trace;
    uint centre = band.first_hit != 0xffffffffu ? imageLoad(uimages[band.first_hit], ivec2(x, y)).x : NO_PRIMITIVE;
    PixelOut g = trace_pixel_from(x, y, centre);
    imageStore(images[band.radiance], ivec2(x, y), g.radiance);
}
