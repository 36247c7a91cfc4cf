//! The view-dependence bound of reprojection, the twin of shaders/view_bound.glsl (derivation:
//! docs/PIPELINE.md, "The view-dependence bound"): an upper bound of the relative change of the
//! BSDF value `f(wi, wo) cos(wi)`, over every incident direction `wi`, when the view direction
//! `wo` turns by `theta`. Since reflected radiance is the integral of `f cos` times incident
//! light, it bounds the relative error of reusing a source's radiance seen `theta` away from the
//! target's direction, whatever the lighting. `reproject` accepts a source only where
//! [`ViewBound::error`] is at most [`crate::reproject::ReprojectionTolerances::view_dependence`].
//!
//! The tests below check the bound against the material model itself
//! (`parallax_scene::bsdf::Bsdf`), and the lavapipe tests that the GPU twin gives the same holes.

use glam::Vec3;
use parallax_scene::bsdf::{MIN_ALPHA, schlick_weight};

/// Least Fresnel F0 the bound assumes (below it, black metal, the relative change of Schlick's
/// Fresnel has no bound).
const MIN_F0: f32 = 0.02;
/// `lobe_share`'s constant: `max_s 2s / ((1 + s²)(1 + r (1 + s²)²)) <= 1 / (1 + 1.93 r)` for
/// every r >= 0 (docs/PIPELINE.md), times the 4 of `r`.
const LOBE_SHARE_K: f32 = 7.7;

/// The terms of the bound that depend on the surface and the target's view only; per source,
/// [`ViewBound::error`] adds the angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewBound {
    /// Specular share of `f` where the GGX lobe is steepest.
    pub lobe_share: Vec3,
    /// Specular share of `f` at the lobe's peak.
    pub peak_share: Vec3,
    /// Largest `|d ln D / d theta|` of the GGX distribution, per radian of view change.
    pub lobe_rate: f32,
    /// Fresnel and visibility terms of the specular lobe, per radian.
    pub peak_rate: Vec3,
    /// The diffuse lobe's Fresnel weight, per radian (0 for metals).
    pub diffuse_rate: f32,
}

impl ViewBound {
    /// The bound at a surface of shading normal `n` seen along the unit `v` (towards the eye),
    /// of `base` colour, `metallic` and perceptual `roughness`; the dielectric specular factor
    /// is taken as 1, its most specular value (the G-buffer does not hold it).
    pub fn new(n: Vec3, v: Vec3, base: Vec3, metallic: f32, roughness: f32) -> Self {
        let alpha = (roughness * roughness).max(MIN_ALPHA);
        let a2 = alpha * alpha;
        let c = n.dot(v).clamp(1e-4, 1.0);
        // The least cos(v, h) over every wi of the hemisphere: wi at grazing, opposite v.
        let c_min = 0.5 * ((1.0 + c).sqrt() - (1.0 - c).sqrt());
        let fw = schlick_weight(c);
        let f0 = Vec3::splat(0.04).lerp(base, metallic).max(Vec3::splat(MIN_F0));
        let f_v = f0 + (Vec3::ONE - f0) * fw;
        let diffuse = (1.0 - metallic) * base * (0.96 - 0.96 * fw);
        let fresnel = f0.to_array().map(|f0| {
            let x = (4.0 * f0 / (1.0 - f0).max(1e-6)).powf(0.2).min(1.0);
            if x >= 1.0 { 5.0 * (1.0 - f0) } else { (1.0 - f0) * x.powi(4) / f0 }
        });
        let tan_v = (1.0 - c * c).max(0.0).sqrt() / c;
        let cd = schlick_weight(c_min);
        let diffuse_slope = 5.0 * (cd / (1.0 - c_min)) * (1.0 - c_min * c_min).max(0.0).sqrt() / (1.0 - cd);
        Self {
            lobe_share: f_v / (f_v + LOBE_SHARE_K * a2 * c * c * diffuse),
            peak_share: f_v / (f_v + 4.0 * a2 * c * c * diffuse),
            lobe_rate: (1.0 - a2) / (alpha * c_min),
            peak_rate: 0.5 * Vec3::from_array(fresnel) + Vec3::splat(tan_v + alpha),
            diffuse_rate: if metallic < 1.0 { 0.5 * diffuse_slope } else { 0.0 },
        }
    }

    /// The bound of the relative radiance error for a view change of `theta` radians.
    pub fn error(&self, theta: f32) -> f32 {
        let grow = |rate: f32| (rate * theta).exp() - 1.0;
        let e = self.lobe_share * grow(self.lobe_rate)
            + self.peak_share * Vec3::from_array(self.peak_rate.to_array().map(grow));
        e.max_element() + grow(self.diffuse_rate)
    }
}

/// The angle between unit vectors, accurate for small angles (where acos is not).
pub fn view_angle(a: Vec3, b: Vec3) -> f32 {
    2.0 * (0.5 * (a - b).length()).min(1.0).asin()
}

#[cfg(test)]
mod tests {
    use super::*;
    use parallax_scene::bsdf::Bsdf;
    use parallax_scene::shading::SurfacePoint;

    fn surface(base: Vec3, metallic: f32, roughness: f32) -> SurfacePoint {
        SurfacePoint {
            position: Vec3::ZERO,
            geometric_normal: Vec3::Z,
            normal: Vec3::Z,
            front_face: true,
            base_color: base,
            metallic,
            roughness,
            specular: 1.0,
            emission: Vec3::ZERO,
        }
    }

