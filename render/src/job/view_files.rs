//! The view files of a finished run: which EXR layers each view gets, the views read back (or
//! received from other ranks) and staged as EXR and PNG, the stale view files of an earlier
//! run removed, and what rank 0 reads of a view. `report.rs` writes them with the rest.

use std::path::Path;

use anyhow::{Context as _, Result};
use glam::Vec3;
use parallax_passes::LightFieldRenderer;
use parallax_passes::pipeline::{PipelineHandles, PipelineKind};
use parallax_scene::output::{ExrLayers, write_exr_with};
use parallax_scene::{Frame, PixelSample, View};

use super::prepare::view_file_name;
use crate::outputs::{Staged, stage};
use crate::ranks::view_source::ViewSource;
use crate::report::pictures::view_png_name;
use crate::settings::RenderSettings;

/// The extra EXR layers of the views.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct ViewLayers {
    /// Albedo, normal and depth, each where the pipeline produces it.
    exr: ExrLayers,
    /// The hole mask of targets (reprojection only).
    holes: bool,
}

/// What `--layers` gives with the plan `renderer` runs: albedo, normal and depth where the
/// pipeline computes them, and the hole mask with reprojection. Path tracing without denoising
/// computes no G-buffer: its views carry radiance alone, which is said once, before the frames
/// (reading a layer no pass writes used to fail the run after all of them).
pub(super) fn view_layers(
    settings: &RenderSettings,
    kind: PipelineKind,
    handles: &PipelineHandles,
    renderer: &LightFieldRenderer,
) -> ViewLayers {
    if !settings.layers {
        return ViewLayers::default();
    }
    // A view this process renders (a rank of several renders only some).
    let view = renderer.plan().passes.first().map_or(0, |p| p.view.0);
    let produced = |family| renderer.plan().final_bands(family, view).is_some();
    let g = &handles.gbuffer;
    let exr = ExrLayers {
        albedo: produced(g.albedo_roughness.family()),
        normal: produced(g.normal_metallic.family()),
        depth: produced(g.position_depth.family()),
    };
    let absent: Vec<&str> = [("albedo", exr.albedo), ("normal", exr.normal), ("depth", exr.depth)]
        .into_iter()
        .filter_map(|(name, there)| (!there).then_some(name))
        .collect();
    if !absent.is_empty() {
        tracing::warn!(
            "--layers: this pipeline computes no {} (no stage needs a G-buffer), so the views' EXRs leave that out; \
             drop --no-denoise or use --pipeline reproject to get every layer",
            absent.join(", ")
        );
    }
    ViewLayers { exr, holes: kind == PipelineKind::Reproject }
}

