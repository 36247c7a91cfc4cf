#version 460
// Test kernel: a synthetic input for firefly suppression, written over the instance's rows:
// radiance (dst) 0.1 grey with a hit (position src0, w = 1) left of column 20, and sky (w = 0,
// radiance (0.5, 0.6, 0.8)) from column 20 on; fireflies at (10, 9) (60, 30, 10), in the
// corner (0, 0) (8, 8, 8), next to the sky at (18, 12) (20, 20, 20) and in the sky at (22, 5)
// (50, 50, 50). lavapipe_firefly.rs states what suppression must make of them.
#include "bindless.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    if (x >= pc.width || y >= pc.y1) {
        return;
    }
    bool hit = x < 20u;
    vec3 rgb = hit ? vec3(0.1) : vec3(0.5, 0.6, 0.8);
    ivec2 p = ivec2(x, y);
    if (p == ivec2(10, 9)) {
        rgb = vec3(60.0, 30.0, 10.0);
    } else if (p == ivec2(0, 0)) {
        rgb = vec3(8.0);
    } else if (p == ivec2(18, 12)) {
        rgb = vec3(20.0);
    } else if (p == ivec2(22, 5)) {
        rgb = vec3(50.0);
    }
    imageStore(images[pc.dst], p, vec4(rgb, 1.0));
    imageStore(images[pc.src0], p, vec4(float(x), float(y), 0.0, hit ? 1.0 : 0.0));
}
