#version 460
// The `motion` pass (parallax_passes::gbuffer::MotionKernel): where each pixel's surface was in
// the previous frame, from its G-buffer world position and the frame block's previous camera —
// what gbuffer_trace.comp computes along with the first hit, for a G-buffer made another way
// (the raster pass). (-1, -1) where there is no hit, the point was off screen, or history is
// invalid.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "frame_block.glsl"

// parallax_passes::shaders::MotionPush, generated from this block.
layout(push_constant, std430) uniform MotionPush {
    FrameBlock block;
    uint position_depth;
    uint motion;
    uint view;
    uint y0;
    uint y1;
    uint width;
    uint height;
    uint pad; // rounds the block to its 8-byte alignment, as the Rust struct is
} pc;

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    if (x >= pc.width || y >= pc.y1) {
        return;
    }
    ivec2 at = ivec2(x, y);
    vec4 position = imageLoad(images[pc.position_depth], at);
    vec2 previous_pixel = vec2(-1.0);
    if (position.w > 0.0 && frame.history_valid != 0u) {
        vec4 clip = pc.block.views[pc.view].previous.view_proj * vec4(position.xyz, 1.0);
        if (clip.w > 0.0) {
            vec2 ndc = clip.xy / clip.w;
            vec2 size = vec2(float(pc.width), float(pc.height));
            vec2 pixel = vec2((ndc.x + 1.0) * 0.5 * size.x, (1.0 - ndc.y) * 0.5 * size.y);
            if (all(greaterThanEqual(pixel, vec2(0.0))) && all(lessThan(pixel, size))) {
                previous_pixel = pixel;
            }
        }
    }
    imageStore(images[pc.motion], at, vec4(previous_pixel, 0.0, 0.0));
}
