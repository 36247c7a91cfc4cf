//! Times each image metric of parallax-accuracy on a synthetic pair (a smooth image and the
//! same with per-pixel hash noise), as reported in docs/RESULTS.md:
//! `cargo run --release --example metric_speed -- 1024` (side in pixels, default 1024).

use std::time::Instant;

use parallax_accuracy::flip::flip_rgb8;
use parallax_accuracy::ssim::ssim_rgb8;
use parallax_accuracy::{RgbImage, compare_images};

fn main() {
    let side: usize = std::env::args().nth(1).map_or(1024, |s| s.parse().expect("side in pixels"));
    let (w, h) = (side, side);
    let smooth = |i: usize| [(i % w) as f32 / w as f32, (i / w) as f32 / h as f32, 0.3];
    let noise = |i: usize| ((i as u32).wrapping_mul(2_654_435_761) >> 8) as f32 / 16_777_216.0 - 0.5;
    let reference = RgbImage::new(w, h, (0..w * h).map(smooth).collect());
    let test = RgbImage::new(w, h, (0..w * h).map(|i| smooth(i).map(|c| (c + 0.1 * noise(i)).max(0.0))).collect());
    let time = |what: &str, f: &mut dyn FnMut()| {
        let t = Instant::now();
        f();
        let s = t.elapsed().as_secs_f64();
        println!("{what:>26}: {:8.1} ms  ({:.1} Mpixel/s)", s * 1e3, (w * h) as f64 / s / 1e6);
    };
    println!("{w}x{h} pixels");
    let (mut r8, mut t8) = (Vec::new(), Vec::new());
    time("tonemap both to sRGB8", &mut || {
        r8 = reference.tonemapped_srgb8(1.0);
        t8 = test.tonemapped_srgb8(1.0);
    });
    time("SSIM (11x11, 3 channels)", &mut || println!("{:>26}  {:.6}", "SSIM", ssim_rgb8(&t8, &r8, w, h)));
    time("FLIP (LDR, nv-flip)", &mut || println!("{:>26}  {:.6}", "FLIP", flip_rgb8(&r8, &t8, w, h)));
    time("all (compare_images)", &mut || {
        let m = compare_images(&test, "test", &reference, "reference").expect("same size, finite").metrics();
        println!("{:>26}  PSNR {:.4} dB, relMSE {:.4e}", "", m.psnr_linear_db, m.rel_mse);
    });
}
