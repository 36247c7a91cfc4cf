//! The figures of one comparison of a test image against a reference, and how they pool over
//! several views.
//!
//! What each figure is computed on:
//! * `psnr_linear_db`: linear radiance clamped to [0, 1], peak 1, MSE over all three channels.
//! * `psnr_tonemapped_db`: the 8-bit sRGB tonemapped images (the PNGs, at one exposure for both
//!   images), values / 255, peak 1.
//! * `ssim`: [`crate::ssim`] on the tonemapped images, mean of R, G and B.
//! * `flip`: LDR-FLIP ([`crate::flip`]) on the tonemapped images.
//! * `rel_mse`: mean over pixels and channels of (test − ref)² / (ref² + 0.01) on linear radiance,
//!   unclamped (the ε = 0.01 keeps dark reference pixels from dominating, as in Rousselle et al. 2011).
//! * `mean_ratio`: per channel (r, g, b), the mean linear radiance of the test over the
//!   reference's, unclamped: a bias (a colour shift of a denoiser, say) shows here even where
//!   noise dominates the squared errors. 1 where both means are zero; `null` in JSON where
//!   only the reference's is.
//!
//! PSNR of identical images is +∞ (JSON: the string `"inf"`), never NaN.

use serde::{Serialize, Serializer};

use crate::error::Result;
use crate::flip::{flip_map_rgb8, mean};
use crate::image::{RgbImage, check_same_size};
use crate::ssim::ssim_rgb8;

/// ε of relMSE.
pub const REL_MSE_EPSILON: f64 = 0.01;

/// Sums from which the figures of one image, or of several pooled, follow.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ErrorSums {
    /// Σ (clamp(test) − clamp(ref))² over channels.
    pub squared_linear: f64,
    /// Σ ((test8 − ref8) / 255)² over channels.
    pub squared_tonemapped: f64,
    /// Σ (test − ref)² / (ref² + ε) over channels.
    pub relative_squared: f64,
    /// Σ of per-view SSIM × pixels and FLIP × pixels (pixel-weighted means when pooled).
    pub ssim_weighted: f64,
    pub flip_weighted: f64,
    /// Σ test and Σ ref per channel, unclamped linear radiance.
    pub test_sum: [f64; 3],
    pub reference_sum: [f64; 3],
    pub pixels: u64,
}

impl ErrorSums {
    pub fn add(&mut self, other: &ErrorSums) {
        self.squared_linear += other.squared_linear;
        self.squared_tonemapped += other.squared_tonemapped;
        self.relative_squared += other.relative_squared;
        self.ssim_weighted += other.ssim_weighted;
        self.flip_weighted += other.flip_weighted;
        for c in 0..3 {
            self.test_sum[c] += other.test_sum[c];
            self.reference_sum[c] += other.reference_sum[c];
        }
        self.pixels += other.pixels;
    }

    pub fn metrics(&self) -> Metrics {
        let samples = (3 * self.pixels).max(1) as f64;
        let pixels = self.pixels.max(1) as f64;
        Metrics {
            psnr_linear_db: psnr_of_mse(self.squared_linear / samples),
            psnr_tonemapped_db: psnr_of_mse(self.squared_tonemapped / samples),
            ssim: self.ssim_weighted / pixels,
            flip: self.flip_weighted / pixels,
            rel_mse: self.relative_squared / samples,
            mse_linear: self.squared_linear / samples,
            mean_ratio: std::array::from_fn(|c| mean_ratio(self.test_sum[c], self.reference_sum[c])),
        }
    }
}

/// The figures of a comparison (see the module docs for what each is computed on).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Metrics {
    #[serde(serialize_with = "serialize_db")]
    pub psnr_linear_db: f64,
    #[serde(serialize_with = "serialize_db")]
    pub psnr_tonemapped_db: f64,
    pub ssim: f64,
    pub flip: f64,
    pub rel_mse: f64,
    pub mse_linear: f64,
    #[serde(serialize_with = "serialize_ratios")]
    pub mean_ratio: [f64; 3],
}

/// Σ test / Σ ref: 1 for two zero sums (nothing to shift), +∞ for a zero reference alone.
fn mean_ratio(test: f64, reference: f64) -> f64 {
    match (test == 0.0, reference == 0.0) {
        (true, true) => 1.0,
        (false, true) => f64::INFINITY,
        _ => test / reference,
    }
}

