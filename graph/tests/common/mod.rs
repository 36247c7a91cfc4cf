//! Shared helpers for the graph integration tests.
#![allow(dead_code)]

use parallax_graph::*;

/// Plans and compiles the standard pipeline.
pub fn standard(
    lf: &LightField,
    devices: u32,
    scheme: Scheme,
    assign: AssignStrategy,
    sources: Option<Vec<u32>>,
) -> (Plan, Schedule) {
    let plan = Plan::new(lf, &PlanConfig { devices, scheme, assign, sources }).expect("valid plan");
    let mut graph = Graph::new(plan.topology.clone());
    declare_standard_pipeline(&mut graph);
    let schedule = compile(&graph, &plan).expect("standard pipeline compiles");
    (plan, schedule)
}

pub fn grid(cols: u32, rows: u32, res: u32) -> LightField {
    LightField::new(LayoutSpec::Grid { cols, rows }, None, Some((res, res)), Rig::default()).unwrap()
}

pub fn preset(spec: LayoutSpec, res: u32) -> LightField {
    LightField::new(spec, None, Some((res, res)), Rig::default()).unwrap()
}