    /// `v` turned by `theta` about `axis` (Rodrigues).
    fn turned(v: Vec3, axis: Vec3, theta: f32) -> Vec3 {
        glam::Quat::from_axis_angle(axis.normalize(), theta) * v
    }

    /// The true worst case the bound must cover: over a grid of incident directions, the largest
    /// relative change of `f cos` per channel between the two view directions.
    fn worst_change(sp: &SurfacePoint, wo: Vec3, turned_wo: Vec3) -> f32 {
        let (a, b) = (Bsdf::new(sp, wo), Bsdf::new(sp, turned_wo));
        let mut worst = 0.0f32;
        for i in 0..48 {
            let polar = (i as f32 + 0.5) / 48.0 * std::f32::consts::FRAC_PI_2;
            for j in 0..96 {
                let azimuth = (j as f32 + 0.5) / 96.0 * std::f32::consts::TAU;
                let wi = Vec3::new(polar.sin() * azimuth.cos(), polar.sin() * azimuth.sin(), polar.cos());
                let (fa, _) = a.eval(wo, wi);
                let (fb, _) = b.eval(turned_wo, wi);
                for (x, y) in fa.to_array().into_iter().zip(fb.to_array()) {
                    if x > 0.0 {
                        worst = worst.max((x - y).abs() / x);
                    }
                }
            }
        }
        worst
    }

    /// Materials from rough diffuse to mirror metal, views from normal to grazing, turns in and
    /// out of the plane of incidence.
    #[test]
    fn the_bound_covers_the_material_models_change_of_f_cos() {
        let materials = [
            (Vec3::splat(0.5), 0.0, 1.0),
            (Vec3::splat(0.5), 0.0, 0.5),
            (Vec3::splat(0.5), 0.0, 0.3),
            (Vec3::new(0.1, 0.2, 0.6), 0.0, 0.25),
            (Vec3::new(0.9, 0.1, 0.1), 0.0, 0.1),
            (Vec3::new(1.0, 0.78, 0.34), 1.0, 0.3),
            (Vec3::splat(0.9), 1.0, 0.05),
            (Vec3::splat(0.9), 1.0, 0.6),
            (Vec3::splat(0.5), 0.5, 0.4),
            (Vec3::splat(0.02), 0.0, 0.4),
            (Vec3::new(0.05, 0.5, 0.05), 1.0, 0.5),
        ];
        let mut tightest = f32::INFINITY;
        for (base, metallic, roughness) in materials {
            let sp = surface(base, metallic, roughness);
            for polar_deg in [0.0f32, 30.0, 60.0, 80.0, 88.0] {
                let polar = polar_deg.to_radians();
                let wo = Vec3::new(polar.sin(), 0.0, polar.cos());
                let bound = ViewBound::new(Vec3::Z, wo, base, metallic, roughness);
                for theta in [1e-3f32, 1e-2, 5e-2] {
                    // In the plane of incidence, and out of it.
                    for axis in [Vec3::Y, Vec3::new(-polar.cos(), 0.0, polar.sin())] {
                        let worst = worst_change(&sp, wo, turned(wo, axis, theta));
                        let claimed = bound.error(theta);
                        assert!(
                            worst <= claimed,
                            "base {base}, metallic {metallic}, roughness {roughness}, view {polar_deg}°, \
                             turn {theta} about {axis}: f cos changes by {worst}, the bound says {claimed}"
                        );
                        if worst > 1e-3 {
                            tightest = tightest.min(claimed / worst);
                        }
                    }
                }
            }
        }
        // Not vacuous: somewhere the bound is within 50 % of the true worst case (1.33 today).
        assert!(tightest < 1.5, "the bound is never tight: {tightest}");
    }

    #[test]
    fn the_bound_is_zero_at_no_turn_and_grows_with_the_angle_and_the_lobes_narrowness() {
        let v = Vec3::new(0.3, 0.0, 1.0).normalize();
        let rough = ViewBound::new(Vec3::Z, v, Vec3::splat(0.5), 0.0, 0.8);
        let glossy = ViewBound::new(Vec3::Z, v, Vec3::splat(0.5), 0.0, 0.2);
        let mirror = ViewBound::new(Vec3::Z, v, Vec3::splat(0.9), 1.0, 0.0);
        for b in [rough, glossy, mirror] {
            assert_eq!(b.error(0.0), 0.0);
            assert!(b.error(1e-3) < b.error(1e-2));
        }
        assert!(rough.error(1e-2) < glossy.error(1e-2) && glossy.error(1e-2) < mirror.error(1e-2));
        // A mirror metal is out of reach at any useful tolerance for a 1 mrad turn.
        assert!(mirror.error(1e-3) > 1.0, "{}", mirror.error(1e-3));
    }

    #[test]
    fn view_angle_is_accurate_for_small_angles() {
        let a = Vec3::Z;
        for theta in [1e-6f32, 1e-4, 0.1, 1.0, 3.0] {
            let b = turned(a, Vec3::X, theta);
            assert!((view_angle(a, b) - theta).abs() <= 1e-6 + 1e-5 * theta, "{theta}: {}", view_angle(a, b));
        }
    }
}
