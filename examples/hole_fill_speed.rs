//! Times hole filling with and without the G-buffer's first hits bounding its camera rays
//! (`parallax_passes::bench_holes`: the same synthetic holes of one target view, filled once
//! with the `first_hit` layer as the pipeline does and once tracing camera rays whole, as with
//! the raster G-buffer), as reported in docs/RESULTS.md:
//! `cargo run --release --example hole_fill_speed -- SCENE WxH FRACTION FRAMES SPP`
//! (SCENE a glTF path or `default`; defaults `default 128x128 0.25 8 1`). On the first GPU, or
//! on lavapipe when it is the only device.

use anyhow::{Context as _, Result};
use parallax_backend::{Context, ContextDesc, DeviceSelection};
use parallax_passes::bench_holes;
use parallax_scene::{TraceSettings, load_scene};

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize, default: &str| args.get(i).cloned().unwrap_or_else(|| default.to_string());
    let scene = load_scene(&arg(0, "default")).context("SCENE: a glTF path or `default`")?;
    let size = arg(1, "128x128");
    let (w, h) = size.split_once('x').context("WxH, e.g. 128x128")?;
    let (width, height): (u32, u32) = (w.parse().context("width")?, h.parse().context("height")?);
    let fraction: f64 = arg(2, "0.25").parse().context("FRACTION in [0, 1]")?;
    let frames: usize = arg(3, "8").parse().context("FRAMES")?;
    let spp: u32 = arg(4, "1").parse().context("SPP")?;
    let settings = TraceSettings { spp, ..TraceSettings::default() };
    let context = Context::new(&ContextDesc::from_env(DeviceSelection::Gpus(1)))?;
    let camera = scene.default_camera();
    for first_hits in [false, true] {
        let b = bench_holes(&context, &scene, camera, (width, height), fraction, &settings, frames, first_hits)?;
        println!(
            "{}: {}x{}, {} holes, first hits {}: hole_fill {:.3} ms median of {} frames ({:.1} ns a hole), \
             full-view path_trace {:.3} ms ({:.1} ns a pixel)",
            b.device,
            b.width,
            b.height,
            b.holes,
            b.first_hits,
            b.hole_fill_ms,
            b.frames,
            b.hole_fill_ms * 1e6 / b.holes.max(1) as f64,
            b.path_trace_ms,
            b.trace_ns_per_pixel
        );
    }
    context.check_validation()?;
    Ok(())
}
