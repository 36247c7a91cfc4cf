//! Host memory of a long frame loop stays flat: 2,000 tiny frames of the reprojection pipeline
//! (2 views of 8×8, SVGF on) through [`LightFieldRenderer`], with the statistics read as
//! `parallax render` reads them. The only test of its binary, so that the process's resident
//! set is this loop's alone.

mod common;

use parallax_backend::{ExecOptions, SUMMARY_SAMPLE};
use parallax_graph::{LayoutSpec, LightField};
use parallax_passes::camera::{lightfield_views, rig_of};
use parallax_scene::{SceneBvh, TraceSettings, default_scene};

const FRAMES: u32 = 2_000;
/// Frame after which the allocations of the first frames (pipelines, driver caches, the
/// statistics' samples) are in place.
const SETTLED: u32 = 200;
/// Allowed growth of the resident set from frame `SETTLED` to the last. Reports kept until the
/// end, as before (`keep_reports(true)`), grow it by 12.8 MB over these frames (7 kB a frame:
/// each report holds every timed pass of its frame); what may still grow is the statistics'
/// bounded samples (6 × 8 bytes × 1,800 frames, 86 kB) and the allocators' steps: the driver's
/// and malloc's arenas grow in steps of about 1 MB that then stay flat (61 kB in one build,
/// 1.8 MB in the next one on the same machine: +0.7 MB by frame 400, +1.1 MB by frame 800, flat
/// to frame 1800). 4 MiB stays a third of what retained reports add.
const MAX_GROWTH_BYTES: u64 = 4 << 20;

/// Resident set of this process (/proc/self/statm, second field, in pages of 4 kB: x86-64 and
/// the usual aarch64 Linux).
fn resident_bytes() -> u64 {
    let statm = std::fs::read_to_string("/proc/self/statm").expect("/proc/self/statm");
    let pages: u64 = statm.split_whitespace().nth(1).and_then(|p| p.parse().ok()).expect("statm's resident field");
    pages * 4096
}

#[test]
fn host_memory_stays_flat_over_two_thousand_frames() {
    let scene = default_scene();
    let bvh = SceneBvh::build(&scene);
    let rig = rig_of(&scene.default_camera(), scene.bounds().center(), None);
    let lf = LightField::new(LayoutSpec::Grid { cols: 2, rows: 1 }, Some(0.02), Some((8, 8)), rig).unwrap();
    let context = common::context(1);
    let options = ExecOptions { frames_in_flight: 2, ..ExecOptions::default() };
    let (mut renderer, _) = common::reprojection_renderer(&context, &scene, &bvh, &lf, options);
    let views = lightfield_views(&lf);
    let settings = TraceSettings { spp: 1, max_depth: 2, ..Default::default() };
    let mut settled = 0;
    for f in 0..FRAMES {
        if f == SETTLED {
            renderer.finish().unwrap();
            settled = resident_bytes();
        }
        renderer.submit(&scene, &views, &TraceSettings { frame: f, ..settings }).unwrap();
    }
    renderer.finish().unwrap();
    let grown = resident_bytes().saturating_sub(settled);
    let stats = renderer.stats();
    assert_eq!(stats.frames(), u64::from(FRAMES), "every frame is counted");
    assert_eq!(stats.gpu_span_ms().sample().len(), (FRAMES as usize).min(SUMMARY_SAMPLE));
    assert!(stats.gpu_span_ms().mean() > 0.0);
    eprintln!(
        "resident set {:.1} MB at frame {SETTLED}, grew {:.1} kB by frame {FRAMES}",
        settled as f64 / 1e6,
        grown as f64 / 1e3
    );
    assert!(grown < MAX_GROWTH_BYTES, "resident set grew {grown} bytes from frame {SETTLED} to {FRAMES}");
    context.check_validation().unwrap();
}
