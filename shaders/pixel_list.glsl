// Pixel lists (parallax_passes::pixel_list): per band, a header that is at once indirect
// dispatch arguments covering the list (groups_x, groups_y, groups_z) and its length (count),
// then `count` entries of x | y << 16. pt_trace.comp dispatches the capacity and stops at count. Each list shader declares the buffer
// with the qualifiers it needs; this is the part they share.
#ifndef PARALLAX_PIXEL_LIST_GLSL
#define PARALLAX_PIXEL_LIST_GLSL

// Invocations per workgroup of the kernels that consume a list (pt_trace.comp).
const uint PIXEL_LIST_GROUP = 64u;
// Workgroups along one axis that every Vulkan device supports.
const uint PIXEL_LIST_MAX_GROUPS = 65535u;

// The workgroups (x, y) covering `count` entries at PIXEL_LIST_GROUP per group: one row of
// ceil(count / 64) groups, folded into more rows only beyond PIXEL_LIST_MAX_GROUPS (4.19M
// entries). Both components grow with `count`, so concurrent producers may combine them with
// atomicMax. x = 0 (nothing to trace) dispatches nothing whatever y is.
uvec2 pixel_list_groups(uint count) {
    uint groups = (count + PIXEL_LIST_GROUP - 1u) / PIXEL_LIST_GROUP;
    return uvec2(min(groups, PIXEL_LIST_MAX_GROUPS), max(1u, (groups + PIXEL_LIST_MAX_GROUPS - 1u) / PIXEL_LIST_MAX_GROUPS));
}

#endif
