// The surface at a hit, the twin of parallax_scene::shading: interpolated attributes and the
// material, textures applied. Shared by the path tracer's first hit and the raster G-buffer
// (shaders/gbuffer_raster.frag), so both write the same G-buffer conventions. Expects the scene
// buffers (pt_scene.glsl) declared before inclusion.

#ifndef PT_SURFACE_GLSL
#define PT_SURFACE_GLSL

struct SurfacePoint {
    vec3 position;
    vec3 geometric_normal;
    vec3 normal;
    bool front_face;
    vec3 base_color;
    float metallic;
    float roughness;
    float specular;
    vec3 emission;
};

vec3 safe_normalize(vec3 v) {
    float l = length(v);
    return (l > 0.0 && !isinf(l)) ? v / l : vec3(0.0);
}

// Triangle normal from its winding, flipped to agree with the vertex normals.
vec3 oriented_face_normal(uint prim) {
    BvhTriangle tri = scene_triangles.data[prim];
    vec3 n = safe_normalize(cross(tri.v1 - tri.v0, tri.v2 - tri.v0));
    TriangleAttributes a = scene_attributes.data[prim];
    vec3 vn = a.normals[0].xyz + a.normals[1].xyz + a.normals[2].xyz;
    return dot(n, vn) < 0.0 ? -n : n;
}

SurfacePoint surface_point(uint prim, vec2 bary, float t, vec3 origin, vec3 dir) {
    SurfacePoint sp;
    TriangleAttributes a = scene_attributes.data[prim];
    float w = 1.0 - bary.x - bary.y;
    vec2 uv = a.uvs[0] * w + a.uvs[1] * bary.x + a.uvs[2] * bary.y;
    vec3 face = oriented_face_normal(prim);
    vec3 shading = safe_normalize(a.normals[0].xyz * w + a.normals[1].xyz * bary.x + a.normals[2].xyz * bary.y);
    if (shading == vec3(0.0)) {
        shading = face;
    }
    sp.front_face = dot(face, dir) < 0.0;
    sp.geometric_normal = sp.front_face ? face : -face;
    sp.normal = sp.front_face ? shading : -shading;
    if (dot(sp.normal, -dir) <= 0.0) {
        sp.normal = sp.geometric_normal;
    }
    Material m = scene_materials.data[scene_triangles.data[prim].material];
    vec4 base = m.base_color;
    if (m.base_color_texture >= 0) {
        vec4 tx = scene_texel(m.base_color_texture, uv);
        base *= vec4(srgb_to_linear(tx.rgb), tx.a);
    }
    float metallic = m.metallic;
    float roughness = m.roughness;
    if (m.metallic_roughness_texture >= 0) {
        vec4 mr = scene_texel(m.metallic_roughness_texture, uv);
        roughness *= mr.g;
        metallic *= mr.b;
    }
    vec3 emission = m.emissive;
    if (m.emissive_texture >= 0) {
        emission *= srgb_to_linear(scene_texel(m.emissive_texture, uv).rgb);
    }
    if (!sp.front_face && (m.flags & TRI_DOUBLE_SIDED) == 0u) {
        emission = vec3(0.0);
    }
    sp.position = origin + dir * t;
    sp.base_color = clamp(base.rgb, 0.0, 1.0);
    sp.metallic = clamp(metallic, 0.0, 1.0);
    sp.roughness = clamp(roughness, 0.0, 1.0);
    sp.specular = clamp(m.specular, 0.0, 1.0);
    sp.emission = max(emission, vec3(0.0));
    return sp;
}

#endif
