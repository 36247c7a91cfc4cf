#version 460
// Benchmark producer (backend/src/bench.rs): writes rows [y0, y1) of image `dst` so the copy
// and overhead benchmarks have real GPU work ahead of their copies. The values are never read.
#include "bindless.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    if (x >= pc.width || y >= pc.y1) {
        return;
    }
    imageStore(images[pc.dst], ivec2(x, y), vec4(x, y, pc.view, 1.0));
}
