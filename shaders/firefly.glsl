// Shared by the firefly kernels (parallax_passes::firefly): the push-constant block and the
// neighbourhood both passes agree on.
//
// Suppression is energy-conserving: where a pixel's luminance exceeds a bound from its
// neighbourhood's statistics (firefly_bound.comp), the pixel keeps the bound and its excess is
// shared equally among its neighbours with a hit; every neighbour with a hit gathers the
// shares of the donors around it (firefly_spread.comp). "q is a neighbour of p" is symmetric
// (both have a hit, |dx|, |dy| <= FIREFLY_RADIUS, both in the view), so each donor's excess is
// received exactly once: a view's per-channel sum is unchanged up to f32 rounding, borders
// included. Where the neighbourhood's expected radiance is uniform, each pixel gives and
// receives the same expected excess: the bias of a pixel's mean is bounded by how much the
// expected excess varies across its neighbourhood, and the image mean has none.
//
// The bound grows with sqrt(n) while the camera stands still (n: frames in SVGF's running mean
// including this one): a sample may pull the mean of n frames by at most k standard deviations
// of its neighbourhood over sqrt(n), the standard error of that mean, so suppression fades as
// the mean converges and the still image converges to the unsuppressed one.
#ifndef PARALLAX_FIREFLY_GLSL
#define PARALLAX_FIREFLY_GLSL

#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "frame_block.glsl"

// 64 bytes; parallax_passes::shaders::FireflyPush, generated from this block.
layout(push_constant, std430) uniform FireflyPush {
    uint radiance; // Rgba32f; bound: read with the halo; spread: read and written in place
    uint position; // position_depth: w = 0 is no hit
    uint share;    // Rgba32f: (excess rgb / receivers, kept fraction); bound writes, spread reads
    uint y0;
    uint y1;
    uint width;
    uint height;
    // Bound = mean + k * sqrt(n) * standard deviation of the neighbours' luminance, n the
    // frames of the still camera's running mean this frame's sample joins.
    float k;
    // Fewest neighbours with a hit a pixel needs to be judged (and to share its excess).
    uint min_neighbours;
    // Bound only: R32f images of n, last frame's (history) and this frame's.
    uint frames_before;
    uint frames;
    // Bound only: the view whose cameras in `block` tell a still camera, and whether `block`
    // holds them (FIREFLY_CAMERAS; without, every frame is a first one).
    uint view;
    uint flags;
    uint pad;
    FrameBlock block;
} pc;

const uint FIREFLY_CAMERAS = 1u;

const int FIREFLY_GROUP = 8;
layout(local_size_x = FIREFLY_GROUP, local_size_y = FIREFLY_GROUP) in;

// 5x5: 24 neighbours, enough for a standard deviation; a firefly's energy spreads over 2 px.
const int FIREFLY_RADIUS = 2;

// Both passes read their 5x5 windows from a shared-memory tile: the group's 8x8 pixels and a
// FIREFLY_RADIUS apron, each texel loaded from memory once per group (144 loads for 64 pixels)
// instead of once per tap (25 per pixel). The windows' arithmetic is unchanged, tap for tap.
const int FIREFLY_TILE = FIREFLY_GROUP + 2 * FIREFLY_RADIUS;
const uint FIREFLY_TILE_TEXELS = uint(FIREFLY_TILE * FIREFLY_TILE);

bool firefly_in_view(ivec2 p) {
    return p.x >= 0 && p.y >= 0 && p.x < int(pc.width) && p.y < int(pc.height);
}

// The image texel of the tile's top-left corner (apron included).
ivec2 firefly_tile_origin() {
    return ivec2(gl_WorkGroupID.xy) * FIREFLY_GROUP + ivec2(0, int(pc.y0)) - FIREFLY_RADIUS;
}

// The image texel the tile's texel i holds.
ivec2 firefly_tile_texel(uint i) {
    return firefly_tile_origin() + ivec2(int(i % uint(FIREFLY_TILE)), int(i / uint(FIREFLY_TILE)));
}

// Whether a tile texel is one this pass may read: in the view and within the rows it declared
// (its band and a FIREFLY_RADIUS halo). The group's last rows may pass y1; their windows are
// never used, and their apron is left unread.
bool firefly_tile_readable(ivec2 q) {
    return firefly_in_view(q) && q.y >= int(pc.y0) - FIREFLY_RADIUS && q.y < int(pc.y1) + FIREFLY_RADIUS;
}

// Where image texel q (within FIREFLY_RADIUS of the group's pixels) is in the tile.
uint firefly_tile_index(ivec2 q) {
    ivec2 t = q - firefly_tile_origin();
    return uint(t.y * FIREFLY_TILE + t.x);
}

bool firefly_hit(ivec2 p) {
    return imageLoad(images[pc.position], p).w != 0.0;
}

float firefly_luminance(vec3 c) {
    return dot(c, vec3(0.2126, 0.7152, 0.0722));
}

#endif