/// Finite ratios as numbers, others as `null` (JSON has no infinity).
fn serialize_ratios<S: Serializer>(v: &[f64; 3], s: S) -> std::result::Result<S::Ok, S::Error> {
    let finite: [Option<f64>; 3] = std::array::from_fn(|c| v[c].is_finite().then_some(v[c]));
    finite.serialize(s)
}

/// PSNR in dB for peak 1: +∞ for zero error.
pub fn psnr_of_mse(mse: f64) -> f64 {
    if mse == 0.0 { f64::INFINITY } else { -10.0 * mse.log10() }
}

/// Finite values as numbers, +∞ as the string "inf" (JSON has no infinity).
fn serialize_db<S: Serializer>(v: &f64, s: S) -> std::result::Result<S::Ok, S::Error> {
    if v.is_finite() { s.serialize_f64(*v) } else { s.serialize_str(if *v > 0.0 { "inf" } else { "-inf" }) }
}

/// Compares `test` against `reference` (named in errors) with the perceptual figures at exposure
/// 1: same size and finite values are required, and the result is the sums to pool;
/// `.metrics()` gives the figures.
pub fn compare_images(
    test: &RgbImage,
    test_name: &str,
    reference: &RgbImage,
    reference_name: &str,
) -> Result<ErrorSums> {
    Ok(compare_images_at(test, test_name, reference, reference_name, 1.0)?.sums)
}

/// One comparison: the sums to pool and the per-pixel FLIP error.
pub struct ImageComparison {
    pub sums: ErrorSums,
    pub flip_map: Vec<f32>,
}

