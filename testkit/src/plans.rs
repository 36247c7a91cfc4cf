//! Hand-laid plans for the executor's tests, written the way the graph compiler lays out a
//! schedule (a program per device, copies only where producer and consumer differ, barriers by
//! the compiler's rule), so the executor can be exercised, and its synchronisation broken on
//! purpose, without compiling a schedule.
//!
//! The reprojection demo: every view `v` is filled (the last view in row bands spread over all
//! devices, like a fine-grained split), then blended with view `v+1` (a gather from another
//! view), and every finished view is gathered on device 0.
//!
//! The passes are laid by hand, but their kernels bind through slot tokens like any other: the
//! tokens come from a declaration of the demo's two passes ([`demo_kernels`]), which the
//! hand-laid instances instantiate (same pass ids, same access numbers).

use std::sync::Arc;

use parallax_backend::{
    Access, AllocId, CopyId, CopyKind, CrossCopy, DeviceId, DeviceProgram, ExecResource, ExecutionPlan, FamilyId,
    Format, InstanceId, KernelGraph, KernelPlan, Kernels, Op, PassId, PassInstance, Region, ViewId, own_access,
};
use parallax_graph::{Origin, Role, ViewTopology};

use crate::kernels::{FillKernel, ShiftBlendKernel};

/// The demo's kernels, bound to the slots of the declaration its passes instantiate: `fill`
/// (pass 0) writes `radiance` (write 0); `shift_blend` (pass 1) reads its own view's `radiance`
/// (read 0) and its sources' (read 1) and writes `output` (write 0); `radiance` is family
/// [`RADIANCE`], `output` [`OUTPUT`].
fn demo_kernels() -> (FillKernel, ShiftBlendKernel) {
    let mut graph = KernelGraph::with_payload(ViewTopology::all_sources(1, 1, 1));
    let mut radiance = graph.image("radiance", Format::Rgba32f);
    let mut output = graph.image("output", Format::Rgba32f);
    assert_eq!((radiance.family(), output.family()), (RADIANCE, OUTPUT));
    let mut fill = graph.pass("fill", Role::All);
    let fill_kernel = FillKernel { out: fill.write_slot(&mut radiance) };
    assert_eq!(fill.add(), FILL);
    let mut blend = graph.pass("shift_blend", Role::All);
    let blend_kernel = ShiftBlendKernel {
        own: blend.read_slot(&radiance),
        sources: blend.read_sources_slot(&radiance),
        out: blend.write_slot(&mut output),
    };
    assert_eq!(blend.add(), SHIFT_BLEND);
    (fill_kernel, blend_kernel)
}

/// The demo's declared passes.
const FILL: PassId = PassId(0);
const SHIFT_BLEND: PassId = PassId(1);

/// The family of the demo's filled images.
pub const RADIANCE: FamilyId = FamilyId(0);
/// The family of the demo's blended images (gathered on device 0).
pub const OUTPUT: FamilyId = FamilyId(1);

/// Resource ids of the reprojection demo.
#[derive(Clone, Debug)]
pub struct DemoResources {
    /// `radiance[v]`: filled image of view v.
    pub radiance: Vec<AllocId>,
    /// `output[v]`: blended image of view v (gathered on device 0).
    pub output: Vec<AllocId>,
}

/// Device owning view `v` in the demo (round robin).
pub fn demo_device_of_view(view: u32, devices: usize) -> DeviceId {
    DeviceId(view % devices as u32)
}

/// Builds the reprojection demo for `views` views of `width`×`height` on `devices` devices.
pub fn reprojection_demo(views: u32, devices: usize, width: u32, height: u32) -> (KernelPlan, DemoResources) {
    assert!(views >= 1 && devices >= 1 && height >= devices as u32);
    let mut demo = Demo::new(views, devices, width, height);
    demo.fills();
    demo.neighbour_copies();
    demo.blends();
    demo.gathers();
    demo.finish()
}

/// The reprojection demo while it is laid out.
struct Demo {
    plan: KernelPlan,
    /// Phase lists per device; concatenated at the end so every wait follows its signal's phase.
    phases: Vec<[Vec<Op>; 4]>,
    views: u32,
    height: u32,
    resources: DemoResources,
}

