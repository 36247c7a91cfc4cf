#version 460
// Test kernel of indirect dispatch, one workgroup: the 64 invocations sum
// hash3(i, frame_index, salt) % 32 into N and add it to args.count; invocation 0 then sets
// args.groups_x = ceil(count / 64). groups_y, groups_z and count start each frame from the
// buffer's reset header (0, 1, 1, 0), so a missing reset shows up as a count that grows.
#extension GL_EXT_buffer_reference : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "hash.glsl"

layout(buffer_reference, std430, buffer_reference_align = 4) buffer IndirectArgs {
    uint groups_x;
    uint groups_y;
    uint groups_z;
    uint count;
};

layout(push_constant, std430) uniform IndirectArgsParams {
    IndirectArgs args;
    uint salt;
    uint pad; // rounds the block to its 8-byte alignment, as the Rust struct is
} pc;

layout(local_size_x = 64) in;

shared uint total;

void main() {
    if (gl_LocalInvocationIndex == 0) {
        total = 0;
    }
    barrier();
    atomicAdd(total, hash3(gl_LocalInvocationIndex, frame.frame_index, pc.salt) % 32u);
    barrier();
    if (gl_LocalInvocationIndex == 0) {
        uint count = atomicAdd(pc.args.count, total) + total;
        pc.args.groups_x = (count + 63u) / 64u;
    }
}
