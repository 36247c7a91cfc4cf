#version 460
// The `visibility_resolve` pass (parallax_passes::visibility::VisibilityResolveKernel): the
// G-buffer of one view's row band from its visibility buffer. Each pixel's key names the
// nearest triangle its centre ray hits (visibility_raster.comp); the ray is intersected with
// that one triangle by the traversal's code and the hit written as gbuffer_trace.comp writes a
// traced one (gbuffer_store.glsl): same images, formats and conventions, zeros where the key
// is empty (the sky).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int8 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "pt_types.glsl"
#include "frame_block.glsl"
#include "visibility.glsl"

// parallax_passes::shaders::VisibilityResolvePush, generated from this block.
layout(push_constant, std430) uniform VisibilityResolvePush {
    SceneRefs scene;
    TraceParamsRef trace; // this view's TraceParams in the per-frame data
    FrameBlock block;     // cameras of every view, current and previous
    VisibilityKeys keys;  // this view's keys, row 0
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
    uint64_t key = pc.keys.data[y * pc.width + x];
    BvhHit hit = BvhHit(0xffffffffu, 1.0 / 0.0, vec2(0.0));
    if (key != VISIBILITY_EMPTY) {
        hit.primitive = visibility_primitive(key);
        hit.t = visibility_t(key);
        // The barycentrics of the traversal's own test of this ray and triangle.
        bvh_intersect_triangle(bvh_load_triangle(hit.primitive), bvh_make_ray(eye, dir, 0.0, 1.0 / 0.0),
                               hit.barycentrics);
    }
    gbuffer_store(x, y, eye, dir, hit);
}
