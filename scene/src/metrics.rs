//! Image comparison figures for accuracy tables: per-channel mean, MSE and PSNR.

use glam::Vec3;

/// Per-channel statistics of one image, computed in f64.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChannelStats {
    pub mean: [f64; 3],
    /// Population variance of the pixel values per channel.
    pub variance: [f64; 3],
}

pub fn channel_stats(pixels: &[Vec3]) -> ChannelStats {
    let n = pixels.len().max(1) as f64;
    let mut mean = [0.0f64; 3];
    for p in pixels {
        for c in 0..3 {
            mean[c] += p[c] as f64;
        }
    }
    mean.iter_mut().for_each(|m| *m /= n);
    let mut variance = [0.0f64; 3];
    for p in pixels {
        for c in 0..3 {
            let d = p[c] as f64 - mean[c];
            variance[c] += d * d;
        }
    }
    variance.iter_mut().for_each(|v| *v /= n);
    ChannelStats { mean, variance }
}

/// Mean squared error per channel; `None` if the images differ in size.
pub fn mse(a: &[Vec3], b: &[Vec3]) -> Option<[f64; 3]> {
    if a.len() != b.len() || a.is_empty() {
        return None;
    }
    let mut e = [0.0f64; 3];
    for (p, q) in a.iter().zip(b) {
        for c in 0..3 {
            let d = p[c] as f64 - q[c] as f64;
            e[c] += d * d;
        }
    }
    Some(e.map(|x| x / a.len() as f64))
}

/// PSNR in dB over all three channels for signals with peak value `peak` (1 for tonemapped or
/// clamped images); infinite for identical images.
pub fn psnr(a: &[Vec3], b: &[Vec3], peak: f64) -> Option<f64> {
    let e = mse(a, b)?;
    let m = (e[0] + e[1] + e[2]) / 3.0;
    Some(if m == 0.0 { f64::INFINITY } else { 10.0 * (peak * peak / m).log10() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_values() {
        let a = vec![Vec3::new(0.0, 1.0, 2.0), Vec3::new(2.0, 1.0, 0.0)];
        let b = vec![Vec3::new(0.0, 1.0, 2.0), Vec3::new(1.0, 1.0, 0.0)];
        let s = channel_stats(&a);
        assert_eq!(s.mean, [1.0, 1.0, 1.0]);
        assert_eq!(s.variance, [1.0, 0.0, 1.0]);
        assert_eq!(mse(&a, &b), Some([0.5, 0.0, 0.0]));
        let p = psnr(&a, &b, 1.0).unwrap();
        assert!((p - 10.0 * (6.0f64).log10()).abs() < 1e-9, "{p}");
        assert_eq!(psnr(&a, &a, 1.0), Some(f64::INFINITY));
        assert_eq!(mse(&a, &b[..1]), None);
    }
}
