#version 460
// Test kernel: overwrites the traced radiance (dst) with a constant and the albedo (src0) with
// another, in place, keeping alpha (hit flag) and roughness: a noiseless input SVGF must give
// back unchanged. The albedo has a zero channel, which SVGF must not divide by.
#include "bindless.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

const vec3 RADIANCE = vec3(0.3, 0.2, 0.1);
const vec3 ALBEDO = vec3(0.5, 0.0, 0.25);

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    if (x >= pc.width || y >= pc.y1) {
        return;
    }
    ivec2 p = ivec2(x, y);
    imageStore(images[pc.dst], p, vec4(RADIANCE, imageLoad(images[pc.dst], p).a));
    imageStore(images[pc.src0], p, vec4(ALBEDO, imageLoad(images[pc.src0], p).a));
}
