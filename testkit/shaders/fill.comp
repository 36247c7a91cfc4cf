#version 460
// Test kernel: writes the pattern of include/pattern.glsl into rows [y0, y1) of image
// `dst`.
#include "bindless.glsl"
#include "pattern.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    if (x >= pc.width || y >= pc.y1) {
        return;
    }
    imageStore(images[pc.dst], ivec2(x, y), fill_pattern(x, y, pc.view));
}
