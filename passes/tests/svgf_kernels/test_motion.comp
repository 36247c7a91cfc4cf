#version 460
// Test kernel: `motion` of a static camera moved by a constant offset: every pixel with a hit
// was at its own centre + (offset_x, offset_y) in the previous frame; (-1, -1) without a hit.
// A zero offset is a static camera; a non-zero one makes reprojection read other rows.
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"

layout(push_constant, std430) uniform MotionPush {
    uint dst;
    uint position;
    uint y0;
    uint y1;
    uint width;
    float offset_x;
    float offset_y;
} pc;

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    if (x >= pc.width || y >= pc.y1) {
        return;
    }
    bool hit = imageLoad(images[pc.position], ivec2(x, y)).w > 0.0;
    vec2 motion = hit ? vec2(x, y) + 0.5 + vec2(pc.offset_x, pc.offset_y) : vec2(-1.0);
    imageStore(images[pc.dst], ivec2(x, y), vec4(motion, 0.0, 0.0));
}
