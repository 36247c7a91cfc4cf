#version 460
// custom_pipeline, pass `pattern` (every view): a procedural pattern of stripes, bands and a
// checker. Every value is a multiple of 2^-5, so the blend of pass `blend` is exact in f32 and
// the CPU (examples/custom_pipeline/pipeline.rs, `pattern`) computes it bit for bit.
#include "bindless.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    if (x >= pc.width || y >= pc.y1) {
        return;
    }
    uint v = pc.view;
    float stripes = float((x + 5u * v) & 31u) * (1.0 / 32.0);
    float bands = float((3u * y + v) & 15u) * (1.0 / 16.0);
    float checker = float(((x >> 3u) ^ (y >> 3u) ^ v) & 1u);
    imageStore(images[pc.dst], ivec2(x, y), vec4(stripes, bands, checker, 1.0));
}
