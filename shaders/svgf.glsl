// Shared by the SVGF kernels (parallax_passes::svgf, after Schied et al. 2017): the push-constant
// block, the packed guide texel, the edge-stopping weights, the workgroup tiles and the guards
// that keep every value finite.
//
// Units: the images of the chain hold illumination E = radiance / a, with a the effective
// albedo (svgf_effective_albedo), per channel; the last à-trous iteration writes a·E. Nothing
// divides one pixel's radiance by another's albedo, and the à-trous iterations exchange E so that
// the radiance a·E of a view is conserved (svgf_atrous.glsl; docs/PIPELINE.md, SVGF, for the
// measurements behind it).
#ifndef PARALLAX_SVGF_GLSL
#define PARALLAX_SVGF_GLSL

#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "frame_block.glsl"

// 96 bytes; parallax_passes::shaders::SvgfPush, generated from this block. Image
// indices into images[]; what in0..in3 and out0..out3 hold depends on the kernel (see its
// header). Rows [y0, y1) are the instance's band; every read with a footprint may touch any row.
layout(push_constant, std430) uniform SvgfPush {
    uint radiance;
    uint albedo;   // albedo_roughness
    uint normal;   // normal_metallic
    uint position; // position_depth
    uint motion;
    uint in0;
    uint in1;
    uint in2;
    uint in3;
    uint out0;
    uint out1;
    uint out2;
    uint out3;
    uint y0;
    uint y1;
    uint width;
    uint height;
    uint step;  // à-trous: tap spacing in pixels
    uint flags; // temporal: SVGF_CAMERAS
    // Temporal only: the accumulation histories' outputs, and the view and frame block whose
    // cameras tell a still camera (svgf_temporal.comp, accumulation).
    uint out4;
    uint out5;
    uint view;
    FrameBlock block;
} pc;

const uint SVGF_CAMERAS = 4u; // temporal: `block` holds the cameras (without, no frame is still)

layout(local_size_x = 8, local_size_y = 8) in;

// Values are clamped here: squares and tap sums then stay far below the f32 range.
const float MAX_VALUE = 1e8;
// Added to every albedo channel before anything divides by it or weighs with it: a black channel
// still has a finite illumination (an emitter on a black base keeps its radiance).
const float ALBEDO_FLOOR = 1e-3;
// À-trous luminance edge-stopping (Schied: σ_l = 4).
const float SIGMA_L = 4.0;
// The 3×3 kernel of the à-trous iterations, per axis (centre, neighbour).
const float KERNEL[2] = float[2](1.0 / 2.0, 1.0 / 4.0);

// The pixel this invocation owns in the row-major layout of 8×8 tiles over the band, or
// ivec2(-1) outside the band.
ivec2 svgf_pixel() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    return (x >= pc.width || y >= pc.y1) ? ivec2(-1) : ivec2(x, y);
}

bool svgf_inside(ivec2 p) {
    return p.x >= 0 && p.y >= 0 && p.x < int(pc.width) && p.y < int(pc.height);
}

bool svgf_in_band(ivec2 p) {
    return p.x >= 0 && p.x < int(pc.width) && p.y >= int(pc.y0) && p.y < int(pc.y1);
}

// NaN and Inf (and negatives) become 0, large values MAX_VALUE.
vec3 svgf_sanitize(vec3 v) {
    bvec3 bad = bvec3(isnan(v).x || isinf(v).x, isnan(v).y || isinf(v).y, isnan(v).z || isinf(v).z);
    return clamp(mix(v, vec3(0.0), bad), vec3(0.0), vec3(MAX_VALUE));
}

float svgf_sanitize(float v) {
    return (isnan(v) || isinf(v)) ? 0.0 : clamp(v, 0.0, MAX_VALUE);
}

float svgf_luminance(vec3 c) {
    return dot(c, vec3(0.2126, 0.7152, 0.0722));
}

// v (in the normal range of half floats) rounded to 10 mantissa bits: a value a half-float image
// stores exactly, whichever rounding its conversion uses (Vulkan allows either).
vec3 svgf_half_exact(vec3 v) {
    return uintBitsToFloat((floatBitsToUint(v) + 0x1000u) & ~uvec3(0x1fffu));
}

// The albedo that weighs and remodulates: the G-buffer's base colour plus the floor, as
// `svgf_albedo` stores it, so the temporal pass remodulates with what the others read.
vec3 svgf_effective_albedo(vec3 base) {
    return svgf_half_exact(svgf_sanitize(min(base, vec3(1.0))) + vec3(ALBEDO_FLOOR));
}

// Luminance of the illumination of a pixel whose radiance is `radiance` and albedo `albedo`
// (effective, so > 0): what edge-stopping compares, free of the texture.
float svgf_illumination_luminance(vec3 radiance, vec3 albedo) {
    return svgf_luminance(radiance) / svgf_luminance(albedo);
}

// Octahedral encoding of a unit normal, 12 bits per axis, as an integer below 2^24 held exactly
// in a float (float images only; integer bits in float texels could be flushed or canonicalised).
// 12 bits: the angle error (< 0.05°) changes the power-128 normal weight by < 1e-5.
float svgf_pack_normal(vec3 n) {
    float l1 = abs(n.x) + abs(n.y) + abs(n.z);
    if (!(l1 > 0.0)) {
        return 0.0;
    }
    vec2 o = n.xy / l1;
    if (n.z < 0.0) {
        o = (1.0 - abs(o.yx)) * vec2(o.x >= 0.0 ? 1.0 : -1.0, o.y >= 0.0 ? 1.0 : -1.0);
    }
    uvec2 q = uvec2(round(clamp(o * 0.5 + 0.5, 0.0, 1.0) * 4095.0));
    return float(q.x * 4096u + q.y);
}

