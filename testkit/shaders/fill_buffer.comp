#version 460
// Test kernel for per-view buffer resources: words[i] = hash3(i, 0, view) for every word
// of the buffer (reached by address).
#extension GL_EXT_buffer_reference : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "hash.glsl"

layout(buffer_reference, std430, buffer_reference_align = 4) writeonly buffer Words {
    uint words[];
};

layout(push_constant, std430) uniform FillBufferParams {
    uint view;
    uint count;
    Words target;
} pc;

layout(local_size_x = 64) in;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i < pc.count) {
        pc.target.words[i] = hash3(i, 0u, pc.view);
    }
}
