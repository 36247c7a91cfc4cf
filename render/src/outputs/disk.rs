//! What `render` will write into `--out-dir`, bounded from above and checked against the free
//! space of the filesystem that receives it before any work: a disk that fills after hours of
//! frames fails the run and removes everything it wrote (outputs are staged, then renamed).

use std::path::Path;

use anyhow::{Result, bail};

use crate::outputs::budget::gib;

/// "2.0 MiB", "344.9 GiB".
fn size(bytes: u64) -> String {
    if bytes < 1 << 30 { format!("{:.1} MiB", bytes as f64 / f64::from(1 << 20)) } else { gib(bytes) }
}

/// A file's header and attributes, at most (an EXR's with its layer names: a few hundred).
const FILE_OVERHEAD_BYTES: u64 = 4 << 10;
/// `viewer.html`: its template and the view PNGs it embeds, at most this many bytes in base64.
const VIEWER_BYTES: u64 =
    (crate::report::viewer::EMBED_LIMIT_BYTES as u64).div_ceil(3) * 4 + crate::report::viewer::TEMPLATE.len() as u64;

/// An EXR of f32 channels as `write_exr_with` writes it, at most: its lossless compression
/// stores a block that would grow uncompressed, and every scanline may be a block with an
/// offset-table entry and a block header (16 bytes).
pub fn exr_bytes(width: u32, height: u32, channels: u64) -> u64 {
    u64::from(width) * u64::from(height) * channels * 4 + 16 * u64::from(height) + FILE_OVERHEAD_BYTES
}

/// An 8-bit RGB PNG, at most: uncompressed deflate blocks (5 bytes per 64 KiB) of the rows,
/// each with its filter byte.
pub fn png_bytes(width: u32, height: u32) -> u64 {
    let raw = (u64::from(width) * 3 + 1) * u64::from(height);
    raw + 5 * raw.div_ceil(1 << 16) + FILE_OVERHEAD_BYTES
}

/// The measured frames `--save-every` saves into `frame_FFFFF/`: every `every`-th of
/// `frames`, but not the last, whose views are the run's own outputs.
pub fn saved_frames(frames: u32, every: Option<u32>) -> u64 {
    every.map_or(0, |every| u64::from(frames.saturating_sub(1).div_ceil(every)))
}

/// `render`'s outputs in `--out-dir`, with the flags that size them.
#[derive(Clone, Copy, Debug)]
pub struct RenderOutputs {
    pub views: u64,
    pub width: u32,
    pub height: u32,
    /// Float channels of each view's EXR (3, more with `--layers`).
    pub channels: u64,
    pub frames: u32,
    pub save_every: Option<u32>,
    /// PNGs of layers per view besides its own picture (`--layers`: depth, and the hole mask
    /// of a reprojection pipeline's targets).
    pub layer_pictures: u64,
    pub quilt: bool,
}

impl RenderOutputs {
    /// Bytes of the saved frames' EXRs (and layer PNGs) and of the final views (EXR, PNG and
    /// layer PNGs), the contact sheet, the quilt and the viewer page.
    pub fn bytes(self) -> u64 {
        let exr = exr_bytes(self.width, self.height, self.channels);
        let png = png_bytes(self.width, self.height);
        let per_view = exr + self.layer_pictures * png;
        let saved = saved_frames(self.frames, self.save_every) * self.views * per_view;
        let pictures = (1 + u64::from(self.quilt)) * self.views * png;
        saved + self.views * (per_view + png) + pictures + VIEWER_BYTES
    }

    /// Refuses outputs of more than `free` bytes (the free space of `out_dir`'s filesystem),
    /// naming every flag that sizes them.
    pub fn check_fits(self, out_dir: &Path, free: u64) -> Result<()> {
        let bytes = self.bytes();
        if bytes <= free {
            return Ok(());
        }
        let views = format!(
            "{} view(s) (--lf) at {}x{} (--resolution), {} float channel(s) per EXR (--layers adds up to 8)",
            self.views, self.width, self.height, self.channels
        );
        let (what, fix) = match self.save_every {
            Some(every) => (
                format!(
                    "--frames {} with --save-every {every} saves {} frame(s) of {views}",
                    self.frames,
                    saved_frames(self.frames, self.save_every)
                ),
                "raise --save-every, lower --frames, --lf or --resolution, or free space",
            ),
            None => (format!("the views of the last frame, {views}"), "lower --lf or --resolution, or free space"),
        };
        bail!(
            "{what}: about {} ({bytes} bytes) with the final pictures, but the filesystem of --out-dir {} has {} ({free} bytes) free: {fix}",
            size(bytes),
            out_dir.display(),
            size(free)
        )
    }
}

