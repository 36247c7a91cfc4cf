//! The flat scene model every consumer shares: world-space indexed triangles, glTF
//! metallic-roughness materials, decoded textures, lights and cameras.
//!
//! Everything is already in world space (node transforms and skinning applied at load time, at
//! t = 0 of the file's animation), so the BVH, the CPU reference and the GPU upload all read the
//! same arrays; [`Scene::pose_at`] moves an animated scene's vertices to another time.

use glam::{Vec2, Vec3, Vec4};

use crate::camera::Camera;

/// One decoded texture, RGBA8, row-major from the top-left texel, ready for upload into a
/// bindless array. Colour space is a property of the material slot that references it
/// (base colour and emissive are sRGB, metallic-roughness is linear), not of the image.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    pub rgba8: Vec<u8>,
}

impl Texture {
    /// One texel, wrapped (glTF's default REPEAT), as 0..1 floats without colour conversion.
    pub fn texel(&self, x: i64, y: i64) -> Vec4 {
        let x = x.rem_euclid(self.width as i64) as usize;
        let y = y.rem_euclid(self.height as i64) as usize;
        let i = 4 * (y * self.width as usize + x);
        let p = &self.rgba8[i..i + 4];
        Vec4::new(p[0] as f32, p[1] as f32, p[2] as f32, p[3] as f32) / 255.0
    }

    /// Bilinear lookup with REPEAT wrapping; `uv` in glTF convention (v = 0 at the top row).
    /// No mipmapping: the CPU reference averages many samples per pixel instead.
    pub fn sample_bilinear(&self, uv: Vec2) -> Vec4 {
        let x = uv.x * self.width as f32 - 0.5;
        let y = uv.y * self.height as f32 - 0.5;
        if !x.is_finite() || !y.is_finite() {
            return self.texel(0, 0);
        }
        // Wrap before converting so that huge UVs cannot overflow the integer conversion.
        let (w, h) = (self.width as f32, self.height as f32);
        let x = x.rem_euclid(w);
        let y = y.rem_euclid(h);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let a = self.texel(x0, y0).lerp(self.texel(x0 + 1, y0), fx);
        let b = self.texel(x0, y0 + 1).lerp(self.texel(x0 + 1, y0 + 1), fx);
        a.lerp(b, fy)
    }
}

/// sRGB transfer function to linear, for base-colour and emissive texels.
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

/// How a material's alpha is interpreted. glTF BLEND is imported as `Mask(0.5)`: a path tracer
/// has no draw order to blend in, and no scene we ship uses BLEND.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AlphaMode {
    Opaque,
    /// Surfaces whose alpha is below the cutoff are not there, for every ray.
    Mask(f32),
}

/// glTF metallic-roughness material. Texture fields index [`Scene::textures`]; all textures use
/// TEXCOORD_0 (the importer rejects anything else).
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    /// Linear RGBA; multiplied by the sRGB-decoded base colour texture.
    pub base_color: Vec4,
    pub base_color_texture: Option<u32>,
    pub metallic: f32,
    pub roughness: f32,
    /// Linear; blue = metallic, green = roughness (glTF convention).
    pub metallic_roughness_texture: Option<u32>,
    /// Emitted radiance: emissiveFactor times KHR_materials_emissive_strength.
    pub emissive: Vec3,
    pub emissive_texture: Option<u32>,
    pub alpha_mode: AlphaMode,
    pub double_sided: bool,
    /// Scale of the dielectric specular lobe: 1 for every glTF material (the spec's 4 % F0);
    /// 0 makes a pure Lambert surface, which the default scene and the white-furnace test need
    /// because the glTF dielectric model is not energy conserving at albedo 1.
    pub specular: f32,
}

impl Default for Material {
    /// The glTF default material: white, fully metallic and rough, opaque, single-sided.
    fn default() -> Self {
        Self {
            name: "default".into(),
            base_color: Vec4::ONE,
            base_color_texture: None,
            metallic: 1.0,
            roughness: 1.0,
            metallic_roughness_texture: None,
            emissive: Vec3::ZERO,
            emissive_texture: None,
            alpha_mode: AlphaMode::Opaque,
            double_sided: false,
            specular: 1.0,
        }
    }
}

impl Material {
    /// A pure Lambert surface of the given linear albedo.
    pub fn diffuse(name: &str, albedo: Vec3) -> Self {
        Self {
            name: name.into(),
            base_color: albedo.extend(1.0),
            metallic: 0.0,
            roughness: 1.0,
            specular: 0.0,
            double_sided: true,
            ..Default::default()
        }
    }

