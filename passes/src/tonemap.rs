//! The `tonemap` pass (shaders/tonemap.comp): a view's linear radiance to display bytes,
//! `display = srgb_encode(aces(exposure * rgb))`, alpha 1, in an Rgba8 (UNORM) image. The
//! curve is Krzysztof Narkowicz's fit of the ACES filmic tone curve ("ACES Filmic Tone
//! Mapping Curve", 2016), per channel; [`tonemap_pixel`] is its CPU twin. The exposure is the
//! configured one, optionally scaled by the texel of a global 1×1 image a stage of the frame
//! measured ([`declare_tonemap_scaled`]: an auto-exposure pass).

use std::sync::Arc;

pub use crate::error::TonemapError;
use crate::shaders::{self, TonemapPush};
use parallax_backend::{BackendError, InstanceId, KernelGraph, PassInstance, PassKernel, Recorder};
use parallax_graph::{Format, Handle, Image, ReadSlot, Role, WriteSlot};

/// Pass name, and the slot of its output (docs/PIPELINE.md).
pub const TONEMAP: &str = "tonemap";
/// Slot name of the output (Rgba8, sRGB-encoded bytes).
pub const DISPLAY: &str = "display";

/// Declares `tonemap` for every view: reads `input` (Rgba32f linear radiance, any slot name,
/// own rows) and returns the `display` handle (Rgba8; not exported). `exposure` scales the
/// radiance before the curve and must be finite and > 0.
pub fn declare_tonemap(
    graph: &mut KernelGraph,
    input: &Handle<Image>,
    exposure: f32,
) -> Result<Handle<Image>, TonemapError> {
    declare_tonemap_scaled(graph, input, exposure, None)
}

/// [`declare_tonemap`], with the exposure multiplied on the GPU by the texel of `scale`, a
/// global 1×1 `R32f` image written earlier in the frame (what an auto-exposure pass measures).
pub fn declare_tonemap_scaled(
    graph: &mut KernelGraph,
    input: &Handle<Image>,
    exposure: f32,
    scale: Option<&Handle<Image>>,
) -> Result<Handle<Image>, TonemapError> {
    if !(exposure.is_finite() && exposure > 0.0) {
        return Err(TonemapError::Exposure { exposure });
    }
    let mut display = graph.image(DISPLAY, Format::Rgba8);
    let mut pass = graph.pass(TONEMAP, Role::All);
    let (src, dst) = (pass.read_slot(input), pass.write_slot(&mut display));
    let scale = scale.map(|s| pass.read_slot(s));
    pass.kernel(Arc::new(TonemapKernel { src, dst, scale, exposure })).add();
    Ok(display)
}

/// Records `tonemap` instances: the radiance read into the `display` write.
struct TonemapKernel {
    src: ReadSlot,
    dst: WriteSlot,
    scale: Option<ReadSlot>,
    exposure: f32,
}

impl PassKernel for TonemapKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, index: InstanceId) -> parallax_backend::Result<()> {
        let (src, dst) = (pass.read(self.src)?, pass.write(self.dst)?);
        let target = rec.resource(dst.alloc);
        if target.format != Format::Rgba8 {
            return Err(BackendError::KernelMisuse {
                kernel: TONEMAP.into(),
                instance: Some(index),
                detail: format!("writes an Rgba8 image, not {:?}", target.format),
            });
        }
        let width = target.width;
        let push = TonemapPush {
            src: rec.image(src.alloc)?,
            dst: rec.image(dst.alloc)?,
            y0: pass.region.y0,
            y1: pass.region.y1,
            width,
            exposure: self.exposure,
            scale: match self.scale {
                Some(slot) => rec.image(pass.read(slot)?.alloc)?,
                None => 0,
            },
            scaled: u32::from(self.scale.is_some()),
        };
        let groups = [width.div_ceil(8), pass.region.len().div_ceil(8).max(1), 1];
        rec.dispatch(shaders::TONEMAP, &push, groups)
    }
}

/// Narkowicz's ACES fit, clamped to [0, 1].
pub fn aces_narkowicz(x: f32) -> f32 {
    ((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14)).clamp(0.0, 1.0)
}

/// The sRGB transfer function (IEC 61966-2-1) of a value in [0, 1].
pub fn srgb_encode(c: f32) -> f32 {
    if c <= 0.003_130_8 { 12.92 * c } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 }
}

/// What `tonemap` writes for linear `rgb` at `exposure`, before quantisation to bytes (NaN and
/// negatives as 0, like the shader).
pub fn tonemap_pixel(rgb: [f32; 3], exposure: f32) -> [f32; 4] {
    let channel = |c: f32| {
        let x = if c.is_nan() { 0.0 } else { (c * exposure).clamp(0.0, 1e6) };
        srgb_encode(aces_narkowicz(x))
    };
    [channel(rgb[0]), channel(rgb[1]), channel(rgb[2]), 1.0]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exposure_must_be_finite_and_positive() {
        let mut graph = KernelGraph::with_payload(parallax_graph::ViewTopology::all_sources(1, 4, 4));
        let input = graph.image("radiance", Format::Rgba32f);
        for exposure in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            let err = declare_tonemap(&mut graph, &input, exposure).unwrap_err();
            assert!(matches!(err, TonemapError::Exposure { .. }), "{exposure}");
            assert!(err.to_string().contains("exposure"), "{err}");
        }
        assert!(declare_tonemap(&mut graph, &input, 1.5).is_ok());
    }

    #[test]
    fn the_curve_maps_black_to_black_and_saturates_to_white() {
        assert_eq!(tonemap_pixel([0.0, -1.0, f32::NAN], 1.0), [0.0, 0.0, 0.0, 1.0]);
        let white = tonemap_pixel([1e9, f32::INFINITY, 100.0], 1.0);
        assert!(white.iter().all(|&c| (c - 1.0).abs() < 1e-6), "{white:?}");
    }
}
