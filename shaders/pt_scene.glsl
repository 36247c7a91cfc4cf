// Scene data for GPU path tracing, mirroring parallax_scene::gpu (std430). Change together with
// scene/src/gpu.rs; its size tests pin the byte sizes written next to each struct.
//
// The including shader picks the descriptor set with `#define SCENE_SET n` (default 0) and
// gets these bindings:
//   0 CWBVH nodes (uvec4[5] each)   1 triangles (BvhTriangle)   2 triangle attributes
//   3 materials                     4 emissive triangles        5 punctual lights
//   6 textures: sampler2D[] (RGBA8 UNORM, linear filter, repeat; sRGB decoded here), absent
//     with `#define PT_SCENE_NO_TEXTURES`
// Requires GL_EXT_nonuniform_qualifier for the texture array.

#ifndef PT_SCENE_GLSL
#define PT_SCENE_GLSL

#extension GL_EXT_nonuniform_qualifier : require

#include "bvh_types.glsl"

#ifndef SCENE_SET
#define SCENE_SET 0
#endif

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

layout(std430, set = SCENE_SET, binding = 0) readonly buffer SceneNodes { uvec4 data[]; } scene_nodes;
layout(std430, set = SCENE_SET, binding = 1) readonly buffer SceneTriangles { BvhTriangle data[]; } scene_triangles;
layout(std430, set = SCENE_SET, binding = 2) readonly buffer SceneAttributes { TriangleAttributes data[]; } scene_attributes;
layout(std430, set = SCENE_SET, binding = 3) readonly buffer SceneMaterials { Material data[]; } scene_materials;
layout(std430, set = SCENE_SET, binding = 4) readonly buffer SceneEmissive { EmissiveTriangle data[]; } scene_emissive;
layout(std430, set = SCENE_SET, binding = 5) readonly buffer SceneLights { PunctualLight data[]; } scene_lights;
#ifndef PT_SCENE_NO_TEXTURES
layout(set = SCENE_SET, binding = 6) uniform sampler2D scene_textures[];
#endif

vec2 scene_uv(uint prim, vec2 bary) {
    TriangleAttributes a = scene_attributes.data[prim];
    return a.uvs[0] * (1.0 - bary.x - bary.y) + a.uvs[1] * bary.x + a.uvs[2] * bary.y;
}

// Level 0 only: compute shaders have no derivatives, and the CPU reference has no mipmaps.
// PT_SCENE_NO_TEXTURES (traversal benchmarks on opaque geometry) reads every texel as white.
vec4 scene_texel(int tex, vec2 uv) {
#ifdef PT_SCENE_NO_TEXTURES
    return vec4(1.0);
#else
    return textureLod(scene_textures[nonuniformEXT(tex)], uv, 0.0);
#endif
}

vec3 srgb_to_linear(vec3 c) {
    return mix(c / 12.92, pow((c + 0.055) / 1.055, vec3(2.4)), greaterThan(c, vec3(0.04045)));
}

// Alpha-mask test used by bvh_traverse.glsl (same rule as the CPU: alpha < cutoff is a hole).
bool bvh_alpha_visible(uint prim, vec2 bary) {
    Material m = scene_materials.data[scene_triangles.data[prim].material];
    float alpha = m.base_color.a;
    if (m.base_color_texture >= 0) {
        alpha *= scene_texel(m.base_color_texture, scene_uv(prim, bary)).a;
    }
    return alpha >= m.alpha_cutoff;
}

#endif
