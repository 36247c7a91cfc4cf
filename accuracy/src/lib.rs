//! parallax-accuracy: how far a rendering is from the truth, and charts of speed against it.
//!
//! * [`metrics`]: PSNR (linear clamped and tonemapped), [`ssim`], [`flip`] (NVIDIA's FLIP
//!   through `nv-flip`), relMSE of a test image against a reference, pooled over views;
//!   [`compare`]: two EXRs or two light-field folders, as JSON or a markdown table.
//! * [`accumulate`]: the f64 accumulator of a progressive reference and its resumable sidecar.
//! * [`points`], [`chart`], [`timeline`]: chart inputs (a small JSON schema that `render`,
//!   `reference` and `compare` write) and plotters charts as SVG or PNG.
//!
//! No GPU here: the `parallax reference` command drives the tracers and feeds this crate.
//!
//! ```
//! use parallax_accuracy::{RgbImage, compare_images};
//! let reference = RgbImage::new(2, 1, vec![[0.25, 0.5, 0.75], [0.5, 0.5, 0.5]]);
//! let same = compare_images(&reference, "a.exr", &reference, "b.exr")?.metrics();
//! assert_eq!((same.psnr_linear_db, same.ssim, same.flip), (f64::INFINITY, 1.0, 0.0));
//! // +1/64 on every channel: MSE = (1/64)², PSNR = 20 log10(64) dB.
//! let brighter = RgbImage::new(2, 1, reference.pixels.iter().map(|p| p.map(|c| c + 1.0 / 64.0)).collect());
//! let m = compare_images(&brighter, "c.exr", &reference, "b.exr")?.metrics();
//! assert!((m.psnr_linear_db - 20.0 * 64f64.log10()).abs() < 1e-6);
//! # Ok::<(), parallax_accuracy::AccuracyError>(())
//! ```

pub mod accumulate;
pub mod chart;
pub mod compare;
pub mod error;
pub mod exposure;
pub mod flip;
pub mod image;
pub mod metrics;
pub mod points;
pub mod ssim;
pub mod timeline;

pub use accumulate::{
    Accumulator, FRAME_BASE, PARTIAL_FILE, ReferenceHeader, folder_gone, remove_stale_temporaries, write_atomically,
    write_failure,
};
pub use compare::{CompareOptions, Comparison, ViewMetrics, compare_paths};
pub use error::{AccuracyError, Result};
pub use image::RgbImage;
pub use metrics::{ErrorSums, ImageComparison, Metrics, compare_images, compare_images_at};
pub use points::{Point, load_points};
