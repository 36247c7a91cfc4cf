#version 460
// Test kernel for global buffers and per-frame data, both reached by buffer reference:
// dst = fill_pattern * weights[view] + frame_data.offset, over rows [y0, y1).
#extension GL_EXT_buffer_reference : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "pattern.glsl"

layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer Floats {
    float values[];
};

layout(push_constant, std430) uniform WeightedFillParams {
    uint dst;
    uint view;
    uint y0;
    uint y1;
    uint width;
    uint pad;
    Floats weights;
    Floats frame_data;
} pc;

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    if (x >= pc.width || y >= pc.y1) {
        return;
    }
    vec4 value = fill_pattern(x, y, pc.view) * pc.weights.values[pc.view] + pc.frame_data.values[0];
    imageStore(images[pc.dst], ivec2(x, y), value);
}
