//! Writing results: one HDR EXR per view (radiance plus optional G-buffer layers) and a
//! tonemapped PNG contact sheet of several views for people to look at.

use std::path::Path;

use crate::input::{EXR_FILE_LIMIT, read_bounded};
use exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes, SmallVec, WritableImage,
};
use glam::Vec3;

use crate::error::SceneError;
use crate::pt::Frame;

/// Which G-buffer layers go into the EXR next to the radiance (R, G, B).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ExrLayers {
    /// `albedo.R/G/B`
    pub albedo: bool,
    /// `normal.X/Y/Z`
    pub normal: bool,
    /// `depth.Z` (linear depth along the camera axis; 0 where nothing was hit)
    pub depth: bool,
}

impl ExrLayers {
    pub const ALL: ExrLayers = ExrLayers { albedo: true, normal: true, depth: true };
}

/// Writes `frame` as a single-part EXR with 32-bit float channels; layers use the usual
/// `layer.channel` names, which Blender, Nuke and oiiotool show as layers.
pub fn write_exr(path: &Path, frame: &Frame, layers: ExrLayers) -> Result<(), SceneError> {
    write_exr_with(path, frame, layers, &[])
}

/// [`write_exr`] with extra float channels, each `(name, one value per pixel)` (e.g.
/// `("holes.Y", mask)`).
pub fn write_exr_with(
    path: &Path,
    frame: &Frame,
    layers: ExrLayers,
    extra: &[(&str, &[f32])],
) -> Result<(), SceneError> {
    let (w, h) = (frame.width as usize, frame.height as usize);
    let px = &frame.pixels;
    if px.len() != w * h {
        return Err(SceneError::ImageWrite {
            path: path.to_path_buf(),
            detail: format!("{} pixels for a {w}x{h} image", px.len()),
        });
    }
    let channel =
        |name: &str, f: &dyn Fn(usize) -> f32| AnyChannel::new(name, FlatSamples::F32((0..w * h).map(f).collect()));
    let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    list.push(channel("R", &|i| px[i].radiance.x));
    list.push(channel("G", &|i| px[i].radiance.y));
    list.push(channel("B", &|i| px[i].radiance.z));
    if layers.albedo {
        list.push(channel("albedo.R", &|i| px[i].albedo.x));
        list.push(channel("albedo.G", &|i| px[i].albedo.y));
        list.push(channel("albedo.B", &|i| px[i].albedo.z));
    }
    if layers.normal {
        list.push(channel("normal.X", &|i| px[i].normal.x));
        list.push(channel("normal.Y", &|i| px[i].normal.y));
        list.push(channel("normal.Z", &|i| px[i].normal.z));
    }
    if layers.depth {
        list.push(channel("depth.Z", &|i| px[i].depth));
    }
    for (name, values) in extra {
        if values.len() != w * h {
            return Err(SceneError::ImageWrite {
                path: path.to_path_buf(),
                detail: format!("channel {name} has {} values for a {w}x{h} image", values.len()),
            });
        }
        list.push(channel(name, &|i| values[i]));
    }
    let layer =
        Layer::new((w, h), LayerAttributes::named("parallax"), Encoding::SMALL_LOSSLESS, AnyChannels::sort(list));
    Image::from_layer(layer)
        .write()
        .to_file(path)
        .map_err(|e| SceneError::ImageWrite { path: path.to_path_buf(), detail: e.to_string() })
}

