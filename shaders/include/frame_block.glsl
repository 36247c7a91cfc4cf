// The per-frame block (parallax_backend::FrameBlock), reached by address: the frame index,
// whether last frame's data may be reused, and per view the current and previous camera.
// std430; the explicit pads make every offset the same under the scalar layout too, and match
// the #[repr(C)] Rust types (checked by backend/tests/lavapipe_frame.rs from this SPIR-V).
// A kernel gets the address from Recorder::frame_section_address(FRAME_BLOCK_SECTION).
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
    GpuCamera previous;   // last frame's current (current on a view's first frame); use only when history_valid != 0
};

layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer FrameBlock {
    uint frame_index;     // the executor's frame index
    uint history_valid;   // the executor's flag: 0 on a plan's first frame and after a camera cut
    uint view_count;
    uint pad;
    ViewCameras views[];
};

#endif