pub(super) fn bytemuck_words(bytes: &[u8]) -> Vec<u32> {
    bytes.chunks_exact(4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
}

fn texels(bytes: &[u8]) -> Vec<[f32; 4]> {
    bytes
        .chunks_exact(16)
        .map(|b| std::array::from_fn(|i| f32::from_le_bytes([b[4 * i], b[4 * i + 1], b[4 * i + 2], b[4 * i + 3]])))
        .collect()
}

/// Stages `view_NNN.exr` of every view into `folder`: the linear radiance after denoising (or
/// after hole filling with --no-denoise), with `layers`: albedo, normal and depth, and the hole
/// mask of targets as channel `holes.Y` (1 = the pixel was path traced by hole filling).
pub(super) fn stage_views(
    renderer: &mut dyn ViewSource,
    handles: &PipelineHandles,
    folder: &Path,
    views: &[View],
    layers: ViewLayers,
) -> Result<Vec<Staged>> {
    let mut staged = Vec::with_capacity(views.len());
    let gbuffer = &handles.gbuffer;
    for view in views {
        let radiance = texels(&renderer.read_view(handles.linear, view.index)?);
        let mut layer = |wanted: bool, family| -> Result<Vec<[f32; 4]>> {
            Ok(if wanted { texels(&renderer.read_view(family, view.index)?) } else { Vec::new() })
        };
        let albedo = layer(layers.exr.albedo, gbuffer.albedo_roughness.family())?;
        let normal = layer(layers.exr.normal, gbuffer.normal_metallic.family())?;
        let position = layer(layers.exr.depth, gbuffer.position_depth.family())?;
        // Sources have no hole mask: only targets get the channel.
        let mask = match &handles.holes {
            Some(mask) if layers.holes => match renderer.read_view(mask.family(), view.index) {
                Ok(bytes) => Some(bytemuck_words(&bytes)),
                Err(parallax_passes::PassError::MissingOutput { .. }) => None,
                Err(e) => return Err(e.into()),
            },
            _ => None,
        };
        let pixels = (0..radiance.len())
            .map(|i| {
                let g = |layer: &[[f32; 4]]| layer.get(i).copied().unwrap_or([0.0; 4]);
                let (a, n, p) = (g(&albedo), g(&normal), g(&position));
                PixelSample {
                    radiance: Vec3::from_slice(&radiance[i][..3]),
                    albedo: Vec3::from_slice(&a[..3]),
                    normal: Vec3::from_slice(&n[..3]),
                    depth: p[3],
                    position: Vec3::from_slice(&p[..3]),
                    roughness: a[3],
                    metallic: n[3],
                    hit: radiance[i][3] > 0.5,
                }
            })
            .collect();
        let frame = Frame { width: view.width, height: view.height, pixels };
        if layers.exr.depth {
            staged.extend(stage_layer_pictures(folder, view.index, &frame, mask.as_deref())?);
        }
        let path = folder.join(view_file_name(view.index));
        let exr_layers = layers.exr;
        let mask: Option<Vec<f32>> = mask.map(|m| m.iter().map(|&h| h as f32).collect());
        let extra: Vec<(&str, &[f32])> = mask.iter().map(|m| ("holes.Y", m.as_slice())).collect();
        staged.push(stage(&path, |tmp| {
            write_exr_with(tmp, &frame, exr_layers, &extra).with_context(|| format!("cannot write {}", path.display()))
        })?);
    }
    Ok(staged)
}

/// With `--layers`, pictures of the layers a person looks at: `view_NNN_depth.png` (grey, the
/// view's nearest hit white, its farthest dark grey, sky black) and, of targets,
/// `view_NNN_holes.png` (white where hole filling path traced the pixel).
fn stage_layer_pictures(folder: &Path, index: u32, frame: &Frame, mask: Option<&[u32]>) -> Result<Vec<Staged>> {
    let hits = || frame.pixels.iter().filter(|p| p.hit).map(|p| p.depth);
    let (near, far) = hits().fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), d| (a.min(d), b.max(d)));
    let grey = |p: &PixelSample| -> u8 {
        if !p.hit {
            return 0;
        }
        let t = if far > near { (p.depth - near) / (far - near) } else { 0.0 };
        (255.0 - 191.0 * t.clamp(0.0, 1.0)).round() as u8
    };
    let depth: Vec<u8> = frame.pixels.iter().map(grey).collect();
    let mut pictures = vec![(format!("view_{index:03}_depth.png"), depth)];
    if let Some(mask) = mask {
        pictures
            .push((format!("view_{index:03}_holes.png"), mask.iter().map(|&h| if h != 0 { 255 } else { 0 }).collect()));
    }
    pictures
        .into_iter()
        .map(|(name, luma)| {
            let path = folder.join(name);
            let image =
                image::GrayImage::from_raw(frame.width, frame.height, luma).context("a layer of the view's size")?;
            stage(&path, |tmp| {
                image
                    .save_with_format(tmp, image::ImageFormat::Png)
                    .with_context(|| format!("cannot write {}", path.display()))
            })
        })
        .collect()
}

/// Removes `view_NNN.exr` and `view_NNN.png` files of an earlier run that this run of `views`
/// views did not write.
pub(super) fn remove_stale_views(out_dir: &Path, views: usize) -> Result<()> {
    let entries = std::fs::read_dir(out_dir).with_context(|| format!("cannot list --out-dir {}", out_dir.display()))?;
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(index) = name.to_str().and_then(parse_view_file_name) else { continue };
        if index as usize >= views && entry.file_type().is_ok_and(|t| t.is_file()) {
            std::fs::remove_file(entry.path())
                .with_context(|| format!("cannot remove stale {}", entry.path().display()))?;
            tracing::info!("removed {} of an earlier run", entry.path().display());
        }
    }
    Ok(())
}

/// The view index of a file name this command writes (`view_007.exr` or `.png` → 7).
fn parse_view_file_name(name: &str) -> Option<u32> {
    let stem = name.strip_prefix("view_")?;
    let digits = stem.strip_suffix(".exr").or_else(|| stem.strip_suffix(".png"))?;
    if digits.len() < 3 || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let index: u32 = digits.parse().ok()?;
    (view_file_name(index) == name || view_png_name(index) == name).then_some(index)
}

/// What rank 0 reads of a view to write the outputs, so what another rank sends of its views:
/// the linear radiance, the tonemapped display (at a fixed exposure), the hole mask
/// (reprojection) and the `--layers`.
#[cfg(feature = "mpi")]
pub(super) fn output_families(
    settings: &RenderSettings,
    job: &super::prepare::RenderJob,
    layers: ViewLayers,
) -> Vec<parallax_graph::FamilyId> {
    let handles = &job.compiled.handles;
    let gbuffer = &handles.gbuffer;
    let mut families = vec![handles.linear];
    if matches!(settings.exposure, parallax_accuracy::exposure::Exposure::Fixed(_)) {
        families.push(handles.display.family());
    }
    if job.compiled.kind == PipelineKind::Reproject {
        families.extend(handles.holes.as_ref().map(|h| h.family()));
    }
    let exr = layers.exr;
    families.extend(exr.albedo.then(|| gbuffer.albedo_roughness.family()));
    families.extend(exr.normal.then(|| gbuffer.normal_metallic.family()));
    families.extend(exr.depth.then(|| gbuffer.position_depth.family()));
    families
}
