#version 460
// The `compact_holes` pass of subsampled hole filling (parallax_passes::hole_subsample,
// `--hole-fill subsampled`): splits the hole pixels of rows [y0, y1) into the ones path traced
// this frame (the band's `hole_list`, which `hole_fill` traces as under `full`) and the ones
// reconstructed from traced neighbours (`hole_reconstruct_list`), and writes each pixel's
// choice to `hole_sampling` (hole_subsample.glsl) for the reconstruction.
//
// The hole pixels with a hit of each aligned 2x2 block take turns by frame: of its m such
// pixels (in raster order within the block) the one of rank frame_index mod m is traced, so a
// still camera traces every hole pixel within 4 frames and a block of one is always traced.
// Every other hole pixel is reconstructed only where one of its 8 neighbours is such a turn's
// traced pixel on the same surface (hole_similarity > 0); else it is traced too: an isolated
// hole, a pixel of a thin feature, a sky pixel on a silhouette (no hit, never similar). The
// choice is a function of the holes mask, the G-buffer and the frame index only, so bands of
// several devices agree on it: the pass reads 2 rows beyond its band (a neighbour's block).
// Both lists are appended one atomic per tile (pixel_list_append.glsl).
#extension GL_EXT_buffer_reference : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "hole_subsample.glsl"

// A band's section of a list. The buffer is zeroed at every frame start, so the count starts
// at 0 and groups_y, groups_z must be written here too.
layout(buffer_reference, std430, buffer_reference_align = 4) buffer PixelList {
    uint groups_x;
    uint groups_y;
    uint groups_z;
    uint count;
    uint data[];
};

#include "pixel_list_append.glsl"

// 48 bytes; parallax_passes::shaders::CompactHolesSubsampledPush, generated from this block.
layout(push_constant, std430) uniform CompactHolesSubsampledPush {
    PixelList traced;        // the band's section of `hole_list`
    PixelList reconstructed; // the band's section of `hole_reconstruct_list`
    uint holes;              // R32u mask (uimages[])
    uint position_depth;     // G-buffer layers (images[]), read 2 rows beyond the band
    uint normal_metallic;
    uint sampling;           // R32u, written over the band (uimages[])
    uint y0;
    uint y1;
    uint width;
    uint height;
} pc;

layout(local_size_x = 8, local_size_y = 8) in;

bool inside(ivec2 q) {
    return q.x >= 0 && q.y >= 0 && q.x < int(pc.width) && q.y < int(pc.height);
}

// A hole pixel whose centre ray hit a surface: the pixels that take turns.
bool surface_hole(ivec2 q) {
    return inside(q) && imageLoad(uimages[pc.holes], q).x != 0u && imageLoad(images[pc.position_depth], q).w > 0.0;
}

// Whether surface hole q is its 2x2 block's turn this frame.
bool turn_traced(ivec2 q) {
    ivec2 block = q & ~ivec2(1);
    uint count = 0u;
    uint rank = 0u;
    for (int i = 0; i < 4; ++i) {
        ivec2 c = block + ivec2(i & 1, i >> 1);
        if (surface_hole(c)) {
            rank = c == q ? count : rank;
            ++count;
        }
    }
    return rank == frame.frame_index % count;
}

// Whether surface hole p has a neighbour traced by its block's turn on the same surface.
bool has_similar_turn(ivec2 p) {
    vec4 position = imageLoad(images[pc.position_depth], p);
    vec3 normal = imageLoad(images[pc.normal_metallic], p).xyz;
    for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
            ivec2 q = p + ivec2(dx, dy);
            if ((dx != 0 || dy != 0) && surface_hole(q) && turn_traced(q)) {
                vec4 position_q = imageLoad(images[pc.position_depth], q);
                vec3 normal_q = imageLoad(images[pc.normal_metallic], q).xyz;
                if (hole_similarity(position, normal, position_q, normal_q) > 0.0) {
                    return true;
                }
            }
        }
    }
    return false;
}

uint sampling_of(ivec2 p) {
    if (imageLoad(uimages[pc.holes], p).x == 0u) {
        return HOLE_NONE;
    }
    bool reconstructed = surface_hole(p) && !turn_traced(p) && has_similar_turn(p);
    return reconstructed ? HOLE_RECONSTRUCTED : HOLE_TRACED;
}

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    // Invocations outside the band still take part in the appends' barriers.
    bool in_band = x < pc.width && y < pc.y1;
    uint sampling = in_band ? sampling_of(ivec2(x, y)) : HOLE_NONE;
    if (in_band) {
        imageStore(uimages[pc.sampling], ivec2(x, y), uvec4(sampling));
    }
    pixel_list_append(pc.traced, sampling == HOLE_TRACED, x, y);
    pixel_list_append(pc.reconstructed, sampling == HOLE_RECONSTRUCTED, x, y);
}
