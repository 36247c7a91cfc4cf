//! The scene laid out for GPU storage buffers (std430), ready for the backend to upload.
//!
//! - nodes: obvhs `CwBvhNode`s as they are (80 B, read in GLSL as `uvec4[5]`);
//! - triangles: corners in BVH order (a leaf's primitive id indexes them directly), 48 B;
//! - attributes: per BVH-ordered triangle, normals, UVs and emissive-light data, 80 B;
//! - materials (64 B), emissive-triangle table (16 B), punctual lights (48 B);
//! - textures: RGBA8 images for a bindless `sampler2D[]` (UNORM; the shader decodes sRGB).
//!
//! The structs below and `shaders/pt_scene.glsl` must change together; the size tests here and
//! the `offsetof`-style comments in the GLSL keep them honest.

use bytemuck::{Pod, Zeroable};

use crate::bvh::SceneBvh;
use crate::lights::LightSet;
use crate::model::{AlphaMode, PunctualKind, Scene, Texture};

/// Triangle flag: the material has an alpha mask (any-hit must look at the texture).
pub const TRI_ALPHA_MASK: u32 = 1;
/// Triangle flag: the material is double-sided.
pub const TRI_DOUBLE_SIDED: u32 = 2;
/// Triangle flag: the material emits.
pub const TRI_EMISSIVE: u32 = 4;

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuTriangle {
    pub v0: [f32; 3],
    pub material: u32,
    pub v1: [f32; 3],
    /// Index into the scene's triangle list (for debugging and CPU/GPU comparisons).
    pub scene_triangle: u32,
    pub v2: [f32; 3],
    pub flags: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuTriangleAttributes {
    /// xyz = vertex normal, w unused.
    pub normals: [[f32; 4]; 3],
    pub uvs: [[f32; 2]; 3],
    /// Probability of this triangle within the emissive-light group (0 if not emissive).
    pub emissive_prob: f32,
    pub area: f32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuMaterial {
    pub base_color: [f32; 4],
    pub emissive: [f32; 3],
    pub metallic: f32,
    pub roughness: f32,
    /// Alpha-mask cutoff; negative for opaque materials.
    pub alpha_cutoff: f32,
    pub specular: f32,
    /// `TRI_*` flags of the material.
    pub flags: u32,
    /// Texture indices, -1 for none.
    pub base_color_texture: i32,
    pub metallic_roughness_texture: i32,
    pub emissive_texture: i32,
    pub _pad: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuEmissiveTriangle {
    /// Index into the BVH-ordered triangle arrays.
    pub bvh_primitive: u32,
    /// Cumulative selection probability up to and including this triangle.
    pub cdf: f32,
    pub _pad: [u32; 2],
}

/// Punctual light kinds in `GpuPunctualLight::kind`.
pub const LIGHT_POINT: u32 = 0;
pub const LIGHT_SPOT: u32 = 1;
pub const LIGHT_DIRECTIONAL: u32 = 2;

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuPunctualLight {
    pub position: [f32; 3],
    pub kind: u32,
    /// Direction the light travels.
    pub direction: [f32; 3],
    pub cos_inner: f32,
    /// color * intensity.
    pub power: [f32; 3],
    pub cos_outer: f32,
}

/// Everything the GPU path tracer reads, as plain arrays.
pub struct GpuScene<'a> {
    pub nodes: &'a [obvhs::cwbvh::node::CwBvhNode],
    pub triangles: Vec<GpuTriangle>,
    pub attributes: Vec<GpuTriangleAttributes>,
    pub materials: Vec<GpuMaterial>,
    pub emissive: Vec<GpuEmissiveTriangle>,
    pub lights: Vec<GpuPunctualLight>,
    pub textures: &'a [Texture],
}

fn material_flags(m: &crate::model::Material) -> u32 {
    let mut f = 0;
    if matches!(m.alpha_mode, AlphaMode::Mask(_)) {
        f |= TRI_ALPHA_MASK;
    }
    if m.double_sided {
        f |= TRI_DOUBLE_SIDED;
    }
    if m.is_emissive() {
        f |= TRI_EMISSIVE;
    }
    f
}

impl<'a> GpuScene<'a> {
    pub fn new(scene: &'a Scene, bvh: &'a SceneBvh) -> Self {
        let lights = LightSet::new(scene);
        let mut triangles = Vec::with_capacity(bvh.tris.len());
        let mut attributes = Vec::with_capacity(bvh.tris.len());
        let mut emissive: Vec<(u32, f32)> = Vec::new();
        for (k, &t) in bvh.cwbvh.primitive_indices.iter().enumerate() {
            let t = t as usize;
            let mi = scene.triangle_materials[t];
            let m = &scene.materials[mi as usize];
            let [a, b, c] = scene.triangle_positions(t);
            triangles.push(GpuTriangle {
                v0: a.into(),
                material: mi,
                v1: b.into(),
                scene_triangle: t as u32,
                v2: c.into(),
                flags: material_flags(m),
            });
            let idx = scene.triangles[t];
            let (prob, area) = lights.emissive_prob_and_area(t as u32);
            attributes.push(GpuTriangleAttributes {
                normals: idx.map(|i| scene.normals[i as usize].extend(0.0).into()),
                uvs: idx.map(|i| scene.uvs[i as usize].into()),
                emissive_prob: prob,
                area,
            });
            if prob > 0.0 {
                emissive.push((k as u32, prob));
            }
        }
        let mut acc = 0.0f64;
        let count = emissive.len();
        let emissive = emissive
            .into_iter()
            .enumerate()
            .map(|(i, (k, p))| {
                acc += p as f64;
                GpuEmissiveTriangle {
                    bvh_primitive: k,
                    cdf: if i + 1 == count { 1.0 } else { acc as f32 },
                    _pad: [0; 2],
                }
            })
            .collect();
        let materials = scene
            .materials
            .iter()
            .map(|m| GpuMaterial {
                base_color: m.base_color.into(),
                emissive: m.emissive.into(),
                metallic: m.metallic,
                roughness: m.roughness,
                alpha_cutoff: match m.alpha_mode {
                    AlphaMode::Mask(c) => c,
                    AlphaMode::Opaque => -1.0,
                },
                specular: m.specular,
                flags: material_flags(m),
                base_color_texture: m.base_color_texture.map_or(-1, |t| t as i32),
                metallic_roughness_texture: m.metallic_roughness_texture.map_or(-1, |t| t as i32),
                emissive_texture: m.emissive_texture.map_or(-1, |t| t as i32),
                _pad: 0,
            })
            .collect();
        let lights = scene
            .lights
            .iter()
            .map(|l| {
                let (kind, ci, co) = match l.kind {
                    PunctualKind::Point => (LIGHT_POINT, 1.0, -1.0),
                    PunctualKind::Spot { inner_cone, outer_cone } => (LIGHT_SPOT, inner_cone.cos(), outer_cone.cos()),
                    PunctualKind::Directional => (LIGHT_DIRECTIONAL, 1.0, -1.0),
                };
                GpuPunctualLight {
                    position: l.position.into(),
                    kind,
                    direction: l.direction.into(),
                    cos_inner: ci,
                    power: (l.color * l.intensity).into(),
                    cos_outer: co,
                }
            })
            .collect();
        Self { nodes: &bvh.cwbvh.nodes, triangles, attributes, materials, emissive, lights, textures: &scene.textures }
    }

    pub fn node_bytes(&self) -> &[u8] {
        bytemuck::cast_slice(self.nodes)
    }
    pub fn triangle_bytes(&self) -> &[u8] {
        bytemuck::cast_slice(&self.triangles)
    }
    pub fn attribute_bytes(&self) -> &[u8] {
        bytemuck::cast_slice(&self.attributes)
    }
    pub fn material_bytes(&self) -> &[u8] {
        bytemuck::cast_slice(&self.materials)
    }
    pub fn emissive_bytes(&self) -> &[u8] {
        bytemuck::cast_slice(&self.emissive)
    }
    pub fn light_bytes(&self) -> &[u8] {
        bytemuck::cast_slice(&self.lights)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::default_scene;

    #[test]
    fn std430_sizes() {
        assert_eq!(std::mem::size_of::<obvhs::cwbvh::node::CwBvhNode>(), 80);
        assert_eq!(std::mem::size_of::<GpuTriangle>(), 48);
        assert_eq!(std::mem::size_of::<GpuTriangleAttributes>(), 80);
        assert_eq!(std::mem::size_of::<GpuMaterial>(), 64);
        assert_eq!(std::mem::size_of::<GpuEmissiveTriangle>(), 16);
        assert_eq!(std::mem::size_of::<GpuPunctualLight>(), 48);
    }

    #[test]
    fn triangles_follow_bvh_order() {
        let scene = default_scene();
        let bvh = SceneBvh::build(&scene);
        let gpu = GpuScene::new(&scene, &bvh);
        assert_eq!(gpu.node_bytes().len(), 80 * bvh.node_count());
        assert_eq!(gpu.triangles.len(), scene.triangle_count());
        for (k, t) in gpu.triangles.iter().enumerate() {
            assert_eq!(t.scene_triangle, bvh.cwbvh.primitive_indices[k]);
            assert_eq!(glam::Vec3A::from(glam::Vec3::from(t.v0)), bvh.tris[k].v0);
            assert_eq!(glam::Vec3A::from(glam::Vec3::from(t.v2)), bvh.tris[k].v2);
        }
        assert_eq!(gpu.emissive.len(), 2, "the default scene's lamp is two triangles");
        assert_eq!(gpu.emissive.last().unwrap().cdf, 1.0);
        for e in &gpu.emissive {
            assert!(gpu.triangles[e.bvh_primitive as usize].flags & TRI_EMISSIVE != 0);
        }
    }
}
