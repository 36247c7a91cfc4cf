#version 460
// The kernel of the `auto_exposure` example (examples/auto_exposure.rs): the log-average
// luminance of the light field mapped to middle grey, on the GPU, as
// parallax_accuracy::exposure::LogAverage computes it on the host (8x8 tiles' mean Rec. 709
// luminance, non-finite pixels and unlit tiles left out, KEY / exp(mean ln) within [1e-6, 1e6],
// 1 when nothing is lit). One workgroup per dispatch, in two modes:
//   mode 0 (`measure_luminance`, per view): the view's linear radiance -> its 1x1 image
//          (sum of ln tile mean, lit tiles);
//   mode 1 (`expose`, global): every view's 1x1 image -> the global 1x1 exposure image, which
//          the tonemap pass multiplies its exposure by.
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_nonuniform_qualifier : require
#include "bindless.glsl"

// Mode 1: the image index of every view's measure.
layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer ImageList {
    uint index[];
};

// 32 bytes; ExposurePush in auto_exposure.rs.
layout(push_constant, std430) uniform ExposurePush {
    uint mode;
    uint src;
    uint dst;
    uint width;
    uint height;
    uint views;
    ImageList list;
} pc;

const uint THREADS = 64;
const uint TILE = 8;
const float KEY = 0.18;

layout(local_size_x = 64) in;

shared float shared_ln[THREADS];
shared float shared_tiles[THREADS];

// Sums (ln, tiles) over the workgroup; thread 0 returns the totals.
vec2 workgroup_sum(float ln_sum, float tiles) {
    uint i = gl_LocalInvocationIndex;
    shared_ln[i] = ln_sum;
    shared_tiles[i] = tiles;
    barrier();
    for (uint stride = THREADS / 2; stride > 0; stride /= 2) {
        if (i < stride) {
            shared_ln[i] += shared_ln[i + stride];
            shared_tiles[i] += shared_tiles[i + stride];
        }
        barrier();
    }
    return vec2(shared_ln[0], shared_tiles[0]);
}

bool finite(float v) {
    return !isnan(v) && !isinf(v);
}

void measure() {
    uint cols = (pc.width + TILE - 1) / TILE;
    uint tiles = cols * ((pc.height + TILE - 1) / TILE);
    float ln_sum = 0.0;
    float lit = 0.0;
    for (uint t = gl_LocalInvocationIndex; t < tiles; t += THREADS) {
        uint x0 = (t % cols) * TILE;
        uint y0 = (t / cols) * TILE;
        float sum = 0.0;
        uint n = 0;
        for (uint y = y0; y < min(y0 + TILE, pc.height); y++) {
            for (uint x = x0; x < min(x0 + TILE, pc.width); x++) {
                vec3 rgb = imageLoad(images[pc.src], ivec2(x, y)).rgb;
                float l = 0.2126 * rgb.r + 0.7152 * rgb.g + 0.0722 * rgb.b;
                if (finite(l)) {
                    sum += l;
                    n++;
                }
            }
        }
        float mean = n > 0 ? sum / float(n) : 0.0;
        if (finite(mean) && mean > 0.0) {
            ln_sum += log(mean);
            lit += 1.0;
        }
    }
    vec2 total = workgroup_sum(ln_sum, lit);
    if (gl_LocalInvocationIndex == 0) {
        imageStore(images[pc.dst], ivec2(0, 0), vec4(total, 0.0, 1.0));
    }
}

void expose() {
    float ln_sum = 0.0;
    float lit = 0.0;
    for (uint v = gl_LocalInvocationIndex; v < pc.views; v += THREADS) {
        // Each invocation reads another view's image: the index varies across the workgroup.
        vec4 m = imageLoad(images[nonuniformEXT(pc.list.index[v])], ivec2(0, 0));
        ln_sum += m.x;
        lit += m.y;
    }
    vec2 total = workgroup_sum(ln_sum, lit);
    if (gl_LocalInvocationIndex == 0) {
        float exposure = total.y > 0.0 ? clamp(KEY / exp(total.x / total.y), 1e-6, 1e6) : 1.0;
        imageStore(images[pc.dst], ivec2(0, 0), vec4(exposure));
    }
}

void main() {
    if (pc.mode == 0u) {
        measure();
    } else {
        expose();
    }
}
