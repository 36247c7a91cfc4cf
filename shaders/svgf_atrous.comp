#version 460
// SVGF, steps 3–7 (`svgf_atrous_1` … `svgf_atrous_5`): one à-trous iteration of the
// edge-avoiding wavelet filter (Schied §4.3): a 5×5 B3-spline kernel with taps `step` pixels
// apart, weighted by depth (against the depth gradient), normal (power 128) and luminance
// (σ_l = 4 times the 3×3-blurred standard deviation of the centre); the variance is filtered
// with the squared weights, so each iteration steers the next.
//   in0: (illumination rgb, variance), whole view; normal, position: whole view
//   out0: (illumination rgb, variance), or on the last iteration `denoised`: the
//   illumination remodulated by albedo (radiance and albedo: own pixel), alpha from radiance
// Pixels without a hit pass through (their radiance on the last iteration); taps without a
// hit get weight 0.
#include "svgf.glsl"

const float SIGMA_L = 4.0;
const float KERNEL[3] = float[3](3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0);

// Standard deviation of the centre's variance, blurred over 3×3 (Gaussian 1-2-1) among pixels
// with a hit: one noisy variance sample must not stop the filter.
float blurred_deviation(ivec2 p) {
    const float g[2] = float[2](0.5, 0.25);
    float sum = 0.0;
    float weight = 0.0;
    for (int dy = -1; dy <= 1; dy++) {
        for (int dx = -1; dx <= 1; dx++) {
            ivec2 q = p + ivec2(dx, dy);
            if (!svgf_inside(q) || !(svgf_depth(q) > 0.0)) {
                continue;
            }
            float w = g[abs(dx)] * g[abs(dy)];
            sum += w * imageLoad(images[pc.in0], q).a;
            weight += w;
        }
    }
    return sqrt(max(0.0, sum / weight));
}

void store(ivec2 p, vec3 illum, float variance) {
    if (pc.last == 0u) {
        imageStore(images[pc.out0], p, vec4(illum, variance));
        return;
    }
    vec4 radiance = imageLoad(images[pc.radiance], p);
    vec3 albedo = svgf_sanitize(imageLoad(images[pc.albedo], p).rgb);
    imageStore(images[pc.out0], p, vec4(min(illum * svgf_albedo_divisor(albedo), vec3(MAX_VALUE)), radiance.a));
}

void main() {
    ivec2 p = svgf_pixel();
    if (p.x < 0) {
        return;
    }
    vec4 centre = imageLoad(images[pc.in0], p);
    float z = svgf_depth(p);
    if (!(z > 0.0)) {
        if (pc.last == 0u) {
            imageStore(images[pc.out0], p, centre);
        } else {
            vec4 radiance = imageLoad(images[pc.radiance], p);
            imageStore(images[pc.out0], p, vec4(svgf_sanitize(radiance.rgb), radiance.a));
        }
        return;
    }
    vec3 n = imageLoad(images[pc.normal], p).xyz;
    vec2 gradient = svgf_depth_gradient(p, z);
    float l = svgf_luminance(centre.rgb);
    float phi_l = SIGMA_L * blurred_deviation(p) + 1e-10;
    // The centre counts with its kernel weight whatever its normal: the sums never vanish.
    float centre_weight = KERNEL[0] * KERNEL[0];
    vec3 illum_sum = centre_weight * centre.rgb;
    float variance_sum = centre_weight * centre_weight * centre.a;
    float weight_sum = centre_weight;
    int step = int(pc.step);
    for (int dy = -2; dy <= 2; dy++) {
        for (int dx = -2; dx <= 2; dx++) {
            ivec2 offset = ivec2(dx, dy) * step;
            ivec2 q = p + offset;
            if ((dx == 0 && dy == 0) || !svgf_inside(q)) {
                continue;
            }
            float zq = svgf_depth(q);
            if (!(zq > 0.0)) {
                continue;
            }
            vec4 cq = imageLoad(images[pc.in0], q);
            float w = KERNEL[abs(dx)] * KERNEL[abs(dy)]
                * svgf_depth_weight(z, zq, gradient, vec2(offset))
                * svgf_normal_weight(n, imageLoad(images[pc.normal], q).xyz)
                * exp(-abs(l - svgf_luminance(cq.rgb)) / phi_l);
            illum_sum += w * cq.rgb;
            variance_sum += w * w * cq.a;
            weight_sum += w;
        }
    }
    store(p, illum_sum / weight_sum, min(variance_sum / (weight_sum * weight_sum), MAX_VALUE));
}
