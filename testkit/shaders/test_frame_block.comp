#version 460
// Test kernel of the frame block: writes the executor's frame constants, the block's view count
// and every camera of the block, member by member, into a buffer of words in a fixed order
// (frame_index, history_valid, view_count, then per view current and previous: view_proj,
// inv_view_proj, position, jitter), so that a wrong offset on either side shows up as wrong
// values on the host.
#extension GL_EXT_buffer_reference : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "frame_block.glsl"

layout(buffer_reference, std430, buffer_reference_align = 4) writeonly buffer Words {
    uint words[];
};

layout(push_constant, std430) uniform FrameBlockProbe {
    FrameBlock block;
    Words target;
    uint max_views;
    uint pad; // rounds the block to its 8-byte alignment, as the Rust struct is
} pc;

layout(local_size_x = 1) in;

uint put_camera(uint at, GpuCamera camera) {
    for (int c = 0; c < 4; c++) {
        for (int r = 0; r < 4; r++) {
            pc.target.words[at + c * 4 + r] = floatBitsToUint(camera.view_proj[c][r]);
            pc.target.words[at + 16 + c * 4 + r] = floatBitsToUint(camera.inv_view_proj[c][r]);
        }
    }
    for (int i = 0; i < 4; i++) {
        pc.target.words[at + 32 + i] = floatBitsToUint(camera.position[i]);
    }
    pc.target.words[at + 36] = floatBitsToUint(camera.jitter.x);
    pc.target.words[at + 37] = floatBitsToUint(camera.jitter.y);
    return at + 38;
}

void main() {
    pc.target.words[0] = frame.frame_index;
    pc.target.words[1] = frame.history_valid;
    pc.target.words[2] = pc.block.view_count;
    uint at = 3;
    for (uint v = 0; v < min(pc.block.view_count, pc.max_views); v++) {
        at = put_camera(at, pc.block.views[v].current);
        at = put_camera(at, pc.block.views[v].previous);
    }
}
