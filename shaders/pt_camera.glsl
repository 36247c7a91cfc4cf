// What a camera ray sees without tracing: its direction through a pixel and, once it has left
// the scene, the sky and the sun disc. The path tracer's primary rays (pt_trace.glsl), the
// G-buffer's centre rays (gbuffer_trace.comp) and reprojection's sky pixels (reproject.comp)
// all come from here, so a sky pixel that reprojection fills is what path tracing that pixel
// gives. Twin of parallax_scene::pt (camera rays) and parallax_scene::lights (sky, sun).
//
// Expects `params` (a TraceParams, pt_types.glsl) named before inclusion, like pt_trace.glsl.

#ifndef PT_CAMERA_GLSL
#define PT_CAMERA_GLSL

#include "pt_constants.glsl"
#include "pt_rng.glsl"

const uint LIGHT_GROUP_SUN = 1u;
const uint LIGHT_GROUP_SKY = 2u;
const uint LIGHT_GROUP_PUNCTUAL = 4u;
const uint LIGHT_GROUP_EMISSIVE = 8u;

// The camera ray of pixel (x, y) through the point `jitter` of the pixel ((0.5, 0.5): centre).
vec3 camera_direction(uint x, uint y, vec2 jitter) {
    float w = float(params.dims.x);
    float h = float(params.dims.y);
    vec2 ndc = vec2((float(x) + jitter.x) / w * 2.0 - 1.0, 1.0 - (float(y) + jitter.y) / h * 2.0);
    vec2 p = ndc + params.shift.xy;
    return normalize(params.right.xyz * p.x + params.up.xyz * p.y + params.forward.xyz);
}

// Where in its pixel camera sample `s` of the path with key `key` passes (rng_key of the pixel).
vec2 camera_jitter(uvec4 key, uint s) {
    return params.sampling.w != 0u ? rng_uniforms(key, s, 0u, DIM_CAMERA).xy : vec2(0.5);
}

vec3 sky_radiance(vec3 dir) {
    if (params.sky_zenith.w == 0.0) {
        return params.sky_zenith.rgb;
    }
    return dir.y >= 0.0 ? mix(params.sky_horizon.rgb, params.sky_zenith.rgb, min(dir.y, 1.0)) : params.sky_ground.rgb;
}

// The sun disc from values the CPU computed precisely (parallax_scene::lights::sun_disc):
// x = cos of the angular radius, y = 1 - cos (0: delta sun), z = radiance per irradiance.
vec3 sun_disc() {
    float one_minus_cos = params.sun_irradiance.w;
    return vec3(params.sun_dir.w, one_minus_cos, 1.0 / (PI * one_minus_cos * (2.0 - one_minus_cos)));
}

// The sun disc's radiance along `dir` (0 off the disc, and for a delta sun, which no ray hits).
vec3 sun_radiance(vec3 dir) {
    vec3 disc = sun_disc();
    if (disc.y <= 0.0 || (params.counts.z & LIGHT_GROUP_SUN) == 0u) {
        return vec3(0.0);
    }
    return dot(dir, normalize(params.sun_dir.xyz)) >= disc.x ? params.sun_irradiance.rgb * disc.z : vec3(0.0);
}

// What a camera ray that leaves the scene at once returns: sky and sun disc, unweighted (no
// light sample came before it to share the estimate with).
vec3 camera_miss_radiance(vec3 dir) {
    return sky_radiance(dir) + sun_radiance(dir);
}

// The path tracer's estimate of pixel (x, y) when every one of its camera samples misses the
// scene: trace_pixel's loop without the tracing, the same samples, jitter and sum.
vec3 sky_pixel(uint x, uint y) {
    uvec4 key = rng_key(x, y, params.dims.z, params.dims.w);
    vec3 sum = vec3(0.0);
    for (uint s = 0u; s < params.sampling.x; s++) {
        vec3 l = camera_miss_radiance(camera_direction(x, y, camera_jitter(key, s)));
        if (!any(isnan(l)) && !any(isinf(l))) {
            sum += l;
        }
    }
    return sum / float(params.sampling.x);
}

#endif
