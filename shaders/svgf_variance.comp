#version 460
// SVGF, step 2 (`svgf_variance`): the luminance variance that steers the à-trous filter.
//   in0 `svgf_illum` (illumination, history length), in1 `svgf_moments`; normal, position:
//   all whole view
//   out0 `svgf_variance`: (illumination rgb, variance)
// With 4 frames of history or more the variance comes from the temporal moments; with fewer it
// is estimated spatially, from the moments of a 7×7 neighbourhood weighted by depth, normal and
// luminance (Schied §4.2), and the illumination is that neighbourhood's bilateral mean too.
#include "svgf.glsl"

const float MIN_LENGTH = 4.0;
const int RADIUS = 3;
// Luminance edge-stopping of the spatial estimate (Schied's reference code: σ_l 10).
const float SIGMA_L = 10.0;

void main() {
    ivec2 p = svgf_pixel();
    if (p.x < 0) {
        return;
    }
    vec4 centre = imageLoad(images[pc.in0], p);
    float z = svgf_depth(p);
    if (!(z > 0.0)) {
        imageStore(images[pc.out0], p, vec4(centre.rgb, 0.0));
        return;
    }
    vec2 centre_moments = imageLoad(images[pc.in1], p).xy;
    if (centre.a >= MIN_LENGTH) {
        float variance = max(0.0, centre_moments.y - centre_moments.x * centre_moments.x);
        imageStore(images[pc.out0], p, vec4(centre.rgb, variance));
        return;
    }
    vec3 n = imageLoad(images[pc.normal], p).xyz;
    vec2 gradient = svgf_depth_gradient(p, z);
    float l = svgf_luminance(centre.rgb);
    // The centre counts with weight 1 whatever its normal, so weight_sum >= 1.
    vec3 illum_sum = centre.rgb;
    vec2 moment_sum = centre_moments;
    float weight_sum = 1.0;
    for (int dy = -RADIUS; dy <= RADIUS; dy++) {
        for (int dx = -RADIUS; dx <= RADIUS; dx++) {
            ivec2 q = p + ivec2(dx, dy);
            if ((dx == 0 && dy == 0) || !svgf_inside(q)) {
                continue;
            }
            float zq = svgf_depth(q);
            if (!(zq > 0.0)) {
                continue;
            }
            vec3 cq = imageLoad(images[pc.in0], q).rgb;
            float w = svgf_depth_weight(z, zq, gradient, vec2(dx, dy))
                * svgf_normal_weight(n, imageLoad(images[pc.normal], q).xyz)
                * exp(-abs(l - svgf_luminance(cq)) / SIGMA_L);
            illum_sum += w * cq;
            moment_sum += w * imageLoad(images[pc.in1], q).xy;
            weight_sum += w;
        }
    }
    illum_sum /= weight_sum;
    moment_sum /= weight_sum;
    // Short histories get a larger variance (Schied's reference code: × 4 / length), so the
    // first frames are filtered harder.
    float variance = max(0.0, moment_sum.y - moment_sum.x * moment_sum.x) * (MIN_LENGTH / max(centre.a, 1.0));
    imageStore(images[pc.out0], p, vec4(illum_sum, min(variance, MAX_VALUE)));
}
