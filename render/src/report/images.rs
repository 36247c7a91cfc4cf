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

/// The views in light-field order, `columns` per row, 2-pixel gaps; with `block` columns, a
/// 16-pixel gap after every `block` columns (NELF's two eye blocks, side by side).
pub fn write_contact_sheet(path: &Path, views: &[DisplayImage<'_>], columns: u32, block: Option<u32>) -> Result<()> {
    let (w, h) = check_sizes(views)?;
    let (gap, block_gap) = (2, 16);
    let columns = columns.clamp(1, views.len() as u32);
    let rows = (views.len() as u32).div_ceil(columns);
    let blocks = block.map_or(0, |b| (columns - 1) / b.max(1));
    let x_of = |c: u32| c * (w + gap) + block.map_or(0, |b| c / b.max(1)) * (block_gap - gap);
    let mut sheet = image::RgbImage::new(
        columns * w + (columns - 1) * gap + blocks * (block_gap - gap),
        rows * h + (rows - 1) * gap,
    );
    for (k, view) in views.iter().enumerate() {
        paste(&mut sheet, view, x_of(k as u32 % columns), (k as u32 / columns) * (h + gap));
    }
    sheet.save_with_format(path, image::ImageFormat::Png).with_context(|| format!("cannot write {}", path.display()))
}

/// `--quilt`'s tiles: as square as the views allow (`auto`), a Looking Glass device's own
/// quilt, or `COLSxROWS`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum QuiltShape {
    Auto,
    Tiles { columns: u32, rows: u32 },
}

impl QuiltShape {
    /// As `--quilt` takes it.
    pub fn spelling(self) -> String {
        match self {
            QuiltShape::Auto => "auto".into(),
            QuiltShape::Tiles { columns, rows } => format!("{columns}x{rows}"),
        }
    }
}

/// The Looking Glass devices' quilts (name, columns, rows).
pub const QUILT_PRESETS: [(&str, u32, u32); 4] = [("go", 11, 6), ("portrait", 8, 6), ("16in", 7, 7), ("65in", 8, 9)];

/// clap value parser of `--quilt`.
pub fn parse_quilt(s: &str) -> Result<QuiltShape, String> {
    if s == "auto" {
        return Ok(QuiltShape::Auto);
    }
    if let Some(&(_, columns, rows)) = QUILT_PRESETS.iter().find(|p| p.0 == s) {
        return Ok(QuiltShape::Tiles { columns, rows });
    }
    let names = QUILT_PRESETS.map(|p| format!("{} ({}x{})", p.0, p.1, p.2)).join(", ");
    let bad = || format!("expected auto, a Looking Glass preset ({names}) or COLSxROWS such as 8x6");
    let (c, r) = s.split_once('x').ok_or_else(bad)?;
    match (c.parse::<u32>(), r.parse::<u32>()) {
        (Ok(columns @ 1..=64), Ok(rows @ 1..=64)) => Ok(QuiltShape::Tiles { columns, rows }),
        (Ok(_), Ok(_)) => Err("a quilt has 1..=64 columns and rows".into()),
        _ => Err(bad()),
    }
}

/// The views a Looking Glass shows, in its order (left to right: a horizontal sweep): a 1D light
/// field's views; of a grid, the row through the rig centre (row ⌊rows/2⌋, the lower middle
/// one of an even count). NELF's two eye blocks are no sweep: refused with the reason.
pub fn quilt_views(cols: u32, rows: u32, nelf: bool) -> Result<Vec<u32>> {
    if nelf {
        return Err(crate::error::UsageError(
            "--quilt: NELF's views are two 6x6 blocks for two eyes 62 mm apart, not one sweep a Looking Glass shows; \
             use a grid (--lf 12x1 or WxH) for a quilt"
                .into(),
        )
        .into());
    }
    let row = rows / 2;
    Ok((0..cols).map(|c| row * cols + c).collect())
}

/// The tiles (columns, rows) of a quilt of `views` views.
pub fn quilt_grid(shape: QuiltShape, views: u32) -> (u32, u32) {
    match shape {
        QuiltShape::Tiles { columns, rows } => (columns, rows),
        QuiltShape::Auto => {
            let columns = (views as f64).sqrt().ceil().max(1.0) as u32;
            (columns, views.div_ceil(columns))
        }
    }
}

/// The quilt's file name by the Looking Glass convention: `{stem}_qs{cols}x{rows}a{aspect}.png`.
pub fn quilt_file_name(stem: &str, (columns, rows): (u32, u32), width: u32, height: u32) -> String {
    let aspect = width as f64 / height as f64;
    format!("{stem}_qs{columns}x{rows}a{}.png", format!("{aspect:.4}").trim_end_matches('0').trim_end_matches('.'))
}

