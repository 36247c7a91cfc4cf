//! SSIM (Wang, Bovik, Sheikh and Simoncelli, "Image Quality Assessment: From Error Visibility
//! to Structural Similarity", IEEE TIP 2004) with the paper's constants: an 11×11 Gaussian
//! window of σ = 1.5, K1 = 0.01, K2 = 0.03, dynamic range L = 1. Windows lie wholly inside the
//! image (no padding, as in the paper's reference code); images smaller than 11 pixels in a
//! dimension get the largest odd window that fits, so tiny test images still have a value.

/// Mean SSIM of two single-channel planes of `width`×`height` values in [0, 1].
pub fn ssim_plane(a: &[f64], b: &[f64], width: usize, height: usize) -> f64 {
    assert!(a.len() == width * height && b.len() == width * height, "plane sizes");
    let size = 11.min(width).min(height);
    let size = if size % 2 == 0 { size - 1 } else { size };
    if size == 0 {
        return 1.0;
    }
    let kernel = gaussian(size, 1.5);
    let blur = |f: &dyn Fn(usize) -> f64| {
        separable_valid(&(0..width * height).map(f).collect::<Vec<_>>(), width, height, &kernel)
    };
    let mu_a = blur(&|i| a[i]);
    let mu_b = blur(&|i| b[i]);
    let aa = blur(&|i| a[i] * a[i]);
    let bb = blur(&|i| b[i] * b[i]);
    let ab = blur(&|i| a[i] * b[i]);
    let (c1, c2) = ((0.01f64).powi(2), (0.03f64).powi(2));
    let n = mu_a.len();
    let sum: f64 = (0..n)
        .map(|i| {
            let (ma, mb) = (mu_a[i], mu_b[i]);
            let (va, vb, cov) = (aa[i] - ma * ma, bb[i] - mb * mb, ab[i] - ma * mb);
            ((2.0 * ma * mb + c1) * (2.0 * cov + c2)) / ((ma * ma + mb * mb + c1) * (va + vb + c2))
        })
        .sum();
    sum / n as f64
}

/// Mean over the three channels of [`ssim_plane`] on interleaved 8-bit RGB.
pub fn ssim_rgb8(a: &[u8], b: &[u8], width: usize, height: usize) -> f64 {
    (0..3)
        .map(|c| {
            let plane = |img: &[u8]| (0..width * height).map(|i| img[3 * i + c] as f64 / 255.0).collect::<Vec<_>>();
            ssim_plane(&plane(a), &plane(b), width, height)
        })
        .sum::<f64>()
        / 3.0
}

fn gaussian(size: usize, sigma: f64) -> Vec<f64> {
    let r = (size / 2) as f64;
    let w: Vec<f64> = (0..size).map(|i| (-((i as f64 - r).powi(2)) / (2.0 * sigma * sigma)).exp()).collect();
    let total: f64 = w.iter().sum();
    w.into_iter().map(|x| x / total).collect()
}

/// Filters with `kernel` along x then y, keeping only positions where it fits inside.
fn separable_valid(v: &[f64], width: usize, height: usize, kernel: &[f64]) -> Vec<f64> {
    let k = kernel.len();
    let (ow, oh) = (width + 1 - k, height + 1 - k);
    let mut rows = vec![0.0; ow * height];
    for y in 0..height {
        for x in 0..ow {
            rows[y * ow + x] = (0..k).map(|i| kernel[i] * v[y * width + x + i]).sum();
        }
    }
    let mut out = vec![0.0; ow * oh];
    for y in 0..oh {
        for x in 0..ow {
            out[y * ow + x] = (0..k).map(|i| kernel[i] * rows[(y + i) * ow + x]).sum();
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: usize, h: usize) -> Vec<f64> {
        (0..w * h).map(|i| ((i % w) as f64 / w as f64 + (i / w) as f64 / h as f64) / 2.0).collect()
    }

    #[test]
    fn identical_is_one_and_changes_lower_it() {
        let a = ramp(24, 20);
        assert_eq!(ssim_plane(&a, &a, 24, 20), 1.0);
        let noisy: Vec<f64> = a.iter().enumerate().map(|(i, v)| v + if i % 2 == 0 { 0.05 } else { -0.05 }).collect();
        let s = ssim_plane(&a, &noisy, 24, 20);
        assert!(s < 0.9 && s > 0.0, "{s}");
        // A constant offset changes only the luminance term: SSIM stays close to 1.
        let shifted: Vec<f64> = a.iter().map(|v| v + 0.01).collect();
        let s2 = ssim_plane(&a, &shifted, 24, 20);
        assert!(s2 > 0.99 && s2 < 1.0, "{s2}");
    }

    /// Two constant planes of means m1, m2: variances and covariance vanish, so SSIM is the
    /// luminance term (2 m1 m2 + C1) / (m1² + m2² + C1) exactly.
    #[test]
    fn constant_planes_give_the_luminance_term() {
        let (w, h) = (16, 13);
        let a = vec![0.25; w * h];
        let b = vec![0.5; w * h];
        let c1 = 1e-4;
        let expected = (2.0 * 0.25 * 0.5 + c1) / (0.0625 + 0.25 + c1);
        assert!((ssim_plane(&a, &b, w, h) - expected).abs() < 1e-12);
        // Tiny images use a smaller window and still give a value.
        assert!((ssim_plane(&a[..12], &b[..12], 4, 3) - expected).abs() < 1e-12);
    }
}
