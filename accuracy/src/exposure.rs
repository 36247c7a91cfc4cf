//! Automatic exposure: the log-average luminance of a light field mapped to a middle-grey key
//! (Reinhard et al., "Photographic Tone Reproduction for Digital Images", 2002), one exposure
//! for every view so that the views of one light field look alike and a change of brightness
//! between them stays visible.
//!
//! The luminance averaged is that of 8×8-pixel tiles, not of single pixels: a path-traced image
//! at a few samples per pixel has many pixels far darker than their surroundings (paths that
//! found little light), and their logarithms would drag the average down by an order of
//! magnitude (Sponza at 8 spp: an exposure 4× too bright, most of the image white). A tile's
//! mean is the same estimate of its light with a 64th of the variance.
//!
//! Computed on the host from linear radiance that is read back anyway (the EXRs' pixels).

/// The key the log-average luminance is mapped to (Reinhard's middle grey).
pub const KEY: f64 = 0.18;
/// The range an exposure may take (that of `--exposure N`).
pub const RANGE: (f32, f32) = (1e-6, 1e6);

/// `--exposure`: `auto` (the default of every command that writes an LDR image) or a fixed
/// multiplier.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Exposure {
    #[default]
    Auto,
    Fixed(f32),
}

impl std::str::FromStr for Exposure {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let s = s.trim();
        if s.eq_ignore_ascii_case("auto") {
            return Ok(Exposure::Auto);
        }
        // Below 1e-6 every radiance an image holds maps to black (1e-45, a denormal, made any
        // two images compare as identical).
        match s.parse::<f32>() {
            Ok(v) if (RANGE.0..=RANGE.1).contains(&v) => Ok(Exposure::Fixed(v)),
            Ok(v) => {
                let shown = if v == 0.0 || (1e-3..1e6).contains(&v.abs()) { v.to_string() } else { format!("{v:e}") };
                Err(format!(
                    "{shown} is outside {:e}..={:e}: the tonemapped image would be black or meaningless",
                    RANGE.0, RANGE.1
                ))
            }
            Err(_) => Err(format!("'{s}' is neither `auto` nor a number")),
        }
    }
}

impl Exposure {
    /// The exposure to use: the fixed one, or the automatic one of `average`.
    pub fn resolve(self, average: &LogAverage) -> f32 {
        match self {
            Exposure::Fixed(v) => v,
            Exposure::Auto => average.exposure(),
        }
    }

    /// `"auto"` or `"fixed"`, as the JSON outputs name the mode.
    pub fn mode(self) -> &'static str {
        match self {
            Exposure::Auto => "auto",
            Exposure::Fixed(_) => "fixed",
        }
    }
}

/// Rec. 709 luminance of linear RGB.
pub fn luminance(rgb: [f32; 3]) -> f64 {
    0.2126 * rgb[0] as f64 + 0.7152 * rgb[1] as f64 + 0.0722 * rgb[2] as f64
}

/// Side of the tiles whose mean luminance is log-averaged.
pub const TILE: usize = 8;

/// A running log-average of luminance over the tiles of any number of views.
///
/// Tiles of zero (or negative) mean luminance are left out, and so are non-finite pixels: a
/// black background would otherwise drag the average towards log 0 without bound and blow out
/// everything that is lit.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LogAverage {
    sum_ln: f64,
    pixels: u64,
}

impl LogAverage {
    /// One tile (or any region) of mean luminance `y`.
    fn add_luminance(&mut self, y: f64) {
        if y.is_finite() && y > 0.0 {
            self.sum_ln += y.ln();
            self.pixels += 1;
        }
    }

    /// The [`TILE`]×[`TILE`] tiles of a row-major image `width` pixels wide (edge tiles are
    /// smaller).
    pub fn add_image(&mut self, width: usize, pixels: &[[f32; 3]]) {
        let width = width.max(1);
        let height = pixels.len() / width;
        for ty in (0..height).step_by(TILE) {
            for tx in (0..width).step_by(TILE) {
                let (mut sum, mut n) = (0.0, 0u32);
                for y in ty..(ty + TILE).min(height) {
                    for p in &pixels[y * width + tx..y * width + (tx + TILE).min(width)] {
                        let l = luminance(*p);
                        if l.is_finite() {
                            sum += l;
                            n += 1;
                        }
                    }
                }
                if n > 0 {
                    self.add_luminance(sum / f64::from(n));
                }
            }
        }
    }

