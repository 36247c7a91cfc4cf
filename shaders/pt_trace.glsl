// GPU path tracer, the twin of parallax_scene::pt::CpuTracer: same camera, random numbers,
// BVH, materials, lights, MIS and depth convention, so that for every pixel it estimates the
// same integral with the same random numbers (values differ only where float rounding of
// transcendental functions sends a path another way).
//
// A library: `trace_pixel(x, y)` returns one pixel's radiance and first-hit data. The kernel
// that includes it (shaders/pt_trace.comp) declares the scene references (`PT_SCENE`, see
// pt_scene.glsl) and names the view's TraceParams `params` before the include:
//   #define params (pc.trace.p)

#ifndef PT_TRACE_GLSL
#define PT_TRACE_GLSL

#include "pt_scene.glsl"
#define BVH_NODES scene_nodes.data
#define BVH_TRIS scene_triangle_words.data
#include "bvh_traverse.glsl"
#include "pt_rng.glsl"
#include "pt_bsdf.glsl"
#include "pt_lights.glsl"

float mis_weight(float pdf_a, float pdf_b) {
    float a = pdf_a * pdf_a;
    float b = pdf_b * pdf_b;
    if (a + b > 0.0 && !isinf(a + b)) {
        return a / (a + b);
    }
    return pdf_a > 0.0 ? 1.0 : 0.0;
}

// Waechter and Binder, Ray Tracing Gems ch. 6: `offset_ray_origin`.
vec3 offset_ray_origin(vec3 p, vec3 n) {
    ivec3 of_i = ivec3(256.0 * n);
    vec3 moved = intBitsToFloat(floatBitsToInt(p) + ivec3(p.x < 0.0 ? -of_i.x : of_i.x,
                                                           p.y < 0.0 ? -of_i.y : of_i.y,
                                                           p.z < 0.0 ? -of_i.z : of_i.z));
    const float origin = 1.0 / 32.0;
    const float float_scale = 1.0 / 65536.0;
    return vec3(abs(p.x) < origin ? p.x + float_scale * n.x : moved.x,
                abs(p.y) < origin ? p.y + float_scale * n.y : moved.y,
                abs(p.z) < origin ? p.z + float_scale * n.z : moved.z);
}

// BVH primitive of no triangle: a centre ray that missed, or a G-buffer without first hits.
const uint NO_PRIMITIVE = 0xffffffffu;

// How far past the distance to a pixel's centre-ray triangle a camera ray's bounded traversal
// reaches (relative): node boxes whose entry rounds beyond the hit must stay in.
const float CAMERA_BOUND_SLACK = 1.0 / 128.0;

// The closest hit of the ray (origin, dir), a camera ray through a pixel whose centre ray
// first hit BVH primitive `centre` (the G-buffer's `first_hit`), or any ray with NO_PRIMITIVE.
// Where the ray hits that triangle too (alpha mask included), at t, its closest hit is no
// farther than t, so the traversal starts with tmax just past t and skips every node behind
// the surface. The hit is the unbounded traversal's: nodes are visited in the same order (the
// order of children depends on the ray's octant, not on tmax), and every triangle up to t is
// tested in both, so the same one wins by the same rule (the closest, the earlier at equal
// distance). Should rounding at a box face still lose that triangle (nothing found, or
// something farther), the ray is traced again unbounded. One traversal call site: each one
// inlines the whole traversal loop.
BvhHit closest_hit_from(vec3 origin, vec3 dir, uint centre) {
    const float unbounded = 1.0 / 0.0;
    float t_centre = unbounded;
    if (centre != NO_PRIMITIVE) {
        vec2 bary;
        float t = bvh_test_triangle(bvh_load_triangle(centre), centre, bvh_make_ray(origin, dir, 0.0, unbounded), bary);
        t_centre = t >= 0.0 ? t : unbounded;
    }
    float tmax = t_centre + t_centre * CAMERA_BOUND_SLACK;
    BvhHit hit;
    bool lost;
    do {
        hit = bvh_closest_hit(bvh_make_ray(origin, dir, 0.0, tmax));
        lost = tmax != unbounded && (hit.primitive == NO_PRIMITIVE || hit.t > t_centre);
        tmax = unbounded;
    } while (lost);
    return hit;
}

