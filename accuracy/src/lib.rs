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

pub mod accumulate;
pub mod chart;
pub mod compare;
pub mod error;
pub mod flip;
pub mod image;
pub mod metrics;
pub mod points;
pub mod ssim;
pub mod timeline;

pub use accumulate::{
    Accumulator, FRAME_BASE, PARTIAL_FILE, ReferenceHeader, remove_stale_temporaries, write_atomically,
};
pub use compare::{Comparison, ViewMetrics, compare_paths};
pub use error::{AccuracyError, Result};
pub use image::RgbImage;
pub use metrics::{ErrorSums, Metrics, compare_images};
pub use points::{Point, load_points};