impl Demo {
    fn new(views: u32, devices: usize, width: u32, height: u32) -> Self {
        let (fill, blend) = demo_kernels();
        let mut kernels = Kernels::default();
        kernels.insert(FILL, Arc::new(fill));
        kernels.insert(SHIFT_BLEND, Arc::new(blend));
        let mut plan = KernelPlan { kernels, ..KernelPlan::default() };
        let mut image = |name: &str, family: FamilyId, view: u32| {
            plan.resources.push(ExecResource::image(name, family, view, width, height, Format::Rgba32f));
            AllocId(plan.resources.len() as u32 - 1)
        };
        let radiance: Vec<AllocId> = (0..views).map(|v| image("radiance", RADIANCE, v)).collect();
        let output: Vec<AllocId> = (0..views).map(|v| image("output", OUTPUT, v)).collect();
        let phases = (0..devices).map(|_| Default::default()).collect();
        Self { plan, phases, views, height, resources: DemoResources { radiance, output } }
    }

    fn devices(&self) -> usize {
        self.phases.len()
    }

    fn owner(&self, v: u32) -> DeviceId {
        demo_device_of_view(v, self.devices())
    }

    fn all(&self) -> Region {
        Region::new(0, self.height)
    }

    fn add_pass(&mut self, pass: PassInstance, phase: usize) {
        let device = pass.device;
        self.plan.passes.push(pass);
        self.phases[device.index()][phase].push(Op::Pass(InstanceId(self.plan.passes.len() as u32 - 1)));
    }

    /// The copy's producer side in phase `out`, its consumer side in the next one.
    fn add_copy(&mut self, copy: CrossCopy, out: usize) {
        self.plan.copies.push(copy);
        let c = CopyId(self.plan.copies.len() as u32 - 1);
        self.phases[copy.from.index()][out].extend([Op::CopyOut(c), Op::Signal(c)]);
        self.phases[copy.to.index()][out + 1].extend([Op::Wait(c), Op::CopyIn(c)]);
    }

    /// A copy of `rows` of version 1 of `resource` (one id on both devices, as each device
    /// holds every resource of the demo).
    fn copy(&self, resource: AllocId, rows: Region, from: DeviceId, to: DeviceId, kind: CopyKind) -> CrossCopy {
        self.plan.laid_copy((resource, resource), rows, (from, to), kind)
    }

    /// Phase 0: fills; the last view in row bands over every device, each band sent to the
    /// view's owner.
    fn fills(&mut self) {
        let (devices, height) = (self.devices(), self.height);
        let split_view = self.views - 1;
        for v in 0..self.views {
            let bands: Vec<(DeviceId, Region)> = if v == split_view {
                (0..devices as u32)
                    .map(|d| {
                        let y0 = height * d / devices as u32;
                        let y1 = height * (d + 1) / devices as u32;
                        (DeviceId(d), Region::new(y0, y1))
                    })
                    .collect()
            } else {
                vec![(self.owner(v), self.all())]
            };
            let radiance = self.resources.radiance[v as usize];
            for (device, rows) in bands {
                let fill = PassInstance {
                    pass: FILL,
                    name: "fill".into(),
                    view: ViewId(v),
                    region: rows,
                    device,
                    reads: vec![],
                    history_reads: vec![],
                    writes: vec![own_access(0, radiance, rows)],
                };
                self.add_pass(fill, 0);
                if device != self.owner(v) {
                    let copy = self.copy(radiance, rows, device, self.owner(v), CopyKind::Dependency);
                    self.add_copy(copy, 0);
                }
            }
        }
    }

    /// Phase 1→2: each view's radiance goes to the device of the view that reads it.
    fn neighbour_copies(&mut self) {
        for v in 0..self.views {
            let source = (v + 1) % self.views;
            if self.owner(source) != self.owner(v) {
                let radiance = self.resources.radiance[source as usize];
                let copy = self.copy(radiance, self.all(), self.owner(source), self.owner(v), CopyKind::Dependency);
                self.add_copy(copy, 1);
            }
        }
    }

