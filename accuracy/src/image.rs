//! Linear RGB images for comparison: loading the radiance channels of an EXR, the checks every
//! metric needs (same size, finite values), and the tonemapped 8-bit sRGB version that the
//! perceptual metrics (SSIM, FLIP) see, which is also what the PNG contact sheets show.

use std::path::Path;

use glam::Vec3;
use parallax_scene::output::{read_exr_channels, tonemap_to_srgb8};

use crate::error::{AccuracyError, Result};

/// A row-major linear RGB image (radiance).
#[derive(Clone, Debug, PartialEq)]
pub struct RgbImage {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<[f32; 3]>,
}

impl RgbImage {
    pub fn new(width: usize, height: usize, pixels: Vec<[f32; 3]>) -> Self {
        assert_eq!(pixels.len(), width * height, "pixel count of a {width}x{height} image");
        Self { width, height, pixels }
    }

    /// The R, G, B channels of the first layer of an EXR.
    pub fn read_exr(path: &Path) -> Result<Self> {
        let (width, height, channels) = read_exr_channels(path, &["R", "G", "B"])
            .map_err(|e| AccuracyError::Read { path: path.to_path_buf(), detail: e.to_string() })?;
        let pixels = (0..width * height).map(|i| [channels[0][i], channels[1][i], channels[2][i]]).collect();
        Ok(Self { width, height, pixels })
    }

    /// Writes R, G, B as 32-bit float channels, with `attributes` as text attributes of the
    /// layer (what `reference` stores its spp count in, beside the sidecar that resumes it).
    pub fn write_exr(&self, path: &Path, attributes: &[(&str, String)]) -> Result<()> {
        use exr::prelude::*;
        let (w, h) = (self.width, self.height);
        let channel =
            |name: &str, c: usize| AnyChannel::new(name, FlatSamples::F32(self.pixels.iter().map(|p| p[c]).collect()));
        let list: SmallVec<[AnyChannel<FlatSamples>; 4]> =
            SmallVec::from_vec(vec![channel("R", 0), channel("G", 1), channel("B", 2)]);
        let mut layer_attributes = LayerAttributes::named("parallax");
        for (key, value) in attributes {
            layer_attributes.other.insert(Text::new_or_panic(*key), AttributeValue::Text(Text::new_or_panic(value)));
        }
        // Increasing line order: blocks are written in order, not as the parallel compressor
        // finishes them, so equal pixels give byte-identical files.
        let encoding = Encoding { line_order: LineOrder::Increasing, ..Encoding::SMALL_LOSSLESS };
        let layer = Layer::new((w, h), layer_attributes, encoding, AnyChannels::sort(list));
        crate::accumulate::write_atomically_to_path(path, |tmp| {
            Image::from_layer(layer)
                .write()
                .to_file(tmp)
                .map_err(|e| AccuracyError::Write { path: path.into(), detail: e.to_string() })
        })
    }

    /// Pixels with a NaN or infinite channel: their count and the first one's (x, y).
    pub fn non_finite(&self) -> Option<(usize, (usize, usize))> {
        let bad: Vec<usize> =
            self.pixels.iter().enumerate().filter(|(_, p)| p.iter().any(|c| !c.is_finite())).map(|(i, _)| i).collect();
        bad.first().map(|&i| (bad.len(), (i % self.width, i / self.width)))
    }

    /// Fails with [`AccuracyError::NonFinite`] naming `name` if any pixel is not finite.
    pub fn check_finite(&self, name: &str) -> Result<()> {
        match self.non_finite() {
            None => Ok(()),
            Some((count, (x, y))) => Err(AccuracyError::NonFinite { name: name.into(), count, x, y }),
        }
    }

    /// ACES filmic + sRGB at `exposure`, 8 bits per channel, interleaved RGB: the same mapping
    /// as the PNGs the renderer writes.
    pub fn tonemapped_srgb8(&self, exposure: f32) -> Vec<u8> {
        self.pixels.iter().flat_map(|p| tonemap_to_srgb8(Vec3::from_array(*p), exposure)).collect()
    }
}

/// Fails with [`AccuracyError::SizeMismatch`] unless `a` and `b` have the same size.
pub fn check_same_size(a: &RgbImage, a_name: &str, b: &RgbImage, b_name: &str) -> Result<()> {
    if (a.width, a.height) == (b.width, b.height) {
        return Ok(());
    }
    Err(AccuracyError::SizeMismatch {
        a: a_name.into(),
        aw: a.width,
        ah: a.height,
        b: b_name.into(),
        bw: b.width,
        bh: b.height,
    })
}
