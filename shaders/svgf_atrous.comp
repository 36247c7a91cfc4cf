#version 460
// SVGF, steps 4–7 (`svgf_atrous_2` … `svgf_atrous_5`): one à-trous iteration of the
// edge-avoiding wavelet filter (Schied §4.3): a 5×5 B3-spline kernel with taps `step` pixels
// apart, weighted by svgf_edge_weight (depth, normal, illumination luminance; symmetric), as a
// ratio estimate of illumination remodulated by the pixel's albedo (svgf.glsl). Their input is
// the first iteration's output, whose radiance is already its albedo times an illumination, so
// the ratio gives a smooth illumination back unchanged; the variance is filtered with the
// squared weights and steers the next iteration.
//   in0: (radiance rgb, variance), in1 `svgf_guide`, in2 `svgf_albedo`: whole view (tile)
//   out0: (radiance rgb, variance), or on the last iteration `denoised` (alpha from radiance)
//   radiance (last iteration): own pixel, what pixels without a hit pass through
// The workgroup owns 8×8 pixels of one phase of the step (svgf_tile_base) and reads their 12×12
// taps into shared memory once: 2.25 reads of 3 texels per pixel instead of 75 texel reads
// (25 taps × 3 images) plus the variance blur and the depth gradient.
#define SVGF_TILE 12
#include "svgf_tile.glsl"

const int HALO = 2;

void main() {
    int step = int(pc.step);
    ivec2 base = svgf_tile_base(pc.step);
    svgf_load_tile(base - step * ivec2(HALO), step, SVGF_TILE);
    barrier();
    ivec2 p = base + step * ivec2(gl_LocalInvocationID.xy);
    if (!svgf_in_band(p)) {
        return;
    }
    int c = (int(gl_LocalInvocationID.y) + HALO) * SVGF_TILE + int(gl_LocalInvocationID.x) + HALO;
    vec4 centre = tile_radiance[c];
    if (!(tile_guide[c].x > 0.0)) {
        svgf_pass_through(p, centre);
        return;
    }
    vec3 albedo = tile_albedo[c].rgb;
    // The centre counts with its kernel weight whatever its normal: the sums never vanish.
    float centre_weight = KERNEL[0] * KERNEL[0];
    vec3 radiance_sum = centre_weight * centre.rgb;
    vec3 albedo_sum = centre_weight * albedo;
    float variance_sum = centre_weight * centre_weight * centre.a;
    float weight_sum = centre_weight;
    for (int dy = -2; dy <= 2; dy++) {
        for (int dx = -2; dx <= 2; dx++) {
            int e = c + dy * SVGF_TILE + dx;
            if ((dx == 0 && dy == 0) || !(tile_guide[e].x > 0.0)) {
                continue;
            }
            float w = KERNEL[abs(dx)] * KERNEL[abs(dy)] * svgf_tile_weight(c, e, vec2(step * dx, step * dy));
            radiance_sum += w * tile_radiance[e].rgb;
            albedo_sum += w * tile_albedo[e].rgb;
            variance_sum += w * w * tile_radiance[e].a;
            weight_sum += w;
        }
    }
    vec3 radiance = min(albedo * (radiance_sum / albedo_sum), vec3(MAX_VALUE));
    if ((pc.flags & SVGF_LAST) != 0u) {
        imageStore(images[pc.out0], p, vec4(radiance, imageLoad(images[pc.radiance], p).a));
    } else {
        imageStore(images[pc.out0], p, vec4(radiance, min(variance_sum / (weight_sum * weight_sum), MAX_VALUE)));
    }
}
