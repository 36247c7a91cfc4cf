// What the two dispatches of the `visibility_raster` pass share
// (parallax_passes::visibility::VisibilityRasterKernel): the push block, the pixel box of a
// triangle, the test of one pixel, and the band's tile list.
//
// visibility_raster.comp takes one triangle an invocation. A triangle of a small box tests its
// pixels itself; a larger one is shared by its workgroup; one of a box over TILED_PIXELS is cut
// into TILE × TILE tiles appended to the band's tile list, which visibility_raster_tiles.comp
// then runs as one workgroup a tile (an indirect dispatch on the list's count), so a triangle
// that covers half the view is spread over the whole GPU instead of holding up one workgroup.
// The atomicMax of each test makes the result independent of who tests which pixel, in which
// order: the keys are the same bits whichever path a triangle takes.

#ifndef VISIBILITY_RASTER_GLSL
#define VISIBILITY_RASTER_GLSL

#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int8 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_atomic_int64 : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "pt_types.glsl"
#include "visibility.glsl"

// The band's tile list, at the band's first row of the `visibility_tiles` row buffer (reset to
// zeros every frame): indirect dispatch arguments whose x is the number of tiles, then the
// tiles. A tile is (triangle, first pixel x | y << 16, end pixel x | y << 16, unused).
layout(buffer_reference, std430, buffer_reference_align = 16) buffer VisibilityTiles {
    uint count; // the dispatch's x: tiles listed, at most pc.tile_capacity
    uint groups_y;
    uint groups_z;
    uint pad;
    uvec4 tile[];
};

// parallax_passes::shaders::VisibilityRasterPush, generated from this block.
layout(push_constant, std430) uniform VisibilityRasterPush {
    SceneRefs scene;
    TraceParamsRef trace; // this view's TraceParams in the per-frame data
    VisibilityKeys keys;  // this view's keys, row 0
    VisibilityTiles tiles; // this band's tile list
    uint y0;
    uint y1;
    uint width;
    uint triangles;
    uint groups_x; // workgroups per row of the per-triangle dispatch grid
    uint tile_capacity;
} pc;

#define PT_SCENE pc.scene
#define params (pc.trace.p)
#include "pt_trace.glsl"

const uint TILE = 16u;
const uint TILED_PIXELS = 1024u;

// +inf and -inf, for box corners that go to infinity.
const float INFINITY = 1.0 / 0.0;

// The pixels [x0, x1) × [y0, y1) of the band whose centre rays may hit `tri` (empty: x0 >= x1
// or y0 >= y1). A point q = v - eye is a·right + b·up + c·forward in the camera's orthogonal
// basis, and the ray through image-plane point p = ndc + shift is right·p.x + up·p.y + forward,
// so q projects to p = (a, b) / c. A camera ray's points at t > 0 all have c > 0, so only the
// part of the triangle in front of the eye's plane can be hit: the triangle is clipped to
// c > 0, and each point where an edge crosses c = 0 projects to infinity in the direction of
// its (a, b), which stretches the box to the band's edges on those sides only (both sides of
// an axis where the direction's component is too small to know its sign). The box of the
// clipped triangle bounds the projection of every point of it.
uvec4 pixel_box(BvhTriangle tri) {
    vec3 eye = params.eye.xyz;
    vec3 right = params.right.xyz / dot(params.right.xyz, params.right.xyz);
    vec3 up = params.up.xyz / dot(params.up.xyz, params.up.xyz);
    vec3 forward = params.forward.xyz / dot(params.forward.xyz, params.forward.xyz);
    vec3 corners[3] = vec3[3](tri.v0 - eye, tri.v1 - eye, tri.v2 - eye);
    vec2 size = vec2(params.dims.xy);
    vec2 lo = vec2(INFINITY);
    vec2 hi = vec2(-INFINITY);
    uint in_front = 0u;
    for (uint k = 0u; k < 3u; k++) {
        vec3 q = corners[k];
        float c = dot(q, forward);
        if (c > 0.0) {
            in_front++;
            vec2 ndc = vec2(dot(q, right), dot(q, up)) / c - params.shift.xy;
            // Pixel coordinates: x + 0.5 is pixel x's centre; y grows downwards.
            vec2 pixel = vec2((ndc.x + 1.0) * 0.5 * size.x, (1.0 - ndc.y) * 0.5 * size.y);
            lo = min(lo, pixel);
            hi = max(hi, pixel);
        }
        vec3 r = corners[(k + 1u) % 3u];
        float d = dot(r, forward);
        if ((c > 0.0) != (d > 0.0)) {
            // The edge crosses the eye's plane at s: (a, b) there is the direction its
            // projection leaves in. Pixel x grows with a, pixel y falls with b.
            float s = c / (c - d);
            vec3 crossing = q + s * (r - q);
            vec2 ab = vec2(dot(crossing, right), dot(crossing, up));
            // Rounding moves the computed crossing by far less than this.
            vec2 tiny = vec2(1e-5 * (length(q) + length(r)));
            if (ab.x > tiny.x) {
                hi.x = INFINITY;
            } else if (ab.x < -tiny.x) {
                lo.x = -INFINITY;
            } else {
                lo.x = -INFINITY;
                hi.x = INFINITY;
            }
            if (ab.y > tiny.y) {
                lo.y = -INFINITY;
            } else if (ab.y < -tiny.y) {
                hi.y = INFINITY;
            } else {
                lo.y = -INFINITY;
                hi.y = INFINITY;
            }
        }
    }
    if (in_front == 0u || any(isnan(lo)) || any(isnan(hi))) {
        // Wholly behind the eye (nothing to hit); a NaN corner bounds nothing: the band.
        return in_front == 0u ? uvec4(0u) : uvec4(0u, pc.y0, pc.width, pc.y1);
    }
    // Pixels whose centres x + 0.5 lie within the projected box widened by a margin far above
    // the rounding of the projection and of the ray test (a twentieth of a pixel, and a
    // relative 1e-5 for corners far outside), clamped to the band before converting. A
    // triangle between pixel centres then tests no pixel at all; the ray test decides the rest.
    vec2 first = clamp(ceil(lo - 0.5 - (0.05 + 1e-5 * abs(lo))), vec2(0.0), size);
    vec2 last = clamp(floor(hi - 0.5 + (0.05 + 1e-5 * abs(hi))) + 1.0, vec2(0.0), size);
    return uvec4(uint(first.x), max(uint(first.y), pc.y0), uint(last.x), min(uint(last.y), pc.y1));
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

#endif
