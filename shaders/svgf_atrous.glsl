// SVGF, steps 3–7 (`svgf_atrous_1` … `svgf_atrous_5`), included by the shaders of the first
// (svgf_atrous_first.comp), the middle (svgf_atrous.comp) and the last (svgf_atrous_last.comp)
// iteration, which define SVGF_ATROUS_FIRST and SVGF_ATROUS_LAST (0 or 1): one à-trous iteration (after Schied §4.3,
// with a 3×3 kernel: 9 taps instead of the 5×5 B3 spline's 25): a kernel h of 1/4, 1/2, 1/4 per
// axis with taps `step` pixels apart, each weighted by svgf_edge_weight (depth, normal,
// illumination luminance), as an energy-conserving exchange of illumination E between
// neighbours: per channel
//   E'_p = E_p + Σ_q h_pq w_pq (min(a_p, a_q) / a_p) (E_q − E_p)
// with a the effective albedo. The exchange between p and q is antisymmetric in radiance a·E
// (w is symmetric), so the view's radiance sum is exactly what it was, whatever the weights, the
// textures, the depth edges and the image border; a smooth illumination comes out unchanged; and
// E'_p is a weighted mean of E (the centre keeps 1 − Σ of the others' weights ≥ h_00 = 1/4 > 0).
// A normalised filter (Σ w L / Σ w) does neither: its rows sum to 1, not its columns, so pixels
// at depth edges, borders and beside dark albedo count less than others, and one whose
// jittered sample saw another texel or surface than its centre is divided by the wrong albedo:
// measured on Sponza at 96×54, −4 … −13 % per channel (docs/PIPELINE.md).
// Neighbours of low albedo in a channel move the pixel's illumination little (min(a_p, a_q) /
// a_p): a texel black in green tells nothing about green light. The variance is propagated with
// the squared weights (in luminance) and steers the next iteration. The first iteration blurs the
// variance over 3×3 (Gaussian 1-2-1, among pixels with a hit) before the weights use it, at the
// centre and the taps alike, and propagates the blurred variance.
//   in0: (illumination rgb, variance), in1 `svgf_guide`, in2 `svgf_albedo`: whole view
//   out0: (illumination rgb, variance), or on the last iteration `denoised`: a·E (alpha from
//   radiance)
//   out1 (first iteration): `svgf_color`, the colour history: (illumination rgb, length)
//   radiance (last iteration): own pixel, what pixels without a hit pass through
// The workgroup owns 8×8 pixels of one phase of the step (svgf_tile_base) and reads their taps
// into shared memory once (10×10: 4,800 bytes; the first, with the blur's ring, 12×12: 6,912
// bytes): 1.56 (2.25) reads of 3 texels per pixel instead of 27 (9 taps × 3 images) plus 9 for
// the blur. The steps are bound by the arithmetic of the taps, not by memory (docs/RESULTS.md,
// SVGF at the memory limit): the taps are unrolled, and what depends on the centre alone is
// computed once (svgf_edge_weight).
// Which iteration a shader runs is known when it compiles: the tile's size is a constant (no
// integer division by it when a tile entry is placed), and each shader has only its own work
// (the variance blur in the first; neither the propagated variance nor the blur in the last).
#ifndef PARALLAX_SVGF_ATROUS_GLSL
#define PARALLAX_SVGF_ATROUS_GLSL

#include "svgf.glsl"

const bool FIRST = SVGF_ATROUS_FIRST != 0;
const bool LAST = SVGF_ATROUS_LAST != 0;

// The tile's ring: the taps reach one step, the first iteration's variance blur one more.
const int HALO = FIRST ? 2 : 1;
const int SIZE = 8 + 2 * HALO;
// The blurred entries (all but the outer ring) per invocation, rounded up.
const int BLUR_ROUNDS = ((SIZE - 2) * (SIZE - 2) + 63) / 64;

// 48 bytes an entry: what a tap reads without converting in f32 (illumination, normal, depth),
// the rest in half floats (albedo, depth gradient: they only weigh) and the variance in f32.
shared vec4 tile_illumination[SIZE * SIZE]; // rgb, illumination luminance
shared vec4 tile_geometry[SIZE * SIZE];     // normal xyz (0: no hit or outside), depth
// half2 depth gradient, half2 albedo rg, half2 (albedo b, albedo luminance), variance the weights
// use (f32 bits)
shared uvec4 tile_packed[SIZE * SIZE];

// Entries an invocation reads, rounded up (10 × 10: two rounds of 64; the first's 12 × 12: three).
const int LOAD_ROUNDS = (SIZE * SIZE + 63) / 64;

