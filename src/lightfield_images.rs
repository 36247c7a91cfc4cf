//! Pictures of a light field for people: one PNG per view, the contact sheet (every view, one
//! row per light-field row), the Looking Glass quilt and the wiggle (an animated PNG sweeping
//! through the views), all from display images (RGBA8, sRGB-encoded).

use std::path::Path;

use anyhow::{Context as _, Result, bail};

/// One view's display image: `width × height` RGBA8 texels, row-major.
pub struct DisplayImage<'a> {
    pub width: u32,
    pub height: u32,
    pub rgba8: &'a [u8],
}

fn check_sizes(views: &[DisplayImage<'_>]) -> Result<(u32, u32)> {
    let Some(first) = views.first() else { bail!("no views to put in a picture") };
    let (w, h) = (first.width, first.height);
    if views.iter().any(|v| v.width != w || v.height != h || v.rgba8.len() != (w * h * 4) as usize) {
        bail!("the views differ in size");
    }
    Ok((w, h))
}

fn paste(canvas: &mut image::RgbImage, view: &DisplayImage<'_>, x0: u32, y0: u32) {
    for y in 0..view.height {
        for x in 0..view.width {
            let i = ((y * view.width + x) * 4) as usize;
            canvas.put_pixel(x0 + x, y0 + y, image::Rgb([view.rgba8[i], view.rgba8[i + 1], view.rgba8[i + 2]]));
        }
    }
}

/// The views in light-field order, `columns` per row, 2-pixel gaps.
pub fn write_contact_sheet(path: &Path, views: &[DisplayImage<'_>], columns: u32) -> Result<()> {
    let (w, h) = check_sizes(views)?;
    let gap = 2;
    let columns = columns.clamp(1, views.len() as u32);
    let rows = (views.len() as u32).div_ceil(columns);
    let mut sheet = image::RgbImage::new(columns * w + (columns - 1) * gap, rows * h + (rows - 1) * gap);
    for (k, view) in views.iter().enumerate() {
        paste(&mut sheet, view, (k as u32 % columns) * (w + gap), (k as u32 / columns) * (h + gap));
    }
    sheet.save_with_format(path, image::ImageFormat::Png).with_context(|| format!("cannot write {}", path.display()))
}

/// The quilt grid for `views` views: as square as the views allow, columns first.
pub fn quilt_grid(views: u32) -> (u32, u32) {
    let columns = (views as f64).sqrt().ceil().max(1.0) as u32;
    (columns, views.div_ceil(columns))
}

/// The quilt's file name by the Looking Glass convention: `{stem}_qs{cols}x{rows}a{aspect}.png`.
pub fn quilt_file_name(stem: &str, views: u32, width: u32, height: u32) -> String {
    let (columns, rows) = quilt_grid(views);
    let aspect = width as f64 / height as f64;
    format!("{stem}_qs{columns}x{rows}a{}.png", format!("{aspect:.4}").trim_end_matches('0').trim_end_matches('.'))
}

/// A Looking Glass quilt: view 0 at the bottom left, then left to right and bottom to top, no
/// gaps; cells past the last view stay black.
pub fn write_quilt(path: &Path, views: &[DisplayImage<'_>]) -> Result<()> {
    let (w, h) = check_sizes(views)?;
    let (columns, rows) = quilt_grid(views.len() as u32);
    let mut quilt = image::RgbImage::new(columns * w, rows * h);
    for (k, view) in views.iter().enumerate() {
        let (column, row_from_bottom) = (k as u32 % columns, k as u32 / columns);
        paste(&mut quilt, view, column * w, (rows - 1 - row_from_bottom) * h);
    }
    quilt.save_with_format(path, image::ImageFormat::Png).with_context(|| format!("cannot write {}", path.display()))
}

/// One view as an RGB PNG, in memory (written beside the EXR and embedded in the viewer).
pub fn encode_png(view: &DisplayImage<'_>) -> Result<Vec<u8>> {
    check_sizes(std::slice::from_ref(view))?;
    let rgb: Vec<u8> = view.rgba8.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
    let mut bytes = Vec::new();
    image::ImageEncoder::write_image(
        image::codecs::png::PngEncoder::new(&mut bytes),
        &rgb,
        view.width,
        view.height,
        image::ExtendedColorType::Rgb8,
    )
    .context("cannot encode a view as PNG")?;
    Ok(bytes)
}

/// Most views one sweep of a wiggle shows: a longer row is stepped through evenly, so that the
/// file stays small enough for a slide or a README.
const WIGGLE_STEPS: u32 = 25;
/// Widest frame of a wiggle; wider views are scaled down.
const WIGGLE_WIDTH: u32 = 480;

/// The views a wiggle sweeps through, there and back: the middle row (at most [`WIGGLE_STEPS`]
/// of its views, evenly spaced, the last included), and of a light field with two eye blocks
/// (`eye_cols < cols`) only the left eye's columns, so that the sweep never jumps between the
/// eyes.
pub fn wiggle_order(cols: u32, rows: u32, eye_cols: u32) -> Vec<u32> {
    let row = rows / 2;
    let n = eye_cols.min(cols);
    let step = n.div_ceil(WIGGLE_STEPS).max(1);
    let mut columns: Vec<u32> = (0..n).step_by(step as usize).collect();
    if columns.last() != Some(&(n - 1)) {
        columns.push(n - 1);
    }
    let there: Vec<u32> = columns.iter().map(|c| row * cols + c).collect();
    let back = there.iter().rev().skip(1).take(there.len().saturating_sub(2)).copied();
    there.iter().copied().chain(back).collect()
}

/// Milliseconds each frame of a wiggle of `frames` frames shows: a sweep there and back takes
/// about two seconds, and no frame is shorter than 40 ms (browsers slow faster ones down).
pub fn wiggle_delay_ms(frames: usize) -> u16 {
    (2000 / frames.max(1)).clamp(40, 1000) as u16
}

/// An animated PNG (APNG, shown by every current browser and by GitHub) of `views` in `order`,
/// looping forever; views wider than [`WIGGLE_WIDTH`] are scaled down to it.
pub fn write_wiggle(path: &Path, views: &[DisplayImage<'_>], order: &[u32]) -> Result<()> {
    let (vw, vh) = check_sizes(views)?;
    let (w, h) = if vw > WIGGLE_WIDTH { (WIGGLE_WIDTH, (vh * WIGGLE_WIDTH).div_ceil(vw).max(1)) } else { (vw, vh) };
    let frame = |v: &DisplayImage<'_>| -> Vec<u8> {
        let rgb: Vec<u8> = v.rgba8.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
        if (w, h) == (vw, vh) {
            return rgb;
        }
        let image = image::RgbImage::from_raw(vw, vh, rgb).expect("the checked size");
        image::imageops::resize(&image, w, h, image::imageops::FilterType::Triangle).into_raw()
    };
    if order.is_empty() || order.iter().any(|&v| v as usize >= views.len()) {
        bail!("the wiggle's frames are not views of this light field");
    }
    let file = std::fs::File::create(path).with_context(|| format!("cannot write {}", path.display()))?;
    let encode = || -> std::result::Result<(), png::EncodingError> {
        let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), w, h);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_animated(order.len() as u32, 0)?;
        encoder.set_frame_delay(wiggle_delay_ms(order.len()), 1000)?;
        let mut writer = encoder.write_header()?;
        for &v in order {
            writer.write_image_data(&frame(&views[v as usize]))?;
        }
        writer.finish()
    };
    encode().with_context(|| format!("cannot write {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quilt_names_follow_the_looking_glass_convention() {
        assert_eq!(quilt_file_name("lightfield", 32, 128, 96), "lightfield_qs6x6a1.3333.png");
        assert_eq!(quilt_file_name("q", 100, 768, 432), "q_qs10x10a1.7778.png");
        assert_eq!(quilt_file_name("q", 4, 64, 64), "q_qs2x2a1.png");
    }

    #[test]
    fn a_wiggle_sweeps_the_middle_row_there_and_back() {
        assert_eq!(wiggle_order(4, 1, 4), [0, 1, 2, 3, 2, 1]);
        assert_eq!(wiggle_order(4, 3, 4), [4, 5, 6, 7, 6, 5]);
        // NELF: the left eye's six columns of row 3.
        assert_eq!(wiggle_order(12, 6, 6), [36, 37, 38, 39, 40, 41, 40, 39, 38, 37]);
        assert_eq!(wiggle_order(1, 1, 1), [0]);
        assert_eq!(wiggle_order(2, 1, 2), [0, 1]);
        // Multiscopic: every 4th of 100 views and the last, there and back.
        let long = wiggle_order(100, 1, 100);
        assert_eq!(&long[..3], &[0, 4, 8]);
        assert_eq!((long.len(), long[25], long[26]), (50, 99, 96));
        assert_eq!(wiggle_delay_ms(6), 333);
        assert_eq!(wiggle_delay_ms(200), 40);
    }

    #[test]
    fn a_wiggle_is_an_animated_png_of_the_views() {
        let dir = tempfile::tempdir().unwrap();
        let texels: Vec<[u8; 4]> = vec![[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255]];
        let views: Vec<DisplayImage<'_>> =
            texels.iter().map(|t| DisplayImage { width: 1, height: 1, rgba8: t }).collect();
        let path = dir.path().join("w.png");
        write_wiggle(&path, &views, &[0, 1, 2, 1]).unwrap();
        let mut reader =
            png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap())).read_info().unwrap();
        let control = reader.info().animation_control.unwrap();
        assert_eq!((control.num_frames, control.num_plays), (4, 0));
        let mut frames = Vec::new();
        let mut buffer = vec![0; reader.output_buffer_size().unwrap()];
        for _ in 0..4 {
            reader.next_frame(&mut buffer).unwrap();
            frames.push(buffer[..3].to_vec());
        }
        assert_eq!(frames, [vec![255, 0, 0], vec![0, 255, 0], vec![0, 0, 255], vec![0, 255, 0]]);
        assert!(write_wiggle(&path, &views, &[3]).is_err());
        // Wide views are scaled down to 480 pixels across.
        let wide = vec![200u8; 960 * 2 * 4];
        write_wiggle(&path, &[DisplayImage { width: 960, height: 2, rgba8: &wide }], &[0]).unwrap();
        let reader =
            png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap())).read_info().unwrap();
        assert_eq!((reader.info().width, reader.info().height), (480, 1));
    }

    #[test]
    fn a_view_png_holds_its_rgb() {
        let texel = [10u8, 20, 30, 255];
        let png = encode_png(&DisplayImage { width: 1, height: 1, rgba8: &texel }).unwrap();
        let decoded = image::load_from_memory(&png).unwrap().to_rgb8();
        assert_eq!(decoded.get_pixel(0, 0).0, [10, 20, 30]);
    }

    #[test]
    fn view_zero_sits_bottom_left() {
        let dir = tempfile::tempdir().unwrap();
        let red = [255u8, 0, 0, 255];
        let blue = [0u8, 0, 255, 255];
        let views =
            [DisplayImage { width: 1, height: 1, rgba8: &red }, DisplayImage { width: 1, height: 1, rgba8: &blue }];
        let path = dir.path().join("q.png");
        write_quilt(&path, &views).unwrap();
        let quilt = image::open(&path).unwrap().to_rgb8();
        assert_eq!(quilt.dimensions(), (2, 1));
        assert_eq!(quilt.get_pixel(0, 0).0, [255, 0, 0]);
        assert_eq!(quilt.get_pixel(1, 0).0, [0, 0, 255]);
    }
}