/// Reads the named channels of the first layer of an EXR (row-major), e.g. `["R","G","B"]`.
/// The file must be a regular file of at most [`EXR_FILE_LIMIT`] bytes whose headers declare at
/// most [`EXR_PIXEL_BYTES_LIMIT`] bytes of pixels: checked before any pixel is decoded.
pub fn read_exr_channels(path: &Path, names: &[&str]) -> Result<(usize, usize, Vec<Vec<f32>>), SceneError> {
    let bad = |detail: String| SceneError::ImageRead { path: path.to_path_buf(), detail };
    let bytes = read_bounded(path, EXR_FILE_LIMIT, "EXR image")?;
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(&bytes), false)
        .map_err(|e| bad(format!("not a readable EXR ({e})")))?;
    for header in &meta.headers {
        let declared = header
            .layer_size
            .width()
            .checked_mul(header.layer_size.height())
            .and_then(|pixels| pixels.checked_mul(header.channels.bytes_per_pixel))
            .filter(|&b| b as u64 <= EXR_PIXEL_BYTES_LIMIT);
        if declared.is_none() {
            return Err(bad(format!(
                "its header declares a {}x{} layer of {} bytes a pixel, more than the {EXR_PIXEL_BYTES_LIMIT} bytes of pixels an EXR may have",
                header.layer_size.width(),
                header.layer_size.height(),
                header.channels.bytes_per_pixel
            )));
        }
    }
    use exr::prelude::ReadChannels as _;
    use exr::prelude::ReadLayers as _;
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(&bytes))
        .map_err(|e| bad(e.to_string()))?;
    let size = image.layer_data.size;
    let mut out = Vec::new();
    for name in names {
        let c = image
            .layer_data
            .channel_data
            .list
            .iter()
            .find(|c| c.name == **name)
            .ok_or_else(|| bad(format!("no channel {name}")))?;
        out.push(c.sample_data.values_as_f32().collect());
    }
    Ok((size.width(), size.height(), out))
}

/// The pixels an EXR's headers may declare: 4 GiB (e.g. 16384x16384 of RGBA f32).
pub const EXR_PIXEL_BYTES_LIMIT: u64 = 4 << 30;

/// Exposed radiance at which the curve is past white: it reaches 1 at 7.24 and is 1.018 at 16.
const ACES_WHITE_INPUT: f32 = 16.0;

/// ACES filmic curve (Narkowicz 2015 fit) followed by the sRGB transfer function. The exposed
/// radiance is clamped to [`ACES_WHITE_INPUT`] first, which changes no output (both give white)
/// but keeps the curve finite: above about 1e19 its squares overflow f32 and inf/inf made a
/// bright pixel black (and `compare` scored two different images as equal).
pub fn tonemap_to_srgb8(c: Vec3, exposure: f32) -> [u8; 3] {
    let x = (c * exposure).clamp(Vec3::ZERO, Vec3::splat(ACES_WHITE_INPUT));
    let mapped = (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14);
    let encode = |v: f32| {
        let v = if v.is_finite() { v.clamp(0.0, 1.0) } else { 0.0 };
        let s = if v <= 0.003_130_8 { 12.92 * v } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 };
        (s * 255.0 + 0.5) as u8
    };
    [encode(mapped.x), encode(mapped.y), encode(mapped.z)]
}

/// Tiles the frames (all the same size) into a grid `columns` wide with a 2-pixel gap, tonemaps
/// them and writes an 8-bit sRGB PNG.
pub fn write_contact_sheet(path: &Path, frames: &[&Frame], columns: u32, exposure: f32) -> Result<(), SceneError> {
    let bad = |detail: String| SceneError::ImageWrite { path: path.to_path_buf(), detail };
    let first = frames.first().ok_or_else(|| bad("no views to put on the sheet".into()))?;
    let (fw, fh) = (first.width, first.height);
    if frames.iter().any(|f| f.width != fw || f.height != fh || f.pixels.len() != (fw * fh) as usize) {
        return Err(bad("views differ in size".into()));
    }
    let gap = 2;
    let columns = columns.clamp(1, frames.len() as u32);
    let rows = (frames.len() as u32).div_ceil(columns);
    let (w, h) = (columns * fw + (columns - 1) * gap, rows * fh + (rows - 1) * gap);
    let mut sheet = image::RgbImage::new(w, h);
    for (k, frame) in frames.iter().enumerate() {
        let (cx, cy) = ((k as u32 % columns) * (fw + gap), (k as u32 / columns) * (fh + gap));
        for y in 0..fh {
            for x in 0..fw {
                let p = frame.pixels[(y * fw + x) as usize].radiance;
                sheet.put_pixel(cx + x, cy + y, image::Rgb(tonemap_to_srgb8(p, exposure)));
            }
        }
    }
    sheet.save_with_format(path, image::ImageFormat::Png).map_err(|e| bad(e.to_string()))
}