// Reads the SIZE² entries origin + step * (i, j), row-major. Every round's texels are requested
// before the first is used, so an invocation's loads are in flight together and a workgroup waits
// for memory once, not once a round (a loop over the rounds, its bound known only at run time,
// waited for each round's loads before requesting the next's).
void load_tile(ivec2 origin, int step) {
    vec4 illumination[LOAD_ROUNDS];
    vec4 guide[LOAD_ROUNDS];
    vec3 albedo[LOAD_ROUNDS];
    [[unroll]] for (int k = 0; k < LOAD_ROUNDS; k++) {
        uint e = gl_LocalInvocationIndex + 64u * uint(k);
        ivec2 q = origin + step * ivec2(int(e % uint(SIZE)), int(e / uint(SIZE)));
        illumination[k] = vec4(0.0);
        guide[k] = vec4(0.0);
        albedo[k] = vec3(1.0);
        if (e < uint(SIZE * SIZE) && svgf_inside(q)) {
            illumination[k] = imageLoad(images[pc.in0], q);
            guide[k] = imageLoad(images[pc.in1], q);
            albedo[k] = imageLoad(images[pc.in2], q).rgb;
        }
    }
    [[unroll]] for (int k = 0; k < LOAD_ROUNDS; k++) {
        uint e = gl_LocalInvocationIndex + 64u * uint(k);
        if (e >= uint(SIZE * SIZE)) {
            continue;
        }
        bool hit = guide[k].x > 0.0;
        float l = hit ? svgf_illumination_luminance(illumination[k].rgb * albedo[k], albedo[k]) : 0.0;
        tile_illumination[e] = vec4(illumination[k].rgb, l);
        tile_geometry[e] = vec4(hit ? svgf_unpack_normal(guide[k].w) : vec3(0.0), hit ? guide[k].x : 0.0);
        tile_packed[e] = uvec4(packHalf2x16(guide[k].yz), packHalf2x16(albedo[k].rg),
                               packHalf2x16(vec2(albedo[k].b, svgf_luminance(albedo[k]))),
                               floatBitsToUint(illumination[k].a));
    }
}

float variance_of(int e) {
    return uintBitsToFloat(tile_packed[e].w);
}

// The first iteration: the 3×3-blurred variance of the entries inside the outer ring.
void blur_tile() {
    const float g[2] = float[2](0.5, 0.25);
    const int inner = SIZE - 2;
    float blurred[BLUR_ROUNDS];
    for (int k = 0; k < BLUR_ROUNDS; k++) {
        int i = int(gl_LocalInvocationIndex) + 64 * k;
        blurred[k] = 0.0;
        if (i >= inner * inner) {
            continue;
        }
        int e = (i / inner + 1) * SIZE + i % inner + 1;
        float sum = 0.0;
        float weight = 0.0;
        for (int dy = -1; dy <= 1; dy++) {
            for (int dx = -1; dx <= 1; dx++) {
                int q = e + dy * SIZE + dx;
                if (tile_geometry[q].w > 0.0) {
                    float w = g[abs(dx)] * g[abs(dy)];
                    sum += w * variance_of(q);
                    weight += w;
                }
            }
        }
        blurred[k] = weight > 0.0 ? sum / weight : 0.0;
    }
    barrier();
    for (int k = 0; k < BLUR_ROUNDS; k++) {
        int i = int(gl_LocalInvocationIndex) + 64 * k;
        if (i < inner * inner) {
            tile_packed[(i / inner + 1) * SIZE + i % inner + 1].w = floatBitsToUint(blurred[k]);
        }
    }
}

// The centre pixel's share of every tap's weight, computed once (svgf_edge_weight).
vec3 centre_illumination;
float centre_luminance;
vec3 centre_normal;
float centre_depth;
float centre_variance;
vec3 centre_albedo;
float inverse_albedo_luminance;
float spacing;
// Sums over the taps, per channel u_q = h w_pq min(a_p, a_q): Σ u_q E_q and Σ u_q, from which
// the change of the illumination is (Σ u_q E_q − E_p Σ u_q) / a_p (the exchange above, with one
// division per pixel instead of a product, a minimum and a difference per tap); the shares
// (luminance) and the propagated variance.
vec3 exchanged;
vec3 exchange_weight;
float share_sum;
float variance_sum;

// Exchanges with the tap in entry e of kernel weight h, one step along ±direction, whose centre
// part of the depth scale is reach_p (svgf_depth_reach). Taps without a hit have a zero normal:
// the normal test drops them.
void tap(int e, float h, vec2 direction, float reach_p) {
    vec4 geometry_q = tile_geometry[e];
    float d = dot(centre_normal, geometry_q.xyz);
    if (!(d > 0.0)) {
        return;
    }
    vec4 illumination_q = tile_illumination[e];
    uvec4 packed_q = tile_packed[e];
    vec2 blue_luminance_q = unpackHalf2x16(packed_q.z);
    vec3 albedo_q = vec3(unpackHalf2x16(packed_q.y), blue_luminance_q.x);
    float v_q = uintBitsToFloat(packed_q.w);
    float reach_q = svgf_depth_reach(geometry_q.w, unpackHalf2x16(packed_q.x), direction, spacing);
    float w = h * svgf_edge_weight(d, centre_depth, geometry_q.w, reach_p + reach_q, centre_luminance,
                                   illumination_q.w, centre_variance, v_q);
    vec3 u = w * min(centre_albedo, albedo_q);
    exchanged += u * illumination_q.rgb;
    exchange_weight += u;
    float share = w * min(1.0, blue_luminance_q.y * inverse_albedo_luminance);
    share_sum += share;
    variance_sum += share * share * v_q;
}

