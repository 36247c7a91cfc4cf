// std430 layouts of parallax_scene::gpu (scene, trace parameters, traced pixel) and the buffer
// reference types through which kernels reach them. Change together with scene/src/gpu.rs; its
// size tests pin the byte sizes written next to each struct.
//
// Scene buffers are global buffers of the executor (uploaded once by the passes crate,
// `parallax_passes::scene_upload`); a kernel gets their addresses in push constants as a
// `SceneRefs` and names it for pt_scene.glsl with `#define PT_SCENE <expression>`.

#ifndef PT_TYPES_GLSL
#define PT_TYPES_GLSL

#extension GL_EXT_buffer_reference : require

#include "bvh_types.glsl"

// GpuTriangleAttributes, 80 bytes.
struct TriangleAttributes {
    vec4 normals[3];
    vec2 uvs[3];
    float emissive_prob;
    float area;
};

// GpuMaterial, 64 bytes.
struct Material {
    vec4 base_color;
    vec3 emissive;
    float metallic;
    float roughness;
    float alpha_cutoff; // < 0: opaque
    float specular;
    uint flags;
    int base_color_texture; // -1: none
    int metallic_roughness_texture;
    int emissive_texture;
    uint pad;
};

// GpuEmissiveTriangle, 16 bytes.
struct EmissiveTriangle {
    uint bvh_primitive;
    float cdf;
    uint pad0;
    uint pad1;
};

// GpuPunctualLight, 48 bytes.
const uint LIGHT_POINT = 0u;
const uint LIGHT_SPOT = 1u;
const uint LIGHT_DIRECTIONAL = 2u;
struct PunctualLight {
    vec3 position;
    uint kind;
    vec3 direction;
    float cos_inner;
    vec3 power;
    float cos_outer;
};

// GpuTraceParams, 224 bytes: one view's camera, frame, sampling settings, sky and sun. The
// pixel fields (counts.w, pixels) are the CPU's description of a pixel set; kernels take the
// pixels to trace from their pass instance instead.
struct TraceParams {
    vec4 eye;
    vec4 right;
    vec4 up;
    vec4 forward;
    vec4 shift;
    uvec4 dims;     // width, height, view, frame
    uvec4 sampling; // spp, max depth, roulette from (0xffffffff off), jitter
    uvec4 counts;   // punctual lights, emissive triangles, light-group bits, pixel mode
    uvec4 pixels;   // rows: y0, y1; list: z = length
    vec4 sky_zenith; // w: 0 constant, 1 gradient
    vec4 sky_horizon;
    vec4 sky_ground;
    vec4 sun_dir;        // w: cos of the angular radius
    vec4 sun_irradiance; // w: 1 - cos of the angular radius (0: delta sun)
};

// GpuPixel, 64 bytes: what one traced pixel yields.
struct PixelOut {
    vec4 radiance; // a = 1 if the first hit exists
    vec4 albedo_roughness;
    vec4 normal_metallic;
    vec4 position_depth;
};

layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer SceneNodes { uvec4 data[]; };
layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer SceneTriangles { BvhTriangle data[]; };
// The same triangles as three 16-byte words each: what traversal loads (see bvh_traverse.glsl).
layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer SceneTriangleWords { uvec4 data[]; };
layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer SceneAttributes { TriangleAttributes data[]; };
layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer SceneMaterials { Material data[]; };
layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer SceneEmissive { EmissiveTriangle data[]; };
layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer SceneLights { PunctualLight data[]; };
layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer TraceParamsRef { TraceParams p; };

// The six scene buffers, in the order of parallax_passes::SCENE_BUFFERS (48 bytes).
struct SceneRefs {
    SceneNodes nodes;
    SceneTriangles triangles;
    SceneAttributes attributes;
    SceneMaterials materials;
    SceneEmissive emissive;
    SceneLights lights;
};

#endif
