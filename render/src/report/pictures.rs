//! The LDR pictures `render` writes beside its EXRs: `view_NNN.png` per view, the contact sheet,
//! the optional quilt and wiggle, and `viewer.html`, all at one exposure for the whole light
//! field.
//!
//! With `--exposure N` they are the GPU's display images (the `tonemap` pass at N). With
//! `--exposure auto` (the default) the exposure is the log-average luminance of the last
//! frame's views mapped to 0.18 ([`parallax_accuracy::exposure`]), computed on the host from
//! the linear views read back for the EXRs; the views are then tonemapped on the host by the
//! pass's CPU twin ([`tonemap_pixel`], the same curve) from a second read-back, and the GPU's
//! display images of that frame are not used (the pass ran at exposure 1, and costs the same at
//! any exposure). The same measure as a GPU pass before the tonemapper, through a global
//! resource, is `examples/auto_exposure.rs`.

use std::path::Path;

use anyhow::Result;
use parallax_accuracy::exposure::{Exposure, LogAverage};
use parallax_graph::LightField;
use parallax_passes::pipeline::PipelineHandles;
use parallax_passes::tonemap::tonemap_pixel;

use crate::outputs::{Staged, stage};
use crate::report::images::{
    DisplayImage, QuiltShape, encode_png, quilt_file_name, quilt_grid, quilt_views, wiggle_order, write_contact_sheet,
    write_quilt, write_wiggle,
};
use crate::report::viewer::{ViewGeometry, ViewerPage, settings_of_render_json};

/// Most views per row of the contact sheet: a 100×1 light field wraps into 10 rows, which a
/// screen shows whole.
const SHEET_COLUMNS: u32 = 10;

/// File name of view `index`'s PNG.
pub fn view_png_name(index: u32) -> String {
    format!("view_{index:03}.png")
}

/// The exposure of the GPU's `tonemap` pass: the fixed one, or 1 under `auto` (the written
/// pictures are then tonemapped on the host).
pub fn gpu_exposure(exposure: Exposure) -> f32 {
    match exposure {
        Exposure::Fixed(v) => v,
        Exposure::Auto => 1.0,
    }
}

/// Every view's display image (RGBA8) at the exposure used, and that exposure. Under `auto` the
/// linear views are read back twice, once for the log-average and once to tonemap, rather than
/// all held in memory at once (a NELF light field is over a gigabyte of Rgba32f).
pub fn display_images(
    renderer: &mut dyn crate::ranks::view_source::ViewSource,
    handles: &PipelineHandles,
    (views, width): (u32, u32),
    exposure: Exposure,
) -> Result<(f32, Vec<Vec<u8>>)> {
    let mut average = LogAverage::default();
    if exposure == Exposure::Auto {
        for v in 0..views {
            let bytes = renderer.read_view(handles.linear, v)?;
            average.add_image(width as usize, &texels_rgb(&bytes));
        }
    }
    let value = exposure.resolve(&average);
    let displays = (0..views)
        .map(|v| match exposure {
            Exposure::Fixed(_) => Ok(renderer.read_view(handles.display.family(), v)?),
            Exposure::Auto => Ok(tonemap_rgba8(&renderer.read_view(handles.linear, v)?, value)),
        })
        .collect::<Result<_>>()?;
    Ok((value, displays))
}

/// The RGB of Rgba32f texels.
fn texels_rgb(bytes: &[u8]) -> Vec<[f32; 3]> {
    bytes
        .chunks_exact(16)
        .map(|t| std::array::from_fn(|i| f32::from_le_bytes([t[4 * i], t[4 * i + 1], t[4 * i + 2], t[4 * i + 3]])))
        .collect()
}

/// Rgba32f texels to RGBA8 through the tonemap pass's curve, rounded as a UNORM store rounds.
fn tonemap_rgba8(bytes: &[u8], exposure: f32) -> Vec<u8> {
    texels_rgb(bytes)
        .into_iter()
        .flat_map(|rgb| tonemap_pixel(rgb, exposure).map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8))
        .collect()
}

/// The pictures of one run, staged: view PNGs (kept in memory for the viewer), contact sheet,
/// quilt and wiggle.
pub struct Pictures {
    pub staged: Vec<Staged>,
    views: Vec<(String, Vec<u8>)>,
}

/// Columns of one eye: the NELF preset's two 6×6 blocks sit side by side.
fn eye_cols(lf: &LightField) -> u32 {
    if lf.name == "nelf" { lf.cols / 2 } else { lf.cols }
}

/// Stages the view PNGs, the contact sheet and, when asked, the quilt and the wiggle.
pub fn stage_pictures(
    out_dir: &Path,
    lf: &LightField,
    displays: &[Vec<u8>],
    quilt: Option<QuiltShape>,
    wiggle: Option<&Path>,
) -> Result<Pictures> {
    let images: Vec<DisplayImage<'_>> =
        displays.iter().map(|d| DisplayImage { width: lf.width, height: lf.height, rgba8: d }).collect();
    let mut staged = Vec::new();
    let mut views = Vec::with_capacity(images.len());
    // PNG compression is the slow part of writing a large light field: one view per core.
    let pngs: Vec<Vec<u8>> = {
        use rayon::prelude::*;
        images.par_iter().map(encode_png).collect::<Result<_>>()?
    };
    for (v, png) in pngs.into_iter().enumerate() {
        let name = view_png_name(v as u32);
        let path = out_dir.join(&name);
        staged.push(stage(&path, |tmp| Ok(std::fs::write(tmp, &png)?))?);
        views.push((name, png));
    }
    let sheet = out_dir.join("lightfield.png");
    // NELF: its two eye blocks, each whole, side by side; a grid wider than SHEET_COLUMNS wraps.
    let (columns, block) =
        if lf.name == "nelf" { (lf.cols, Some(eye_cols(lf))) } else { (lf.cols.min(SHEET_COLUMNS), None) };
    staged.push(stage(&sheet, |tmp| write_contact_sheet(tmp, &images, columns, block))?);
    if let Some(shape) = quilt {
        let sweep: Vec<DisplayImage<'_>> = quilt_views(lf.cols, lf.rows, lf.name == "nelf")?
            .into_iter()
            .map(|v| DisplayImage { width: lf.width, height: lf.height, rgba8: &displays[v as usize] })
            .collect();
        let grid = quilt_grid(shape, sweep.len() as u32);
        let quilt = out_dir.join(quilt_file_name("lightfield", grid, lf.width, lf.height));
        staged.push(stage(&quilt, |tmp| write_quilt(tmp, &sweep, grid))?);
    }
    if let Some(path) = wiggle {
        let order = wiggle_order(lf.cols, lf.rows, eye_cols(lf));
        staged.push(stage(path, |tmp| write_wiggle(tmp, &images, &order))?);
    }
    Ok(Pictures { staged, views })
}

impl Pictures {
    /// Stages `viewer.html` in `out_dir`, showing `render_json`'s settings.
    pub fn stage_viewer(&self, out_dir: &Path, lf: &LightField, render_json: &serde_json::Value) -> Result<Staged> {
        let page = ViewerPage {
            title: format!("{} · {} · parallax", render_json["scene"].as_str().unwrap_or("scene"), lf.name),
            cols: lf.cols,
            rows: lf.rows,
            width: lf.width,
            height: lf.height,
            eye_cols: eye_cols(lf),
            geometry: ViewGeometry::of(lf),
            views: &self.views,
            settings: settings_of_render_json(render_json),
        };
        let html = page.html();
        stage(&out_dir.join("viewer.html"), |tmp| Ok(std::fs::write(tmp, html)?))
    }
}
