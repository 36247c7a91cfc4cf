#version 460
// The `gbuffer` pass (parallax_passes::GbufferKernel): the first hit of every pixel's centre ray
// in the instance's row band, as the path tracer's first hit records it (same ray, same
// surface evaluation), plus where that surface was in the previous frame (`motion`, from the
// frame block's previous camera). The G-buffer the reconstruction reads for every view. With
// hole filling after it, also the BVH primitive that ray hit (`first_hit`, NO_PRIMITIVE on a
// miss): hole_fill.comp bounds its camera rays' traversals by it (pt_trace.glsl,
// closest_hit_from).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int8 : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "pt_types.glsl"
#include "frame_block.glsl"

// parallax_passes::shaders::GbufferPush, generated from this block.
layout(push_constant, std430) uniform GbufferPush {
    SceneRefs scene;
    TraceParamsRef trace; // this view's TraceParams in the per-frame data
    FrameBlock block;     // cameras of every view, current and previous
    uint position_depth;  // image indices (images[] of bindless.glsl)
    uint normal_metallic;
    uint albedo_roughness;
    uint motion;
    uint view;
    uint y0;
    uint y1;
    uint width;
    uint first_hit; // NO_IMAGE: not written
    uint pad;
} pc;

#define PT_SCENE pc.scene
#define params (pc.trace.p)
#include "pt_trace.glsl"
#include "gbuffer_store.glsl"

layout(local_size_x = 64) in;

void main() {
    uint local = gl_LocalInvocationIndex;
    uint x = gl_WorkGroupID.x * 8u + (local & 7u);
    uint y = pc.y0 + gl_WorkGroupID.y * 8u + (local >> 3u);
    if (x >= pc.width || y >= pc.y1) {
        return;
    }
    vec3 dir = camera_direction(x, y, vec2(0.5));
    vec3 eye = params.eye.xyz;
    BvhHit hit = bvh_closest_hit(bvh_make_ray(eye, dir, 0.0, 1.0 / 0.0));
    gbuffer_store(x, y, eye, dir, hit);
}
