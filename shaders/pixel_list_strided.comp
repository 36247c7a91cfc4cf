#version 460
// The `pixel_list` demo pass (parallax_passes::pixel_list::StridedPixelListKernel): writes the
// compacted list of every `stride`-th pixel of a view (row-major index = phase + k * stride)
// into a per-view buffer as the path tracer's list mode reads it: word 0 = count, then
// x | y << 16. A deterministic stand-in for the hole compaction of reprojection.
#extension GL_EXT_buffer_reference : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"

layout(buffer_reference, std430, buffer_reference_align = 4) writeonly buffer PixelList {
    uint count;
    uint data[];
};

layout(push_constant, std430) uniform StridedListParams {
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
        pc.list.count = count;
    }
    if (k < count) {
        uint l = pc.phase + k * pc.stride;
        pc.list.data[k] = (l % pc.width) | ((l / pc.width) << 16u);
    }
}