    /// exp(mean ln Y) over the lit tiles; `None` if no tile is lit.
    pub fn luminance(&self) -> Option<f64> {
        (self.pixels > 0).then(|| (self.sum_ln / self.pixels as f64).exp())
    }

    /// [`KEY`] / the log-average, within [`RANGE`]; 1 when nothing is lit (black stays black
    /// at any exposure).
    pub fn exposure(&self) -> f32 {
        match self.luminance() {
            Some(y) => ((KEY / y) as f32).clamp(RANGE.0, RANGE.1),
            None => 1.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An image of `tiles` 8×8 tiles side by side, tile k all of `values[k]`.
    fn tiles(values: &[[f32; 3]]) -> (usize, Vec<[f32; 3]>) {
        let width = TILE * values.len();
        (width, (0..width * TILE).map(|i| values[(i % width) / TILE]).collect())
    }

    #[test]
    fn the_log_average_of_tiles_maps_to_the_key() {
        let mut a = LogAverage::default();
        // Tiles of luminance 0.01 and 1: log-average 0.1, so the exposure is 1.8.
        let (w, px) = tiles(&[[0.01; 3], [1.0; 3]]);
        a.add_image(w, &px);
        assert!((a.luminance().unwrap() - 0.1).abs() < 1e-8, "{:?}", a.luminance());
        assert!((a.exposure() - 1.8).abs() < 1e-6, "{}", a.exposure());
        // A black tile does not count; a non-finite pixel leaves its tile's other pixels.
        let (w, mut px) = tiles(&[[0.0; 3], [0.1; 3]]);
        px[TILE] = [f32::NAN, 0.0, 0.0];
        let mut b = LogAverage::default();
        b.add_image(w, &px);
        assert!((b.luminance().unwrap() - 0.1).abs() < 1e-8);
    }

    /// Noise of few samples per pixel: a tile whose pixels are 0 and 2·m in turn has mean m,
    /// and that is what counts, where a per-pixel average would see only the 2·m half.
    #[test]
    fn pixel_noise_does_not_move_the_key() {
        let mut px = vec![[0.0f32; 3]; TILE * TILE];
        for (i, p) in px.iter_mut().enumerate() {
            *p = if i % 2 == 0 { [0.02; 3] } else { [1e-6; 3] };
        }
        let mut a = LogAverage::default();
        a.add_image(TILE, &px);
        assert!((a.luminance().unwrap() - 0.0100005).abs() < 1e-6, "{:?}", a.luminance());
        // Edge tiles are partial: a 3×1 image is one tile.
        let mut b = LogAverage::default();
        b.add_image(3, &[[0.1; 3], [0.2; 3], [0.3; 3]]);
        assert!((b.luminance().unwrap() - 0.2).abs() < 1e-7);
    }

    #[test]
    fn nothing_lit_gives_exposure_one_and_extremes_are_clamped() {
        let mut a = LogAverage::default();
        assert_eq!(a.exposure(), 1.0);
        a.add_image(1, &[[0.0; 3]]);
        assert_eq!(a.exposure(), 1.0);
        a.add_image(1, &[[1e-30; 3]]);
        assert_eq!(a.exposure(), RANGE.1);
    }

    #[test]
    fn exposure_arguments() {
        assert_eq!("auto".parse::<Exposure>(), Ok(Exposure::Auto));
        assert_eq!("AUTO".parse::<Exposure>(), Ok(Exposure::Auto));
        assert_eq!("2.5".parse::<Exposure>(), Ok(Exposure::Fixed(2.5)));
        assert_eq!("1e-6".parse::<Exposure>(), Ok(Exposure::Fixed(1e-6)));
        for bad in ["0", "-1", "NaN", "inf", "2e6", "1e-45", "9e-7", "bright"] {
            assert!(bad.parse::<Exposure>().is_err(), "{bad}");
        }
        assert!("x".parse::<Exposure>().unwrap_err().contains("neither `auto` nor a number"));
        let mut a = LogAverage::default();
        a.add_image(1, &[[1.0; 3]]);
        assert_eq!(Exposure::Fixed(3.0).resolve(&a), 3.0);
        assert!((Exposure::Auto.resolve(&a) - 0.18).abs() < 1e-7);
    }
}
