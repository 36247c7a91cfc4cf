//! Comparing two EXR files, or two light-field folders view by view (matched by file name,
//! `view_NNN.exr`), into per-view and pooled [`Metrics`], as JSON or a markdown table. The
//! perceptual figures see both sides tonemapped at one exposure: a fixed one, or by default the
//! automatic exposure of the whole reference ([`crate::exposure`]), so they measure the error
//! as the images show at a visible brightness.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::error::{AccuracyError, Result};
use crate::exposure::{Exposure, LogAverage};
use crate::image::RgbImage;
use crate::metrics::{ErrorSums, Metrics, compare_images_at};

/// One view's figures.
#[derive(Clone, Debug, Serialize)]
pub struct ViewMetrics {
    pub name: String,
    pub width: usize,
    pub height: usize,
    #[serde(flatten)]
    pub metrics: Metrics,
}

/// The figures of every view and, pooled over all pixels of all views, `overall`: PSNR and
/// relMSE from the pooled squared errors, SSIM and FLIP as pixel-weighted means.
#[derive(Clone, Debug, Serialize)]
pub struct Comparison {
    pub test: PathBuf,
    pub reference: PathBuf,
    /// The exposure both sides were tonemapped at for PSNR tm, SSIM and FLIP.
    pub exposure: f32,
    /// `auto` (the reference's) or `fixed`.
    pub exposure_mode: &'static str,
    pub views: Vec<ViewMetrics>,
    pub overall: Metrics,
    /// Each view's per-pixel FLIP error (row-major), in `views` order, when asked for.
    #[serde(skip)]
    pub flip_maps: Vec<Vec<f32>>,
}

/// How to compare.
#[derive(Clone, Copy, Debug, Default)]
pub struct CompareOptions {
    pub exposure: Exposure,
    /// Keep each view's FLIP error map in [`Comparison::flip_maps`].
    pub flip_maps: bool,
}

/// Compares `test` against `reference`: two EXR files, or two folders whose `view_*.exr` sets
/// must be equal.
pub fn compare_paths(test: &Path, reference: &Path, options: &CompareOptions) -> Result<Comparison> {
    let pairs = match (test.is_dir(), reference.is_dir()) {
        (true, true) => matched_views(test, reference)?,
        (false, false) => {
            vec![(
                test.file_name().map_or("image".into(), |n| n.to_string_lossy().into_owned()),
                test.into(),
                reference.into(),
            )]
        }
        _ => {
            return Err(AccuracyError::BadInput {
                path: if test.is_dir() { reference.into() } else { test.into() },
                detail: "compare two EXR files or two light-field folders, not one of each".into(),
            });
        }
    };
    // The automatic exposure is the reference's, over all its views: one pass to find it, one
    // to compare (a light field is too large to hold whole).
    let mut average = LogAverage::default();
    if options.exposure == Exposure::Auto {
        for (_, _, b) in &pairs {
            let image = RgbImage::read_exr(b)?;
            average.add_image(image.width, &image.pixels);
        }
    }
    let exposure = options.exposure.resolve(&average);
    let mut pooled = ErrorSums::default();
    let mut views = Vec::new();
    let mut flip_maps = Vec::new();
    // Non-finite pixels are counted over every image first, so one error reports them all.
    let (mut non_finite, mut total) = (Vec::new(), 0);
    for (name, a, b) in pairs {
        let (ta, tb) = (RgbImage::read_exr(&a)?, RgbImage::read_exr(&b)?);
        let mut finite = true;
        for (path, image) in [(&a, &ta), (&b, &tb)] {
            if let Some((count, (x, y))) = image.non_finite() {
                non_finite.push(format!("{}: {count}, first at ({x}, {y})", path.display()));
                total += count;
                finite = false;
            }
        }
        if !finite {
            continue;
        }
        let one = compare_images_at(&ta, &a.display().to_string(), &tb, &b.display().to_string(), exposure)?;
        pooled.add(&one.sums);
        views.push(ViewMetrics { name, width: ta.width, height: ta.height, metrics: one.sums.metrics() });
        if options.flip_maps {
            flip_maps.push(one.flip_map);
        }
    }
    if !non_finite.is_empty() {
        return Err(AccuracyError::NonFiniteViews { total, report: non_finite.join("; ") });
    }
    Ok(Comparison {
        test: test.into(),
        reference: reference.into(),
        exposure,
        exposure_mode: options.exposure.mode(),
        views,
        overall: pooled.metrics(),
        flip_maps,
    })
}

fn view_names(folder: &Path) -> Result<BTreeSet<String>> {
    let entries =
        std::fs::read_dir(folder).map_err(|e| AccuracyError::Read { path: folder.into(), detail: e.to_string() })?;
    let mut names = BTreeSet::new();
    for entry in entries {
        let entry = entry.map_err(|e| AccuracyError::Read { path: folder.into(), detail: e.to_string() })?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.starts_with("view_") && name.ends_with(".exr") {
            names.insert(name);
        }
    }
    Ok(names)
}

fn matched_views(test: &Path, reference: &Path) -> Result<Vec<(String, PathBuf, PathBuf)>> {
    let (a, b) = (view_names(test)?, view_names(reference)?);
    let missing = |from: &Path, names: Vec<&String>| AccuracyError::MissingViews {
        folder: from.into(),
        missing: names.into_iter().cloned().collect::<Vec<_>>().join(", "),
    };
    if a.is_empty() {
        return Err(AccuracyError::BadInput { path: test.into(), detail: "no view_*.exr in this folder".into() });
    }
    if b.difference(&a).next().is_some() {
        return Err(missing(test, b.difference(&a).collect()));
    }
    if a.difference(&b).next().is_some() {
        return Err(missing(reference, a.difference(&b).collect()));
    }
    Ok(a.into_iter().map(|n| (n.clone(), test.join(&n), reference.join(&n))).collect())
}

fn db(v: f64) -> String {
    if v.is_infinite() { "∞".into() } else { format!("{v:.3}") }
}

impl Comparison {
    /// A markdown table: one row per view, then the pooled figures.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "`{}` against the reference `{}`. PSNR lin: linear radiance clamped to [0, 1]; PSNR tm, SSIM, FLIP: \
             tonemapped 8-bit sRGB (ACES, exposure {:.4}, {}); relMSE: linear, ε = 0.01; mean ratio: mean linear r, g, b \
             of the test over the reference's.\n\n",
            self.test.display(),
            self.reference.display(),
            self.exposure,
            self.exposure_mode
        );
        s += "| view | size | PSNR lin (dB) | PSNR tm (dB) | SSIM | FLIP | relMSE | mean ratio r, g, b |\n|---|---|---|---|---|---|---|---|\n";
        let row = |name: &str, size: String, m: &Metrics| {
            format!(
                "| {name} | {size} | {} | {} | {:.5} | {:.5} | {:.3e} | {} |\n",
                db(m.psnr_linear_db),
                db(m.psnr_tonemapped_db),
                m.ssim,
                m.flip,
                m.rel_mse,
                m.mean_ratio.map(|r| format!("{r:.4}")).join(", ")
            )
        };
        for v in &self.views {
            s += &row(&v.name, format!("{}x{}", v.width, v.height), &v.metrics);
        }
        s += &row("**all**", format!("{} views", self.views.len()), &self.overall);
        s
    }
}
