// The per-frame block (parallax_backend::FrameBlock), reached by address: per view the current
// and previous camera. The frame index and whether last frame's data may be reused are the
// frame constants of bindless.glsl (frame.frame_index, frame.history_valid).
// std430; the explicit pads make every offset the same under the scalar layout too, and match
// the #[repr(C)] Rust types (checked by backend/tests/lavapipe_frame.rs from this SPIR-V).
// A kernel gets the address from Recorder::frame_block_address().
#ifndef PARALLAX_FRAME_BLOCK_GLSL
#define PARALLAX_FRAME_BLOCK_GLSL

#extension GL_EXT_buffer_reference : require

struct GpuCamera {
    mat4 view_proj;       // world -> clip, column-major
    mat4 inv_view_proj;   // clip -> world
    vec4 position;        // eye in world space; w unused
    vec2 jitter;          // sub-pixel offset of this frame's projection, in pixels
    vec2 pad;
};

struct ViewCameras {
    GpuCamera current;
    GpuCamera previous;   // last frame's current (current on a view's first frame); use only when frame.history_valid != 0
};

layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer FrameBlock {
    uint view_count;
    uint pad[3];          // the views start 16-byte aligned, as their matrices
    ViewCameras views[];
};

#endif
