#version 460
// Test kernel: spoils a traced G-buffer in place the ways a renderer can: radiance NaN, +Inf,
// -Inf or huge (dst), albedo 0 or NaN (src0), a zero or NaN normal (src1), a NaN depth
// (image `param`), on a fixed pattern of pixels. SVGF must still write only finite values.
#include "bindless.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    if (x >= pc.width || y >= pc.y1) {
        return;
    }
    ivec2 p = ivec2(x, y);
    float nan = uintBitsToFloat(0x7fc00000u);
    float inf = uintBitsToFloat(0x7f800000u);
    vec4 radiance = imageLoad(images[pc.dst], p);
    vec4 albedo = imageLoad(images[pc.src0], p);
    vec4 normal = imageLoad(images[pc.src1], p);
    vec4 position = imageLoad(images[pc.param], p);
    switch ((x * 7u + y * 13u) % 11u) {
        case 0u: radiance.rgb = vec3(nan); break;
        case 1u: radiance.rgb = vec3(inf); break;
        case 2u: radiance.rgb = vec3(-inf, 1e38, -1.0); break;
        case 3u: albedo.rgb = vec3(0.0); break;
        case 4u: albedo.rgb = vec3(nan); break;
        case 5u: normal.xyz = vec3(0.0); break;
        case 6u: normal.xyz = vec3(nan); break;
        case 7u: position.w = nan; break;
        default: break;
    }
    imageStore(images[pc.dst], p, radiance);
    imageStore(images[pc.src0], p, albedo);
    imageStore(images[pc.src1], p, normal);
    imageStore(images[pc.param], p, position);
}
