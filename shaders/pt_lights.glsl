// Light sampling, the twin of parallax_scene::lights (surface evaluation: pt_surface.glsl; the
// sky and sun a ray sees: pt_camera.glsl).
// Expects, declared before inclusion: the scene buffers (pt_scene.glsl), the BVH traversal,
// and `params` (TraceParams of pt_trace.glsl) holding sky, sun and light-group data.

#ifndef PT_LIGHTS_GLSL
#define PT_LIGHTS_GLSL

#include "pt_camera.glsl"
#include "pt_surface.glsl"

uint light_group_count() {
    return bitCount(params.counts.z);
}

float light_group_prob(uint group) {
    return (params.counts.z & group) != 0u ? 1.0 / float(light_group_count()) : 0.0;
}

struct LightSample {
    vec3 wi;
    float distance; // < 0: infinitely far
    vec3 radiance;
    float pdf;
    bool is_delta;
};

bool sample_light(vec3 p, vec3 n, vec4 u, out LightSample ls) {
    ls.wi = vec3(0.0);
    ls.distance = -1.0;
    ls.radiance = vec3(0.0);
    ls.pdf = 0.0;
    ls.is_delta = false;
    uint count = light_group_count();
    if (count == 0u) {
        return false;
    }
    uint gi = min(uint(u.x * float(count)), count - 1u);
    float p_group = 1.0 / float(count);
    float u_within = clamp(u.x * float(count) - float(gi), 0.0, 0.99999994);
    // The gi-th set bit of the group mask.
    uint mask = params.counts.z;
    for (uint k = 0u; k < gi; k++) {
        mask &= mask - 1u;
    }
    uint group = mask & (~mask + 1u);

    if (group == LIGHT_GROUP_SUN) {
        vec3 to_sun = normalize(params.sun_dir.xyz);
        vec3 disc = sun_disc();
        if (disc.y <= 0.0) {
            ls.wi = to_sun;
            ls.radiance = params.sun_irradiance.rgb;
            ls.pdf = p_group;
            ls.is_delta = true;
            return true;
        }
        float cos_t = 1.0 - u.y * disc.y;
        float sin_t = sqrt(max(1.0 - cos_t * cos_t, 0.0));
        float phi = TAU * u.z;
        vec3 t, b;
        orthonormal_basis(to_sun, t, b);
        ls.wi = normalize(t * (sin_t * cos(phi)) + b * (sin_t * sin(phi)) + to_sun * cos_t);
        ls.radiance = params.sun_irradiance.rgb * disc.z;
        ls.pdf = p_group / (TAU * disc.y);
        return true;
    }
    if (group == LIGHT_GROUP_SKY) {
        ls.wi = sample_cosine_hemisphere(n, u.y, u.z);
        ls.pdf = p_group * max(dot(ls.wi, n), 0.0) * INV_PI;
        ls.radiance = sky_radiance(ls.wi);
        return ls.pdf > 0.0;
    }
    if (group == LIGHT_GROUP_PUNCTUAL) {
        uint n_lights = params.counts.x;
        uint k = min(uint(u_within * float(n_lights)), n_lights - 1u);
        PunctualLight l = scene_lights.data[k];
        ls.pdf = p_group / float(n_lights);
        ls.is_delta = true;
        if (l.kind == LIGHT_DIRECTIONAL) {
            ls.wi = -l.direction;
            ls.radiance = l.power;
            return true;
        }
        vec3 to_light = l.position - p;
        float d2 = dot(to_light, to_light);
        if (d2 <= 0.0) {
            return false;
        }
        ls.wi = to_light / sqrt(d2);
        ls.distance = sqrt(d2);
        ls.radiance = l.power / d2;
        if (l.kind == LIGHT_SPOT) {
            float scale = 1.0 / max(l.cos_inner - l.cos_outer, 1e-3);
            float a = clamp((dot(l.direction, -ls.wi) - l.cos_outer) * scale, 0.0, 1.0);
            ls.radiance *= a * a;
        }
        return true;
    }
    // Emissive triangles: the first entry whose cumulative probability exceeds u_within.
    uint lo = 0u;
    uint hi = params.counts.y;
    while (lo < hi) {
        uint mid = (lo + hi) / 2u;
        if (scene_emissive.data[mid].cdf <= u_within) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    uint prim = scene_emissive.data[min(lo, params.counts.y - 1u)].bvh_primitive;
    BvhTriangle tri = scene_triangles.data[prim];
    float su = sqrt(u.y);
    float b1 = su * (1.0 - u.z);
    float b2 = su * u.z;
    vec3 q = tri.v0 * (1.0 - b1 - b2) + tri.v1 * b1 + tri.v2 * b2;
    vec3 to_light = q - p;
    float d2 = dot(to_light, to_light);
    if (d2 <= 0.0) {
        return false;
    }
    float dist = sqrt(d2);
    ls.wi = to_light / dist;
    Material m = scene_materials.data[tri.material];
    float cos_l = dot(oriented_face_normal(prim), -ls.wi);
    bool facing = cos_l > 0.0 || ((m.flags & TRI_DOUBLE_SIDED) != 0u && cos_l < 0.0);
    if (!facing) {
        return false;
    }
    ls.radiance = m.emissive;
    if (m.emissive_texture >= 0) {
        TriangleAttributes a = scene_attributes.data[prim];
        vec2 uv = a.uvs[0] * (1.0 - b1 - b2) + a.uvs[1] * b1 + a.uvs[2] * b2;
        ls.radiance *= srgb_to_linear(scene_texel(m.emissive_texture, uv).rgb);
    }
    TriangleAttributes a = scene_attributes.data[prim];
    ls.pdf = p_group * a.emissive_prob * d2 / (a.area * abs(cos_l));
    ls.distance = dist;
    return ls.pdf > 0.0 && !isinf(ls.pdf);
}

float pdf_sun(vec3 dir) {
    vec3 disc = sun_disc();
    if (disc.y <= 0.0) {
        return 0.0;
    }
    return dot(dir, normalize(params.sun_dir.xyz)) >= disc.x ? light_group_prob(LIGHT_GROUP_SUN) / (TAU * disc.y) : 0.0;
}

float pdf_sky(vec3 n, vec3 dir) {
    return light_group_prob(LIGHT_GROUP_SKY) * max(dot(n, dir), 0.0) * INV_PI;
}

float pdf_emissive(uint prim, vec3 from, vec3 hit, vec3 light_normal) {
    TriangleAttributes a = scene_attributes.data[prim];
    if (a.emissive_prob <= 0.0) {
        return 0.0;
    }
    vec3 d = hit - from;
    float d2 = dot(d, d);
    float cos_l = abs(dot(light_normal, d / sqrt(d2)));
    if (cos_l <= 0.0) {
        return 0.0;
    }
    return light_group_prob(LIGHT_GROUP_EMISSIVE) * a.emissive_prob * d2 / (a.area * cos_l);
}

#endif