/// [`compare_images`] with both images tonemapped at `exposure` for PSNR tm, SSIM and FLIP.
pub fn compare_images_at(
    test: &RgbImage,
    test_name: &str,
    reference: &RgbImage,
    reference_name: &str,
    exposure: f32,
) -> Result<ImageComparison> {
    check_same_size(test, test_name, reference, reference_name)?;
    test.check_finite(test_name)?;
    reference.check_finite(reference_name)?;
    let mut sums = ErrorSums { pixels: test.pixels.len() as u64, ..Default::default() };
    for (t, r) in test.pixels.iter().zip(&reference.pixels) {
        for c in 0..3 {
            let (t, r) = (t[c] as f64, r[c] as f64);
            sums.squared_linear += (t.clamp(0.0, 1.0) - r.clamp(0.0, 1.0)).powi(2);
            sums.relative_squared += (t - r).powi(2) / (r * r + REL_MSE_EPSILON);
            sums.test_sum[c] += t;
            sums.reference_sum[c] += r;
        }
    }
    let (t8, r8) = (test.tonemapped_srgb8(exposure), reference.tonemapped_srgb8(exposure));
    sums.squared_tonemapped = t8.iter().zip(&r8).map(|(&a, &b)| ((a as f64 - b as f64) / 255.0).powi(2)).sum();
    let (w, h) = (test.width, test.height);
    sums.ssim_weighted = ssim_rgb8(&t8, &r8, w, h) * (w * h) as f64;
    let flip_map = flip_map_rgb8(&r8, &t8, w, h);
    sums.flip_weighted = mean(&flip_map) * (w * h) as f64;
    Ok(ImageComparison { sums, flip_map })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::AccuracyError;

    /// A 32×24 image of dyadic values (exact in f32, so adding a dyadic δ is exact too).
    fn dyadic(w: usize, h: usize) -> RgbImage {
        let px = (0..w * h).map(|i| [(i % 7) as f32 / 16.0, (i % 5) as f32 / 16.0, (i % 11) as f32 / 32.0]).collect();
        RgbImage::new(w, h, px)
    }

    #[test]
    fn an_image_against_itself() {
        let a = dyadic(32, 24);
        let m = compare_images(&a, "a", &a, "a").unwrap().metrics();
        assert_eq!(m.psnr_linear_db, f64::INFINITY);
        assert_eq!(m.psnr_tonemapped_db, f64::INFINITY);
        assert_eq!(m.ssim, 1.0);
        assert_eq!(m.flip, 0.0);
        assert_eq!(m.rel_mse, 0.0);
        assert_eq!(m.mean_ratio, [1.0; 3]);
        let json = serde_json::to_value(m).unwrap();
        assert_eq!(json["psnr_linear_db"], "inf");
    }

    /// A test 3 % brighter in red and 5 % darker in blue shows exactly that, pooled too; a zero
    /// reference channel gives `null`, not a number, in JSON.
    #[test]
    fn the_mean_ratio_shows_a_colour_shift() {
        let a = dyadic(32, 24);
        let b = RgbImage::new(32, 24, a.pixels.iter().map(|p| [p[0] * 1.03, p[1], p[2] * 0.95]).collect());
        let mut sums = compare_images(&b, "b", &a, "a").unwrap();
        sums.add(&compare_images(&b, "b", &a, "a").unwrap());
        let ratio = sums.metrics().mean_ratio;
        for (got, want) in ratio.iter().zip([1.03, 1.0, 0.95]) {
            assert!((got - want).abs() < 1e-6, "{ratio:?}");
        }
        let black = RgbImage::new(2, 1, vec![[0.0, 0.0, 1.0]; 2]);
        let lit = RgbImage::new(2, 1, vec![[1.0, 0.0, 1.0]; 2]);
        let m = compare_images(&lit, "lit", &black, "black").unwrap().metrics();
        assert_eq!(serde_json::to_value(m).unwrap()["mean_ratio"], serde_json::json!([null, 1.0, 1.0]));
    }

    /// +δ on every channel of values that stay inside [0, 1]: MSE = δ², PSNR = −20 log10 δ.
    #[test]
    fn a_constant_offset_gives_the_analytic_psnr() {
        let a = dyadic(32, 24);
        let delta = 1.0 / 64.0;
        let b = RgbImage::new(32, 24, a.pixels.iter().map(|p| p.map(|c| c + delta)).collect());
        let m = compare_images(&b, "b", &a, "a").unwrap().metrics();
        let analytic = -20.0 * (delta as f64).log10();
        assert!((m.psnr_linear_db - analytic).abs() < 1e-6, "{} vs {analytic}", m.psnr_linear_db);
        assert!(m.ssim < 1.0 && m.flip > 0.0);
        // Pooling two identical comparisons changes nothing.
        let mut pooled = compare_images(&b, "b", &a, "a").unwrap();
        pooled.add(&compare_images(&b, "b", &a, "a").unwrap());
        assert!((pooled.metrics().psnr_linear_db - analytic).abs() < 1e-6);
    }

    /// The perceptual figures see the tonemapped images: an error too dark to see at exposure 1
    /// shows at a higher exposure, while the linear figures do not move.
    #[test]
    fn the_exposure_changes_what_the_perceptual_figures_see() {
        let a = RgbImage::new(32, 24, dyadic(32, 24).pixels.iter().map(|p| p.map(|c| c / 256.0)).collect());
        let b = RgbImage::new(32, 24, a.pixels.iter().map(|p| p.map(|c| c * 1.5)).collect());
        let dim = compare_images_at(&b, "b", &a, "a", 1.0).unwrap();
        let bright = compare_images_at(&b, "b", &a, "a", 64.0).unwrap();
        let (dim_m, bright_m) = (dim.sums.metrics(), bright.sums.metrics());
        assert!(bright_m.flip > 2.0 * dim_m.flip, "{} vs {}", bright_m.flip, dim_m.flip);
        assert_eq!(dim_m.psnr_linear_db, bright_m.psnr_linear_db);
        assert_eq!(dim.flip_map.len(), 32 * 24);
        assert!((crate::flip::mean(&bright.flip_map) - bright_m.flip).abs() < 1e-12);
    }

    #[test]
    fn size_mismatch_and_non_finite_pixels_are_errors() {
        let a = dyadic(32, 24);
        let small = dyadic(16, 24);
        let err = compare_images(&a, "a.exr", &small, "small.exr").unwrap_err();
        assert!(matches!(err, AccuracyError::SizeMismatch { aw: 32, bw: 16, .. }), "{err}");
        let mut bad = a.clone();
        bad.pixels[5][1] = f32::NAN;
        bad.pixels[40][0] = f32::INFINITY;
        let err = compare_images(&bad, "bad.exr", &a, "a.exr").unwrap_err();
        assert!(matches!(err, AccuracyError::NonFinite { count: 2, x: 5, y: 0, .. }), "{err}");
        assert!(err.to_string().contains("bad.exr"));
    }
}