    /// A glTF dielectric or metal with the given roughness.
    pub fn glossy(name: &str, base: Vec3, metallic: f32, roughness: f32) -> Self {
        Self {
            name: name.into(),
            base_color: base.extend(1.0),
            metallic,
            roughness,
            specular: 1.0,
            double_sided: true,
            ..Default::default()
        }
    }

    /// An emitter with a black diffuse base.
    pub fn emitter(name: &str, radiance: Vec3) -> Self {
        Self {
            name: name.into(),
            base_color: Vec4::new(0.0, 0.0, 0.0, 1.0),
            metallic: 0.0,
            roughness: 1.0,
            specular: 0.0,
            emissive: radiance,
            double_sided: false,
            ..Default::default()
        }
    }

    pub fn is_emissive(&self) -> bool {
        self.emissive.max_element() > 0.0
    }
}

/// Kinds of KHR_lights_punctual lights, already in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PunctualKind {
    /// Radiant intensity `intensity * color` (glTF candela, taken as W/sr) from `position`.
    Point,
    /// As Point, restricted to a cone around `direction` with a smooth falloff between the
    /// angles (radians).
    Spot { inner_cone: f32, outer_cone: f32 },
    /// Irradiance `intensity * color` (glTF lux) arriving along `direction`.
    Directional,
}

#[derive(Clone, Debug, PartialEq)]
pub struct PunctualLight {
    pub kind: PunctualKind,
    pub position: Vec3,
    /// The direction the light travels (glTF: the node's -Z).
    pub direction: Vec3,
    pub color: Vec3,
    pub intensity: f32,
}

/// The sun: a distant disc. `irradiance` is what a surface facing it receives; the disc's
/// radiance is irradiance / solid angle. An angular radius of 0 makes it a delta light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sun {
    /// Unit vector from the scene towards the sun.
    pub to_sun: Vec3,
    pub irradiance: Vec3,
    /// Half the apparent diameter, radians (the real sun: about 0.00465).
    pub angular_radius: f32,
}

/// Radiance arriving from directions where no geometry is hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Sky {
    Constant(Vec3),
    /// Linear blend from `horizon` at the horizon to `zenith` straight up (+Y); `ground` below.
    Gradient {
        zenith: Vec3,
        horizon: Vec3,
        ground: Vec3,
    },
}

impl Sky {
    pub const BLACK: Sky = Sky::Constant(Vec3::ZERO);

    pub fn radiance(&self, dir: Vec3) -> Vec3 {
        match *self {
            Sky::Constant(c) => c,
            Sky::Gradient { zenith, horizon, ground } => {
                if dir.y >= 0.0 {
                    horizon.lerp(zenith, dir.y.min(1.0))
                } else {
                    ground
                }
            }
        }
    }

    pub fn is_black(&self) -> bool {
        match *self {
            Sky::Constant(c) => c.max_element() <= 0.0,
            Sky::Gradient { zenith, horizon, ground } => zenith.max(horizon).max(ground).max_element() <= 0.0,
        }
    }
}

/// Axis-aligned bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    pub min: Vec3,
    pub max: Vec3,
}

impl Bounds {
    pub fn center(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }
    pub fn diagonal(&self) -> f32 {
        (self.max - self.min).length()
    }
}

/// The whole scene, flat and in world space.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    pub name: String,
    pub positions: Vec<Vec3>,
    /// Unit shading normals, one per vertex (generated flat when a file has none).
    pub normals: Vec<Vec3>,
    /// TEXCOORD_0 per vertex (zero when the file has none).
    pub uvs: Vec<Vec2>,
    /// Vertex indices of each triangle.
    pub triangles: Vec<[u32; 3]>,
    /// Material index of each triangle.
    pub triangle_materials: Vec<u32>,
    pub materials: Vec<Material>,
    pub textures: Vec<Texture>,
    pub lights: Vec<PunctualLight>,
    pub cameras: Vec<Camera>,
    /// How the first camera moves, when the file animates it (or a node above it).
    pub camera_animation: Option<crate::animation::CameraAnimation>,
    /// How the meshes move, when the file's first animation moves a skin's joints or a mesh's
    /// node; the arrays above hold its pose at t = 0 until [`Scene::pose_at`] poses another.
    pub geometry_animation: Option<crate::posing::GeometryAnimation>,
    /// Set by the caller (CLI); glTF files carry no sun.
    pub sun: Option<Sun>,
    /// Set by the caller (CLI); black unless set.
    pub sky: Option<Sky>,
    /// Every file the scene was read from (empty for a built-in scene).
    pub sources: Vec<crate::input::SourceFile>,
}

