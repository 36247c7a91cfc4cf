#version 460
// The `tonemap` pass (parallax_passes::tonemap): display = sRGB(ACES(exposure * rgb)), alpha 1,
// into an RGBA8 UNORM image. ACES is Krzysztof Narkowicz's fit of the ACES filmic curve
// (2016), applied per channel; the CPU twin is parallax_passes::tonemap::tonemap_pixel.
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"

// 32 bytes; parallax_passes::shaders::TonemapPush, generated from this block.
layout(push_constant, std430) uniform TonemapPush {
    uint src;
    uint dst;
    uint y0;
    uint y1;
    uint width;
    float exposure;
    // With scaled = 1, exposure is multiplied by texel (0, 0) of images[scale]: a global 1x1
    // image an earlier pass of the frame measured (auto-exposure).
    uint scale;
    uint scaled;
} pc;

layout(local_size_x = 8, local_size_y = 8) in;

vec3 aces_narkowicz(vec3 x) {
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}

vec3 srgb_encode(vec3 c) {
    return mix(1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, 12.92 * c, lessThanEqual(c, vec3(0.0031308)));
}

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    if (x >= pc.width || y >= pc.y1) {
        return;
    }
    float exposure = pc.exposure;
    if (pc.scaled != 0u) {
        exposure *= imageLoad(images[pc.scale], ivec2(0, 0)).r;
    }
    vec3 rgb = imageLoad(images[pc.src], ivec2(x, y)).rgb * exposure;
    // NaN and negatives show as black, +Inf as white (the curve saturates at 1; 1e6 keeps its
    // squares finite).
    rgb = mix(rgb, vec3(0.0), isnan(rgb));
    rgb = clamp(rgb, vec3(0.0), vec3(1e6));
    imageStore(images[pc.dst], ivec2(x, y), vec4(srgb_encode(aces_narkowicz(rgb)), 1.0));
}
