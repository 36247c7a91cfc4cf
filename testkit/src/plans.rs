//! Hand-laid plans for the executor's tests, written the way the graph compiler lays out a
//! schedule (op lists per device, copies only where producer and consumer differ), so the
//! executor can be exercised, and its synchronisation broken on purpose, without the graph crate.
//!
//! The reprojection demo: every view `v` is filled (the last view in row bands spread over all
//! devices, like a fine-grained split), then blended with view `v+1` (a gather from another
//! view), and every finished view is gathered on device 0.

use parallax_backend::plan::Kernels;
use parallax_backend::{
    ExecAccess, ExecCopy, ExecOp, ExecPass, ExecResource, ExecutionPlan, Format, PassId, Region, ResourceKind,
};

use crate::kernels::{FillKernel, ShiftBlendKernel};

/// Resource ids of the reprojection demo.
#[derive(Clone, Debug)]
pub struct DemoResources {
    /// `radiance[v]`: filled image of view v.
    pub radiance: Vec<usize>,
    /// `output[v]`: blended image of view v (gathered on device 0).
    pub output: Vec<usize>,
}

/// Device owning view `v` in the demo (round robin).
pub fn demo_device_of_view(view: u32, devices: usize) -> usize {
    view as usize % devices
}

/// Builds the reprojection demo for `views` views of `width`×`height` on `devices` devices.
pub fn reprojection_demo(views: u32, devices: usize, width: u32, height: u32) -> (ExecutionPlan, DemoResources) {
    assert!(views >= 1 && devices >= 1 && height >= devices as u32);
    let mut kernels = Kernels::default();
    kernels.push(FillKernel);
    kernels.push(ShiftBlendKernel);
    let mut plan = ExecutionPlan { devices: vec![Vec::new(); devices], kernels, ..ExecutionPlan::default() };
    let all = Region::new(0, height);
    let mut image = |name: &str, view: u32| {
        plan.resources.push(ExecResource {
            name: name.to_string(),
            view,
            width,
            height,
            format: Format::Rgba32f,
            kind: ResourceKind::Image,
            storage: 0,
            exported: false,
            reset: None,
        });
        plan.resources.len() - 1
    };
    let radiance: Vec<usize> = (0..views).map(|v| image("radiance", v)).collect();
    let output: Vec<usize> = (0..views).map(|v| image("output", v)).collect();
    let owner = |v: u32| demo_device_of_view(v, devices);
    let split_view = views - 1;
    // Phase lists per device; concatenated at the end so every wait follows its signal's phase.
    let mut phases: Vec<[Vec<ExecOp>; 4]> = (0..devices).map(|_| Default::default()).collect();

    let add_pass = |plan: &mut ExecutionPlan, pass: ExecPass| {
        plan.passes.push(pass);
        plan.passes.len() - 1
    };
    let add_copy = |plan: &mut ExecutionPlan, phases: &mut Vec<[Vec<ExecOp>; 4]>, copy: ExecCopy, out: usize| {
        plan.copies.push(copy);
        let c = plan.copies.len() - 1;
        phases[copy.from][out].extend([ExecOp::CopyOut(c), ExecOp::Signal(c)]);
        phases[copy.to][out + 1].extend([ExecOp::Wait(c), ExecOp::CopyIn(c)]);
    };

    // Phase 0: fills; the split view's bands go to its owner.
    for v in 0..views {
        let bands: Vec<(usize, Region)> = if v == split_view {
            (0..devices)
                .map(|d| {
                    let y0 = height * d as u32 / devices as u32;
                    let y1 = height * (d as u32 + 1) / devices as u32;
                    (d, Region::new(y0, y1))
                })
                .collect()
        } else {
            vec![(owner(v), all)]
        };
        for (device, rows) in bands {
            let p = add_pass(
                &mut plan,
                ExecPass {
                    name: "fill".into(),
                    pass: PassId(0),
                    kernel: 0,
                    view: v,
                    rows,
                    device,
                    reads: vec![],
                    history_reads: vec![],
                    writes: vec![ExecAccess::own("radiance", 0, radiance[v as usize], 1, rows)],
                },
            );
            phases[device][0].push(ExecOp::Pass(p));
            if device != owner(v) {
                let copy = ExecCopy {
                    resource: radiance[v as usize],
                    dst: radiance[v as usize],
                    version: 1,
                    rows,
                    from: device,
                    to: owner(v),
                    gather: false,
                };
                add_copy(&mut plan, &mut phases, copy, 0);
            }
        }
    }
    // Phase 1→2: each view's radiance goes to the device of the view that reads it.
    for v in 0..views {
        let source = (v + 1) % views;
        if owner(source) != owner(v) {
            let copy = ExecCopy {
                resource: radiance[source as usize],
                dst: radiance[source as usize],
                version: 1,
                rows: all,
                from: owner(source),
                to: owner(v),
                gather: false,
            };
            add_copy(&mut plan, &mut phases, copy, 1);
        }
    }
    // Phase 2: blends, then the gather of finished views to device 0 (phase 2→3).
    for v in 0..views {
        let source = (v + 1) % views;
        let access = |slot: &str, decl: u16, resource: usize| ExecAccess::own(slot, decl, resource, 1, all);
        let p = add_pass(
            &mut plan,
            ExecPass {
                name: "shift_blend".into(),
                pass: PassId(1),
                kernel: 1,
                view: v,
                rows: all,
                device: owner(v),
                reads: vec![
                    access("radiance", 0, radiance[v as usize]),
                    access("source", 1, radiance[source as usize]),
                ],
                history_reads: vec![],
                writes: vec![access("output", 0, output[v as usize])],
            },
        );
        phases[owner(v)][2].push(ExecOp::Pass(p));
    }
    for v in 0..views {
        if owner(v) != 0 {
            let copy = ExecCopy {
                resource: output[v as usize],
                dst: output[v as usize],
                version: 1,
                rows: all,
                from: owner(v),
                to: 0,
                gather: true,
            };
            add_copy(&mut plan, &mut phases, copy, 2);
        }
    }
    for (d, device_phases) in phases.into_iter().enumerate() {
        plan.devices[d] = device_phases.into_iter().flatten().collect();
    }
    (plan, DemoResources { radiance, output })
}