impl Scene {
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Whether the scene's geometry moves over time (skinned or node-animated meshes).
    pub fn geometry_moves(&self) -> bool {
        self.geometry_animation.is_some()
    }

    /// Poses the moving meshes at `t` seconds of the animation (held at its ends): their
    /// positions and normals change in place, nothing else does. A still scene is left as it is.
    /// A pose that throws a vertex beyond ±[`crate::MAX_COORDINATE`] is refused naming the vertex and
    /// the time (the scene is then partly posed: drop it).
    pub fn pose_at(&mut self, t: f32) -> Result<(), crate::SceneError> {
        match &self.geometry_animation {
            Some(animation) => animation.pose(t, &mut self.positions, &mut self.normals),
            None => Ok(()),
        }
    }

    /// Base-colour alpha of material `m` at `uv` (factor times texture), for alpha masking.
    pub fn base_color_alpha(&self, m: &Material, uv: Vec2) -> f32 {
        match m.base_color_texture {
            Some(t) => m.base_color.w * self.textures[t as usize].sample_bilinear(uv).w,
            None => m.base_color.w,
        }
    }

    /// The three world-space corners of triangle `t`.
    pub fn triangle_positions(&self, t: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[t];
        [self.positions[a as usize], self.positions[b as usize], self.positions[c as usize]]
    }

    pub fn bounds(&self) -> Bounds {
        let mut min = Vec3::splat(f32::INFINITY);
        let mut max = Vec3::splat(f32::NEG_INFINITY);
        for p in &self.positions {
            min = min.min(*p);
            max = max.max(*p);
        }
        if self.positions.is_empty() {
            min = Vec3::ZERO;
            max = Vec3::ZERO;
        }
        Bounds { min, max }
    }

    /// Total area of all triangles (zero when every triangle is degenerate).
    pub fn surface_area(&self) -> f64 {
        (0..self.triangle_count())
            .map(|t| {
                let [a, b, c] = self.triangle_positions(t).map(|p| p.as_dvec3());
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }

    /// Whether anything emits light: a sun, a non-black sky, a punctual light or an emissive
    /// material. Without any, every pixel is black.
    pub fn has_light(&self) -> bool {
        self.sun.is_some_and(|s| s.irradiance.max_element() > 0.0)
            || !self.sky().is_black()
            || self.lights.iter().any(|l| l.intensity > 0.0 && l.color.max_element() > 0.0)
            || self.materials.iter().any(|m| m.is_emissive())
    }

    pub fn sky(&self) -> Sky {
        self.sky.unwrap_or(Sky::BLACK)
    }

    /// The file's first camera, or one that frames the whole scene from +Z (slightly above).
    pub fn default_camera(&self) -> Camera {
        if let Some(c) = self.cameras.first() {
            return *c;
        }
        let b = self.bounds();
        let yfov = 0.8f32;
        let radius = 0.5 * b.diagonal().max(1e-3);
        let distance = radius / (0.5 * yfov).tan() * 1.1;
        let dir = Vec3::new(0.0, 0.25, 1.0).normalize();
        Camera::look_at(b.center() + dir * distance, b.center(), Vec3::Y, yfov)
    }

    /// Checks the invariants every consumer relies on (index ranges, parallel array lengths,
    /// material and texture references). The importer and the default scene guarantee them;
    /// this exists for scenes built by hand.
    pub fn check(&self) -> Result<(), String> {
        let n = self.positions.len();
        if self.normals.len() != n || self.uvs.len() != n {
            return Err(format!("{} positions, {} normals, {} uvs", n, self.normals.len(), self.uvs.len()));
        }
        if self.triangle_materials.len() != self.triangles.len() {
            return Err("one material per triangle required".into());
        }
        if let Some(t) = self.triangles.iter().flatten().find(|&&i| i as usize >= n) {
            return Err(format!("vertex index {t} out of range ({n} vertices)"));
        }
        let m = self.materials.len();
        if let Some(x) = self.triangle_materials.iter().find(|&&i| i as usize >= m) {
            return Err(format!("material {x} out of range ({m} materials)"));
        }
        let t = self.textures.len() as u32;
        for mat in &self.materials {
            for tex in
                [mat.base_color_texture, mat.metallic_roughness_texture, mat.emissive_texture].into_iter().flatten()
            {
                if tex >= t {
                    return Err(format!("material {} uses texture {tex} of {t}", mat.name));
                }
            }
        }
        for tex in &self.textures {
            if tex.width == 0 || tex.height == 0 || tex.rgba8.len() != 4 * tex.width as usize * tex.height as usize {
                return Err("texture size does not match its data".into());
            }
        }
        Ok(())
    }
}
