// Shared by the SVGF kernels (parallax_passes::svgf, Schied et al. 2017): the push-constant
// block, the G-buffer reads and the guards that keep every value finite.
#ifndef PARALLAX_SVGF_GLSL
#define PARALLAX_SVGF_GLSL

#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"

// 72 bytes; parallax_passes::svgf::SvgfPush (a test holds the layouts together). Image
// indices into images[]; what in0..in3 and out0..out2 hold depends on the kernel (see its
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
    uint y0;
    uint y1;
    uint width;
    uint height;
    uint step; // à-trous: tap spacing in pixels
    uint last; // à-trous: 1 on the last iteration (remodulate into `denoised`)
} pc;

layout(local_size_x = 8, local_size_y = 8) in;

// Illumination and moments are clamped here: squares and 49-tap sums then stay far below the
// f32 range, so no sum overflows to Inf.
const float MAX_VALUE = 1e8;
// Below this an albedo channel is treated as black: it is neither divided out nor multiplied
// back (radiance on a black surface, e.g. emission, is filtered as it is, not blown up).
const float MIN_ALBEDO = 1e-3;

// The pixel this invocation owns, or ivec2(-1) when it lies outside the band.
ivec2 svgf_pixel() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    return (x >= pc.width || y >= pc.y1) ? ivec2(-1) : ivec2(x, y);
}

bool svgf_inside(ivec2 p) {
    return p.x >= 0 && p.y >= 0 && p.x < int(pc.width) && p.y < int(pc.height);
}

// NaN and Inf (and negatives) become 0, large values MAX_VALUE.
vec3 svgf_sanitize(vec3 v) {
    bvec3 bad = bvec3(isnan(v).x || isinf(v).x, isnan(v).y || isinf(v).y, isnan(v).z || isinf(v).z);
    return clamp(mix(v, vec3(0.0), bad), vec3(0.0), vec3(MAX_VALUE));
}

// Per channel: what radiance is divided by to give illumination, and multiplied by to go back.
vec3 svgf_albedo_divisor(vec3 albedo) {
    return mix(albedo, vec3(1.0), lessThan(albedo, vec3(MIN_ALBEDO)));
}

float svgf_luminance(vec3 c) {
    return dot(c, vec3(0.2126, 0.7152, 0.0722));
}

// Linear depth of pixel p of the current frame; 0: no hit (sky).
float svgf_depth(ivec2 p) {
    return imageLoad(images[pc.position], p).w;
}

// One axis of the screen-space depth gradient: of the forward and backward differences, the
// smaller in magnitude, so that a depth edge on one side does not inflate it; a side without a
// hit (or off the image) is not used.
float svgf_depth_slope(ivec2 p, ivec2 axis, float z) {
    float best = 0.0;
    bool found = false;
    for (int s = -1; s <= 1; s += 2) {
        ivec2 q = p + s * axis;
        if (!svgf_inside(q)) {
            continue;
        }
        float zq = svgf_depth(q);
        // Written so that NaN fails too.
        if (!(zq > 0.0)) {
            continue;
        }
        float d = float(s) * (zq - z);
        if (!found || abs(d) < abs(best)) {
            best = d;
            found = true;
        }
    }
    return best;
}

// Depth change per pixel along x and y at p (depth z > 0).
vec2 svgf_depth_gradient(ivec2 p, float z) {
    return vec2(svgf_depth_slope(p, ivec2(1, 0), z), svgf_depth_slope(p, ivec2(0, 1), z));
}

// Edge-stopping weight on depth (Schied's w_z, σ_z = 1): the difference against what the
// gradient predicts for the offset, plus a floor relative to depth for curved or slanted
// surfaces that the linear prediction misses.
float svgf_depth_weight(float zp, float zq, vec2 gradient, vec2 offset) {
    float expected = abs(dot(gradient, offset));
    return exp(-abs(zp - zq) / (expected + 1e-3 * zp + 1e-12));
}

// Edge-stopping weight on normals (Schied's w_n, σ_n = 128).
// A NaN normal gives 0 (max(0, NaN) is undefined in GLSL, the comparison is not).
float svgf_normal_weight(vec3 np, vec3 nq) {
    float d = dot(np, nq);
    return d > 0.0 ? pow(min(d, 1.0), 128.0) : 0.0;
}

#endif
