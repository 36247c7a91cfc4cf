#version 460
// Test kernel for integer images (`uimages`, R32_UINT): writes hash3(x, y, view) into rows
// [y0, y1) of `dst`, the shape of a hole mask or an id buffer.
#include "bindless.glsl"
#include "hash.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = pc.y0 + gl_GlobalInvocationID.y;
    if (x >= pc.width || y >= pc.y1) {
        return;
    }
    imageStore(uimages[pc.dst], ivec2(x, y), uvec4(hash3(x, y, pc.view)));
}
