//! The scene BVH: one obvhs CWBVH (8-wide, compressed, Ylitie et al. 2017) over all triangles,
//! and the CPU traversals (closest hit, any hit) that the reference path tracer uses.
//!
//! The GPU traverses the very same nodes (`shaders/bvh_traverse.glsl`); [`crate::gpu`] lays out
//! the buffers. Triangles are kept in BVH order ("direct layout") so a leaf's primitive ids index
//! the triangle array directly; [`SceneBvh::scene_triangle`] maps them back to scene triangles.

use std::time::{Duration, Instant};

use glam::{Vec2, Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;
use obvhs::{Boundable, BvhBuildParams};

use crate::bvh_coincident::{LARGEST_PLAIN_GROUP, build_grouped, centroid_groups};
use crate::model::{AlphaMode, Scene};

/// A ray-triangle hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Index into [`Scene::triangles`].
    pub triangle: u32,
    /// Index into the BVH-ordered triangle array (what the GPU reports).
    pub bvh_primitive: u32,
    pub t: f32,
    /// Barycentric weights of the triangle's second and third vertices.
    pub barycentrics: Vec2,
}

/// The CWBVH of a scene plus its triangles in BVH order.
pub struct SceneBvh {
    pub cwbvh: CwBvh,
    /// Triangle corners in BVH order: `tris[i]` is scene triangle `cwbvh.primitive_indices[i]`.
    pub tris: Vec<Triangle>,
    /// Wall-clock time of the whole build (obvhs core build plus triangle reordering).
    pub build_time: Duration,
    /// obvhs's own accounting of its core build time.
    pub core_build_time: Duration,
}

/// How much build time to spend for traversal speed (obvhs's presets). `Slow` and `VerySlow`
/// pre-split large triangles, so one triangle can sit in several leaves; hits still map to scene
/// triangles through `primitive_indices`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BvhQuality {
    Fast,
    #[default]
    Medium,
    Slow,
    VerySlow,
}

impl BvhQuality {
    fn params(self) -> BvhBuildParams {
        match self {
            BvhQuality::Fast => BvhBuildParams::fast_build(),
            BvhQuality::Medium => BvhBuildParams::medium_build(),
            BvhQuality::Slow => BvhBuildParams::slow_build(),
            BvhQuality::VerySlow => BvhBuildParams::very_slow_build(),
        }
    }
}

impl std::str::FromStr for BvhQuality {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "fast" => Ok(BvhQuality::Fast),
            "medium" => Ok(BvhQuality::Medium),
            "slow" => Ok(BvhQuality::Slow),
            "very-slow" => Ok(BvhQuality::VerySlow),
            _ => Err(format!("unknown BVH quality '{s}': use fast, medium, slow or very-slow")),
        }
    }
}

impl SceneBvh {
    /// Builds with obvhs's `medium_build` preset (PLOC + reinsertion).
    pub fn build(scene: &Scene) -> Self {
        Self::build_with(scene, BvhQuality::Medium)
    }

    /// Builds with the preset of `quality`.
    pub fn build_with(scene: &Scene, quality: BvhQuality) -> Self {
        let start = Instant::now();
        let tris: Vec<Triangle> = (0..scene.triangle_count())
            .map(|t| {
                let [a, b, c] = scene.triangle_positions(t);
                Triangle { v0: a.into(), v1: b.into(), v2: c.into() }
            })
            .collect();
        let mut core = Duration::ZERO;
        let aabbs: Vec<Aabb> = tris.iter().map(Boundable::aabb).collect();
        let groups = centroid_groups(&aabbs);
        let cwbvh = if tris.is_empty() {
            CwBvh::default()
        } else if groups.iter().any(|g| g.len() > LARGEST_PLAIN_GROUP) {
            // Quality is moot for such a scene; pre-splitting (slow presets) is skipped.
            let start = Instant::now();
            let cwbvh = build_grouped(&aabbs, &groups, &quality.params());
            core = start.elapsed();
            cwbvh
        } else {
            obvhs::cwbvh::builder::build_cwbvh_from_tris(&tris, quality.params(), &mut core)
        };
        let tris = cwbvh.primitive_indices.iter().map(|&i| tris[i as usize]).collect();
        Self { cwbvh, tris, build_time: start.elapsed(), core_build_time: core }
    }

    pub fn node_count(&self) -> usize {
        self.cwbvh.nodes.len()
    }

    /// The scene triangle stored at BVH position `bvh_primitive`.
    pub fn scene_triangle(&self, bvh_primitive: u32) -> u32 {
        self.cwbvh.primitive_indices[bvh_primitive as usize]
    }

