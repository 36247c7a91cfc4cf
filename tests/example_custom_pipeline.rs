//! The `custom_pipeline` example runs: its pipeline (the example's own module) on two logical
//! devices, validation on, every pixel checked against the CPU inside `run`, and the PNG it
//! writes decodes at the size of the views' grid, under every scheme (fine-all moves source
//! bands between the devices: the δ-edges cross devices there).

#[path = "../examples/custom_pipeline/pipeline.rs"]
mod pipeline;

use parallax_backend::{DeviceSelection, Validation};
use parallax_graph::Scheme;

#[test]
fn the_example_pipeline_matches_the_cpu_and_writes_its_png_on_two_devices() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("example_custom_pipeline");
    for scheme in Scheme::ALL {
        let out = dir.join(format!("{}.png", scheme.name()));
        let options = pipeline::Options {
            devices: DeviceSelection::FakeDevices(2),
            validation: Validation::Core,
            scheme,
            out: out.clone(),
        };
        let report = pipeline::run(&options).unwrap_or_else(|e| panic!("{}: {e:#}", scheme.name()));
        assert_eq!(report.views, 8);
        assert!(report.delta_edges > 0, "targets read their sources");
        assert!(report.instances >= 8 + 6, "a pattern per view, a blend per target");
        if scheme != Scheme::FineSources {
            assert!(report.copies > 0, "views or bands of device 1 travel to device 0");
        }
        let png = image::open(&out).unwrap();
        // 4×2 views of 64×32 with 2-pixel gaps.
        assert_eq!((png.width(), png.height()), (4 * 64 + 3 * 2, 2 * 32 + 2));
        assert_eq!(report.png_size, (png.width(), png.height()));
    }
}

#[test]
fn the_example_prints_its_schedule_as_dot() {
    let dot = pipeline::schedule_dot(Scheme::MultiSource, 2).unwrap();
    assert!(dot.starts_with("digraph"), "{dot}");
    assert_eq!(dot.matches("subgraph cluster_").count(), 2, "one cluster per device");
    assert!(dot.contains("blend") && dot.contains("pattern"));
    assert!(dot.contains("label=\"δ\""), "the δ-edges are drawn");
}
