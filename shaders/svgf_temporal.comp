#version 460
// SVGF, step 1 (`svgf_temporal`): demodulates radiance by albedo and accumulates the
// illumination and its first two luminance moments through `motion` into history.
//   radiance, albedo, normal, motion: own pixel; position: whole view (depth gradient)
//   in0 `svgf_prev_color`, in1 `svgf_prev_moments`, in2 `svgf_prev_normal`: whole view
//   out0 `svgf_illum`: (accumulated illumination rgb, history length)
//   out1 `svgf_moments`: (m1, m2, history length, 0), read as history next frame
// The previous frame is sampled bilinearly at the motion vector; a tap counts only if it is
// inside the image, had history, and saw the same surface (depth against the gradient, normal
// within ~25°). Without any valid tap the pixel restarts (length 1). Pixels without a hit keep
// their radiance and length 0.
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
    vec4 position = imageLoad(images[pc.position], p);
    vec3 radiance = svgf_sanitize(imageLoad(images[pc.radiance], p).rgb);
    float z = position.w;
    if (!(z > 0.0)) {
        imageStore(images[pc.out0], p, vec4(radiance, 0.0));
        imageStore(images[pc.out1], p, vec4(0.0));
        return;
    }
    vec3 albedo = svgf_sanitize(imageLoad(images[pc.albedo], p).rgb);
    vec3 illum = min(radiance / svgf_albedo_divisor(albedo), vec3(MAX_VALUE));
    float l = svgf_luminance(illum);
    vec3 n = imageLoad(images[pc.normal], p).xyz;
    vec2 gradient = svgf_depth_gradient(p, z);
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
            vec3 pn = imageLoad(images[pc.in2], q).xyz;
            if (pcol.a < 1.0 || !(pm.z > 0.0) || abs(pm.z - z) > tolerance || dot(pn, n) < MIN_NORMAL_DOT) {
                continue;
            }
            prev_illum += w * pcol.rgb;
            prev_moments += w * pm.xy;
            prev_length += w * pcol.a;
            weight_sum += w;
        }
    }
    float length_ = 1.0;
    vec3 out_illum = illum;
    vec2 moments = vec2(l, l * l);
    if (weight_sum > 1e-3) {
        prev_illum /= weight_sum;
        prev_moments /= weight_sum;
        length_ = min(prev_length / weight_sum + 1.0, MAX_LENGTH);
        float a = max(ALPHA_COLOR, 1.0 / length_);
        float am = max(ALPHA_MOMENTS, 1.0 / length_);
        out_illum = mix(prev_illum, illum, a);
        moments = mix(prev_moments, moments, am);
    }
    imageStore(images[pc.out0], p, vec4(out_illum, length_));
    imageStore(images[pc.out1], p, vec4(moments, length_, 0.0));
}