/// Bytes an unprivileged user may still write on the filesystem of `path`, or of the nearest
/// folder above it that exists (`--out-dir` may not exist yet). None where it cannot be told.
pub fn free_bytes(path: &Path) -> Option<u64> {
    let existing =
        path.ancestors().find(|a| a.exists()).filter(|a| !a.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let stat = nix::sys::statvfs::statvfs(existing).ok()?;
    // The block count and size are 32-bit on some targets.
    #[allow(clippy::useless_conversion)]
    Some(u64::from(stat.blocks_available()).saturating_mul(u64::from(stat.fragment_size())))
}

#[cfg(test)]
mod tests {
    use super::*;
    use parallax_scene::output::{ExrLayers, write_exr_with};
    use parallax_scene::{Frame, PixelSample};

    #[test]
    fn the_last_frame_is_not_saved_twice() {
        assert_eq!(saved_frames(1, Some(1)), 0);
        assert_eq!(saved_frames(10, Some(1)), 9);
        assert_eq!(saved_frames(10, Some(3)), 3, "frames 0, 3 and 6; 9 is the last");
        assert_eq!(saved_frames(100_000, Some(1)), 99_999);
        assert_eq!(saved_frames(100_000, None), 0);
    }

    /// Noise does not compress: an EXR of it is as large as an EXR gets, and within the bound.
    #[test]
    fn exr_and_png_bounds_hold_for_noise() {
        let (w, h) = (37u32, 23u32);
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut noise = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            f32::from_bits((state as u32 & 0x007F_FFFF) | 0x3F80_0000)
        };
        let pixels: Vec<PixelSample> = (0..w * h)
            .map(|_| PixelSample {
                radiance: glam::Vec3::new(noise(), noise(), noise()),
                albedo: glam::Vec3::new(noise(), noise(), noise()),
                normal: glam::Vec3::new(noise(), noise(), noise()),
                depth: noise(),
                ..Default::default()
            })
            .collect();
        let holes: Vec<f32> = (0..w * h).map(|_| noise()).collect();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("noise.exr");
        let frame = Frame { width: w, height: h, pixels };
        write_exr_with(&path, &frame, ExrLayers::ALL, &[("holes.Y", &holes)]).unwrap();
        let written = std::fs::metadata(&path).unwrap().len();
        let pixel_bytes = u64::from(w * h) * 11 * 4;
        assert!(written > pixel_bytes / 2 && written <= exr_bytes(w, h, 11), "{written} bytes");
        let rgba: Vec<u8> = (0..w * h * 4).map(|_| noise().to_bits() as u8).collect();
        let image = crate::report::images::DisplayImage { width: w, height: h, rgba8: &rgba };
        let png = crate::report::images::encode_png(&image).unwrap();
        assert!(png.len() as u64 <= png_bytes(w, h), "{} bytes", png.len());
    }

    /// The 2 MiB filesystem that took 128 frames before ENOSPC: refused before the first one,
    /// naming the flags and the bytes.
    #[test]
    fn saved_frames_beyond_the_free_space_are_refused() {
        let outputs = RenderOutputs {
            views: 32,
            width: 64,
            height: 64,
            channels: 3,
            frames: 100_000,
            save_every: Some(1),
            layer_pictures: 0,
            quilt: false,
        };
        // The viewer page's share follows its template, which changes with the page.
        let bytes = 99_999 * 32 * 54_272 + 32 * (54_272 + 16_453) + 32 * 16_453 + VIEWER_BYTES;
        assert_eq!(outputs.bytes(), bytes);
        let err = outputs.check_fits(Path::new("out"), 2 << 20).unwrap_err().to_string();
        assert_eq!(
            err,
            format!(
                "--frames 100000 with --save-every 1 saves 99999 frame(s) of 32 view(s) (--lf) at 64x64 (--resolution), \
                 3 float channel(s) per EXR (--layers adds up to 8): about 161.8 GiB ({bytes} bytes) with the final \
                 pictures, but the filesystem of --out-dir out has 2.0 MiB (2097152 bytes) free: raise --save-every, \
                 lower --frames, --lf or --resolution, or free space"
            )
        );
        // Each layer picture a view gets adds a PNG to every saved frame and to the final views.
        let with_layers = RenderOutputs { layer_pictures: 2, ..outputs };
        assert_eq!(with_layers.bytes(), bytes + 2 * 16_453 * 32 * 100_000);
        assert!(RenderOutputs { frames: 1, ..outputs }.check_fits(Path::new("out"), 64 << 20).is_ok());
    }

    #[test]
    fn the_free_space_of_a_folder_yet_to_be_made_is_its_parents() {
        let dir = tempfile::tempdir().unwrap();
        assert!(free_bytes(&dir.path().join("not/yet")).is_some_and(|b| b > 0));
    }
}