vec3 svgf_unpack_normal(float packed) {
    uint v = uint(clamp(packed, 0.0, 16777215.0));
    vec2 o = vec2(float(v >> 12u), float(v & 4095u)) / 4095.0 * 2.0 - 1.0;
    vec3 n = vec3(o, 1.0 - abs(o.x) - abs(o.y));
    if (n.z < 0.0) {
        n.xy = (1.0 - abs(n.yx)) * vec2(n.x >= 0.0 ? 1.0 : -1.0, n.y >= 0.0 ? 1.0 : -1.0);
    }
    return normalize(n);
}

// The normal term for normals whose cosine `d` is > 0: d to the power 128. Callers return 0
// for normals 90° or more apart before calling it: the control flow of the à-trous taps
// measured in docs/RESULTS.md (a variant that tested the power for 0 after computing it came
// with 5 % slower à-trous passes on the H200).
float svgf_normal_weight(float d) {
    d = min(d, 1.0);
    d *= d; d *= d; d *= d; d *= d; d *= d; d *= d; d *= d;
    return d;
}

// The depth difference over what the two pixels' depth gradients expect across `offset`.
float svgf_depth_distance(float zp, float zq, vec2 gp, vec2 gq, vec2 offset) {
    float expected = 0.5 * (abs(dot(gp, offset)) + abs(dot(gq, offset)));
    return abs(zp - zq) / (expected + 0.5e-3 * (zp + zq) + 1e-12);
}

// One pixel's part of the depth scale of an à-trous tap `spacing` pixels away along ±direction:
// what its depth gradient predicts for the offset plus a floor relative to depth, for curved or
// slanted surfaces that the linear prediction misses. The pair's scale is the sum of both parts
// (symmetric); the centre's part is computed once per direction.
float svgf_depth_reach(float z, vec2 gradient, vec2 direction, float spacing) {
    return spacing * abs(dot(gradient, direction)) + 1e-3 * z + 1e-12;
}

// The edge-stopping weight of à-trous taps p and q whose normals have the cosine d > 0 (callers
// drop the others; a tap without a hit has a zero normal) and whose depth scale is depth_scale
// (the sum of their svgf_depth_reach): Schied's w_z · w_n · w_l with σ_z = 1, σ_n = 128, σ_l = 4,
// symmetric in p and q, so that a filter built on it can conserve energy (svgf_atrous.glsl):
// - depth: the difference against half the depth scale (the mean of the two predictions);
// - normal: d^128 (7 squarings, no transcendental);
// - illumination luminance: the difference against σ_l times √((v_p + v_q) / 2), the spread of a
//   difference of the two. A scale of the centre's variance alone (Schied) lets a noisy bright
//   pixel take in its dark neighbours while they refuse it: measured −3.4 % green, +2.3 % blue
//   on a saturated checker.
// One exp2 of the summed exponents (log2 e folded into the constants), one reciprocal, one
// inverse square root.
float svgf_edge_weight(float d, float zp, float zq, float depth_scale, float lp, float lq, float vp, float vq) {
    const float LOG2_E = 1.4426950408889634;
    float depth = (2.0 * LOG2_E) * abs(zp - zq) / depth_scale;
    float luminance = abs(lp - lq) * inversesqrt(max(vp + vq, 2e-20)) * (1.4142135623730951 / SIGMA_L * LOG2_E);
    return svgf_normal_weight(d) * exp2(-(depth + luminance));
}

// The depth-and-normal part of svgf_edge_weight, for the spatial variance estimate.
float svgf_geometry_weight(float zp, float zq, vec2 gp, vec2 gq, vec3 np, vec3 nq, vec2 offset) {
    float d = dot(np, nq);
    if (!(d > 0.0)) {
        return 0.0;
    }
    float w_n = svgf_normal_weight(d);
    return w_n * exp(-svgf_depth_distance(zp, zq, gp, gq, offset));
}

// The phase-tiled layout of a pass with tap spacing `step`: workgroup (gx, gy) owns the 8×8
// pixels base + step * (lx, ly), all of one phase (x mod step, y mod step), so the taps of a
// whole workgroup are one (8 + 2 halo)² block of that phase's subgrid and fit in shared memory
// for every step. Rows are absolute: phase py owns rows py + step * j, j from y0 / step.
// parallax_passes::svgf::phase_groups gives the dispatch size. Steps are powers of two
// (parallax_passes::svgf::ATROUS_STEPS), so the divisions by one are shifts and masks (an
// integer division by a value known only at run time is a loop of a dozen instructions or more).
ivec2 svgf_tile_base(uint step) {
    uint shift = uint(findLSB(step));
    uint phase = step - 1u;
    uint gx = gl_WorkGroupID.x;
    uint gy = gl_WorkGroupID.y;
    uint j0 = pc.y0 >> shift;
    return ivec2((gx & phase) + step * 8u * (gx >> shift), (gy & phase) + step * (j0 + 8u * (gy >> shift)));
}

#endif