/// A Looking Glass quilt of `columns × rows` tiles: the sweep's first view at the bottom left,
/// then left to right and bottom to top, no gaps. Every tile shows the view nearest its place
/// in the sweep (tile k of T: view round(k · (n − 1) / (T − 1))), so a device's quilt is full
/// whatever the number of views: more tiles repeat neighbours, fewer skip some.
pub fn write_quilt(path: &Path, sweep: &[DisplayImage<'_>], (columns, rows): (u32, u32)) -> Result<()> {
    let (w, h) = check_sizes(sweep)?;
    let tiles = columns * rows;
    let mut quilt = image::RgbImage::new(columns * w, rows * h);
    for k in 0..tiles {
        let v =
            if tiles == 1 { 0 } else { ((k as f64 * (sweep.len() - 1) as f64) / (tiles - 1) as f64).round() as usize };
        let (column, row_from_bottom) = (k % columns, k / columns);
        paste(&mut quilt, &sweep[v], column * w, (rows - 1 - row_from_bottom) * h);
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
        let auto = |n| quilt_grid(QuiltShape::Auto, n);
        assert_eq!(quilt_file_name("lightfield", auto(8), 128, 96), "lightfield_qs3x3a1.3333.png");
        assert_eq!(quilt_file_name("q", auto(100), 768, 432), "q_qs10x10a1.7778.png");
        assert_eq!(quilt_file_name("q", auto(4), 64, 64), "q_qs2x2a1.png");
        let go = parse_quilt("go").unwrap();
        assert_eq!(quilt_file_name("q", quilt_grid(go, 8), 768, 432), "q_qs11x6a1.7778.png");
        assert_eq!(parse_quilt("portrait"), Ok(QuiltShape::Tiles { columns: 8, rows: 6 }));
        assert_eq!(parse_quilt("16in"), Ok(QuiltShape::Tiles { columns: 7, rows: 7 }));
        assert_eq!(parse_quilt("65in"), Ok(QuiltShape::Tiles { columns: 8, rows: 9 }));
        assert_eq!(parse_quilt("5x3"), Ok(QuiltShape::Tiles { columns: 5, rows: 3 }));
        assert!(parse_quilt("big").unwrap_err().contains("go (11x6), portrait (8x6), 16in (7x7), 65in (8x9)"));
        assert!(parse_quilt("0x3").is_err());
    }

    /// A grid's quilt is the row through the rig centre, left to right (the main job's 8x4 went
    /// into a 6x6 quilt with four black tiles, showing the sweep four times); NELF is refused.
    #[test]
    fn a_quilt_sweeps_the_centre_row_and_fills_every_tile() {
        assert_eq!(quilt_views(8, 4, false).unwrap(), (16..24).collect::<Vec<_>>());
        assert_eq!(quilt_views(100, 1, false).unwrap(), (0..100).collect::<Vec<_>>());
        assert!(quilt_views(12, 6, true).unwrap_err().to_string().contains("NELF's views are two 6x6 blocks"));
        let pixels: Vec<[u8; 4]> = (0..3).map(|v| [v * 100, 0, 0, 255]).collect();
        let sweep: Vec<DisplayImage<'_>> =
            pixels.iter().map(|p| DisplayImage { width: 1, height: 1, rgba8: p }).collect();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("q.png");
        write_quilt(&path, &sweep, (3, 2)).unwrap();
        let quilt = image::open(&path).unwrap().to_rgb8();
        // Tiles 0..6 bottom-left first: views 0, 0, 1, 2, 2, 2 → round(k · 2 / 5).
        let red = |x, y| quilt.get_pixel(x, y).0[0];
        assert_eq!([red(0, 1), red(1, 1), red(2, 1), red(0, 0), red(1, 0), red(2, 0)], [0, 0, 100, 100, 200, 200]);
    }

    /// NELF's sheet is its two 6x6 eye blocks side by side, a wider gap between them.
    #[test]
    fn a_sheet_keeps_blocks_apart() {
        let pixel = [255u8, 255, 255, 255];
        let views: Vec<DisplayImage<'_>> =
            (0..4).map(|_| DisplayImage { width: 1, height: 1, rgba8: &pixel }).collect();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.png");
        write_contact_sheet(&path, &views, 4, Some(2)).unwrap();
        let sheet = image::open(&path).unwrap().to_rgb8();
        assert_eq!(sheet.dimensions(), (4 + 2 * 2 + 16, 1));
        let lit: Vec<u32> = (0..sheet.width()).filter(|&x| sheet.get_pixel(x, 0).0[0] == 255).collect();
        assert_eq!(lit, [0, 3, 20, 23], "2 px between views, 16 between the blocks");
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
        write_quilt(&path, &views, (2, 1)).unwrap();
        let quilt = image::open(&path).unwrap().to_rgb8();
        assert_eq!(quilt.dimensions(), (2, 1));
        assert_eq!(quilt.get_pixel(0, 0).0, [255, 0, 0]);
        assert_eq!(quilt.get_pixel(1, 0).0, [0, 0, 255]);
    }
}
