//! Host memory of a long frame loop stays flat: 2,000 tiny frames of the reprojection pipeline
//! (2 views of 8×8, SVGF on) through [`LightFieldRenderer`], with the statistics read as
//! `parallax render` reads them.
//!
//! What is measured is the loop's own memory: every byte the Rust code holds, counted by a
//! global allocator of this test binary. The process's resident set is no measure of that: it
//! mixes the driver's and malloc's arenas, which grow in steps of about 1 MB at moments that
//! depend on the machine's load (1.8 to 5.0 MB over these frames in five runs of the same
//! build), so a bound on it sits at the edge of its noise. The resident set of a real run is
//! measured on a GPU instead (docs/RESULTS.md, 3,000 frames on one H200).

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicI64, Ordering};

use parallax_backend::{ExecOptions, SUMMARY_SAMPLE};
use parallax_graph::{LayoutSpec, LightField};
use parallax_passes::camera::{lightfield_views, rig_of};
use parallax_scene::{SceneBvh, TraceSettings, default_scene};

/// Bytes currently allocated through Rust's global allocator by this process.
static LIVE_BYTES: AtomicI64 = AtomicI64::new(0);

/// The system allocator, counting the bytes it hands out and takes back.
struct CountingAllocator;

// SAFETY: every call forwards to `System` with the caller's arguments unchanged; the counter
// is only bookkeeping.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let ptr = unsafe { System.alloc(layout) };
        if !ptr.is_null() {
            LIVE_BYTES.fetch_add(layout.size() as i64, Ordering::Relaxed);
        }
        ptr
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let ptr = unsafe { System.alloc_zeroed(layout) };
        if !ptr.is_null() {
            LIVE_BYTES.fetch_add(layout.size() as i64, Ordering::Relaxed);
        }
        ptr
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        LIVE_BYTES.fetch_sub(layout.size() as i64, Ordering::Relaxed);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let moved = unsafe { System.realloc(ptr, layout, new_size) };
        if !moved.is_null() {
            LIVE_BYTES.fetch_add(new_size as i64 - layout.size() as i64, Ordering::Relaxed);
        }
        moved
    }
}

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

const FRAMES: u32 = 2_000;
/// Frame after which the allocations of the first frames (pipelines, caches, the statistics'
/// samples, reserved whole at the first frame) are in place.
const SETTLED: u32 = 200;
/// Frames between two readings of the live bytes.
const READING_EVERY: u32 = 100;
/// Allowed excess of live bytes over the reading at `SETTLED`, at any reading after it. The
/// loop holds nothing that grows with the frame count (the statistics keep a sample reserved
/// whole at the first frame), and each reading follows `finish()`, so nothing of a frame in
/// flight is held: measured, the excess is 0 bytes at every reading. The bound leaves room for
/// a lazily grown buffer of the driver's Rust wrappers, and catches a leak of 10 bytes a frame
/// by frame 1,840 (a retained report, 7 kB a frame, by frame 203).
const MAX_EXCESS_BYTES: i64 = 16 << 10;

fn live_bytes() -> i64 {
    LIVE_BYTES.load(Ordering::Relaxed)
}

#[test]
fn the_loops_own_memory_stays_flat_over_two_thousand_frames() {
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
    let mut readings = Vec::with_capacity((FRAMES / READING_EVERY) as usize);
    for f in 0..FRAMES {
        if f % READING_EVERY == 0 && f >= SETTLED {
            renderer.finish().unwrap();
            if f == SETTLED {
                settled = live_bytes();
            }
            readings.push((f, live_bytes() - settled));
        }
        renderer.submit(&scene, &views, &TraceSettings { frame: f, ..settings }).unwrap();
    }
    renderer.finish().unwrap();
    readings.push((FRAMES, live_bytes() - settled));
    let stats = renderer.stats();
    assert_eq!(stats.frames(), u64::from(FRAMES), "every frame is counted");
    assert_eq!(stats.gpu_span_ms().sample().len(), (FRAMES as usize).min(SUMMARY_SAMPLE));
    assert!(stats.gpu_span_ms().mean() > 0.0);
    eprintln!("live bytes at frame {SETTLED}: {settled}; excess at later readings (frame, bytes): {readings:?}");
    for &(frame, excess) in &readings {
        assert!(excess < MAX_EXCESS_BYTES, "live bytes grew by {excess} from frame {SETTLED} to frame {frame}");
    }
    context.check_validation().unwrap();
}
