#version 460
// A synthetic hole mask (parallax_passes::hole_bench::HashedHoleMaskKernel), for benchmarks and
// tests of hole filling before reprojection produces real ones: pixel (x, y) of `view` is a
// hole (1) when the low 16 bits of hash3(x, y, view) are below `param` (0: no hole,
// 65536: all holes), else 0. Rows [y0, y1) of the R32_UINT image `dst`.
#include "bindless.glsl"
#include "hash.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    if (x >= pc.width || y >= pc.y1) {
        return;
    }
    uint hole = (hash3(x, y, pc.view) & 0xffffu) < pc.param ? 1u : 0u;
    imageStore(uimages[pc.dst], ivec2(x, y), uvec4(hole));
}
