#version 460
// SVGF, step 3 (`svgf_atrous_1`): the first à-trous iteration (step 1), which takes in this
// frame's samples, so it is the one that must not move energy: an energy-conserving ratio filter.
// The radiance of a fresh sample is not its pixel's albedo times an illumination (the sample is
// jittered, the albedo is the pixel centre's; it may have hit another texel or another surface),
// and a plain normalised filter (Σ w L / Σ w) counts a pixel at a depth edge, an image border or
// next to dark albedo less than its neighbours. Here pixel q hands pixel p the share
//   T_qp = a_p w_pq / max(A_p, A_q)  (q ≠ p),  T_pp = 1 − Σ_q a_q w_pq / max(A_p, A_q),
// per channel, with a the effective albedo, w the symmetric tap weight (kernel times
// svgf_edge_weight) and A_p = Σ_q w_pq a_q (q = p included). Every column sums to 1 (energy is
// conserved: the view's radiance sum is unchanged, whatever the weights were) and a radiance that
// is its albedo times one illumination comes out unchanged; T_pp ≥ w_pp a_p / A_p > 0.
// The variance used by the weights is blurred over 3×3 first (Gaussian 1-2-1, among pixels with a
// hit), the same blurred value at the centre and at the taps; the variance of the output is
// propagated with the squared shares (in luminance).
//   in0 `svgf_variance`: (radiance rgb, variance), in1 `svgf_guide`, in2 `svgf_albedo`: whole view
//   out0 `svgf_atrous`: (radiance rgb, variance)
//   out1 `svgf_color`: the colour history, (illumination rgb = radiance / albedo, length)
// The workgroup reads the 18×18 pixels around its 8×8 into shared memory: 2 rings for its taps,
// 2 for their taps (A), 1 for the blur.
#define SVGF_TILE 18
#include "svgf_tile.glsl"

const int HALO = 5;
// Entries whose A is needed: the 8×8 pixels and their taps (tile coordinates 3..14).
const int SUMS = 12;
const int SUMS_FROM = HALO - 2;

shared vec4 tile_sum[SUMS * SUMS]; // A rgb, A luminance

float blurred_variance(int e) {
    const float g[2] = float[2](0.5, 0.25);
    float sum = 0.0;
    float weight = 0.0;
    for (int dy = -1; dy <= 1; dy++) {
        for (int dx = -1; dx <= 1; dx++) {
            int q = e + dy * SVGF_TILE + dx;
            if (!(tile_guide[q].x > 0.0)) {
                continue;
            }
            float w = g[abs(dx)] * g[abs(dy)];
            sum += w * tile_radiance[q].a;
            weight += w;
        }
    }
    return sum / weight;
}

// Replaces the variance the weights use by its blur on the 16×16 entries the sums reach.
void blur_tile() {
    float blurred[4];
    int e[4];
    for (int k = 0; k < 4; k++) {
        int i = int(gl_LocalInvocationIndex) + 64 * k;
        e[k] = (i / 16 + 1) * SVGF_TILE + i % 16 + 1;
        blurred[k] = tile_guide[e[k]].x > 0.0 ? blurred_variance(e[k]) : 0.0;
    }
    barrier();
    for (int k = 0; k < 4; k++) {
        tile_normal[e[k]].w = blurred[k];
    }
}

// Tile entry of tile coordinates t.
int entry(ivec2 t) {
    return t.y * SVGF_TILE + t.x;
}

// A of entry e (a hit): Σ_q w_eq a_q over its 5×5 taps, the centre with its kernel weight.
vec3 albedo_sum(int e) {
    vec3 sum = KERNEL[0] * KERNEL[0] * tile_albedo[e].rgb;
    for (int dy = -2; dy <= 2; dy++) {
        for (int dx = -2; dx <= 2; dx++) {
            int f = e + dy * SVGF_TILE + dx;
            if ((dx == 0 && dy == 0) || !(tile_guide[f].x > 0.0)) {
                continue;
            }
            sum += KERNEL[abs(dx)] * KERNEL[abs(dy)] * svgf_tile_weight(e, f, vec2(dx, dy) * float(pc.step)) * tile_albedo[f].rgb;
        }
    }
    return sum;
}

