#version 460
// The `visibility_raster` pass (parallax_passes::visibility::VisibilityRasterKernel): every BVH
// triangle against one view's row band, without tracing. Each invocation takes one triangle,
// bounds the pixels whose centre rays can reach it (its projection through the view's camera,
// exactly the camera of pt_camera.glsl, widened by a pixel), and tests those pixels' centre rays
// against it with the traversal's own triangle test (bvh_test_triangle: Moeller-Trumbore and
// the alpha mask), so coverage and distance are the traced first hit's bit for bit; the nearest
// triangle of each pixel is kept by a 64-bit atomicMax on its key (visibility.glsl).
//
// Triangles whose box holds more than LARGE_PIXELS pixels (or that cross the eye's plane, whose
// box is the whole band) are not looped over by their own invocation: they are queued in
// workgroup memory and the whole workgroup then shares each one's pixels, so one big triangle
// does not hold up a thread for its whole area.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int8 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_atomic_int64 : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "pt_types.glsl"
#include "visibility.glsl"

// parallax_passes::visibility::VisibilityRasterPush.
layout(push_constant, std430) uniform VisibilityRasterPush {
    SceneRefs scene;
    TraceParamsRef trace; // this view's TraceParams in the per-frame data
    VisibilityKeys keys;  // this view's keys, row 0
    uint y0;
    uint y1;
    uint width;
    uint triangles;
    uint groups_x; // workgroups per row of the dispatch grid
    uint pad;
} pc;

#define PT_SCENE pc.scene
#define params (pc.trace.p)
#include "pt_trace.glsl"

const uint GROUP = 64u;
const uint LARGE_PIXELS = 64u;

layout(local_size_x = 64) in;

shared uint large_count;
shared uint large_primitive[GROUP];
shared uvec4 large_box[GROUP];

// The pixels [x0, x1) × [y0, y1) of the band whose centre rays may hit `tri` (empty: x0 >= x1
// or y0 >= y1). A point q = v - eye is a·right + b·up + c·forward in the camera's orthogonal
// basis, and the ray through image-plane point p = ndc + shift is right·p.x + up·p.y + forward,
// so q projects to p = (a, b) / c; a triangle in front of the eye projects into the triangle
// of its projected corners. One crossing the eye's plane (a corner with c <= 0) gets the band.
uvec4 pixel_box(BvhTriangle tri) {
    vec3 eye = params.eye.xyz;
    vec3 right = params.right.xyz / dot(params.right.xyz, params.right.xyz);
    vec3 up = params.up.xyz / dot(params.up.xyz, params.up.xyz);
    vec3 forward = params.forward.xyz / dot(params.forward.xyz, params.forward.xyz);
    vec3 corners[3] = vec3[3](tri.v0 - eye, tri.v1 - eye, tri.v2 - eye);
    vec2 size = vec2(params.dims.xy);
    vec2 lo = vec2(1.0 / 0.0);
    vec2 hi = vec2(-1.0 / 0.0);
    uint behind = 0u;
    for (uint k = 0u; k < 3u; k++) {
        vec3 q = corners[k];
        float c = dot(q, forward);
        if (!(c > 0.0)) {
            behind++;
            continue;
        }
        vec2 ndc = vec2(dot(q, right), dot(q, up)) / c - params.shift.xy;
        // Pixel coordinates: x + 0.5 is pixel x's centre; y grows downwards.
        vec2 pixel = vec2((ndc.x + 1.0) * 0.5 * size.x, (1.0 - ndc.y) * 0.5 * size.y);
        lo = min(lo, pixel);
        hi = max(hi, pixel);
    }
    if (behind == 3u) {
        return uvec4(0u);
    }
    uvec4 box = uvec4(0u, pc.y0, pc.width, pc.y1);
    if (behind == 0u && all(equal(lo, lo)) && all(equal(hi, hi))) {
        // Pixels whose centres lie within the projected box, one more on each side against
        // rounding (the ray test decides), clamped to the band before converting.
        vec2 first = clamp(floor(lo - 0.5) - 1.0, vec2(0.0), size);
        vec2 last = clamp(ceil(hi - 0.5) + 2.0, vec2(0.0), size);
        box = uvec4(uint(first.x), max(uint(first.y), pc.y0), uint(last.x), min(uint(last.y), pc.y1));
    }
    return box;
}

void test_pixel(BvhTriangle tri, uint prim, uint x, uint y) {
    BvhRay ray = bvh_make_ray(params.eye.xyz, camera_direction(x, y, vec2(0.5)), 0.0, 1.0 / 0.0);
    vec2 bary;
    float t = bvh_test_triangle(tri, prim, ray, bary);
    // bvh_consider's acceptance: t < the initial tmax (infinity).
    if (t >= 0.0 && t < ray.tmax) {
        uint64_t key = visibility_key(t, prim);
        uint i = y * pc.width + x;
        // Most tests lose to what is there already: read before the atomic.
        if (key > pc.keys.data[i]) {
            atomicMax(pc.keys.data[i], key);
        }
    }
}

void main() {
    uint local = gl_LocalInvocationIndex;
    if (local == 0u) {
        large_count = 0u;
    }
    barrier();
    uint prim = (gl_WorkGroupID.y * pc.groups_x + gl_WorkGroupID.x) * GROUP + local;
    if (prim < pc.triangles) {
        BvhTriangle tri = bvh_load_triangle(prim);
        uvec4 box = pixel_box(tri);
        if (box.x < box.z && box.y < box.w) {
            uint box_width = box.z - box.x;
            if (box_width * (box.w - box.y) > LARGE_PIXELS) {
                uint slot = atomicAdd(large_count, 1u);
                large_primitive[slot] = prim;
                large_box[slot] = box;
            } else {
                for (uint y = box.y; y < box.w; y++) {
                    for (uint x = box.x; x < box.z; x++) {
                        test_pixel(tri, prim, x, y);
                    }
                }
            }
        }
    }
    barrier();
    uint large = large_count;
    for (uint k = 0u; k < large; k++) {
        uint p = large_primitive[k];
        uvec4 box = large_box[k];
        BvhTriangle tri = bvh_load_triangle(p);
        uint box_width = box.z - box.x;
        uint area = box_width * (box.w - box.y);
        for (uint i = local; i < area; i += GROUP) {
            test_pixel(tri, p, box.x + i % box_width, box.y + i / box_width);
        }
    }
}
