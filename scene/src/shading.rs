//! Surface data at a hit: interpolated attributes plus the material, textures applied.

use glam::{Vec2, Vec3, Vec4};

use crate::bvh::Hit;
use crate::model::{Scene, srgb_to_linear};

/// Everything the BSDF and the G-buffer need about one hit point.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    pub position: Vec3,
    /// Geometric normal, flipped to the side the ray came from.
    pub geometric_normal: Vec3,
    /// Interpolated shading normal on the same side as `geometric_normal`.
    pub normal: Vec3,
    /// True if the ray hit the side the triangle's vertex normals point to.
    pub front_face: bool,
    pub base_color: Vec3,
    pub metallic: f32,
    /// Perceptual roughness (glTF), 0..1.
    pub roughness: f32,
    pub specular: f32,
    /// Emitted radiance towards the ray origin (zero on the back of single-sided emitters).
    pub emission: Vec3,
}

fn sample_srgb(scene: &Scene, tex: u32, uv: Vec2) -> Vec4 {
    let t = scene.textures[tex as usize].sample_bilinear(uv);
    Vec4::new(srgb_to_linear(t.x), srgb_to_linear(t.y), srgb_to_linear(t.z), t.w)
}

/// The unit normal of triangle `t` from its winding, flipped to agree with its vertex normals
/// (files do not always wind consistently with the normals they store).
pub fn oriented_face_normal(scene: &Scene, t: usize) -> Vec3 {
    let [a, b, c] = scene.triangle_positions(t);
    let n = (b - a).cross(c - a).normalize_or_zero();
    let [i, j, k] = scene.triangles[t];
    let vn = scene.normals[i as usize] + scene.normals[j as usize] + scene.normals[k as usize];
    if n.dot(vn) < 0.0 { -n } else { n }
}

/// Evaluates attributes and material at `hit` for a ray travelling along `dir`.
pub fn surface_point(scene: &Scene, hit: &Hit, origin: Vec3, dir: Vec3) -> SurfacePoint {
    let t = hit.triangle as usize;
    let [i0, i1, i2] = scene.triangles[t].map(|i| i as usize);
    let (u, v) = (hit.barycentrics.x, hit.barycentrics.y);
    let w = 1.0 - u - v;
    let uv = scene.uvs[i0] * w + scene.uvs[i1] * u + scene.uvs[i2] * v;
    let face = oriented_face_normal(scene, t);
    let mut shading = (scene.normals[i0] * w + scene.normals[i1] * u + scene.normals[i2] * v).normalize_or_zero();
    if shading == Vec3::ZERO || !shading.is_finite() {
        shading = face;
    }
    let front_face = face.dot(dir) < 0.0;
    let (geometric_normal, mut normal) = if front_face { (face, shading) } else { (-face, -shading) };
    // A shading normal pointing away from the viewer makes the BSDF meaningless; fall back.
    if normal.dot(-dir) <= 0.0 {
        normal = geometric_normal;
    }

    let m = &scene.materials[scene.triangle_materials[t] as usize];
    let mut base = m.base_color;
    if let Some(tex) = m.base_color_texture {
        base *= sample_srgb(scene, tex, uv);
    }
    let (mut metallic, mut roughness) = (m.metallic, m.roughness);
    if let Some(tex) = m.metallic_roughness_texture {
        let mr = scene.textures[tex as usize].sample_bilinear(uv);
        roughness *= mr.y;
        metallic *= mr.z;
    }
    let mut emission = m.emissive;
    if let Some(tex) = m.emissive_texture {
        emission *= sample_srgb(scene, tex, uv).truncate();
    }
    if !front_face && !m.double_sided {
        emission = Vec3::ZERO;
    }
    SurfacePoint {
        position: origin + dir * hit.t,
        geometric_normal,
        normal,
        front_face,
        base_color: base.truncate().clamp(Vec3::ZERO, Vec3::ONE),
        metallic: metallic.clamp(0.0, 1.0),
        roughness: roughness.clamp(0.0, 1.0),
        specular: m.specular.clamp(0.0, 1.0),
        emission: emission.max(Vec3::ZERO),
    }
}
