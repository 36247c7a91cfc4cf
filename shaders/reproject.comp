#version 460
// The `reproject` pass (parallax_passes::ReprojectKernel), a gather: each target pixel projects
// its G-buffer world position into its sources (nearest first) and takes the radiance of the
// first source that saw the same surface there. "The same surface" means: in front of the
// source camera and inside its image, the source pixel has a hit whose linear depth and world
// position agree with the projected point within a tolerance relative to the distance, and
// whose normal agrees within `normal_cos`. Only diffuse surfaces are reprojected (their
// radiance does not depend on the view direction): metallic <= max_metallic and roughness >=
// min_roughness. Everything else is a hole (holes = 1, radiance 0 with a = 1 where the pixel
// has a hit), path traced afterwards by hole filling. No division can produce NaN here: every
// divisor is a positive clip w.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "frame_block.glsl"

const uint MAX_SOURCES = 4u;

// parallax_passes::reproject::ReprojectPush.
layout(push_constant, std430) uniform ReprojectPush {
    FrameBlock block;
    uint position_depth; // the target's own G-buffer (images[])
    uint normal_metallic;
    uint albedo_roughness;
    uint radiance;       // output
    uint holes;          // output (uimages[])
    uint source_count;
    uint y0;
    uint y1;
    uint width;
    uint height;
    float position_tolerance; // relative to the distance from the source camera
    float normal_cos;
    float min_roughness;
    float max_metallic;
    // Per source, nearest first: view index, then its position_depth, normal_metallic and
    // radiance images.
    uvec4 sources[MAX_SOURCES];
} pc;

layout(local_size_x = 8, local_size_y = 8) in;

// The source radiance at world point `p` (normal `n`) seen from source `s`, or a < 0 if the
// source did not see that surface.
vec4 gather(uvec4 s, vec3 p, vec3 n) {
    vec4 clip = pc.block.views[s.x].current.view_proj * vec4(p, 1.0);
    if (clip.w <= 0.0) {
        return vec4(-1.0);
    }
    vec2 ndc = clip.xy / clip.w;
    vec2 pixel = vec2((ndc.x + 1.0) * 0.5 * float(pc.width), (1.0 - ndc.y) * 0.5 * float(pc.height));
    if (any(lessThan(pixel, vec2(0.0))) || pixel.x >= float(pc.width) || pixel.y >= float(pc.height)) {
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
    return vec4(imageLoad(images[s.w], at).rgb, 1.0);
}

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    if (x >= pc.width || y >= pc.y1) {
        return;
    }
    ivec2 at = ivec2(x, y);
    vec4 position = imageLoad(images[pc.position_depth], at);
    vec4 result = vec4(-1.0);
    bool hit = position.w > 0.0;
    if (hit) {
        vec4 normal = imageLoad(images[pc.normal_metallic], at);
        float roughness = imageLoad(images[pc.albedo_roughness], at).w;
        bool diffuse = normal.w <= pc.max_metallic && roughness >= pc.min_roughness;
        for (uint i = 0u; diffuse && i < pc.source_count && result.a < 0.0; i++) {
            result = gather(pc.sources[i], position.xyz, normal.xyz);
        }
    }
    bool reprojected = result.a >= 0.0;
    imageStore(images[pc.radiance], at, reprojected ? vec4(result.rgb, 1.0) : vec4(0.0, 0.0, 0.0, hit ? 1.0 : 0.0));
    imageStore(uimages[pc.holes], at, uvec4(reprojected ? 0u : 1u));
}