    /// Closest hit in `(tmin, tmax)`, skipping alpha-masked-out texels.
    pub fn closest_hit(&self, scene: &Scene, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit> {
        if self.tris.is_empty() {
            return None;
        }
        let ray = Ray::new(origin.into(), dir.into(), tmin, tmax);
        let mut hit = RayHit::none();
        let mut bary = Vec2::ZERO;
        self.cwbvh.ray_traverse(ray, &mut hit, |r, id| match self.intersect_visible(scene, id, r) {
            Some((t, uv)) => {
                bary = uv;
                t
            }
            None => f32::INFINITY,
        });
        // obvhs records the barycentrics of the last accepted candidate, which is the closest
        // because it shrinks tmax on every accepted hit.
        (hit.t < tmax).then(|| Hit {
            triangle: self.scene_triangle(hit.primitive_id),
            bvh_primitive: hit.primitive_id,
            t: hit.t,
            barycentrics: bary,
        })
    }

    /// True if anything (alpha-aware) lies in `(tmin, tmax)` along the ray: shadow rays.
    pub fn occluded(&self, scene: &Scene, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> bool {
        if self.tris.is_empty() {
            return false;
        }
        let ray = Ray::new(origin.into(), dir.into(), tmin, tmax);
        !self
            .cwbvh
            .ray_traverse_miss(ray, |r, id| self.intersect_visible(scene, id, r).map_or(f32::INFINITY, |(t, _)| t))
    }

    /// Ray-triangle test plus the alpha mask.
    fn intersect_visible(&self, scene: &Scene, id: usize, ray: &Ray) -> Option<(f32, Vec2)> {
        let (t, uv) = intersect_triangle(&self.tris[id], ray)?;
        let tri = self.cwbvh.primitive_indices[id] as usize;
        let material = &scene.materials[scene.triangle_materials[tri] as usize];
        if let AlphaMode::Mask(cutoff) = material.alpha_mode {
            let [a, b, c] = scene.triangles[tri];
            let tex_uv = scene.uvs[a as usize] * (1.0 - uv.x - uv.y)
                + scene.uvs[b as usize] * uv.x
                + scene.uvs[c as usize] * uv.y;
            if scene.base_color_alpha(material, tex_uv) < cutoff {
                return None;
            }
        }
        Some((t, uv))
    }
}

/// Moeller-Trumbore as obvhs writes it (two-sided, `t` in `[tmin, tmax]`), also returning the
/// barycentrics of v1 and v2. The GLSL version in `shaders/bvh_traverse.glsl` is line for line
/// the same so that CPU and GPU agree to rounding.
pub fn intersect_triangle(tri: &Triangle, ray: &Ray) -> Option<(f32, Vec2)> {
    let e1 = tri.v0 - tri.v1;
    let e2 = tri.v2 - tri.v0;
    let n = e1.cross(e2);
    let c = tri.v0 - ray.origin;
    let r = ray.direction.cross(c);
    let inv_det = 1.0 / n.dot(ray.direction);
    let u = r.dot(e2) * inv_det;
    let v = r.dot(e1) * inv_det;
    let w = 1.0 - u - v;
    // Sign-bit test as in obvhs: -0.0 counts as outside, so shared edges are not hit twice.
    let outside = (u.to_bits() | v.to_bits() | w.to_bits()) & 0x8000_0000 != 0;
    if inv_det == 0.0 || !inv_det.is_finite() || outside {
        return None;
    }
    let t = n.dot(c) * inv_det;
    (t >= ray.tmin && t <= ray.tmax).then_some((t, Vec2::new(u, v)))
}

/// Closest hit by testing every triangle (no BVH, no alpha): the oracle for BVH tests.
pub fn brute_force_closest(scene: &Scene, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<(u32, f32)> {
    let ray = Ray::new(Vec3A::from(origin), Vec3A::from(dir), tmin, tmax);
    let mut best: Option<(u32, f32)> = None;
    for t in 0..scene.triangle_count() {
        let [a, b, c] = scene.triangle_positions(t);
        let tri = Triangle { v0: a.into(), v1: b.into(), v2: c.into() };
        if let Some((d, _)) = intersect_triangle(&tri, &ray) {
            if best.is_none_or(|(_, bd)| d < bd) {
                best = Some((t as u32, d));
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn barycentrics_reconstruct_the_hit_point() {
        let tri =
            Triangle { v0: Vec3A::new(0.0, 0.0, 0.0), v1: Vec3A::new(2.0, 0.0, 0.0), v2: Vec3A::new(0.0, 3.0, 0.0) };
        let ray = Ray::new(Vec3A::new(0.5, 0.75, 1.0), Vec3A::new(0.0, 0.0, -1.0), 0.0, 10.0);
        let (t, uv) = intersect_triangle(&tri, &ray).unwrap();
        assert!((t - 1.0).abs() < 1e-6);
        let p = tri.v0 * (1.0 - uv.x - uv.y) + tri.v1 * uv.x + tri.v2 * uv.y;
        assert!((p - Vec3A::new(0.5, 0.75, 0.0)).length() < 1e-6, "{p}");
        assert_eq!(tri.intersect(&ray), t, "same formula as obvhs");
    }
}
