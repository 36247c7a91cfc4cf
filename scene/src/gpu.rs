//! The scene laid out for GPU storage buffers (std430), ready for the backend to upload.
//!
//! - nodes: obvhs `CwBvhNode`s as they are (80 B, read in GLSL as `uvec4[5]`);
//! - triangles: corners in BVH order (a leaf's primitive id indexes them directly), 48 B;
//! - attributes: per BVH-ordered triangle, normals, UVs and emissive-light data, 80 B;
//! - materials (64 B), emissive-triangle table (16 B), punctual lights (48 B);
//! - textures: RGBA8 images for a bindless `sampler2D[]` (UNORM; the shader decodes sRGB).
//!
//! The structs below and `shaders/pt_types.glsl` must change together; the size tests here and
//! the `offsetof`-style comments in the GLSL keep them honest.

use bytemuck::{Pod, Zeroable};

use crate::bvh::SceneBvh;
use crate::lights::{LightSet, sun_disc};
use glam::Vec3;

use crate::model::{AlphaMode, PunctualKind, Scene, Sky, Sun, Texture};
use crate::pt::{PixelSet, TraceSettings, View};

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

/// Light-group bits in `GpuTraceParams::counts.z` (same order as the CPU's NEE groups).
pub const LIGHT_GROUP_SUN: u32 = 1;
pub const LIGHT_GROUP_SKY: u32 = 2;
pub const LIGHT_GROUP_PUNCTUAL: u32 = 4;
pub const LIGHT_GROUP_EMISSIVE: u32 = 8;

/// Pixel selection in `GpuTraceParams::counts.w`.
pub const PIXELS_ROWS: u32 = 0;
pub const PIXELS_LIST: u32 = 1;

/// Per-view parameters of `shaders/pt_trace.glsl` (std430, 224 bytes): camera, view,
/// frame, sampling settings, sky, sun and which pixels to trace.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuTraceParams {
    /// Camera position (xyz).
    pub eye: [f32; 4],
    /// Camera right axis times tan(yfov/2) * aspect.
    pub right: [f32; 4],
    /// Camera up axis times tan(yfov/2).
    pub up: [f32; 4],
    /// Camera forward axis (unit).
    pub forward: [f32; 4],
    /// xy: off-axis shift (NDC); zw unused.
    pub shift: [f32; 4],
    /// width, height, view index, frame.
    pub dims: [u32; 4],
    /// spp, max depth, Russian roulette from bounce (u32::MAX = off), jitter (0/1).
    pub sampling: [u32; 4],
    /// punctual light count, emissive triangle count, light-group bits, pixel mode.
    pub counts: [u32; 4],
    /// Rows mode: first row, end row; list mode: list length in z.
    pub pixels: [u32; 4],
    /// xyz radiance; w = 0 constant sky (this colour), 1 gradient (zenith).
    pub sky_zenith: [f32; 4],
    pub sky_horizon: [f32; 4],
    pub sky_ground: [f32; 4],
    /// xyz unit vector to the sun; w cosine of the disc's angular radius.
    pub sun_dir: [f32; 4],
    /// xyz irradiance; w 1 - cos(angular radius), 0 for a delta sun (see `lights::sun_disc`).
    pub sun_irradiance: [f32; 4],
}

/// The part of [`GpuTraceParams`] that only the scene decides: light counts and groups, sky and
/// sun. Counting the emissive triangles walks every triangle of the scene; a renderer that has
/// uploaded a [`GpuScene`] knows the count (its emissive table) and builds this per frame with
/// [`Self::with_emissive_triangles`] instead, in constant time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceLighting {
    /// punctual light count, emissive triangle count, light-group bits.
    counts: [u32; 3],
    sky_zenith: [f32; 4],
    sky_horizon: [f32; 4],
    sky_ground: [f32; 4],
    sun_dir: [f32; 4],
    sun_irradiance: [f32; 4],
}

impl TraceLighting {
    pub fn new(scene: &Scene) -> Self {
        Self::with_emissive_triangles(scene, LightSet::new(scene).emissive_triangle_count())
    }

    /// The lighting of `scene` whose light set has `emissive_triangles` emissive triangles (the
    /// length of [`GpuScene::emissive`]).
    pub fn with_emissive_triangles(scene: &Scene, emissive_triangles: usize) -> Self {
        let (sky_kind, zenith, horizon, ground) = match scene.sky() {
            Sky::Constant(c) => (0.0, c, c, c),
            Sky::Gradient { zenith, horizon, ground } => (1.0, zenith, horizon, ground),
        };
        let sun = scene.sun.unwrap_or(Sun { to_sun: Vec3::Y, irradiance: Vec3::ZERO, angular_radius: 0.0 });
        let disc = sun_disc(sun.angular_radius.max(0.0));
        Self {
            counts: [
                scene.lights.len() as u32,
                emissive_triangles as u32,
                LightSet::group_mask_of(scene, emissive_triangles),
            ],
            sky_zenith: zenith.extend(sky_kind).into(),
            sky_horizon: horizon.extend(0.0).into(),
            sky_ground: ground.extend(0.0).into(),
            sun_dir: sun.to_sun.normalize_or(Vec3::Y).extend(disc.cos_max).into(),
            sun_irradiance: sun
                .irradiance
                .extend(if sun.angular_radius > 0.0 { disc.one_minus_cos } else { 0.0 })
                .into(),
        }
    }
}

