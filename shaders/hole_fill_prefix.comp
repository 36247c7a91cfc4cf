#version 460
// First dispatch of a `hole_fill` op (parallax_passes::hole_fill::HoleFillKernel): one
// workgroup sums the hole lists of the op's targets into workgroups of HOLE_FILL_GROUP entries,
// each target starting a workgroup of its own, and writes each target's first workgroup and
// count and the indirect arguments of hole_fill.comp into the table (hole_fill.glsl).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "hole_fill.glsl"

// 16 bytes; parallax_passes::shaders::HoleFillPrefixPush, generated from this block.
layout(push_constant, std430) uniform HoleFillPrefixPush {
    HoleFillTable table;
    uint target_count;
    uint pad;
} pc;

const uint SCAN = 64u;
layout(local_size_x = SCAN) in;

// Inclusive prefix sums of one chunk of SCAN targets' workgroups.
shared uint scan[SCAN];

void main() {
    uint lane = gl_LocalInvocationIndex;
    // Workgroups of the chunks before (the same in every invocation).
    uint before = 0u;
    for (uint base = 0u; base < pc.target_count; base += SCAN) {
        uint t = base + lane;
        uint count = t < pc.target_count ? pc.table.targets[t].list.count : 0u;
        uint groups = (count + HOLE_FILL_GROUP - 1u) / HOLE_FILL_GROUP;
        scan[lane] = groups;
        barrier();
        // Hillis-Steele: after the step of `width`, scan[i] sums groups[i - 2 * width + 1 ..= i].
        for (uint width = 1u; width < SCAN; width <<= 1u) {
            uint left = lane >= width ? scan[lane - width] : 0u;
            barrier();
            scan[lane] += left;
            barrier();
        }
        if (t < pc.target_count) {
            pc.table.targets[t].first_group = before + scan[lane] - groups;
            pc.table.targets[t].count = count;
        }
        before += scan[SCAN - 1u];
        // Every invocation has read scan[SCAN - 1] before the next chunk overwrites it.
        barrier();
    }
    if (lane == 0u) {
        pc.table.groups = before;
        pc.table.groups_x = min(before, 65535u);
        pc.table.groups_y = (before + 65534u) / 65535u; // 0 without holes: nothing dispatched
        pc.table.groups_z = 1u;
    }
}
