#version 460
// Test raster pass: two quads (6 vertices each, no vertex buffer). Instance 0 covers the
// left half of the image at depth 0.25, instance 1 the whole image at depth 0.75; instance 0 is
// drawn first, so only the depth test keeps it visible.

layout(location = 0) flat out uint instance;

const vec2 CORNERS[6] = vec2[](vec2(0, 0), vec2(1, 0), vec2(0, 1), vec2(1, 0), vec2(1, 1), vec2(0, 1));

void main() {
    vec2 corner = CORNERS[gl_VertexIndex];
    float right = gl_InstanceIndex == 0 ? 0.0 : 1.0;
    gl_Position = vec4(mix(-1.0, right, corner.x), mix(-1.0, 1.0, corner.y), gl_InstanceIndex == 0 ? 0.25 : 0.75, 1.0);
    instance = gl_InstanceIndex;
}
