//! Pictures of a light field for people: the contact sheet (every view, one row per light-field
//! row) and the Looking Glass quilt, both from the display images the GPU tonemapped (RGBA8,
//! sRGB-encoded).

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
