#version 460
// SVGF, step 2 (`svgf_variance`): the illumination-luminance variance that steers the à-trous
// filter.
//   in0 `svgf_temporal` (illumination rgb, history length), in1 `svgf_moments`, in2 `svgf_guide`:
//   whole view
//   out0 `svgf_variance`: (illumination rgb, variance)
// With 4 frames of history or more the variance comes from the temporal moments; with fewer it
// is estimated spatially, from the moments of a 7×7 neighbourhood weighted by depth, normal and
// luminance (Schied §4.2). The illumination is the temporal one: Schied also replaces it by the
// neighbourhood's bilateral mean, a filter that does not conserve energy (at depth edges,
// borders, next to dark albedo) on the very frames that have the least history; the
// energy-conserving à-trous iterations do that smoothing instead. A workgroup with
// short histories reads its 14×14 neighbourhood into shared memory once.
#include "svgf.glsl"

const float MIN_LENGTH = 4.0;
const int RADIUS = 3;
const int TILE = 8 + 2 * RADIUS;
// Luminance edge-stopping of the spatial estimate (Schied's reference code: σ_l 10), on
// illumination luminance.
const float SIGMA_L_SPATIAL = 10.0;

shared vec4 tile_moments[TILE * TILE]; // m1, m2, depth gradient x, y
shared vec4 tile_geometry[TILE * TILE]; // normal xyz, depth (0: no hit or outside)
shared uint any_short;

void load_tile(ivec2 origin) {
    for (uint e = gl_LocalInvocationIndex; e < uint(TILE * TILE); e += 64u) {
        ivec2 q = origin + ivec2(int(e % uint(TILE)), int(e / uint(TILE)));
        vec4 guide = vec4(0.0);
        vec2 moments = vec2(0.0);
        if (svgf_inside(q)) {
            guide = imageLoad(images[pc.in2], q);
            moments = imageLoad(images[pc.in1], q).xy;
        }
        bool hit = guide.x > 0.0;
        tile_moments[e] = vec4(moments, guide.yz);
        tile_geometry[e] = vec4(hit ? svgf_unpack_normal(guide.w) : vec3(0.0), hit ? guide.x : 0.0);
    }
}

void main() {
    ivec2 p = svgf_pixel();
    vec4 centre = vec4(0.0);
    vec2 centre_moments = vec2(0.0);
    float z = 0.0;
    if (p.x >= 0) {
        centre = imageLoad(images[pc.in0], p);
        centre_moments = imageLoad(images[pc.in1], p).xy;
        z = imageLoad(images[pc.in2], p).x;
    }
    bool short_history = z > 0.0 && centre.a < MIN_LENGTH;
    if (gl_LocalInvocationIndex == 0u) {
        any_short = 0u;
    }
    barrier();
    if (short_history) {
        atomicOr(any_short, 1u);
    }
    barrier();
    if (any_short != 0u) {
        load_tile(svgf_tile_base(1u) - ivec2(RADIUS));
    }
    barrier();
    if (p.x < 0) {
        return;
    }
    if (!short_history) {
        float variance = z > 0.0 ? max(0.0, centre_moments.y - centre_moments.x * centre_moments.x) : 0.0;
        imageStore(images[pc.out0], p, vec4(centre.rgb, min(variance, MAX_VALUE)));
        return;
    }
    int c = (int(gl_LocalInvocationID.y) + RADIUS) * TILE + int(gl_LocalInvocationID.x) + RADIUS;
    vec3 n = tile_geometry[c].xyz;
    vec2 gradient = tile_moments[c].zw;
    float l = centre_moments.x;
    // The centre counts with weight 1 whatever its normal, so the sums never vanish.
    vec2 moment_sum = centre_moments;
    float weight_sum = 1.0;
    for (int dy = -RADIUS; dy <= RADIUS; dy++) {
        for (int dx = -RADIUS; dx <= RADIUS; dx++) {
            int e = c + dy * TILE + dx;
            float zq = tile_geometry[e].w;
            if ((dx == 0 && dy == 0) || !(zq > 0.0)) {
                continue;
            }
            float w = svgf_geometry_weight(z, zq, gradient, tile_moments[e].zw, n, tile_geometry[e].xyz, vec2(dx, dy))
                * exp(-abs(l - tile_moments[e].x) / SIGMA_L_SPATIAL);
            moment_sum += w * tile_moments[e].xy;
            weight_sum += w;
        }
    }
    moment_sum /= weight_sum;
    // Short histories get a larger variance (Schied's reference code: × 4 / length), so the
    // first frames are filtered harder.
    float variance = max(0.0, moment_sum.y - moment_sum.x * moment_sum.x) * (MIN_LENGTH / max(centre.a, 1.0));
    imageStore(images[pc.out0], p, vec4(centre.rgb, min(variance, MAX_VALUE)));
}
