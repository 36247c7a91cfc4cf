#version 460
// The `compact_holes` pass (parallax_passes::holes::CompactHolesKernel): appends every hole
// pixel (holes != 0) of rows [y0, y1) as x | y << 16 to the band's pixel list and keeps the
// band's header valid indirect arguments for a consumer that dispatches on them (pixel_list.glsl).
//
// One workgroup per 8x8-pixel tile appends its holes with one atomic (pixel_list_append.glsl).
#extension GL_EXT_buffer_reference : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"

// The band's section of the list. The buffer is zeroed at every frame start, so the count
// starts at 0 and groups_y, groups_z must be written here too.
layout(buffer_reference, std430, buffer_reference_align = 4) buffer PixelList {
    uint groups_x;
    uint groups_y;
    uint groups_z;
    uint count;
    uint data[];
};

#include "pixel_list_append.glsl"

// 24 bytes; parallax_passes::shaders::CompactHolesPush, generated from this block.
layout(push_constant, std430) uniform CompactHolesPush {
    PixelList list; // the band's section: list address + y0 * row_bytes
    uint holes;     // R32_UINT image index (uimages[] of bindless.glsl)
    uint y0;
    uint y1;
    uint width;
} pc;

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    // Invocations outside the band still take part in the append's barriers.
    bool hole = x < pc.width && y < pc.y1 && imageLoad(uimages[pc.holes], ivec2(x, y)).x != 0u;
    pixel_list_append(pc.list, hole, x, y);
}