// One path of `sample_index` from the camera ray (origin, dir); `centre` bounds its first
// traversal (closest_hit_from), the bounces after it trace as any path does.
vec3 trace_path(uvec4 key, uint sample_index, vec3 origin, vec3 dir, bool first, uint centre, inout PixelOut g) {
    vec3 radiance = vec3(0.0);
    vec3 throughput = vec3(1.0);
    vec3 ro = origin;
    vec3 rd = dir;
    bool has_prev = false;
    vec3 prev_position = vec3(0.0);
    vec3 prev_normal = vec3(0.0);
    float prev_pdf = 0.0;
    uint max_depth = params.sampling.y;
    for (uint depth = 0u; depth <= max_depth; depth++) {
        BvhHit hit = closest_hit_from(ro, rd, depth == 0u ? centre : NO_PRIMITIVE);
        if (hit.primitive == NO_PRIMITIVE) {
            if (!has_prev) {
                // A camera ray that misses: what reprojection writes for sky pixels too.
                radiance += throughput * camera_miss_radiance(rd);
            } else {
                vec3 sky = sky_radiance(rd);
                vec3 sun = sun_radiance(rd);
                radiance += throughput * (sky * mis_weight(prev_pdf, pdf_sky(prev_normal, rd))
                                          + sun * mis_weight(prev_pdf, pdf_sun(rd)));
            }
            break;
        }
        SurfacePoint sp = surface_point(hit.primitive, hit.barycentrics, hit.t, ro, rd);
        if (first && depth == 0u) {
            g.radiance.a = 1.0;
            g.albedo_roughness = vec4(sp.base_color, sp.roughness);
            g.normal_metallic = vec4(sp.normal, sp.metallic);
            g.position_depth = vec4(sp.position, dot(sp.position - params.eye.xyz, params.forward.xyz));
        }
        if (max(max(sp.emission.x, sp.emission.y), sp.emission.z) > 0.0) {
            float w = 1.0;
            if (has_prev) {
                w = mis_weight(prev_pdf, pdf_emissive(hit.primitive, prev_position, sp.position, sp.geometric_normal));
            }
            radiance += throughput * sp.emission * w;
        }
        if (depth == max_depth) {
            break;
        }
        vec3 wo = -rd;
        Bsdf bsdf = bsdf_new(sp, wo);
        vec3 o = offset_ray_origin(sp.position, sp.geometric_normal);

        vec4 lu = rng_uniforms(key, sample_index, depth + 1u, DIM_LIGHT);
        LightSample ls;
        if (sample_light(sp.position, sp.normal, lu, ls)) {
            vec4 e = bsdf_eval(bsdf, wo, ls.wi);
            if (max(max(e.x, e.y), e.z) > 0.0) {
                float tmax = ls.distance >= 0.0 ? max(ls.distance * (1.0 - 1e-4), 0.0) : 1.0 / 0.0;
                if (!bvh_occluded(bvh_make_ray(o, ls.wi, 0.0, tmax))) {
                    float w = ls.is_delta ? 1.0 : mis_weight(ls.pdf, e.w);
                    radiance += throughput * e.rgb * ls.radiance * (w / ls.pdf);
                }
            }
        }

        vec4 bu = rng_uniforms(key, sample_index, depth + 1u, DIM_BSDF);
        vec3 wi;
        vec3 weight;
        float pdf;
        if (!bsdf_sample(bsdf, wo, bu.xyz, wi, weight, pdf)) {
            break;
        }
        throughput *= weight;
        if (params.sampling.z != 0xffffffffu && depth + 1u >= params.sampling.z) {
            float survive = clamp(max(max(throughput.x, throughput.y), throughput.z), 0.05, 0.95);
            if (rng_uniforms(key, sample_index, depth + 1u, DIM_ROULETTE).x >= survive) {
                break;
            }
            throughput /= survive;
        }
        if (max(max(throughput.x, throughput.y), throughput.z) <= 0.0) {
            break;
        }
        has_prev = true;
        prev_position = sp.position;
        prev_normal = sp.normal;
        prev_pdf = pdf;
        ro = o;
        rd = wi;
    }
    return radiance;
}

// One pixel: `spp` samples (the view's TraceParams), radiance averaged, first-hit data of
// sample 0. Depends only on (x, y) and the parameters, never on which pixels are traced
// alongside or on which device, nor on `centre` (the BVH primitive the pixel's centre ray
// first hit, or NO_PRIMITIVE), which only shortens the camera rays' traversals.
PixelOut trace_pixel_from(uint x, uint y, uint centre) {
    uvec4 key = rng_key(x, y, params.dims.z, params.dims.w);
    PixelOut g;
    g.radiance = vec4(0.0);
    g.albedo_roughness = vec4(0.0);
    g.normal_metallic = vec4(0.0);
    g.position_depth = vec4(0.0);
    vec3 sum = vec3(0.0);
    for (uint s = 0u; s < params.sampling.x; s++) {
        vec3 dir = camera_direction(x, y, camera_jitter(key, s));
        vec3 l = trace_path(key, s, params.eye.xyz, dir, s == 0u, centre, g);
        // Like the CPU: a non-finite sample is dropped, never written.
        if (!any(isnan(l)) && !any(isinf(l))) {
            sum += l;
        }
    }
    g.radiance.rgb = sum / float(params.sampling.x);
    return g;
}

PixelOut trace_pixel(uint x, uint y) {
    return trace_pixel_from(x, y, NO_PRIMITIVE);
}

#endif
