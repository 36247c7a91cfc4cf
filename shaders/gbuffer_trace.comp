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

// parallax_passes::gbuffer::GbufferPush.
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

const uint NO_IMAGE = 0xffffffffu;

#define PT_SCENE pc.scene
#define params (pc.trace.p)
#include "pt_trace.glsl"

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
    ivec2 at = ivec2(x, y);
    vec2 previous_pixel = vec2(-1.0);
    if (pc.first_hit != NO_IMAGE) {
        imageStore(uimages[pc.first_hit], at, uvec4(hit.primitive));
    }
    if (hit.primitive == 0xffffffffu) {
        imageStore(images[pc.position_depth], at, vec4(0.0));
        imageStore(images[pc.normal_metallic], at, vec4(0.0));
        imageStore(images[pc.albedo_roughness], at, vec4(0.0));
        imageStore(images[pc.motion], at, vec4(previous_pixel, 0.0, 0.0));
        return;
    }
    SurfacePoint sp = surface_point(hit.primitive, hit.barycentrics, hit.t, eye, dir);
    imageStore(images[pc.position_depth], at, vec4(sp.position, dot(sp.position - eye, params.forward.xyz)));
    imageStore(images[pc.normal_metallic], at, vec4(sp.normal, sp.metallic));
    imageStore(images[pc.albedo_roughness], at, vec4(sp.base_color, sp.roughness));
    if (frame.history_valid != 0u) {
        vec4 clip = pc.block.views[pc.view].previous.view_proj * vec4(sp.position, 1.0);
        if (clip.w > 0.0) {
            vec2 prev_ndc = clip.xy / clip.w;
            vec2 size = vec2(params.dims.xy);
            vec2 pixel = vec2((prev_ndc.x + 1.0) * 0.5 * size.x, (1.0 - prev_ndc.y) * 0.5 * size.y);
            if (all(greaterThanEqual(pixel, vec2(0.0))) && all(lessThan(pixel, size))) {
                previous_pixel = pixel;
            }
        }
    }
    imageStore(images[pc.motion], at, vec4(previous_pixel, 0.0, 0.0));
}
