// Scene access for GPU path tracing and traversal, mirroring parallax_scene::gpu.
//
// The including shader includes pt_types.glsl and bindless.glsl, declares its push constants
// with a `SceneRefs` member and names it before including this file:
//   #define PT_SCENE pc.scene
// It then gets the scene arrays under the names the path tracer uses (scene_nodes.data[i],
// scene_triangles.data[i], ...) and the textures of set 0 (bindless.glsl `textures[]`, RGBA8
// UNORM, bilinear, repeat; sRGB decoded here). `#define PT_SCENE_NO_TEXTURES` reads every
// texel as white (traversal benchmarks on opaque geometry).

#ifndef PT_SCENE_GLSL
#define PT_SCENE_GLSL

#extension GL_EXT_nonuniform_qualifier : require

#include "pt_types.glsl"

#ifndef PT_SCENE
#error "define PT_SCENE (an expression of type SceneRefs) before including pt_scene.glsl"
#endif

#define scene_nodes (PT_SCENE.nodes)
#define scene_triangles (PT_SCENE.triangles)
#define scene_triangle_words (SceneTriangleWords(PT_SCENE.triangles))
#define scene_attributes (PT_SCENE.attributes)
#define scene_materials (PT_SCENE.materials)
#define scene_emissive (PT_SCENE.emissive)
#define scene_lights (PT_SCENE.lights)

vec2 scene_uv(uint prim, vec2 bary) {
    TriangleAttributes a = scene_attributes.data[prim];
    return a.uvs[0] * (1.0 - bary.x - bary.y) + a.uvs[1] * bary.x + a.uvs[2] * bary.y;
}

// Level 0 only: compute shaders have no derivatives, and the CPU reference has no mipmaps.
vec4 scene_texel(int tex, vec2 uv) {
#ifdef PT_SCENE_NO_TEXTURES
    return vec4(1.0);
#else
    return textureLod(textures[nonuniformEXT(tex)], uv, 0.0);
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
