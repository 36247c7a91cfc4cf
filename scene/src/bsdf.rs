//! The material model: glTF metallic-roughness as Lambert diffuse plus a GGX microfacet lobe
//! (Smith height-correlated masking, Schlick Fresnel), sampled with the GGX distribution of
//! visible normals (Heitz, "Sampling the GGX Distribution of Visible Normals", JCGT 2018).
//!
//! Follows the glTF spec's reference model: dielectric = mix(diffuse, specular, F(0.04)),
//! metal = specular with F(base colour), blended by `metallic`. `specular` scales the dielectric
//! Fresnel (0 = pure Lambert). Directions point away from the surface.

use std::f32::consts::{FRAC_1_PI, PI, TAU};

use glam::Vec3;

use crate::shading::SurfacePoint;

/// Smallest GGX alpha: keeps the distribution finite for roughness 0 (near-mirror).
pub const MIN_ALPHA: f32 = 1e-3;

/// Orthonormal basis around `n` (Duff et al., "Building an Orthonormal Basis, Revisited", 2017).
pub fn orthonormal_basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x), Vec3::new(b, sign + n.y * n.y * a, -n.y))
}

/// Cosine-weighted direction about `n`; pdf = cos / pi.
pub fn sample_cosine_hemisphere(n: Vec3, u0: f32, u1: f32) -> Vec3 {
    let r = u0.sqrt();
    let phi = TAU * u1;
    let (t, b) = orthonormal_basis(n);
    (t * (r * phi.cos()) + b * (r * phi.sin()) + n * (1.0 - u0).max(0.0).sqrt()).normalize()
}

fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

pub fn schlick_weight(cos: f32) -> f32 {
    (1.0 - cos).clamp(0.0, 1.0).powi(5)
}

/// A BSDF sample: direction, `f * cos / pdf`, and the pdf (solid angle) for MIS.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    pub wi: Vec3,
    pub weight: Vec3,
    pub pdf: f32,
}

/// The BSDF at one surface point.
#[derive(Clone, Copy, Debug)]
pub struct Bsdf {
    n: Vec3,
    ng: Vec3,
    base: Vec3,
    metallic: f32,
    specular: f32,
    alpha: f32,
    /// Probability of sampling the specular lobe.
    p_specular: f32,
}

impl Bsdf {
    pub fn new(sp: &SurfacePoint, wo: Vec3) -> Self {
        let alpha = (sp.roughness * sp.roughness).max(MIN_ALPHA);
        let n_dot_v = sp.normal.dot(wo).max(1e-4);
        let fw = schlick_weight(n_dot_v);
        let f_dielectric = sp.specular * (0.04 + 0.96 * fw);
        let f_metal = sp.base_color + (Vec3::ONE - sp.base_color) * fw;
        let spec = luminance(Vec3::splat(f_dielectric).lerp(f_metal, sp.metallic));
        let diff = luminance(sp.base_color) * (1.0 - sp.metallic) * (1.0 - f_dielectric);
        let p_specular = if spec <= 0.0 {
            0.0
        } else if diff <= 0.0 {
            1.0
        } else {
            (spec / (spec + diff)).clamp(0.1, 0.9)
        };
        Self {
            n: sp.normal,
            ng: sp.geometric_normal,
            base: sp.base_color,
            metallic: sp.metallic,
            specular: sp.specular,
            alpha,
            p_specular,
        }
    }

    fn d_ggx(&self, n_dot_h: f32) -> f32 {
        let a2 = self.alpha * self.alpha;
        let d = n_dot_h * n_dot_h * (a2 - 1.0) + 1.0;
        a2 / (PI * d * d)
    }

    fn lambda(&self, cos: f32) -> f32 {
        let c2 = cos * cos;
        let tan2 = (1.0 - c2).max(0.0) / c2.max(1e-12);
        0.5 * (-1.0 + (1.0 + self.alpha * self.alpha * tan2).sqrt())
    }

    /// Both sides of the shading and geometric normals must agree, or light would leak through
    /// surfaces whose shading normals differ from their geometry.
    fn valid_pair(&self, wo: Vec3, wi: Vec3) -> bool {
        self.n.dot(wo) > 0.0 && self.n.dot(wi) > 0.0 && self.ng.dot(wi) > 0.0 && self.ng.dot(wo) > 0.0
    }

