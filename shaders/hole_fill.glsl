// The target table of one `hole_fill` op (parallax_passes::hole_fill): every target band of the
// op with its hole list, its view's TraceParams and its radiance image, then what
// hole_fill_prefix.comp counts each frame. hole_fill_prefix.comp writes it, hole_fill.comp
// reads it. Layouts: parallax_passes::hole_fill::{HoleFillTarget, TABLE_HEADER_BYTES}.
#ifndef PARALLAX_HOLE_FILL_GLSL
#define PARALLAX_HOLE_FILL_GLSL

#include "pt_types.glsl"

// Invocations per workgroup of hole_fill.comp: a workgroup traces entries of one target only.
const uint HOLE_FILL_GROUP = 64u;

// A band's section of the `hole_list` row buffer (compact_holes.comp writes it).
layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer HoleList {
    uint groups_x;
    uint groups_y;
    uint groups_z;
    uint count;
    uint data[];
};

// 32 bytes.
struct HoleFillTarget {
    HoleList list;        // host, at record time
    TraceParamsRef trace; // host: the view's TraceParams in this slot's per-frame data
    uint radiance;        // host: image index of the radiance (images[] of bindless.glsl)
    uint first_group;     // prefix: workgroups of the targets before this one
    uint count;           // prefix: the list's count this frame
    uint first_hit;       // host: image index of the view's `first_hit` layer (uimages[]), or ~0u
};

layout(buffer_reference, std430, buffer_reference_align = 8) buffer HoleFillTable {
    // Indirect arguments of hole_fill.comp covering `groups` workgroups, folded into rows of
    // at most 65535 (the one-axis limit every device supports).
    uint groups_x;
    uint groups_y;
    uint groups_z;
    uint groups;
    HoleFillTarget targets[];
};

#endif
