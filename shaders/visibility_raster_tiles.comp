#version 460
// The `visibility_raster` pass's second dispatch (parallax_passes::visibility::
// VisibilityRasterKernel, an indirect dispatch on the band's tile list that the first wrote):
// one workgroup a listed tile of a large triangle's box, one invocation a pixel, the same test
// and atomicMax as visibility_raster.comp (visibility_raster.glsl).
#extension GL_GOOGLE_include_directive : require
#include "visibility_raster.glsl"

layout(local_size_x = 16, local_size_y = 16) in;

// Whether no centre ray of the pixels [start, end) can hit `tri`, so the tile's workgroup can
// skip its tests: a large box is mostly empty for a thin or diagonal triangle (on Sponza lite
// from the benchmark camera half of the tiles hold no covered pixel centre). With q_i = v_i -
// eye independent, a direction d = Σ λ_i q_i reaches the triangle at t > 0 exactly when every
// λ_i >= 0, and λ_k has the sign of orient · (q_i × q_j) · d (i, j the other two corners,
// orient = (q0 × q1) · q2). That is linear in the pixel position, so where it is negative at
// the four corner pixels' centre rays it is at every pixel's of the tile. Conservative: only
// below a margin far above the rounding of these products and of the ray test (a relative
// 1e-4 of |q_i| |q_j| |d|), and never for a triangle nearly edge-on to the eye.
bool tile_misses(BvhTriangle tri, uvec2 start, uvec2 end) {
    vec3 eye = params.eye.xyz;
    vec3 q[3] = vec3[3](tri.v0 - eye, tri.v1 - eye, tri.v2 - eye);
    float len[3] = float[3](length(q[0]), length(q[1]), length(q[2]));
    float orient = dot(cross(q[0], q[1]), q[2]);
    if (!(abs(orient) > 1e-4 * len[0] * len[1] * len[2])) {
        return false;
    }
    vec3 d[4] = vec3[4](camera_direction(start.x, start.y, vec2(0.5)), camera_direction(end.x - 1u, start.y, vec2(0.5)),
                        camera_direction(start.x, end.y - 1u, vec2(0.5)), camera_direction(end.x - 1u, end.y - 1u, vec2(0.5)));
    for (uint k = 0u; k < 3u; k++) {
        uint i = (k + 1u) % 3u;
        uint j = (k + 2u) % 3u;
        vec3 n = sign(orient) * cross(q[i], q[j]);
        // camera_direction is unit length.
        float margin = -1e-4 * len[i] * len[j];
        if (dot(n, d[0]) < margin && dot(n, d[1]) < margin && dot(n, d[2]) < margin && dot(n, d[3]) < margin) {
            return true;
        }
    }
    return false;
}

void main() {
    uvec4 tile = pc.tiles.tile[gl_WorkGroupID.x];
    uvec2 start = uvec2(tile.y & 0xffffu, tile.y >> 16);
    uvec2 end = uvec2(tile.z & 0xffffu, tile.z >> 16);
    BvhTriangle tri = bvh_load_triangle(tile.x);
    // The same for every invocation of the workgroup.
    if (tile_misses(tri, start, end)) {
        return;
    }
    uvec2 pixel = start + gl_LocalInvocationID.xy;
    if (pixel.x < end.x && pixel.y < end.y) {
        test_pixel(tri, tile.x, pixel.x, pixel.y);
    }
}
