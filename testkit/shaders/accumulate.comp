#version 460
// Test kernel for history: dst = history + (frame index + 1), where history (src0) is last
// frame's final `dst`, or 0 when the frame says history is invalid (a plan's first frame, a
// reset). After frames 0..n-1 a texel holds n(n+1)/2, which only holds if last frame's output
// really arrives through the other half of the double-buffered allocation while this frame
// writes its own. Channel 1 records the flag the frame carried.
#include "bindless.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    if (x >= pc.width || y >= pc.y1) {
        return;
    }
    float previous = frame.history_valid != 0u ? imageLoad(images[pc.src0], ivec2(x, y)).x : 0.0;
    float value = previous + float(frame.frame_index + 1u);
    imageStore(images[pc.dst], ivec2(x, y), vec4(value, float(frame.history_valid), 0.0, 1.0));
}
