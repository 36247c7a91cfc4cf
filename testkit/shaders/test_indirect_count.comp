#version 460
// Test kernel of indirect dispatch, dispatched on the arguments test_indirect_args wrote: every
// invocation below args.count adds one to the counter (reset to zero each frame), so the
// counter equals the count exactly when the dispatch covered it.
#extension GL_EXT_buffer_reference : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"

layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer IndirectArgs {
    uint groups_x;
    uint groups_y;
    uint groups_z;
    uint count;
};

layout(buffer_reference, std430, buffer_reference_align = 4) buffer Counter {
    uint value;
};

layout(push_constant, std430) uniform IndirectCountParams {
    IndirectArgs args;
    Counter counter;
} pc;

layout(local_size_x = 64) in;

void main() {
    if (gl_GlobalInvocationID.x < pc.args.count) {
        atomicAdd(pc.counter.value, 1u);
    }
}
