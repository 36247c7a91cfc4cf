//! Automatic exposure: the log-average luminance of a light field mapped to a middle-grey key
//! (Reinhard et al., "Photographic Tone Reproduction for Digital Images", 2002), one exposure
//! for every view so that the views of one light field look alike and a change of brightness
//! between them stays visible.
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
        match s.parse::<f32>() {
            Ok(v) if v.is_finite() && v > 0.0 && v <= RANGE.1 => Ok(Exposure::Fixed(v)),
            Ok(v) => Err(format!("{v} is not in (0, 1e6]: the tonemapped image would be black or meaningless")),
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

/// A running log-average of luminance over any number of pixels of any number of views.
///
/// Pixels of zero (or negative, or non-finite) luminance are left out: a black background or
/// a path that found no light would otherwise drag the average towards log 0 without bound and
/// blow out everything that is lit.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LogAverage {
    sum_ln: f64,
    pixels: u64,
}

impl LogAverage {
    pub fn add(&mut self, rgb: [f32; 3]) {
        let y = luminance(rgb);
        if y.is_finite() && y > 0.0 {
            self.sum_ln += y.ln();
            self.pixels += 1;
        }
    }

    pub fn add_all<'a>(&mut self, pixels: impl IntoIterator<Item = &'a [f32; 3]>) {
        for p in pixels {
            self.add(*p);
        }
    }

    /// exp(mean ln Y) over the lit pixels; `None` if no pixel is lit.
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

    #[test]
    fn the_log_average_maps_to_the_key() {
        let mut a = LogAverage::default();
        // Luminance 0.01 and 1: log-average 0.1, so the exposure is 1.8.
        a.add_all(&[[0.01; 3], [1.0; 3]]);
        assert!((a.luminance().unwrap() - 0.1).abs() < 1e-8, "{:?}", a.luminance());
        assert!((a.exposure() - 1.8).abs() < 1e-6, "{}", a.exposure());
        // Black and non-finite pixels do not count.
        a.add_all(&[[0.0; 3], [f32::NAN, 0.0, 0.0], [-1.0; 3], [f32::INFINITY; 3]]);
        assert!((a.exposure() - 1.8).abs() < 1e-6);
    }

    #[test]
    fn nothing_lit_gives_exposure_one_and_extremes_are_clamped() {
        let mut a = LogAverage::default();
        assert_eq!(a.exposure(), 1.0);
        a.add([0.0; 3]);
        assert_eq!(a.exposure(), 1.0);
        a.add([1e-30; 3]);
        assert_eq!(a.exposure(), RANGE.1);
    }

    #[test]
    fn exposure_arguments() {
        assert_eq!("auto".parse::<Exposure>(), Ok(Exposure::Auto));
        assert_eq!("AUTO".parse::<Exposure>(), Ok(Exposure::Auto));
        assert_eq!("2.5".parse::<Exposure>(), Ok(Exposure::Fixed(2.5)));
        for bad in ["0", "-1", "NaN", "inf", "2e6", "bright"] {
            assert!(bad.parse::<Exposure>().is_err(), "{bad}");
        }
        assert!("x".parse::<Exposure>().unwrap_err().contains("neither `auto` nor a number"));
        let mut a = LogAverage::default();
        a.add([1.0; 3]);
        assert_eq!(Exposure::Fixed(3.0).resolve(&a), 3.0);
        assert!((Exposure::Auto.resolve(&a) - 0.18).abs() < 1e-7);
    }
}