    /// Phase 2: each view blended with the next one.
    fn blends(&mut self) {
        for v in 0..self.views {
            let source = (v + 1) % self.views;
            let all = self.all();
            let access = |decl: u16, alloc: AllocId| own_access(decl, alloc, all);
            let r = &self.resources;
            let blend = PassInstance {
                pass: SHIFT_BLEND,
                name: "shift_blend".into(),
                view: ViewId(v),
                region: all,
                device: self.owner(v),
                reads: vec![
                    access(0, r.radiance[v as usize]),
                    Access { origin: Origin::Source(0), ..access(1, r.radiance[source as usize]) },
                ],
                history_reads: vec![],
                writes: vec![access(0, r.output[v as usize])],
            };
            self.add_pass(blend, 2);
        }
    }

    /// Phase 2→3: the gather of finished views to device 0.
    fn gathers(&mut self) {
        for v in 0..self.views {
            if self.owner(v) != DeviceId(0) {
                let output = self.resources.output[v as usize];
                let copy = self.copy(output, self.all(), self.owner(v), DeviceId(0), CopyKind::Gather);
                self.add_copy(copy, 2);
            }
        }
    }

    fn finish(mut self) -> (KernelPlan, DemoResources) {
        for (d, device_phases) in self.phases.into_iter().enumerate() {
            let ops = device_phases.into_iter().flatten().collect();
            self.plan.devices.push(DeviceProgram { device: DeviceId(d as u32), ops, barriers: Vec::new() });
        }
        self.plan.place_barriers();
        (self.plan, self.resources)
    }
}

/// One fill on device 0 of a `width`×`height` RGBA32F image and its copy to device 1.
pub fn copy_plan(width: u32, height: u32) -> KernelPlan {
    let all = Region::new(0, height);
    let mut plan = ExecutionPlan {
        resources: vec![ExecResource::image("payload", RADIANCE, 0, width, height, Format::Rgba32f)],
        passes: vec![PassInstance {
            pass: FILL,
            name: "fill".into(),
            view: ViewId(0),
            region: all,
            device: DeviceId(0),
            reads: vec![],
            history_reads: vec![],
            writes: vec![own_access(0, AllocId(0), all)],
        }],
        ..ExecutionPlan::default()
    };
    plan.copies = vec![plan.laid_copy((AllocId(0), AllocId(0)), all, (DeviceId(0), DeviceId(1)), CopyKind::Dependency)];
    let program = |device, ops| DeviceProgram { device: DeviceId(device), ops, barriers: Vec::new() };
    let c = CopyId(0);
    plan.devices = vec![
        program(0, vec![Op::Pass(InstanceId(0)), Op::CopyOut(c), Op::Signal(c)]),
        program(1, vec![Op::Wait(c), Op::CopyIn(c)]),
    ];
    plan.place_barriers();
    KernelPlan { plan, kernels: fill_only() }
}

/// The demo's `fill` alone (pass 0, writing its payload as write 0).
fn fill_only() -> Kernels {
    let mut kernels = Kernels::default();
    kernels.insert(FILL, Arc::new(demo_kernels().0));
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

    #[test]
    fn hand_laid_programs_have_the_barriers_a_compiled_schedule_would() {
        // One device: three fills, then three blends that read the fills' images; the first op
        // follows the previous frame.
        let (plan, _) = reprojection_demo(3, 1, 8, 8);
        assert_eq!(plan.devices[0].barriers, [0, 3]);
        // The copy-out reads what the fill wrote; the receiving device's copy-in is its first
        // memory op.
        let plan = copy_plan(8, 8);
        assert_eq!((plan.devices[0].barriers.as_slice(), plan.devices[1].barriers.as_slice()), (&[0, 1][..], &[1][..]));
    }

    #[test]
    fn the_demo_kernels_tokens_bind_the_hand_laid_accesses() {
        let views = 3;
        let (plan, ids) = reprojection_demo(views, 2, 8, 8);
        let (fill, blend) = demo_kernels();
        for p in &plan.passes {
            let v = p.view.index();
            if p.name == "fill" {
                assert_eq!(p.write(fill.out).unwrap().alloc, ids.radiance[v]);
                assert!(p.read(blend.own).is_err(), "a token of shift_blend binds nothing in fill");
            } else {
                assert_eq!(p.read(blend.own).unwrap().alloc, ids.radiance[v]);
                let sources: Vec<AllocId> = p.sources(blend.sources).unwrap().map(|a| a.alloc).collect();
                assert_eq!(sources, [ids.radiance[(v + 1) % views as usize]]);
                assert_eq!(p.write(blend.out).unwrap().alloc, ids.output[v]);
            }
        }
    }
}
