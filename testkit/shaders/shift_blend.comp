#version 460
// Test kernel shaped like a reprojection gather: every pixel of the target view blends its
// own value with a pixel of another view (`src1`), taken `param` columns to the right
// (wrapping). 0.5*a + 0.5*b is exact for the fill pattern, so results are bit-identical on any
// device and match the Rust reference.
#include "bindless.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    if (x >= pc.width || y >= pc.y1) {
        return;
    }
    vec4 own = imageLoad(images[pc.src0], ivec2(x, y));
    vec4 other = imageLoad(images[pc.src1], ivec2((x + pc.param) % pc.width, y));
    imageStore(images[pc.dst], ivec2(x, y), 0.5 * own + 0.5 * other);
}
