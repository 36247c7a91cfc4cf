//! Light sampling for next-event estimation, and the matching pdfs for multiple importance
//! sampling when a BSDF-sampled ray finds a light by itself.
//!
//! One NEE sample per vertex: first a light *group* is picked uniformly among those present
//! (sun, sky, punctual lights, emissive triangles), then a light within the group (punctual:
//! uniform; emissive triangles: proportional to area times emitted luminance), then a point or
//! direction on it. Sun disc and sky are also reachable by BSDF rays, and emissive triangles
//! by hitting them; their pdfs below let the path tracer weight both strategies (power
//! heuristic). Punctual lights and a sun of zero size are delta lights: NEE only.

use std::f32::consts::{FRAC_1_PI, TAU};

use glam::{Vec2, Vec3};

use crate::bsdf::{orthonormal_basis, sample_cosine_hemisphere};
use crate::model::{PunctualKind, Scene, Sun, srgb_to_linear};
use crate::shading::oriented_face_normal;

/// Which kind of light a group holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Group {
    Sun,
    Sky,
    Punctual,
    Emissive,
}

/// A light sample as seen from a shading point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction from the shading point towards the light.
    pub wi: Vec3,
    /// Distance to the light point; infinite for distant lights.
    pub distance: f32,
    /// Incident radiance (area and distant lights) or irradiance-like `I / d^2` (delta lights).
    pub radiance: Vec3,
    /// Solid-angle pdf including the selection probability; for delta lights the discrete
    /// selection probability.
    pub pdf: f32,
    pub is_delta: bool,
}

/// Precomputed light data of a scene.
pub struct LightSet {
    groups: Vec<Group>,
    /// Scene triangle indices of emissive triangles.
    emissive: Vec<u32>,
    /// Cumulative selection weights over `emissive`, normalised to end at 1.
    emissive_cdf: Vec<f32>,
    /// Per scene triangle: its selection probability within the emissive group (0 if none).
    emissive_prob: Vec<f32>,
    area: Vec<f32>,
    sun: Option<Sun>,
}

fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// The sun disc as NEE and MIS need it: `one_minus_cos` = 1 - cos(angular radius), the cosine
/// threshold of the cone, and the disc's radiance E / (pi sin^2 r).
///
/// For a disc of half a degree, 1 - cos is 4e-5: computed as `1.0 - r.cos()` in f32 it loses
/// a few digits (the GPU's approximate cos loses more), and the pdf 1 / (2 pi (1 - cos)) and the
/// radiance disagree by a fraction of a percent. So it is computed once, in f64, from
/// 2 sin^2(r/2), and the GPU receives this value rather than recomputing it.
pub fn sun_disc(angular_radius: f32) -> SunDisc {
    let r = angular_radius as f64;
    let half = (0.5 * r).sin();
    let one_minus_cos = 2.0 * half * half;
    let sin2 = one_minus_cos * (2.0 - one_minus_cos);
    SunDisc {
        one_minus_cos: one_minus_cos as f32,
        cos_max: (1.0 - one_minus_cos) as f32,
        radiance_scale: (1.0 / (std::f64::consts::PI * sin2)) as f32,
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SunDisc {
    pub one_minus_cos: f32,
    pub cos_max: f32,
    /// Disc radiance per unit irradiance.
    pub radiance_scale: f32,
}

/// The NEE groups of `scene` (in sampling order) and its sun if it shines.
fn groups_of(scene: &Scene, has_emissive: bool) -> (Vec<Group>, Option<Sun>) {
    let sun = scene.sun.filter(|s| s.irradiance.max_element() > 0.0 && s.to_sun.is_finite());
    let mut groups = Vec::new();
    if sun.is_some() {
        groups.push(Group::Sun);
    }
    if !scene.sky().is_black() {
        groups.push(Group::Sky);
    }
    if !scene.lights.is_empty() {
        groups.push(Group::Punctual);
    }
    if has_emissive {
        groups.push(Group::Emissive);
    }
    (groups, sun)
}

fn group_bits(groups: &[Group]) -> u32 {
    groups
        .iter()
        .map(|g| match g {
            Group::Sun => 1,
            Group::Sky => 2,
            Group::Punctual => 4,
            Group::Emissive => 8,
        })
        .sum()
}

/// The sun: its direction when it has no size (a delta light), else a direction uniform in the
/// cone of its disc by `u[1]`, `u[2]`.
fn sample_sun(sun: Sun, u: [f32; 4], p_group: f32) -> Option<LightSample> {
    let to_sun = sun.to_sun.normalize();
    if sun.angular_radius <= 0.0 {
        return Some(LightSample {
            wi: to_sun,
            distance: f32::INFINITY,
            radiance: sun.irradiance,
            pdf: p_group,
            is_delta: true,
        });
    }
    let disc = sun_disc(sun.angular_radius);
    let cos_t = 1.0 - u[1] * disc.one_minus_cos;
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = TAU * u[2];
    let (t, b) = orthonormal_basis(to_sun);
    let wi = (t * (sin_t * phi.cos()) + b * (sin_t * phi.sin()) + to_sun * cos_t).normalize();
    Some(LightSample {
        wi,
        distance: f32::INFINITY,
        radiance: sun.irradiance * disc.radiance_scale,
        pdf: p_group / (TAU * disc.one_minus_cos),
        is_delta: false,
    })
}

/// The sky: a cosine-weighted direction about `n` by `u[1]`, `u[2]`.
fn sample_sky(scene: &Scene, n: Vec3, u: [f32; 4], p_group: f32) -> Option<LightSample> {
    let wi = sample_cosine_hemisphere(n, u[1], u[2]);
    let pdf = p_group * wi.dot(n).max(0.0) * FRAC_1_PI;
    (pdf > 0.0).then(|| LightSample {
        wi,
        distance: f32::INFINITY,
        radiance: scene.sky().radiance(wi),
        pdf,
        is_delta: false,
    })
}

/// A punctual light chosen uniformly by `u_within`; a spot light's radiance falls off between
/// its cone angles.
fn sample_punctual(scene: &Scene, p: Vec3, u_within: f32, p_group: f32) -> Option<LightSample> {
    let k = ((u_within * scene.lights.len() as f32) as usize).min(scene.lights.len() - 1);
    let light = &scene.lights[k];
    let pdf = p_group / scene.lights.len() as f32;
    let power = light.color * light.intensity;
    match light.kind {
        PunctualKind::Directional => {
            Some(LightSample { wi: -light.direction, distance: f32::INFINITY, radiance: power, pdf, is_delta: true })
        }
        PunctualKind::Point | PunctualKind::Spot { .. } => {
            let to_light = light.position - p;
            let d2 = to_light.length_squared();
            if d2 <= 0.0 {
                return None;
            }
            let wi = to_light / d2.sqrt();
            let mut radiance = power / d2;
            if let PunctualKind::Spot { inner_cone, outer_cone } = light.kind {
                // glTF's recommended falloff between the cone angles.
                let (ci, co) = (inner_cone.cos(), outer_cone.cos());
                let scale = 1.0 / (ci - co).max(1e-3);
                let cd = light.direction.dot(-wi);
                let a = ((cd - co) * scale).clamp(0.0, 1.0);
                radiance *= a * a;
            }
            Some(LightSample { wi, distance: d2.sqrt(), radiance, pdf, is_delta: true })
        }
    }
}

impl LightSet {
    pub fn new(scene: &Scene) -> Self {
        let mut emissive = Vec::new();
        let mut weights = Vec::new();
        let mut area = vec![0.0; scene.triangle_count()];
        for (t, (&mi, tri_area)) in scene.triangle_materials.iter().zip(area.iter_mut()).enumerate() {
            let m = &scene.materials[mi as usize];
            if !m.is_emissive() {
                continue;
            }
            let [a, b, c] = scene.triangle_positions(t);
            let ar = 0.5 * (b - a).cross(c - a).length();
            let w = ar * luminance(m.emissive);
            if w > 0.0 && w.is_finite() {
                *tri_area = ar;
                emissive.push(t as u32);
                weights.push(w);
            }
        }
        let total: f64 = weights.iter().map(|&w| w as f64).sum();
        let mut emissive_prob = vec![0.0; scene.triangle_count()];
        let mut acc = 0.0f64;
        let mut emissive_cdf = Vec::with_capacity(weights.len());
        for (k, &w) in weights.iter().enumerate() {
            acc += w as f64;
            emissive_cdf.push((acc / total) as f32);
            emissive_prob[emissive[k] as usize] = (w as f64 / total) as f32;
        }
        if let Some(last) = emissive_cdf.last_mut() {
            *last = 1.0;
        }
        let (groups, sun) = groups_of(scene, !emissive.is_empty());
        Self { groups, emissive, emissive_cdf, emissive_prob, area, sun }
    }

    /// [`Self::group_mask`] of the light set of `scene` with `emissive_triangles` emissive
    /// triangles, without walking the triangles again.
    pub fn group_mask_of(scene: &Scene, emissive_triangles: usize) -> u32 {
        group_bits(&groups_of(scene, emissive_triangles > 0).0)
    }

    pub fn is_empty(&self) -> bool {
        self.groups.is_empty()
    }

    /// Selection probability within the emissive group and area of scene triangle `tri`.
    pub fn emissive_prob_and_area(&self, tri: u32) -> (f32, f32) {
        (self.emissive_prob[tri as usize], self.area[tri as usize])
    }

    /// The emissive triangles (scene indices) and their cumulative selection probabilities, in
    /// the order NEE searches them; the GPU gets the very same table.
    pub fn emissive_table(&self) -> (&[u32], &[f32]) {
        (&self.emissive, &self.emissive_cdf)
    }

    /// Light groups present, as bits: 1 sun, 2 sky, 4 punctual, 8 emissive (the GPU's
    /// `LIGHT_GROUP_*`); NEE picks one uniformly in this order.
    pub fn group_mask(&self) -> u32 {
        group_bits(&self.groups)
    }

    pub fn emissive_triangle_count(&self) -> usize {
        self.emissive.len()
    }

    fn group_prob(&self, g: Group) -> f32 {
        if self.groups.contains(&g) { 1.0 / self.groups.len() as f32 } else { 0.0 }
    }

    /// Samples one light for shading point `p` with shading normal `n`; `u` are four uniforms.
    pub fn sample(&self, scene: &Scene, p: Vec3, n: Vec3, u: [f32; 4]) -> Option<LightSample> {
        if self.groups.is_empty() {
            return None;
        }
        let count = self.groups.len();
        let gi = ((u[0] * count as f32) as usize).min(count - 1);
        let p_group = 1.0 / count as f32;
        // Reuse the part of u[0] left after the group choice for the choice within the group.
        let u_within = (u[0] * count as f32 - gi as f32).clamp(0.0, 0.999_999_9);
        match self.groups[gi] {
            Group::Sun => sample_sun(self.sun?, u, p_group),
            Group::Sky => sample_sky(scene, n, u, p_group),
            Group::Punctual => sample_punctual(scene, p, u_within, p_group),
            Group::Emissive => self.sample_emissive(scene, p, u, u_within, p_group),
        }
    }

    /// An emissive triangle chosen by `u_within` (area times luminance), a point on it uniform
    /// in area by `u[1]`, `u[2]`; `None` when it faces away or the pdf degenerates.
    fn sample_emissive(&self, scene: &Scene, p: Vec3, u: [f32; 4], u_within: f32, p_group: f32) -> Option<LightSample> {
        let k = self.emissive_cdf.partition_point(|&c| c <= u_within).min(self.emissive.len() - 1);
        let tri = self.emissive[k] as usize;
        let [a, b, c] = scene.triangle_positions(tri);
        let su = u[1].sqrt();
        let (b1, b2) = (su * (1.0 - u[2]), su * u[2]);
        let q = a * (1.0 - b1 - b2) + b * b1 + c * b2;
        let to_light = q - p;
        let d2 = to_light.length_squared();
        if d2 <= 0.0 {
            return None;
        }
        let dist = d2.sqrt();
        let wi = to_light / dist;
        let m = &scene.materials[scene.triangle_materials[tri] as usize];
        let ln = oriented_face_normal(scene, tri);
        let cos_l = ln.dot(-wi);
        let facing = cos_l > 0.0 || (m.double_sided && cos_l < 0.0);
        if !facing {
            return None;
        }
        let mut radiance = m.emissive;
        if let Some(tex) = m.emissive_texture {
            let [i, j, k2] = scene.triangles[tri];
            let uv: Vec2 =
                scene.uvs[i as usize] * (1.0 - b1 - b2) + scene.uvs[j as usize] * b1 + scene.uvs[k2 as usize] * b2;
            let t = scene.textures[tex as usize].sample_bilinear(uv);
            radiance *= Vec3::new(srgb_to_linear(t.x), srgb_to_linear(t.y), srgb_to_linear(t.z));
        }
        let pdf = p_group * self.emissive_prob[tri] * d2 / (self.area[tri] * cos_l.abs());
        (pdf.is_finite() && pdf > 0.0).then_some(LightSample { wi, distance: dist, radiance, pdf, is_delta: false })
    }

    /// Radiance of the sun disc seen along `dir` (zero outside it or for a delta sun).
    pub fn sun_radiance(&self, dir: Vec3) -> Vec3 {
        match self.sun {
            Some(sun) if sun.angular_radius > 0.0 => {
                let disc = sun_disc(sun.angular_radius);
                if dir.dot(sun.to_sun.normalize()) >= disc.cos_max {
                    sun.irradiance * disc.radiance_scale
                } else {
                    Vec3::ZERO
                }
            }
            _ => Vec3::ZERO,
        }
    }

    /// NEE pdf of the sun for a BSDF ray leaving along `dir`.
    pub fn pdf_sun(&self, dir: Vec3) -> f32 {
        match self.sun {
            Some(sun) if sun.angular_radius > 0.0 => {
                let disc = sun_disc(sun.angular_radius);
                if dir.dot(sun.to_sun.normalize()) >= disc.cos_max {
                    self.group_prob(Group::Sun) / (TAU * disc.one_minus_cos)
                } else {
                    0.0
                }
            }
            _ => 0.0,
        }
    }

    /// NEE pdf of the sky for a BSDF ray leaving a point with shading normal `n` along `dir`.
    pub fn pdf_sky(&self, n: Vec3, dir: Vec3) -> f32 {
        self.group_prob(Group::Sky) * n.dot(dir).max(0.0) * FRAC_1_PI
    }

    /// NEE pdf (solid angle at `from`) of emissive triangle `tri` hit at `hit` with the
    /// light's outward normal `light_normal`.
    pub fn pdf_emissive(&self, tri: u32, from: Vec3, hit: Vec3, light_normal: Vec3) -> f32 {
        let prob = self.emissive_prob[tri as usize];
        if prob <= 0.0 {
            return 0.0;
        }
        let d = hit - from;
        let d2 = d.length_squared();
        let cos_l = light_normal.dot(d / d2.sqrt()).abs();
        if cos_l <= 0.0 {
            return 0.0;
        }
        self.group_prob(Group::Emissive) * prob * d2 / (self.area[tri as usize] * cos_l)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sun_disc_is_precise_for_small_suns() {
        for degrees in [0.1f64, 0.27, 0.5, 5.0, 30.0] {
            let r = degrees.to_radians();
            let d = sun_disc(r as f32);
            let exact = 1.0 - r.cos();
            assert!(((d.one_minus_cos as f64 - exact) / exact).abs() < 1e-6, "{degrees}: {}", d.one_minus_cos);
            let scale = 1.0 / (std::f64::consts::PI * r.sin() * r.sin());
            assert!(((d.radiance_scale as f64 - scale) / scale).abs() < 1e-5, "{degrees}");
        }
    }
}
