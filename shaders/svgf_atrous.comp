#version 460
// SVGF, steps 3–7 (`svgf_atrous_1` … `svgf_atrous_5`): one à-trous iteration (Schied §4.3): a
// 5×5 B3-spline kernel h with taps `step` pixels apart, each weighted by svgf_edge_weight (depth,
// normal, illumination luminance), as an energy-conserving exchange of illumination E between
// neighbours: per channel
//   E'_p = E_p + Σ_q h_pq w_pq (min(a_p, a_q) / a_p) (E_q − E_p)
// with a the effective albedo. The exchange between p and q is antisymmetric in radiance a·E
// (w is symmetric), so the view's radiance sum is exactly what it was, whatever the weights, the
// textures, the depth edges and the image border; a smooth illumination comes out unchanged; and
// E'_p is a weighted mean of E (the centre keeps 1 − Σ of the others' weights ≥ h_00 > 0).
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
// into shared memory once (12×12, 14×14 with the blur's ring): 2.25 (3.06) reads of 3 texels
// per pixel instead of 75 (25 taps × 3 images) plus 9 for the blur and 4 for the depth gradient.
#include "svgf.glsl"

const int MAX_TILE = 14;

shared vec4 tile_illumination[MAX_TILE * MAX_TILE]; // rgb, illumination luminance
shared vec4 tile_geometry[MAX_TILE * MAX_TILE];     // normal xyz, depth (0: no hit or outside)
// half2 depth gradient, half2 albedo rg, half2 (albedo b, albedo luminance), variance the weights
// use (f32 bits)
shared uvec4 tile_packed[MAX_TILE * MAX_TILE];

// Reads the size² entries origin + step * (i, j), row-major.
void load_tile(ivec2 origin, int step, int size) {
    for (uint e = gl_LocalInvocationIndex; e < uint(size * size); e += 64u) {
        ivec2 q = origin + step * ivec2(int(e % uint(size)), int(e / uint(size)));
        vec4 illumination = vec4(0.0);
        vec4 guide = vec4(0.0);
        vec3 albedo = vec3(1.0);
        if (svgf_inside(q)) {
            illumination = imageLoad(images[pc.in0], q);
            guide = imageLoad(images[pc.in1], q);
            albedo = imageLoad(images[pc.in2], q).rgb;
        }
        bool hit = guide.x > 0.0;
        float l = hit ? svgf_illumination_luminance(illumination.rgb * albedo, albedo) : 0.0;
        tile_illumination[e] = vec4(illumination.rgb, l);
        tile_geometry[e] = vec4(hit ? svgf_unpack_normal(guide.w) : vec3(0.0), hit ? guide.x : 0.0);
        tile_packed[e] = uvec4(packHalf2x16(guide.yz), packHalf2x16(albedo.rg),
                               packHalf2x16(vec2(albedo.b, svgf_luminance(albedo))), floatBitsToUint(illumination.a));
    }
}

float variance_of(int e) {
    return uintBitsToFloat(tile_packed[e].w);
}

// The first iteration: the 3×3-blurred variance of the entries inside the outer ring.
void blur_tile(int size) {
    const float g[2] = float[2](0.5, 0.25);
    int inner = size - 2;
    float blurred[3];
    for (int k = 0; k < 3; k++) {
        int i = int(gl_LocalInvocationIndex) + 64 * k;
        blurred[k] = 0.0;
        if (i >= inner * inner) {
            continue;
        }
        int e = (i / inner + 1) * size + i % inner + 1;
        float sum = 0.0;
        float weight = 0.0;
        for (int dy = -1; dy <= 1; dy++) {
            for (int dx = -1; dx <= 1; dx++) {
                int q = e + dy * size + dx;
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
    for (int k = 0; k < 3; k++) {
        int i = int(gl_LocalInvocationIndex) + 64 * k;
        if (i < inner * inner) {
            tile_packed[(i / inner + 1) * size + i % inner + 1].w = floatBitsToUint(blurred[k]);
        }
    }
}

void main() {
    int step = int(pc.step);
    bool first = (pc.flags & SVGF_FIRST) != 0u;
    int halo = first ? 3 : 2;
    int size = 8 + 2 * halo;
    ivec2 base = svgf_tile_base(pc.step);
    load_tile(base - step * ivec2(halo), step, size);
    barrier();
    if (first) {
        blur_tile(size);
        barrier();
    }
    ivec2 p = base + step * ivec2(gl_LocalInvocationID.xy);
    if (!svgf_in_band(p)) {
        return;
    }
    int c = (int(gl_LocalInvocationID.y) + halo) * size + int(gl_LocalInvocationID.x) + halo;
    vec4 centre = tile_illumination[c];
    vec4 geometry = tile_geometry[c];
    if (!(geometry.w > 0.0)) {
        svgf_pass_through(p, vec4(centre.rgb, 0.0));
        if (first) {
            imageStore(images[pc.out1], p, vec4(0.0));
        }
        return;
    }
    uvec4 packed = tile_packed[c];
    vec2 gradient = unpackHalf2x16(packed.x);
    vec2 blue_luminance = unpackHalf2x16(packed.z);
    vec3 albedo = vec3(unpackHalf2x16(packed.y), blue_luminance.x);
    vec3 inverse_albedo = 1.0 / albedo;
    float inverse_albedo_luminance = 1.0 / blue_luminance.y;
    float v = uintBitsToFloat(packed.w);
    float spacing = float(step);
    vec3 change = vec3(0.0);
    float share_sum = 0.0; // in luminance, for the variance
    float variance = 0.0;
    for (int dy = -2; dy <= 2; dy++) {
        for (int dx = -2; dx <= 2; dx++) {
            int e = c + dy * size + dx;
            vec4 geometry_q = tile_geometry[e];
            if ((dx == 0 && dy == 0) || !(geometry_q.w > 0.0)) {
                continue;
            }
            vec4 illumination_q = tile_illumination[e];
            uvec4 packed_q = tile_packed[e];
            vec2 blue_luminance_q = unpackHalf2x16(packed_q.z);
            vec3 albedo_q = vec3(unpackHalf2x16(packed_q.y), blue_luminance_q.x);
            float v_q = uintBitsToFloat(packed_q.w);
            float w = KERNEL[abs(dx)] * KERNEL[abs(dy)]
                * svgf_edge_weight(geometry.w, geometry_q.w, gradient, unpackHalf2x16(packed_q.x), geometry.xyz,
                                   geometry_q.xyz, centre.w, illumination_q.w, v, v_q, spacing * vec2(dx, dy));
            change += (w * min(vec3(1.0), albedo_q * inverse_albedo)) * (illumination_q.rgb - centre.rgb);
            float share = w * min(1.0, blue_luminance_q.y * inverse_albedo_luminance);
            share_sum += share;
            variance += share * share * v_q;
        }
    }
    vec3 illumination = min(max(centre.rgb + change, vec3(0.0)), vec3(MAX_VALUE));
    float kept = max(0.0, 1.0 - share_sum);
    variance = min(variance + kept * kept * v, MAX_VALUE);
    if ((pc.flags & SVGF_LAST) != 0u) {
        imageStore(images[pc.out0], p, vec4(albedo * illumination, imageLoad(images[pc.radiance], p).a));
        return;
    }
    imageStore(images[pc.out0], p, vec4(illumination, variance));
    if (first) {
        imageStore(images[pc.out1], p, vec4(illumination, imageLoad(images[pc.in2], p).a));
    }
}
