#version 460
// custom_pipeline, pass `blend` (every target view): half its own pattern plus half the
// brightest of its sources' patterns, each source shifted by its disparity (`shift`, from the
// views' distance in the grid) — a reprojection in miniature. The reads of the sources are
// the δ-edges. max() and halving are exact, so the CPU reproduces every bit.
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"

// Mirrored by `BlendParams` in pipeline.rs; the example checks the two layouts agree.
#define MAX_SOURCES 4
layout(push_constant, std430) uniform BlendParams {
    uint dst;
    uint own;
    uint y0;
    uint y1;
    uint width;
    uint sources;
    uint source_image[MAX_SOURCES];
    uint shift[MAX_SOURCES];
} pc;

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    if (x >= pc.width || y >= pc.y1) {
        return;
    }
    vec4 seen = vec4(0.0);
    for (uint i = 0u; i < pc.sources; ++i) {
        ivec2 p = ivec2((x + pc.shift[i]) % pc.width, y);
        seen = max(seen, imageLoad(images[pc.source_image[i]], p));
    }
    vec4 own = imageLoad(images[pc.own], ivec2(x, y));
    imageStore(images[pc.dst], ivec2(x, y), vec4(0.5 * own.rgb + 0.5 * seen.rgb, 1.0));
}