impl GpuTraceParams {
    /// Parameters for tracing `pixels` of `view`; a pixel list itself goes in its own buffer
    /// (x | y << 16 per pixel), of which this records only the length. Walks the scene's
    /// triangles for its lights: for many views, build a [`TraceLighting`] once and use
    /// [`Self::with_lighting`].
    pub fn new(scene: &Scene, view: &View, settings: &TraceSettings, pixels: &PixelSet) -> Self {
        Self::with_lighting(&TraceLighting::new(scene), view, settings, pixels)
    }

    /// [`Self::new`] with the scene's lighting already gathered.
    pub fn with_lighting(lighting: &TraceLighting, view: &View, settings: &TraceSettings, pixels: &PixelSet) -> Self {
        let (right, up, back) = view.camera.basis();
        let tan_half = (0.5 * view.camera.yfov).tan();
        let (mode, range) = match pixels {
            PixelSet::All => (PIXELS_ROWS, [0, view.height, 0, 0]),
            PixelSet::Rows { start, end } => (PIXELS_ROWS, [*start, (*end).min(view.height), 0, 0]),
            PixelSet::List(l) => (PIXELS_LIST, [0, 0, l.len() as u32, 0]),
        };
        let [punctual, emissive, groups] = lighting.counts;
        Self {
            eye: view.camera.eye.extend(0.0).into(),
            right: (right * (tan_half * view.aspect())).extend(0.0).into(),
            up: (up * tan_half).extend(0.0).into(),
            forward: (-back).extend(0.0).into(),
            shift: [view.camera.shift.x, view.camera.shift.y, 0.0, 0.0],
            dims: [view.width, view.height, view.index, settings.frame],
            sampling: [
                settings.spp,
                settings.max_depth,
                settings.russian_roulette_from.unwrap_or(u32::MAX),
                settings.jitter as u32,
            ],
            counts: [punctual, emissive, groups, mode],
            pixels: range,
            sky_zenith: lighting.sky_zenith,
            sky_horizon: lighting.sky_horizon,
            sky_ground: lighting.sky_ground,
            sun_dir: lighting.sun_dir,
            sun_irradiance: lighting.sun_irradiance,
        }
    }
}

/// One traced pixel as `shaders/pt_trace.glsl` writes it (std430, 64 bytes); misses have zero
/// G-buffer values, like [`crate::PixelSample`].
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuPixel {
    /// rgb radiance, a = 1 if the first hit exists.
    pub radiance: [f32; 4],
    /// rgb albedo, a roughness.
    pub albedo_roughness: [f32; 4],
    /// xyz normal, w metallic.
    pub normal_metallic: [f32; 4],
    /// xyz position, w linear depth.
    pub position_depth: [f32; 4],
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
        for &t in &bvh.cwbvh.primitive_indices {
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
        }
        // The CPU's table, with scene triangle indices mapped to BVH positions.
        let mut bvh_position = vec![0u32; scene.triangle_count()];
        for (k, &t) in bvh.cwbvh.primitive_indices.iter().enumerate() {
            bvh_position[t as usize] = k as u32;
        }
        let (emissive_tris, emissive_cdf) = lights.emissive_table();
        let emissive = emissive_tris
            .iter()
            .zip(emissive_cdf)
            .map(|(&t, &cdf)| GpuEmissiveTriangle { bvh_primitive: bvh_position[t as usize], cdf, _pad: [0; 2] })
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
        assert_eq!(std::mem::size_of::<GpuTraceParams>(), 224);
        assert_eq!(std::mem::size_of::<GpuPixel>(), 64);
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

    #[test]
    fn lighting_from_the_uploaded_emissive_table_gives_the_same_parameters() {
        let mut scene = default_scene();
        let bvh = SceneBvh::build(&scene);
        let emissive = GpuScene::new(&scene, &bvh).emissive.len();
        let view = View { camera: scene.default_camera(), width: 40, height: 30, index: 3 };
        let settings = TraceSettings { spp: 4, frame: 7, ..Default::default() };
        let same = |scene: &Scene| {
            let lit = TraceLighting::with_emissive_triangles(scene, emissive);
            assert_eq!(lit, TraceLighting::new(scene));
            let params = GpuTraceParams::with_lighting(&lit, &view, &settings, &PixelSet::All);
            assert_eq!(params, GpuTraceParams::new(scene, &view, &settings, &PixelSet::All));
            params
        };
        let params = same(&scene);
        assert_eq!(params.counts[1], 2, "the lamp's two triangles");
        let sun_and_sky = LIGHT_GROUP_SUN | LIGHT_GROUP_SKY;
        assert_eq!(
            params.counts[2],
            sun_and_sky | LIGHT_GROUP_EMISSIVE | if scene.lights.is_empty() { 0 } else { LIGHT_GROUP_PUNCTUAL }
        );
        // Sun and sky may change between frames: the groups follow them.
        scene.sun = None;
        scene.sky = Some(Sky::Constant(Vec3::ZERO));
        let dark = same(&scene);
        assert_eq!(dark.counts[2] & sun_and_sky, 0);
    }
}
