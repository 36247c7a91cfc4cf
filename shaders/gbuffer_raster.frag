#version 460
// The raster G-buffer pass, fragment stage: alpha-masked texels are discarded (the rule of the
// traversal's any-hit test, bvh_alpha_visible), then the surface is evaluated by the path
// tracer's own code (pt_surface.glsl) and written with its first-hit conventions
// (parallax_passes::TRACE_OUTPUTS): albedo + roughness, shading normal facing the camera +
// metallic, world position + linear depth (distance along the camera's forward axis, which is
// clip w for a perspective view-projection).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_nonuniform_qualifier : require
#include "gbuffer_raster.glsl"
#define PT_SCENE pc.scene
#include "pt_scene.glsl"
#include "pt_surface.glsl"

layout(location = 0) in vec2 barycentrics;
layout(location = 1) flat in uint primitive;

layout(location = 0) out vec4 albedo_roughness;
layout(location = 1) out vec4 normal_metallic;
layout(location = 2) out vec4 position_depth;

void main() {
    BvhTriangle tri = scene_triangles.data[primitive];
    if ((tri.flags & TRI_ALPHA_MASK) != 0u && !bvh_alpha_visible(primitive, barycentrics)) {
        discard;
    }
    vec3 eye = pc.frame.views[pc.view].current.position.xyz;
    vec3 position = tri.v0 * (1.0 - barycentrics.x - barycentrics.y) + tri.v1 * barycentrics.x
                    + tri.v2 * barycentrics.y;
    vec3 to_point = position - eye;
    float distance = length(to_point);
    vec3 dir = distance > 0.0 ? to_point / distance : vec3(0.0, 0.0, -1.0);
    SurfacePoint sp = surface_point(primitive, barycentrics, distance, eye, dir);
    albedo_roughness = vec4(sp.base_color, sp.roughness);
    normal_metallic = vec4(sp.normal, sp.metallic);
    position_depth = vec4(position, 1.0 / gl_FragCoord.w);
}
