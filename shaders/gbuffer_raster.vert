#version 460
// The raster G-buffer pass, vertex stage: corner gl_VertexIndex % 3 of BVH triangle
// gl_VertexIndex / 3, projected by this view's current view-projection (frame block).
#extension GL_GOOGLE_include_directive : require
#include "gbuffer_raster.glsl"

layout(location = 0) out vec2 barycentrics;
layout(location = 1) flat out uint primitive;

void main() {
    uint prim = uint(gl_VertexIndex) / 3u;
    uint corner = uint(gl_VertexIndex) % 3u;
    BvhTriangle tri = pc.scene.triangles.data[prim];
    vec3 position = corner == 0u ? tri.v0 : (corner == 1u ? tri.v1 : tri.v2);
    gl_Position = pc.frame.views[pc.view].current.view_proj * vec4(position, 1.0);
    // The frame block's clip space has y up, like the path tracer's image plane; Vulkan's
    // framebuffer rows grow downwards.
    gl_Position.y = -gl_Position.y;
    // Weights of the second and third corners, as a ray hit reports them.
    barycentrics = vec2(corner == 1u ? 1.0 : 0.0, corner == 2u ? 1.0 : 0.0);
    primitive = prim;
}
