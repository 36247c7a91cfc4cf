// Appending an 8x8 workgroup's pixels to a band's pixel list (pixel_list.glsl), for the
// compaction shaders (compact_holes.comp, compact_holes_subsampled.comp). Each includer
// declares `PixelList` (the band's section, the buffer zeroed at every frame start).
//
// The workgroup compacts its members locally (subgroup ballots, then a prefix over the
// subgroups in shared memory) and reserves room with a single atomic on the band's count, so
// the global atomics are one per tile with a member rather than one per pixel. A tile's
// members stay together in the list, so a subgroup of a consumer gets nearby pixels. The order
// of the tiles in the list depends on which workgroup reaches the atomic first and is not
// deterministic; nothing depends on it, because each listed pixel's result is a function of
// the pixel, its view and the frame only.
#ifndef PARALLAX_PIXEL_LIST_APPEND_GLSL
#define PARALLAX_PIXEL_LIST_APPEND_GLSL

#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
#include "pixel_list.glsl"

// Per subgroup: its member count, then (after the prefix) its first slot within the tile's run.
shared uint append_subgroup_offset[64];
shared uint append_tile_base;

// Appends x | y << 16 of every invocation with `member` to `list` and keeps its header valid
// indirect arguments. Called by every invocation of the workgroup (it has barriers).
void pixel_list_append(PixelList list, bool member, uint x, uint y) {
    uvec4 ballot = subgroupBallot(member);
    uint lane_offset = subgroupBallotExclusiveBitCount(ballot);
    if (subgroupElect()) {
        append_subgroup_offset[gl_SubgroupID] = subgroupBallotBitCount(ballot);
    }
    barrier();
    if (gl_LocalInvocationIndex == 0u) {
        uint total = 0u;
        for (uint s = 0u; s < gl_NumSubgroups; ++s) {
            uint n = append_subgroup_offset[s];
            append_subgroup_offset[s] = total;
            total += n;
        }
        if (total > 0u) {
            uint base = atomicAdd(list.count, total);
            append_tile_base = base;
            // The final count is the largest `base + total` of all tiles, and the groups grow
            // with the count: the largest value wins whatever the order of the tiles.
            uvec2 groups = pixel_list_groups(base + total);
            atomicMax(list.groups_x, groups.x);
            if (groups.y > 1u) {
                atomicMax(list.groups_y, groups.y);
            }
        }
        // One tile gives every band its constant parts, members or not (a band without any
        // keeps groups_x = 0 and dispatches nothing).
        if (gl_WorkGroupID.xy == uvec2(0u)) {
            atomicMax(list.groups_y, 1u);
            list.groups_z = 1u;
        }
    }
    barrier();
    if (member) {
        list.data[append_tile_base + append_subgroup_offset[gl_SubgroupID] + lane_offset] = x | (y << 16u);
    }
    // The shared words are reused by the next call.
    barrier();
}

#endif
