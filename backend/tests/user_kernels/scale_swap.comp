#version 460
// A kernel from outside shaders/ (backend/tests/lavapipe_user_kernels.rs compiles it at run
// time): writes scale_swap of image `src0` into rows [y0, y1) of image `dst`.
#include "bindless.glsl"
#include "scale_swap.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    if (x >= pc.width || y >= pc.y1) {
        return;
    }
    imageStore(images[pc.dst], ivec2(x, y), scale_swap(imageLoad(images[pc.src0], ivec2(x, y)), pc.view));
}
