// Resources every Parallax compute kernel sees (set 0), and the push-constant block the
// backend's `Recorder::dispatch` fills.
#ifndef PARALLAX_BINDLESS_GLSL
#define PARALLAX_BINDLESS_GLSL

// Storage images are declared without a format qualifier so that one array holds every float
// format a plan uses (needs shaderStorageImage{Read,Write}WithoutFormat, checked at device
// creation).
#extension GL_EXT_shader_image_load_formatted : require

// Number of images on this device; the backend specialises it per plan.
layout(constant_id = 0) const uint IMAGE_COUNT = 1;
layout(set = 0, binding = 0) uniform image2D images[IMAGE_COUNT];
// The same indices for integer images (hole masks, ids). Slot i of `images` holds image i if it
// is a float image, and slot i of `uimages` holds it if it is R32_UINT; the other array has a
// never-read 1x1 placeholder there.
layout(set = 0, binding = 2, r32ui) uniform uimage2D uimages[IMAGE_COUNT];

// Sampled RGBA8 textures (Executor::upload_textures), bilinear, repeat, level 0; unused slots
// hold a 1x1 white texture. The size is parallax_backend::MAX_TEXTURES. Index with
// nonuniformEXT (GL_EXT_nonuniform_qualifier) where the index varies across invocations.
#define PARALLAX_MAX_TEXTURES 1024
layout(set = 0, binding = 3) uniform sampler2D textures[PARALLAX_MAX_TEXTURES];

// Depth images (Format::Depth32f: raster passes' depth attachments) at the same indices again,
// as sampled images: depth formats cannot be storage images. Read them with
// texelFetch(depth_images[i], pixel, 0).r (1.0 = far); other slots hold a 1x1 placeholder.
#extension GL_EXT_samplerless_texture_functions : require
layout(set = 0, binding = 4) uniform texture2D depth_images[IMAGE_COUNT];

// Per frame-in-flight constants, written by the host before each submission, so that recorded
// command buffers stay valid from frame to frame.
layout(set = 0, binding = 1, std140) uniform FrameConstants {
    uint frame_index;
    // 0 on the first frame of a plan and after Executor::reset_history (a camera cut): what
    // history reads see then is not last frame's output and must not be blended in.
    uint history_valid;
} frame;

// Generic pass parameters: image indices into `images`, the row band of the instance, and two
// kernel-specific words. A kernel that needs more (buffer addresses, ...) defines
// PARALLAX_CUSTOM_PUSH_CONSTANTS before the include and declares its own block (<= 128 bytes).
#ifndef PARALLAX_CUSTOM_PUSH_CONSTANTS
layout(push_constant, std430) uniform PassParams {
    uint dst;
    uint src0;
    uint src1;
    uint view;
    uint y0;
    uint y1;
    uint width;
    uint param;
} pc;
#endif

#endif
