//! Counter-based random numbers: every value is a pure function of (pixel, view, frame, sample,
//! bounce, dimension), so a pixel's estimate does not depend on which device, thread or pixel
//! subset traced it. The GLSL twin is `shaders/pt_rng.glsl`; both use PCG4D (Jarzynski and Olano,
//! "Hash Functions for GPU Rendering", JCGT 2020).

use glam::UVec4;

/// PCG4D: a bijective hash of four 32-bit words into four well-mixed words.
pub fn pcg4d(v: UVec4) -> UVec4 {
    let mut v = v.wrapping_mul(UVec4::splat(1_664_525)).wrapping_add(UVec4::splat(1_013_904_223));
    v.x = v.x.wrapping_add(v.y.wrapping_mul(v.w));
    v.y = v.y.wrapping_add(v.z.wrapping_mul(v.x));
    v.z = v.z.wrapping_add(v.x.wrapping_mul(v.y));
    v.w = v.w.wrapping_add(v.y.wrapping_mul(v.z));
    v ^= v >> 16;
    v.x = v.x.wrapping_add(v.y.wrapping_mul(v.w));
    v.y = v.y.wrapping_add(v.z.wrapping_mul(v.x));
    v.z = v.z.wrapping_add(v.x.wrapping_mul(v.y));
    v.w = v.w.wrapping_add(v.y.wrapping_mul(v.z));
    v
}

/// Maps the top 24 bits to a float in [0, 1).
pub fn to_unit_float(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// The random stream of one path: a key hashed from (pixel, view, frame), from which each
/// (sample, bounce, dimension group) draws four independent uniforms.
#[derive(Clone, Copy, Debug)]
pub struct PathRng {
    key: UVec4,
}

/// Dimension groups within one bounce; four uniforms each.
#[derive(Clone, Copy, Debug)]
#[repr(u32)]
pub enum Dim {
    /// Pixel jitter (bounce 0 only).
    Camera = 0,
    /// Light choice and the point on the light.
    Light = 1,
    /// Lobe choice and the BSDF direction.
    Bsdf = 2,
    /// Russian roulette.
    Roulette = 3,
}

impl PathRng {
    pub fn new(pixel_x: u32, pixel_y: u32, view: u32, frame: u32) -> Self {
        Self { key: pcg4d(UVec4::new(pixel_x, pixel_y, view, frame)) }
    }

    /// Four uniforms in [0, 1) for (sample, bounce, dim).
    pub fn uniforms(&self, sample: u32, bounce: u32, dim: Dim) -> [f32; 4] {
        let h = pcg4d(UVec4::new(self.key.x ^ sample, self.key.y ^ bounce, self.key.z ^ dim as u32, self.key.w));
        [h.x, h.y, h.z, h.w].map(to_unit_float)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniforms_look_uniform_and_independent_of_neighbours() {
        let mut sum = 0.0f64;
        let mut sum_sq = 0.0f64;
        let mut n = 0;
        let mut histogram = [0u32; 16];
        for y in 0..64 {
            for x in 0..64 {
                let r = PathRng::new(x, y, 3, 7);
                for b in 0..4 {
                    for u in r.uniforms(0, b, Dim::Bsdf) {
                        assert!((0.0..1.0).contains(&u));
                        sum += u as f64;
                        sum_sq += (u * u) as f64;
                        histogram[(u * 16.0) as usize] += 1;
                        n += 1;
                    }
                }
            }
        }
        let mean = sum / n as f64;
        let var = sum_sq / n as f64 - mean * mean;
        assert!((mean - 0.5).abs() < 0.01, "mean {mean}");
        assert!((var - 1.0 / 12.0).abs() < 0.005, "variance {var}");
        let expected = n as f64 / 16.0;
        for h in histogram {
            assert!((h as f64 - expected).abs() < 0.1 * expected, "{histogram:?}");
        }
    }

    #[test]
    fn streams_differ_per_coordinate() {
        let a = PathRng::new(1, 2, 3, 4).uniforms(0, 0, Dim::Light);
        assert_ne!(a, PathRng::new(2, 1, 3, 4).uniforms(0, 0, Dim::Light));
        assert_ne!(a, PathRng::new(1, 2, 4, 4).uniforms(0, 0, Dim::Light));
        assert_ne!(a, PathRng::new(1, 2, 3, 5).uniforms(0, 0, Dim::Light));
        assert_ne!(a, PathRng::new(1, 2, 3, 4).uniforms(1, 0, Dim::Light));
        assert_ne!(a, PathRng::new(1, 2, 3, 4).uniforms(0, 1, Dim::Light));
        assert_ne!(a, PathRng::new(1, 2, 3, 4).uniforms(0, 0, Dim::Bsdf));
        assert_eq!(a, PathRng::new(1, 2, 3, 4).uniforms(0, 0, Dim::Light));
    }
}
