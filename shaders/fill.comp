#version 460
// Test/demo kernel: writes a deterministic pattern into rows [y0, y1) of image `dst`.
// Every value is a multiple of 2^-16 in [0, 1), so it survives float arithmetic on any
// device bit for bit; `rust_reference_fill` in backend/src/kernels.rs computes the same.
#include "bindless.glsl"
#include "hash.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    if (x >= pc.width || y >= pc.y1) {
        return;
    }
    uint h = hash3(x, y, pc.view);
    vec4 value = vec4(float(h & 0xffffu), float(h >> 16u), float(pc.view & 0xffffu), 65535.0)
        / 65536.0;
    imageStore(images[pc.dst], ivec2(x, y), value);
}
