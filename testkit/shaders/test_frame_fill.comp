#version 460
// Test kernel of the frame loop and of per-pass frame-data sections: the R32_UINT image dst gets
// hash3(x, y, 8 * frame_index + view) ^ salt, where frame_index is the executor's frame constant
// and salt comes from the pass's own section of the per-frame data.
#extension GL_EXT_buffer_reference : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "frame_block.glsl"
#include "hash.glsl"

layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer FillSection {
    uint salt;
};

layout(push_constant, std430) uniform FrameFillParams {
    uint dst;
    uint view;
    uint width;
    uint height;
    FrameBlock block;
    FillSection section;
} pc;

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    uvec2 p = gl_GlobalInvocationID.xy;
    if (p.x >= pc.width || p.y >= pc.height) {
        return;
    }
    uint value = hash3(p.x, p.y, 8u * frame.frame_index + pc.view) ^ pc.section.salt;
    imageStore(uimages[pc.dst], ivec2(p), uvec4(value));
}
