//! Declaring a pipeline of your own as a graph and printing its schedule as DOT.
//!
//! This one is not the paper's pipeline: sources are path traced at a high sample count, every
//! target is reprojected from all of its sources (reads of the sources' `radiance` and `depth`
//! are what make the δ-edges), a depth-aware blur runs over each whole view, and a debug
//! histogram pass is kept alive by `side_effect()` although nothing reads its output.
//!
//! Run: `cargo run --example custom_pipeline | dot -Tsvg > custom.svg`

use parallax_graph::*;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let lf = LightField::new("4x2".parse()?, None, Some((64, 32)), Rig::default())?;
    let config =
        PlanConfig { devices: 2, scheme: Scheme::FineAll, assign: AssignStrategy::Compact, sources: Some(vec![0, 7]) };
    let plan = Plan::new(&lf, &config)?;

    let mut g = Graph::new(plan.topology.clone());
    let mut depth = g.image("depth", Format::R32f);
    let mut radiance = g.image("radiance", Format::Rgba32f);
    let mut blurred = g.image("blurred", Format::Rgba16f);
    let mut histogram = g.buffer("histogram", 256 * 4);

    g.pass("raster_depth", Role::All).write(&mut depth).record();
    g.pass("trace_hq", Role::Sources).read(&depth).write(&mut radiance).record();
    g.pass("reproject_all", Role::Targets)
        .read(&depth)
        .read_sources(&depth)
        .read_sources(&radiance)
        .write(&mut radiance)
        .record();
    // A blur needs neighbouring rows, so it reads the whole view and is never split in bands.
    g.pass("depth_blur", Role::All).read_whole(&radiance).read(&depth).write(&mut blurred).whole_view().record();
    g.pass("histogram", Role::All).read(&blurred).write(&mut histogram).side_effect().record();
    g.export(&blurred);

    let schedule = compile(&g, &plan)?;
    let report = schedule.validate();
    assert!(report.is_ok(), "{:?}", report.errors);
    eprintln!(
        "{} pass instances, {} δ-edges, {} copies + {} gathers",
        schedule.instances.len(),
        schedule.delta_edges.len(),
        schedule.dependency_copies().count(),
        schedule.gather_copies().count()
    );
    print!("{}", schedule.to_dot());
    Ok(())
}
