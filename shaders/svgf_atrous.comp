#version 460
// SVGF, steps 3–7 (`svgf_atrous_1` … `svgf_atrous_5`): one à-trous iteration of the
// edge-avoiding wavelet filter (Schied §4.3): a 5×5 B3-spline kernel with taps `step` pixels
// apart, weighted by depth (against both pixels' depth gradients), normal (power 128) and
// illumination luminance (σ_l = 4 times the standard deviation of the difference, symmetric:
// svgf_luminance_weight), as a ratio estimate of illumination remodulated by the pixel's albedo
// (svgf.glsl); the variance is filtered with the squared weights, so each iteration steers the
// next. The first iteration blurs the variance over 3×3 (Gaussian 1-2-1, among pixels with a
// hit) before using it, at the centre and at every tap alike; later ones use the variance the
// previous iteration filtered.
//   in0: (radiance rgb, variance), in1 `svgf_guide`, in2 `svgf_albedo`: whole view
//   out0: (radiance rgb, variance), or on the last iteration `denoised` (alpha from radiance)
//   out1 (first iteration): `svgf_color`, the colour history: (illumination rgb, length)
//   radiance (last iteration): own pixel, what pixels without a hit pass through
// The workgroup owns 8×8 pixels of one phase of the step (svgf_tile_base) and reads their
// (8 + 2·halo)² taps into shared memory once: a handful of texel reads per pixel instead of
// 75 (25 taps × 3 images) plus the variance blur and the depth gradient.
#include "svgf.glsl"

const float KERNEL[3] = float[3](3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0);
// The first iteration needs one more ring: the 3×3 variance blur of its outermost taps.
const int MAX_HALO = 3;
const int MAX_TILE = 8 + 2 * MAX_HALO;

shared vec4 tile_radiance[MAX_TILE * MAX_TILE]; // rgb, variance
shared vec4 tile_albedo[MAX_TILE * MAX_TILE];   // rgb, illumination luminance
shared vec4 tile_guide[MAX_TILE * MAX_TILE];    // depth (0: no hit or outside), gradient x, y, unused
shared vec3 tile_normal[MAX_TILE * MAX_TILE];
shared float tile_deviation[MAX_TILE * MAX_TILE]; // variance used by the weights

void load_tile(ivec2 origin, int step, int size) {
    for (uint e = gl_LocalInvocationIndex; e < uint(size * size); e += 64u) {
        ivec2 q = origin + step * ivec2(int(e % uint(size)), int(e / uint(size)));
        vec4 radiance = vec4(0.0);
        vec4 guide = vec4(0.0);
        vec3 albedo = vec3(1.0);
        if (svgf_inside(q)) {
            radiance = imageLoad(images[pc.in0], q);
            guide = imageLoad(images[pc.in1], q);
            albedo = imageLoad(images[pc.in2], q).rgb;
        }
        bool hit = guide.x > 0.0;
        tile_radiance[e] = radiance;
        tile_albedo[e] = vec4(albedo, hit ? svgf_illumination_luminance(radiance.rgb, albedo) : 0.0);
        tile_guide[e] = vec4(hit ? guide.x : 0.0, guide.yz, 0.0);
        tile_normal[e] = hit ? svgf_unpack_normal(guide.w) : vec3(0.0);
        tile_deviation[e] = radiance.a;
    }
}

// The 3×3-blurred variance of entry e (a hit, not on the tile's outer ring).
float blurred_variance(int e, int size) {
    const float g[2] = float[2](0.5, 0.25);
    float sum = 0.0;
    float weight = 0.0;
    for (int dy = -1; dy <= 1; dy++) {
        for (int dx = -1; dx <= 1; dx++) {
            int q = e + dy * size + dx;
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

// The first iteration's blurred variances of the inner entries, in place of the raw ones.
void blur_tile(int size) {
    float blurred[4];
    for (uint k = 0u; k < 4u; k++) {
        uint e = gl_LocalInvocationIndex + 64u * k;
        int x = int(e % uint(size));
        int y = int(e / uint(size));
        bool inner = e < uint(size * size) && x > 0 && y > 0 && x < size - 1 && y < size - 1;
        blurred[k] = inner && tile_guide[e].x > 0.0 ? blurred_variance(int(e), size) : 0.0;
    }
    barrier();
    for (uint k = 0u; k < 4u; k++) {
        uint e = gl_LocalInvocationIndex + 64u * k;
        if (e < uint(size * size)) {
            tile_deviation[e] = blurred[k];
        }
    }
}

void main() {
    int step = int(pc.step);
    bool first = (pc.flags & SVGF_FIRST) != 0u;
    bool last = (pc.flags & SVGF_LAST) != 0u;
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
    vec4 centre = tile_radiance[c];
    float z = tile_guide[c].x;
    if (!(z > 0.0)) {
        if (last) {
            vec4 radiance = imageLoad(images[pc.radiance], p);
            imageStore(images[pc.out0], p, vec4(svgf_sanitize(radiance.rgb), radiance.a));
        } else {
            imageStore(images[pc.out0], p, centre);
        }
        if (first) {
            imageStore(images[pc.out1], p, vec4(0.0));
        }
        return;
    }
    vec3 n = tile_normal[c];
    vec2 gradient = tile_guide[c].yz;
    vec3 albedo = tile_albedo[c].rgb;
    float l = tile_albedo[c].w;
    float v = tile_deviation[c];
    // The centre counts with its kernel weight whatever its normal: the sums never vanish.
    float centre_weight = KERNEL[0] * KERNEL[0];
    vec3 radiance_sum = centre_weight * centre.rgb;
    vec3 albedo_sum = centre_weight * albedo;
    float variance_sum = centre_weight * centre_weight * centre.a;
    float weight_sum = centre_weight;
    for (int dy = -2; dy <= 2; dy++) {
        for (int dx = -2; dx <= 2; dx++) {
            int e = c + dy * size + dx;
            float zq = tile_guide[e].x;
            if ((dx == 0 && dy == 0) || !(zq > 0.0)) {
                continue;
            }
            float w = KERNEL[abs(dx)] * KERNEL[abs(dy)]
                * svgf_depth_weight(z, zq, gradient, tile_guide[e].yz, vec2(step * dx, step * dy))
                * svgf_normal_weight(n, tile_normal[e])
                * svgf_luminance_weight(l, tile_albedo[e].w, v, tile_deviation[e]);
            radiance_sum += w * tile_radiance[e].rgb;
            albedo_sum += w * tile_albedo[e].rgb;
            variance_sum += w * w * tile_radiance[e].a;
            weight_sum += w;
        }
    }
    vec3 illumination = radiance_sum / albedo_sum;
    vec3 radiance = min(albedo * illumination, vec3(MAX_VALUE));
    if (last) {
        imageStore(images[pc.out0], p, vec4(radiance, imageLoad(images[pc.radiance], p).a));
        return;
    }
    imageStore(images[pc.out0], p, vec4(radiance, min(variance_sum / (weight_sum * weight_sum), MAX_VALUE)));
    if (first) {
        float length_ = imageLoad(images[pc.in2], p).a;
        imageStore(images[pc.out1], p, vec4(min(illumination, vec3(MAX_VALUE)), length_));
    }
}