// Where an iteration puts pixel p without a hit: its texel as is, which the temporal pass made
// the pixel's radiance (on a still camera, its running mean, so the sky converges too); the last
// iteration takes the alpha of the radiance image.
void pass_through(ivec2 p, vec4 texel) {
    if (LAST) {
        texel.a = imageLoad(images[pc.radiance], p).a;
    }
    imageStore(images[pc.out0], p, texel);
}

void main() {
    int step = int(pc.step);
    ivec2 base = svgf_tile_base(pc.step);
    load_tile(base - step * ivec2(HALO), step);
    barrier();
    if (FIRST) {
        blur_tile();
        barrier();
    }
    ivec2 p = base + step * ivec2(gl_LocalInvocationID.xy);
    if (!svgf_in_band(p)) {
        return;
    }
    int c = (int(gl_LocalInvocationID.y) + HALO) * SIZE + int(gl_LocalInvocationID.x) + HALO;
    vec4 centre = tile_illumination[c];
    vec4 geometry = tile_geometry[c];
    if (!(geometry.w > 0.0)) {
        pass_through(p, vec4(centre.rgb, 0.0));
        if (FIRST) {
            imageStore(images[pc.out1], p, vec4(0.0));
        }
        return;
    }
    uvec4 packed = tile_packed[c];
    vec2 gradient = unpackHalf2x16(packed.x);
    vec2 blue_luminance = unpackHalf2x16(packed.z);
    vec3 albedo = vec3(unpackHalf2x16(packed.y), blue_luminance.x);
    centre_illumination = centre.rgb;
    centre_luminance = centre.w;
    centre_normal = geometry.xyz;
    centre_depth = geometry.w;
    centre_variance = uintBitsToFloat(packed.w);
    centre_albedo = albedo;
    inverse_albedo_luminance = 1.0 / blue_luminance.y;
    spacing = float(step);
    exchanged = vec3(0.0);
    exchange_weight = vec3(0.0);
    share_sum = 0.0;
    variance_sum = 0.0;
    // The four directions of the taps (the depth scale takes |gradient · direction|).
    const vec2 ACROSS = vec2(1.0, 0.0);
    const vec2 DOWN = vec2(0.0, 1.0);
    const vec2 DIAGONAL = vec2(1.0, 1.0);
    const vec2 ANTIDIAGONAL = vec2(1.0, -1.0);
    float reach_across = svgf_depth_reach(centre_depth, gradient, ACROSS, spacing);
    float reach_down = svgf_depth_reach(centre_depth, gradient, DOWN, spacing);
    float reach_diagonal = svgf_depth_reach(centre_depth, gradient, DIAGONAL, spacing);
    float reach_antidiagonal = svgf_depth_reach(centre_depth, gradient, ANTIDIAGONAL, spacing);
    const float EDGE = KERNEL[0] * KERNEL[1];
    const float CORNER = KERNEL[1] * KERNEL[1];
    tap(c - SIZE - 1, CORNER, DIAGONAL, reach_diagonal);
    tap(c - SIZE, EDGE, DOWN, reach_down);
    tap(c - SIZE + 1, CORNER, ANTIDIAGONAL, reach_antidiagonal);
    tap(c - 1, EDGE, ACROSS, reach_across);
    tap(c + 1, EDGE, ACROSS, reach_across);
    tap(c + SIZE - 1, CORNER, ANTIDIAGONAL, reach_antidiagonal);
    tap(c + SIZE, EDGE, DOWN, reach_down);
    tap(c + SIZE + 1, CORNER, DIAGONAL, reach_diagonal);
    vec3 change = (exchanged - exchange_weight * centre_illumination) / albedo;
    vec3 illumination = min(max(centre_illumination + change, vec3(0.0)), vec3(MAX_VALUE));
    float kept = max(0.0, 1.0 - share_sum);
    float variance = min(variance_sum + kept * kept * centre_variance, MAX_VALUE);
    if (LAST) {
        imageStore(images[pc.out0], p, vec4(albedo * illumination, imageLoad(images[pc.radiance], p).a));
        return;
    }
    imageStore(images[pc.out0], p, vec4(illumination, variance));
    if (FIRST) {
        imageStore(images[pc.out1], p, vec4(illumination, imageLoad(images[pc.in2], p).a));
    }
}

#endif