    /// `(f * cos(wi), pdf(wi))` for the pair; zero when `wi` is below the surface.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        if !self.valid_pair(wo, wi) {
            return (Vec3::ZERO, 0.0);
        }
        let n_dot_v = self.n.dot(wo).max(1e-6);
        let n_dot_l = self.n.dot(wi).max(1e-6);
        let h = (wo + wi).normalize_or_zero();
        if h == Vec3::ZERO {
            return (Vec3::ZERO, 0.0);
        }
        let n_dot_h = self.n.dot(h).max(0.0);
        let v_dot_h = wo.dot(h).clamp(0.0, 1.0);
        let fw = schlick_weight(v_dot_h);
        let f_dielectric = self.specular * (0.04 + 0.96 * fw);
        let f_metal = self.base + (Vec3::ONE - self.base) * fw;
        let f = Vec3::splat(f_dielectric).lerp(f_metal, self.metallic);
        let d = self.d_ggx(n_dot_h);
        let lambda_v = self.lambda(n_dot_v);
        let g2 = 1.0 / (1.0 + lambda_v + self.lambda(n_dot_l));
        let specular = f * (d * g2 / (4.0 * n_dot_v * n_dot_l));
        let diffuse = self.base * ((1.0 - self.metallic) * (1.0 - f_dielectric) * FRAC_1_PI);
        let pdf_spec = d / (1.0 + lambda_v) / (4.0 * n_dot_v);
        let pdf_diff = n_dot_l * FRAC_1_PI;
        let pdf = self.p_specular * pdf_spec + (1.0 - self.p_specular) * pdf_diff;
        ((diffuse + specular) * n_dot_l, pdf)
    }

    /// Samples a direction: the GGX lobe by visible normals, or the diffuse lobe by cosine.
    pub fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        if self.n.dot(wo) <= 0.0 {
            return None;
        }
        let wi = if u[0] < self.p_specular {
            let (t, b) = orthonormal_basis(self.n);
            let v_local = Vec3::new(wo.dot(t), wo.dot(b), wo.dot(self.n));
            let m = sample_ggx_vndf(v_local, self.alpha, u[1], u[2]);
            let m_world = t * m.x + b * m.y + self.n * m.z;
            (2.0 * wo.dot(m_world) * m_world - wo).normalize_or_zero()
        } else {
            sample_cosine_hemisphere(self.n, u[1], u[2])
        };
        let (fcos, pdf) = self.eval(wo, wi);
        if pdf <= 0.0 || !pdf.is_finite() {
            return None;
        }
        let weight = fcos / pdf;
        weight.is_finite().then_some(BsdfSample { wi, weight, pdf })
    }
}

/// A GGX visible normal for the local view direction `v` (z = normal), isotropic `alpha`.
fn sample_ggx_vndf(v: Vec3, alpha: f32, u0: f32, u1: f32) -> Vec3 {
    let vh = Vec3::new(alpha * v.x, alpha * v.y, v.z).normalize();
    let len_sq = vh.x * vh.x + vh.y * vh.y;
    let t1 = if len_sq > 0.0 { Vec3::new(-vh.y, vh.x, 0.0) / len_sq.sqrt() } else { Vec3::X };
    let t2 = vh.cross(t1);
    let r = u0.sqrt();
    let phi = TAU * u1;
    let p1 = r * phi.cos();
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
    let nh = t1 * p1 + t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
    Vec3::new(alpha * nh.x, alpha * nh.y, nh.z.max(0.0)).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{Dim, PathRng};

    fn surface(base: Vec3, metallic: f32, roughness: f32, specular: f32) -> SurfacePoint {
        SurfacePoint {
            position: Vec3::ZERO,
            geometric_normal: Vec3::Z,
            normal: Vec3::Z,
            front_face: true,
            base_color: base,
            metallic,
            roughness,
            specular,
            emission: Vec3::ZERO,
        }
    }

    /// Estimates the directional albedo by importance sampling and checks the sampling weights
    /// against an independent uniform-hemisphere estimate of the same integral.
    fn albedo_two_ways(sp: &SurfacePoint, wo: Vec3) -> (Vec3, Vec3) {
        let bsdf = Bsdf::new(sp, wo);
        let n = 200_000;
        // f64 sums: 200k f32 additions would lose the last digits we compare.
        let mut importance = glam::DVec3::ZERO;
        let mut uniform = glam::DVec3::ZERO;
        for i in 0..n {
            let r = PathRng::new(i, 0, 0, 0).uniforms(0, 0, Dim::Bsdf);
            if let Some(s) = bsdf.sample(wo, [r[0], r[1], r[2]]) {
                importance += s.weight.as_dvec3();
            }
            // Uniform hemisphere: pdf 1 / (2 pi).
            let z = r[3];
            let phi = TAU * r[1];
            let rr = (1.0 - z * z).sqrt();
            let wi = Vec3::new(rr * phi.cos(), rr * phi.sin(), z);
            uniform += (bsdf.eval(wo, wi).0 * TAU).as_dvec3();
        }
        ((importance / n as f64).as_vec3(), (uniform / n as f64).as_vec3())
    }

    #[test]
    fn lambert_albedo_is_base_colour() {
        let sp = surface(Vec3::new(0.8, 0.5, 0.2), 0.0, 1.0, 0.0);
        let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
        let (imp, uni) = albedo_two_ways(&sp, wo);
        assert!((imp - sp.base_color).abs().max_element() < 1e-3, "{imp}");
        assert!((uni - sp.base_color).abs().max_element() < 0.01, "{uni}");
    }

    #[test]
    fn ggx_sampling_weights_match_evaluation() {
        for (metallic, roughness) in [(1.0, 0.5), (0.0, 0.6), (1.0, 0.9), (0.5, 0.7)] {
            let sp = surface(Vec3::new(0.9, 0.6, 0.3), metallic, roughness, 1.0);
            let wo = Vec3::new(0.5, 0.0, 0.8).normalize();
            let (imp, uni) = albedo_two_ways(&sp, wo);
            assert!(
                (imp - uni).abs().max_element() < 0.02,
                "metallic {metallic} roughness {roughness}: {imp} vs {uni}"
            );
            assert!(imp.max_element() <= 1.0 + 1e-2, "energy gain: {imp}");
        }
    }
}
