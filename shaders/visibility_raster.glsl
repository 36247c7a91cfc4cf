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

// Vertices a triangle clipped by the four side planes can have (3 + 4), and one more.
const uint CLIP_VERTICES = 8u;

// The side plane `k` of the band's frustum as coefficients l of l · h >= 0 inside, for points
// h = (X, Y, c) of homogeneous pixel space (pixel_box): the pixel edges x = 0, x = width, y = y0
// and y = y1. Each plane goes through the eye, and the outermost pixel centres of the band lie
// half a pixel inside it.
vec3 band_plane(uint k, vec2 size) {
    return k == 0u ? vec3(1.0, 0.0, 0.0)
        : k == 1u  ? vec3(-1.0, 0.0, size.x)
        : k == 2u  ? vec3(0.0, 1.0, -float(pc.y0))
                   : vec3(0.0, -1.0, float(pc.y1));
}

// The pixels [x0, x1) × [y0, y1) of the band whose centre rays may hit `tri` (empty: x0 >= x1
// or y0 >= y1). A point q = v - eye is a·right + b·up + c·forward in the camera's orthogonal
// basis, and the ray through image-plane point p = ndc + shift is right·p.x + up·p.y + forward,
// so q projects to p = (a, b) / c, pixel (X, Y) / c with (X, Y, c) linear in q (homogeneous
// pixel space, below). A camera ray's points at t > 0 all have c > 0 and the band's centre rays
// lie in the pyramid of its four side planes through the eye (band_plane), which holds no point
// with c < 0 (X >= 0 and X <= width · c there): the triangle is clipped to that pyramid
// (Sutherland–Hodgman in homogeneous pixel space, where the planes are linear) and the box is
// that of the clipped polygon's projection, which bounds every point of the triangle that a
// centre ray of the band can reach.
//
// Why clip rather than bound the corners: a triangle crossing the eye's plane (a building's
// floor, walls and ceiling reaching behind the camera) projects to infinity, and a thin
// triangle's box reaches far outside the view; stretched to the band's edges such boxes were
// 72 % of Sponza's pixel tests (docs/PIPELINE.md). A triangle inside every plane, the common
// case, is not clipped: its box is its corners' box as before.
uvec4 pixel_box(BvhTriangle tri) {
    vec3 eye = params.eye.xyz;
    vec3 right = params.right.xyz / dot(params.right.xyz, params.right.xyz);
    vec3 up = params.up.xyz / dot(params.up.xyz, params.up.xyz);
    vec3 forward = params.forward.xyz / dot(params.forward.xyz, params.forward.xyz);
    vec2 size = vec2(params.dims.xy);
    vec3 world[3] = vec3[3](tri.v0, tri.v1, tri.v2);
    vec3 poly[CLIP_VERTICES];
    // The rounding of h's components is far below this (a relative 1e-5 of the largest).
    float tiny = 0.0;
    for (uint k = 0u; k < 3u; k++) {
        vec3 q = world[k] - eye;
        float c = dot(q, forward);
        // pixel = ((a / c - shift.x + 1) · width / 2, (1 - (b / c - shift.y)) · height / 2)
        // times c; y grows downwards.
        poly[k] = vec3((dot(q, right) + (1.0 - params.shift.x) * c) * 0.5 * size.x,
                       ((1.0 + params.shift.y) * c - dot(q, up)) * 0.5 * size.y, c);
        tiny = max(tiny, max(abs(poly[k].x), max(abs(poly[k].y), abs(c))));
    }
    tiny *= 1e-5;
    if (any(isnan(poly[0])) || any(isnan(poly[1])) || any(isnan(poly[2])) || isinf(tiny)) {
        // A NaN or infinite corner bounds nothing: the band.
        return uvec4(0u, pc.y0, pc.width, pc.y1);
    }
    // Wholly behind the eye's plane, or wholly outside one side plane: nothing to hit.
    if (poly[0].z <= 0.0 && poly[1].z <= 0.0 && poly[2].z <= 0.0) {
        return uvec4(0u);
    }
    bool clipped = false;
    for (uint k = 0u; k < 4u; k++) {
        vec3 l = band_plane(k, size);
        vec3 f = vec3(dot(l, poly[0]), dot(l, poly[1]), dot(l, poly[2]));
        if (all(lessThan(f, vec3(0.0)))) {
            return uvec4(0u);
        }
        clipped = clipped || any(lessThan(f, vec3(0.0)));
    }
    uint count = 3u;
    if (clipped) {
        for (uint k = 0u; k < 4u; k++) {
            vec3 l = band_plane(k, size);
            vec3 kept[CLIP_VERTICES];
            uint n = 0u;
            for (uint i = 0u; i < count; i++) {
                vec3 q = poly[i];
                vec3 r = poly[i + 1u == count ? 0u : i + 1u];
                float fq = dot(l, q);
                float fr = dot(l, r);
                if (n + 2u > CLIP_VERTICES) {
                    // More vertices than a convex polygon has (rounding): the band.
                    return uvec4(0u, pc.y0, pc.width, pc.y1);
                }
                if (fq >= 0.0) {
                    kept[n++] = q;
                }
                if ((fq >= 0.0) != (fr >= 0.0)) {
                    kept[n++] = q + (fq / (fq - fr)) * (r - q);
                }
            }
            if (n == 0u) {
                return uvec4(0u);
            }
            poly = kept;
            count = n;
        }
    }
    vec2 lo = vec2(INFINITY);
    vec2 hi = vec2(-INFINITY);
    for (uint i = 0u; i < count; i++) {
        vec3 h = poly[i];
        if (h.z <= 0.0) {
            // A corner behind the eye's plane (not clipped) or a clipped vertex at the eye
            // itself (a triangle through the eye): the band, as the test decides.
            return uvec4(0u, pc.y0, pc.width, pc.y1);
        }
        vec2 pixel = h.xy / h.z;
        // A clipped vertex moves by the rounding of the interpolation, at most `tiny` in X and
        // Y, which the division by c scales up.
        vec2 moved = vec2(clipped ? tiny / h.z : 0.0);
        lo = min(lo, pixel - moved);
        hi = max(hi, pixel + moved);
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
