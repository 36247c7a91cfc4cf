#version 460
// Test/demo kernel for history resources: adds (frame index + 1) to every texel of `dst` in
// rows [y0, y1), reading the value the previous frame left there. After frames 0..n-1 a texel
// holds n(n+1)/2, which only holds if the image survives from frame to frame and the frame
// constants change without re-recording.
#include "bindless.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    if (x >= pc.width || y >= pc.y1) {
        return;
    }
    vec4 previous = imageLoad(images[pc.dst], ivec2(x, y));
    imageStore(images[pc.dst], ivec2(x, y), previous + vec4(float(frame.frame_index + 1u)));
}