/// One fill on device 0 of a `width`×`height` RGBA32F image and its copy to device 1.
pub fn copy_plan(width: u32, height: u32) -> ExecutionPlan {
    let all = Region::new(0, height);
    ExecutionPlan {
        resources: vec![ExecResource {
            name: "payload".into(),
            view: 0,
            width,
            height,
            format: Format::Rgba32f,
            kind: ResourceKind::Image,
            storage: 0,
            exported: false,
            reset: None,
        }],
        passes: vec![ExecPass {
            name: "fill".into(),
            pass: PassId(0),
            kernel: 0,
            view: 0,
            rows: all,
            device: 0,
            reads: vec![],
            history_reads: vec![],
            writes: vec![ExecAccess::own("payload", 0, 0, 1, all)],
        }],
        copies: vec![ExecCopy { resource: 0, dst: 0, version: 1, rows: all, from: 0, to: 1, gather: false }],
        devices: vec![
            vec![ExecOp::Pass(0), ExecOp::CopyOut(0), ExecOp::Signal(0)],
            vec![ExecOp::Wait(0), ExecOp::CopyIn(0)],
        ],
        history_pairs: vec![],
        kernels: fill_only(),
    }
}

fn fill_only() -> Kernels {
    let mut kernels = Kernels::default();
    kernels.push(FillKernel);
    kernels
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn demo_plans_validate_and_count_copies() {
        for devices in 1..=3 {
            let (plan, _) = reprojection_demo(3, devices, 32, 32);
            plan.validate(devices).unwrap();
            let expected = match devices {
                1 => 0,
                // bands: 1 (view 2 owned by dev 0, band 1 on dev 1); radiance: v0 reads v1 (1→0),
                // v1 reads v2 (0→1); v2 reads v0 (same); gather: v1 → 0.
                2 => 1 + 2 + 1,
                // bands: 2; radiance: v0←v1, v1←v2, v2←v0; gather: v1, v2.
                _ => 2 + 3 + 2,
            };
            assert_eq!(plan.copies.len(), expected, "devices = {devices}");
        }
        copy_plan(64, 64).validate(2).unwrap();
    }
}
