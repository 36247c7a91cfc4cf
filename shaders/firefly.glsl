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

// 64 bytes; parallax_passes::firefly::FireflyPush (a test holds the layouts together).
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

layout(local_size_x = 8, local_size_y = 8) in;

// 5x5: 24 neighbours, enough for a standard deviation; a firefly's energy spreads over 2 px.
const int FIREFLY_RADIUS = 2;

bool firefly_in_view(ivec2 p) {
    return p.x >= 0 && p.y >= 0 && p.x < int(pc.width) && p.y < int(pc.height);
}

bool firefly_hit(ivec2 p) {
    return imageLoad(images[pc.position], p).w != 0.0;
}

float firefly_luminance(vec3 c) {
    return dot(c, vec3(0.2126, 0.7152, 0.0722));
}

#endif
