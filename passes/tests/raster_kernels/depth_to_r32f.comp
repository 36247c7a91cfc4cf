#version 460
// Test kernel of tests/lavapipe_raster.rs: copies the depth resource `src0` (a Depth32f image,
// read through the sampled depth array) into the R32f storage image `dst` over the instance's
// rows: what any later compute pass does to read a raster pass's depth.
#extension GL_GOOGLE_include_directive : require
#include "bindless.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    if (x >= pc.width || y >= pc.y1) {
        return;
    }
    float depth = texelFetch(depth_images[pc.src0], ivec2(x, y), 0).r;
    imageStore(images[pc.dst], ivec2(x, y), vec4(depth, 0.0, 0.0, 0.0));
}