void compute_sums() {
    for (int i = int(gl_LocalInvocationIndex); i < SUMS * SUMS; i += 64) {
        int e = entry(ivec2(i % SUMS, i / SUMS) + SUMS_FROM);
        vec3 sum = tile_guide[e].x > 0.0 ? albedo_sum(e) : vec3(1.0);
        tile_sum[i] = vec4(sum, svgf_luminance(sum));
    }
}

void main() {
    int step = int(pc.step);
    ivec2 base = svgf_tile_base(pc.step);
    svgf_load_tile(base - step * ivec2(HALO), step, SVGF_TILE);
    barrier();
    if ((pc.flags & 4u) != 0u) {
        blur_tile();
    }
    barrier();
    compute_sums();
    barrier();
    ivec2 p = base + step * ivec2(gl_LocalInvocationID.xy);
    if (!svgf_in_band(p)) {
        return;
    }
    ivec2 t = ivec2(gl_LocalInvocationID.xy) + HALO;
    int c = entry(t);
    vec4 centre = tile_radiance[c];
    if (!(tile_guide[c].x > 0.0)) {
        svgf_pass_through(p, centre);
        if ((pc.flags & 4u) != 0u) {
            imageStore(images[pc.out1], p, vec4(0.0));
        }
        return;
    }
    vec3 albedo = tile_albedo[c].rgb;
    vec4 sum_p = tile_sum[(t.y - SUMS_FROM) * SUMS + t.x - SUMS_FROM];
    vec3 received = vec3(0.0); // Σ_q w L_q / M_pq
    vec3 given = vec3(0.0);    // Σ_q w a_q / M_pq: the share of the centre's own radiance it gives away
    float share_sum = 0.0;     // in luminance, for the variance
    float variance = 0.0;
    for (int dy = -2; dy <= 2; dy++) {
        for (int dx = -2; dx <= 2; dx++) {
            int e = c + dy * SVGF_TILE + dx;
            if ((dx == 0 && dy == 0) || !(tile_guide[e].x > 0.0)) {
                continue;
            }
            vec4 sum_q = tile_sum[(t.y + dy - SUMS_FROM) * SUMS + t.x + dx - SUMS_FROM];
            float w = KERNEL[abs(dx)] * KERNEL[abs(dy)] * svgf_tile_weight(c, e, vec2(dx, dy) * float(step));
            vec3 m = max(sum_p.rgb, sum_q.rgb);
            received += w * tile_radiance[e].rgb / m;
            given += w * tile_albedo[e].rgb / m;
            float share = w * svgf_luminance(tile_albedo[e].rgb) / max(sum_p.w, sum_q.w);
            share_sum += share;
            variance += share * share * tile_radiance[e].a;
        }
    }
    vec3 kept = max(vec3(0.0), 1.0 - given);
    vec3 radiance = min(kept * centre.rgb + albedo * received, vec3(MAX_VALUE));
    float centre_share = max(0.0, 1.0 - share_sum);
    variance += centre_share * centre_share * centre.a;
    if ((pc.flags & SVGF_LAST) != 0u) {
        imageStore(images[pc.out0], p, vec4(radiance, imageLoad(images[pc.radiance], p).a));
        return;
    }
    imageStore(images[pc.out0], p, vec4(radiance, min(variance, MAX_VALUE)));
    if ((pc.flags & 4u) != 0u) {
        float length_ = imageLoad(images[pc.in2], p).a;
        imageStore(images[pc.out1], p, vec4(min(radiance / albedo, vec3(MAX_VALUE)), length_));
    }
}
