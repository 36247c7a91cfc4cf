#version 460
// The `pixel_list` test pass (parallax_passes::pixel_list::StridedPixelListKernel): writes the
// list of every `stride`-th pixel of a view (row-major index = phase + k * stride) into a
// per-view buffer as one band's pixel list (pixel_list.glsl): the header with the indirect
// arguments and count, then x | y << 16. A deterministic stand-in for hole compaction.
#extension GL_EXT_buffer_reference : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "pixel_list.glsl"

layout(buffer_reference, std430, buffer_reference_align = 4) writeonly buffer PixelList {
    uint groups_x;
    uint groups_y;
    uint groups_z;
    uint count;
    uint data[];
};

// 32 bytes; parallax_passes::shaders::StridedListPush, generated from this block.
layout(push_constant, std430) uniform StridedListPush {
    uint width;
    uint height;
    uint stride;
    uint phase;
    uint capacity; // entries the buffer holds
    uint pad;
    PixelList list;
} pc;

layout(local_size_x = 64) in;

void main() {
    uint k = gl_GlobalInvocationID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
    uint n = pc.width * pc.height;
    uint count = pc.phase < n ? min((n - pc.phase + pc.stride - 1u) / pc.stride, pc.capacity) : 0u;
    if (k == 0u) {
        uvec2 groups = pixel_list_groups(count);
        pc.list.groups_x = groups.x;
        pc.list.groups_y = groups.y;
        pc.list.groups_z = 1u;
        pc.list.count = count;
    }
    if (k < count) {
        uint l = pc.phase + k * pc.stride;
        pc.list.data[k] = (l % pc.width) | ((l / pc.width) << 16u);
    }
}
