#version 460
// The `visibility_raster` pass's second dispatch (parallax_passes::visibility::
// VisibilityRasterKernel, an indirect dispatch on the band's tile list that the first wrote):
// one workgroup a listed tile of a large triangle's box, one invocation a pixel, the same test
// and atomicMax as visibility_raster.comp (visibility_raster.glsl).
#extension GL_GOOGLE_include_directive : require
#include "visibility_raster.glsl"

layout(local_size_x = 16, local_size_y = 16) in;

void main() {
    uvec4 tile = pc.tiles.tile[gl_WorkGroupID.x];
    uvec2 pixel = uvec2(tile.y & 0xffffu, tile.y >> 16) + gl_LocalInvocationID.xy;
    if (pixel.x < (tile.z & 0xffffu) && pixel.y < (tile.z >> 16)) {
        test_pixel(bvh_load_triangle(tile.x), tile.x, pixel.x, pixel.y);
    }
}
