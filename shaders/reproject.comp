#version 460
// The `reproject` pass (parallax_passes::ReprojectKernel), a gather: each target pixel projects
// its G-buffer world position into its sources (nearest first) and takes the radiance of the
// first source that saw the same surface there from a direction close enough to its own.
// "The same surface" means: in front of the source camera and inside its image, the source
// pixel has a hit whose linear depth and world position agree with the projected point within
// a tolerance relative to the distance, and whose normal agrees within `normal_cos`. "Close
// enough" means: the view-dependence bound of the surface (view_bound.glsl, docs/PIPELINE.md)
// for the angle between the target's and the source's view directions is at most
// `view_tolerance`, so the radiance the source saw differs from the target's by at most that
// fraction. A pixel no source passes is a hole (holes = 1, radiance 0 with a = 1), path traced
// afterwards by hole filling. A pixel whose centre ray misses the scene is not a hole: it gets
// the sky and sun the path tracer would give it (pt_camera.glsl), a = 0; unless it lies on a
// silhouette (a neighbour's centre ray hits), where the path tracer's jittered samples may hit
// the surface too: that pixel is a hole, so hole filling gives it path tracing's very value.
// No division can produce NaN here: every divisor is a positive clip w, and the bound rejects
// a NaN.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int8 : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "pt_types.glsl"
#include "frame_block.glsl"

const uint MAX_SOURCES = 4u;

// parallax_passes::shaders::ReprojectPush, generated from this block.
layout(push_constant, std430) uniform ReprojectPush {
    FrameBlock block;
    TraceParamsRef trace; // the target view's TraceParams (camera, size, sky, sun, sampling)
    uint position_depth;  // the target's own G-buffer (images[])
    uint normal_metallic;
    uint albedo_roughness;
    uint radiance;        // output
    uint holes;           // output (uimages[])
    uint source_count;
    uint y0;
    uint y1;
    float position_tolerance; // relative to the distance from the source camera
    float normal_cos;
    float view_tolerance;     // largest accepted view-dependence bound (relative radiance error)
    uint pad;
    // Per source, nearest first: view index, then its position_depth, normal_metallic and
    // radiance images.
    uvec4 sources[MAX_SOURCES];
} pc;

#define params (pc.trace.p)
#include "pt_camera.glsl"
#include "view_bound.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// The source radiance at world point `p` (normal `n`) seen from source `s`, or a < 0 if the
// source did not see that surface, or saw it from too far off the target's direction `to_eye`.
vec4 gather(uvec4 s, vec3 p, vec3 n, vec3 to_eye, ViewBound bound) {
    vec4 clip = pc.block.views[s.x].current.view_proj * vec4(p, 1.0);
    if (clip.w <= 0.0) {
        return vec4(-1.0);
    }
    vec2 size = vec2(params.dims.xy);
    vec2 ndc = clip.xy / clip.w;
    vec2 pixel = vec2((ndc.x + 1.0) * 0.5 * size.x, (1.0 - ndc.y) * 0.5 * size.y);
    if (any(lessThan(pixel, vec2(0.0))) || pixel.x >= size.x || pixel.y >= size.y) {
        return vec4(-1.0);
    }
    ivec2 at = ivec2(pixel);
    vec4 seen = imageLoad(images[s.y], at);
    if (seen.w <= 0.0) {
        return vec4(-1.0); // the source saw the sky there
    }
    float tolerance = pc.position_tolerance * clip.w;
    // Occlusion: something nearer (or farther) than the point covers that source pixel.
    if (abs(seen.w - clip.w) > tolerance || distance(seen.xyz, p) > tolerance) {
        return vec4(-1.0);
    }
    if (dot(imageLoad(images[s.z], at).xyz, n) < pc.normal_cos) {
        return vec4(-1.0);
    }
    vec3 source_to_eye = normalize(pc.block.views[s.x].current.position.xyz - p);
    // `!(<=)`: a NaN bound is a hole, never a reprojection.
    if (!(view_bound_error(bound, view_angle(to_eye, source_to_eye)) <= pc.view_tolerance)) {
        return vec4(-1.0);
    }
    return vec4(imageLoad(images[s.w], at).rgb, 1.0);
}

// Whether a neighbour of sky pixel `at` has a hit. Only rows of this instance's band are
// looked at (others may live on another device): a silhouette that runs exactly along a band
// border is seen from one side only.
bool on_silhouette(ivec2 at) {
    for (int dy = -1; dy <= 1; dy++) {
        for (int dx = -1; dx <= 1; dx++) {
            ivec2 q = at + ivec2(dx, dy);
            if (q.x < 0 || q.x >= int(params.dims.x) || q.y < int(pc.y0) || q.y >= int(pc.y1)) {
                continue;
            }
            if (imageLoad(images[pc.position_depth], q).w > 0.0) {
                return true;
            }
        }
    }
    return false;
}

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    if (x >= params.dims.x || y >= pc.y1) {
        return;
    }
    ivec2 at = ivec2(x, y);
    vec4 position = imageLoad(images[pc.position_depth], at);
    if (position.w <= 0.0) {
        bool silhouette = on_silhouette(at);
        imageStore(images[pc.radiance], at, silhouette ? vec4(0.0) : vec4(sky_pixel(x, y), 0.0));
        imageStore(uimages[pc.holes], at, uvec4(silhouette ? 1u : 0u));
        return;
    }
    vec4 normal = imageLoad(images[pc.normal_metallic], at);
    vec4 albedo = imageLoad(images[pc.albedo_roughness], at);
    vec3 to_eye = normalize(params.eye.xyz - position.xyz);
    ViewBound bound = view_bound_of(normal.xyz, to_eye, albedo.rgb, normal.w, albedo.w);
    vec4 result = vec4(-1.0);
    for (uint i = 0u; i < pc.source_count && result.a < 0.0; i++) {
        result = gather(pc.sources[i], position.xyz, normal.xyz, to_eye, bound);
    }
    bool reprojected = result.a >= 0.0;
    imageStore(images[pc.radiance], at, reprojected ? vec4(result.rgb, 1.0) : vec4(0.0, 0.0, 0.0, 1.0));
    imageStore(uimages[pc.holes], at, uvec4(reprojected ? 0u : 1u));
}
