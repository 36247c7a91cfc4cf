//! FLIP (Andersson et al., "FLIP: A Difference Evaluator for Alternating Images", HPG 2020)
//! through the `nv-flip` crate, which compiles NVIDIA's own C++ implementation. This is LDR-FLIP:
//! both images are first tonemapped to 8-bit sRGB exactly as the PNGs are (ACES + sRGB at one
//! exposure for both; see [`crate::image::RgbImage::tonemapped_srgb8`]), so the value is the
//! error a person sees on the PNGs, and NVIDIA's tool run on those PNGs gives the same number.
//! [`error_map_rgb8`] colours the per-pixel error with NVIDIA's magma map, as their tool does.

/// Pixels per degree of visual angle of NVIDIA's reference tools: 0.7 m from a 0.7 m wide
/// monitor 3840 pixels across, 67.0206 (nv-flip's own default rounds it to 67.0, which moves
/// the mean error in the third decimal on small images).
pub fn pixels_per_degree() -> f32 {
    nv_flip::pixels_per_degree(0.7, 3840.0, 0.7)
}

/// Mean LDR-FLIP error (0 = identical, 1 = maximal) of `test` against `reference`, both
/// interleaved 8-bit sRGB of `width`×`height`; the mean over the per-pixel error map in f64.
pub fn flip_rgb8(reference: &[u8], test: &[u8], width: usize, height: usize) -> f64 {
    mean(&flip_map_rgb8(reference, test, width, height))
}

/// The per-pixel LDR-FLIP error (row-major, each in [0, 1]) of `test` against `reference`.
pub fn flip_map_rgb8(reference: &[u8], test: &[u8], width: usize, height: usize) -> Vec<f32> {
    assert!(reference.len() == 3 * width * height && test.len() == 3 * width * height, "image sizes");
    let r = nv_flip::FlipImageRgb8::with_data(width as u32, height as u32, reference);
    let t = nv_flip::FlipImageRgb8::with_data(width as u32, height as u32, test);
    nv_flip::flip(r, t, pixels_per_degree()).to_vec()
}

/// The mean of an error map, in f64.
pub fn mean(map: &[f32]) -> f64 {
    map.iter().map(|&e| e as f64).sum::<f64>() / map.len().max(1) as f64
}

/// An error map in NVIDIA's magma colour map (black for 0, through purple and orange, to pale
/// yellow for 1), interleaved 8-bit RGB.
pub fn error_map_rgb8(map: &[f32], width: usize, height: usize) -> Vec<u8> {
    assert_eq!(map.len(), width * height, "error map size");
    nv_flip::FlipImageFloat::with_data(width as u32, height as u32, map).apply_color_lut(&nv_flip::magma_lut()).to_vec()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_error_map_runs_from_black_to_pale_yellow() {
        let rgb = error_map_rgb8(&[0.0, 1.0], 2, 1);
        assert_eq!(&rgb[..3], &[0, 0, 4], "magma starts near black");
        assert!(rgb[3] > 240 && rgb[4] > 240 && rgb[5] > 150, "magma ends pale yellow: {rgb:?}");
    }
}
