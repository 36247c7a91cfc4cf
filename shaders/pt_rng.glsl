// Counter-based random numbers, the twin of parallax_scene::rng: every value is a function of
// (pixel, view, frame, sample, bounce, dimension), so any device tracing a pixel draws the
// same numbers as the CPU reference. PCG4D (Jarzynski and Olano, JCGT 2020).

#ifndef PT_RNG_GLSL
#define PT_RNG_GLSL

const uint DIM_CAMERA = 0u;
const uint DIM_LIGHT = 1u;
const uint DIM_BSDF = 2u;
const uint DIM_ROULETTE = 3u;

uvec4 pcg4d(uvec4 v) {
    v = v * 1664525u + 1013904223u;
    v.x += v.y * v.w;
    v.y += v.z * v.x;
    v.z += v.x * v.y;
    v.w += v.y * v.z;
    v ^= v >> 16u;
    v.x += v.y * v.w;
    v.y += v.z * v.x;
    v.z += v.x * v.y;
    v.w += v.y * v.z;
    return v;
}

// The per-path key; `PathRng::new`.
uvec4 rng_key(uint pixel_x, uint pixel_y, uint view, uint frame) {
    return pcg4d(uvec4(pixel_x, pixel_y, view, frame));
}

// Four uniforms in [0, 1) for (sample, bounce, dim); `PathRng::uniforms`.
vec4 rng_uniforms(uvec4 key, uint sample_index, uint bounce, uint dim) {
    uvec4 h = pcg4d(uvec4(key.x ^ sample_index, key.y ^ bounce, key.z ^ dim, key.w));
    return vec4(h >> 8u) * (1.0 / 16777216.0);
}

#endif
