#version 460
// SVGF, step 1 (`svgf_temporal`): accumulates radiance and the first two moments of its
// illumination luminance through `motion`, and packs what the later passes read of the G-buffer.
//   radiance, albedo, normal, motion: own pixel; position: own pixel and its 4 neighbours
//   in0 `svgf_prev_color` (illumination rgb, length), in1 `svgf_prev_moments` (m1, m2, depth,
//   packed normal): whole view
//   out0 `svgf_temporal`: (accumulated radiance / albedo: illumination rgb, history length)
//   out1 `svgf_moments`: (m1, m2, linear depth, packed normal), read as history next frame
//   out2 `svgf_guide`: (linear depth, depth gradient x, y, packed normal)
//   out3 `svgf_albedo`: (effective albedo rgb, history length)
// The previous frame is sampled bilinearly at the motion vector; a tap counts only if it is
// inside the image, had history, and saw the same surface (depth against the gradient, normal
// within ~25°). The history holds illumination, which is remodulated by this pixel's albedo
// before it is blended with this frame's radiance (so a texture is never smeared by the
// bilinear taps). Without any valid tap the pixel restarts (length 1). Pixels without a hit
// keep their radiance and length 0; their guide depth is 0, which every later pass skips.
#include "svgf.glsl"

// Exponential moving average weights (Schied: 0.2 for colour and moments), replaced by 1/n
// while the history is shorter than 1/α frames, so early frames are a plain mean.
const float ALPHA_COLOR = 0.2;
const float ALPHA_MOMENTS = 0.2;
// History lengths are capped: beyond 1/α they change nothing but must not grow without bound.
const float MAX_LENGTH = 64.0;
// Reprojection tolerances: depth within this many gradient steps plus this fraction of depth;
// normals within acos(MIN_NORMAL_DOT).
const float DEPTH_GRADIENT_STEPS = 2.0;
const float DEPTH_RELATIVE = 0.02;
const float MIN_NORMAL_DOT = 0.9;

void main() {
    ivec2 p = svgf_pixel();
    if (p.x < 0) {
        return;
    }
    vec3 radiance = svgf_sanitize(imageLoad(images[pc.radiance], p).rgb);
    float z = imageLoad(images[pc.position], p).w;
    if (!(z > 0.0)) {
        // No albedo to divide by: the radiance as is (the à-trous passes let it through).
        imageStore(images[pc.out0], p, vec4(radiance, 0.0));
        imageStore(images[pc.out1], p, vec4(0.0));
        imageStore(images[pc.out2], p, vec4(0.0));
        imageStore(images[pc.out3], p, vec4(0.0));
        return;
    }
    vec3 albedo = svgf_effective_albedo(imageLoad(images[pc.albedo], p).rgb);
    // Clamped so that its square (the second moment) stays far inside the f32 range.
    float l = min(svgf_illumination_luminance(radiance, albedo), MAX_VALUE);
    vec3 n = imageLoad(images[pc.normal], p).xyz;
    float packed_normal = svgf_pack_normal(n);
    vec2 gradient = vec2(svgf_depth_slope(p, ivec2(1, 0), z), svgf_depth_slope(p, ivec2(0, 1), z));
    float tolerance = DEPTH_GRADIENT_STEPS * (abs(gradient.x) + abs(gradient.y)) + DEPTH_RELATIVE * z;

    // Motion is in pixels of the previous frame with centres at i + 0.5.
    vec2 motion = imageLoad(images[pc.motion], p).xy;
    vec3 prev_illum = vec3(0.0);
    vec2 prev_moments = vec2(0.0);
    float prev_length = 0.0;
    float weight_sum = 0.0;
    if (motion.x >= 0.0 && motion.y >= 0.0 && !any(isnan(motion)) && !any(isinf(motion))) {
        vec2 at = motion - 0.5;
        ivec2 base = ivec2(floor(at));
        vec2 f = at - vec2(base);
        for (int k = 0; k < 4; k++) {
            ivec2 o = ivec2(k & 1, k >> 1);
            float w = (o.x == 1 ? f.x : 1.0 - f.x) * (o.y == 1 ? f.y : 1.0 - f.y);
            ivec2 q = base + o;
            // Zero-weight taps are skipped, so a pixel centre reads exactly one texel.
            if (w <= 0.0 || !svgf_inside(q)) {
                continue;
            }
            vec4 pcol = imageLoad(images[pc.in0], q);
            vec4 pm = imageLoad(images[pc.in1], q);
            if (pcol.a < 1.0 || !(pm.z > 0.0) || abs(pm.z - z) > tolerance
                || dot(svgf_unpack_normal(pm.w), n) < MIN_NORMAL_DOT) {
                continue;
            }
            prev_illum += w * pcol.rgb;
            prev_moments += w * pm.xy;
            prev_length += w * pcol.a;
            weight_sum += w;
        }
    }
    float length_ = 1.0;
    vec3 out_radiance = radiance;
    vec2 moments = vec2(l, l * l);
    if (weight_sum > 1e-3) {
        length_ = min(prev_length / weight_sum + 1.0, MAX_LENGTH);
        float a = max(ALPHA_COLOR, 1.0 / length_);
        float am = max(ALPHA_MOMENTS, 1.0 / length_);
        out_radiance = mix(min(albedo * (prev_illum / weight_sum), vec3(MAX_VALUE)), radiance, a);
        moments = mix(prev_moments / weight_sum, moments, am);
    }
    imageStore(images[pc.out0], p, vec4(min(out_radiance / albedo, vec3(MAX_VALUE)), length_));
    imageStore(images[pc.out1], p, vec4(moments, z, packed_normal));
    imageStore(images[pc.out2], p, vec4(z, gradient, packed_normal));
    imageStore(images[pc.out3], p, vec4(albedo, length_));
}
