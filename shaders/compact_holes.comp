#version 460
// The `compact_holes` pass (parallax_passes::holes::CompactHolesKernel): appends every hole
// pixel (holes != 0) of rows [y0, y1) as x | y << 16 to the band's pixel list and keeps the
// band's header valid indirect arguments for a consumer that dispatches on them (pixel_list.glsl).
//
// One workgroup per 8x8-pixel tile compacts its holes locally (subgroup ballots, then a prefix
// over the subgroups in shared memory) and reserves room with a single atomic on the band's
// count, so the global atomics are one per tile with a hole rather than one per hole pixel.
// A tile's holes stay together in the list, so a subgroup of the hole-filling trace gets
// nearby pixels. The order of the tiles in the list depends on which workgroup reaches the
// atomic first and is not deterministic; nothing depends on it, because each traced pixel's
// path is a function of (pixel, view, frame) only (pt_trace.comp).
#extension GL_EXT_buffer_reference : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "pixel_list.glsl"

// The band's section of the list. The buffer is zeroed at every frame start, so the count
// starts at 0 and groups_y, groups_z must be written here too.
layout(buffer_reference, std430, buffer_reference_align = 4) buffer PixelList {
    uint groups_x;
    uint groups_y;
    uint groups_z;
    uint count;
    uint data[];
};

// 24 bytes; parallax_passes::shaders::CompactHolesPush, generated from this block.
layout(push_constant, std430) uniform CompactHolesPush {
    PixelList list; // the band's section: list address + y0 * row_bytes
    uint holes;     // R32_UINT image index (uimages[] of bindless.glsl)
    uint y0;
    uint y1;
    uint width;
} pc;

layout(local_size_x = 8, local_size_y = 8) in;

// Per subgroup: its hole count, then (after the prefix) its first slot within the tile's run.
shared uint subgroup_offset[64];
shared uint tile_base;

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    // Invocations outside the band still take part in the barriers below.
    bool hole = x < pc.width && y < pc.y1 && imageLoad(uimages[pc.holes], ivec2(x, y)).x != 0u;

    uvec4 ballot = subgroupBallot(hole);
    uint lane_offset = subgroupBallotExclusiveBitCount(ballot);
    if (subgroupElect()) {
        subgroup_offset[gl_SubgroupID] = subgroupBallotBitCount(ballot);
    }
    barrier();
    if (gl_LocalInvocationIndex == 0u) {
        uint total = 0u;
        for (uint s = 0u; s < gl_NumSubgroups; ++s) {
            uint n = subgroup_offset[s];
            subgroup_offset[s] = total;
            total += n;
        }
        if (total > 0u) {
            uint base = atomicAdd(pc.list.count, total);
            tile_base = base;
            // The final count is the largest `base + total` of all tiles, and the groups grow
            // with the count: the largest value wins whatever the order of the tiles.
            uvec2 groups = pixel_list_groups(base + total);
            atomicMax(pc.list.groups_x, groups.x);
            if (groups.y > 1u) {
                atomicMax(pc.list.groups_y, groups.y);
            }
        }
        // One tile gives every band its constant parts, holes or not (a band without holes
        // keeps groups_x = 0 and dispatches nothing).
        if (gl_WorkGroupID.xy == uvec2(0u)) {
            atomicMax(pc.list.groups_y, 1u);
            pc.list.groups_z = 1u;
        }
    }
    barrier();
    if (hole) {
        pc.list.data[tile_base + subgroup_offset[gl_SubgroupID] + lane_offset] = x | (y << 16u);
    }
}
