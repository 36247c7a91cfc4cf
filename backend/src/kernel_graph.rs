//! A graph whose passes carry kernels ([`KernelGraph`]), and its compiled `parallax_graph::Schedule`
//! made into the executor's
//! [`KernelPlan`]: an [`ExecutionPlan`] and its kernels. The schedule's pass instances, copies,
//! device programs (ops and barriers, by device id) and history pairs are taken as they are:
//! nothing is re-planned, and the op order (batching included, `parallax_graph::CompileOptions`)
//! is the order the executor submits. [`KernelPlan::from_schedule`] adds each declared pass's kernel, and each
//! allocation's GPU description: a resource of its declared resource's family (a history pair's
//! previous half described as its current half, the two swapped by frame parity).
//! [`Compiled::compile`] compiles and builds the kernel plan in one call, so that a caller holds
//! what executes without building anything itself.

use std::collections::HashMap;
use std::sync::Arc;

use parallax_graph::{AllocId, Format, Graph, Placement, ProvenSchedule, ResourceDesc, Schedule};

use crate::error::{CompileError, KernelPlanError};
use crate::kernel::{KernelPlan, Kernels, PassKernel};
use crate::plan::{ExecResource, ExecutionPlan, ResourceKind};

/// A render graph whose passes carry their kernels: what the executor runs.
pub type KernelGraph = Graph<Arc<dyn PassKernel>>;

/// A kernel graph compiled for the executor: its proven schedule (what a plan is drawn, summed
/// up and cut into ranks from) and the plan built from it (what `Executor::new` runs), both
/// from one [`Compiled::compile`].
#[derive(Clone, Debug)]
pub struct Compiled {
    pub schedule: ProvenSchedule,
    pub plan: KernelPlan,
}

impl Compiled {
    /// Compiles `graph` under `placement` (`parallax_graph::compile`, which proves the
    /// schedule) and builds the kernel plan from it ([`KernelPlan::from_schedule`]). The error is the
    /// step's own: a `GraphError` of compiling or a `KernelPlanError` of building the kernel plan.
    pub fn compile(graph: &KernelGraph, placement: &dyn Placement) -> Result<Compiled, CompileError> {
        let schedule = parallax_graph::compile(graph, placement)?;
        let plan = KernelPlan::from_schedule(graph, &schedule)?;
        Ok(Compiled { schedule, plan })
    }
}

impl KernelPlan {
    /// The kernel plan of `schedule`, compiled from `graph`. The schedule is proven (`ProvenSchedule`: it
    /// passed `Schedule::validate()` once, when it was compiled or changed): that is the proof of
    /// the plan's ids, rows, op order, barriers, copies, history pairs and storage, so nothing
    /// here checks them again; `KernelPlan::validate` (the executor runs it) adds only what
    /// the backend knows (device count, kernels, resets).
    pub fn from_schedule(graph: &KernelGraph, schedule: &ProvenSchedule) -> Result<KernelPlan, KernelPlanError> {
        let mut kernels = Kernels::default();
        for inst in &schedule.instances {
            if kernels.of(inst.pass).is_some() {
                continue;
            }
            let kernel =
                graph.payload(inst.pass).ok_or_else(|| KernelPlanError::MissingKernel { pass: inst.name.clone() })?;
            // The schedule's order defers a grouped pass's copy-outs to the end of its runs; a
            // kernel that records groups needs that, or each group is one instance.
            if kernel.records_groups() && !schedule.passes[inst.pass.index()].grouped {
                return Err(KernelPlanError::UngroupedKernel { pass: inst.name.clone() });
            }
            kernels.insert(inst.pass, kernel.clone());
        }

        // A history pair's previous half holds no version of the frame: it is its current half's
        // twin, read back through the parity map as the half the frame wrote.
        let twin_of: HashMap<AllocId, AllocId> = schedule.history.iter().map(|p| (p.previous, p.current)).collect();
        let resources: Vec<ExecResource> = (0..schedule.allocations.len() as u32)
            .map(AllocId)
            .map(|a| match twin_of.get(&a) {
                Some(&current) => ExecResource { storage: a.0, exported: false, ..resource_of(schedule, current) },
                None => resource_of(schedule, a),
            })
            .collect();
        let mut devices = schedule.devices.clone();
        devices.sort_by_key(|p| p.device);
        let ids: Vec<u32> = devices.iter().map(|p| p.device.0).collect();
        if ids.iter().enumerate().any(|(i, &d)| d as usize != i) {
            return Err(KernelPlanError::DevicePrograms { found: ids, expected: devices.len() });
        }
        let plan = ExecutionPlan {
            resources,
            passes: schedule.instances.clone(),
            copies: schedule.copies.clone(),
            batches: schedule.batches.clone(),
            devices,
            history: schedule.history.clone(),
        };
        Ok(KernelPlan { plan, kernels })
    }
}

/// The executor resource of allocation `a`.
fn resource_of(schedule: &Schedule, a: AllocId) -> ExecResource {
    let alloc = &schedule.allocations[a.index()];
    let info = schedule.resource(alloc.resource);
    let (width, height, format, kind) = match info.desc {
        ResourceDesc::Image { width, height, format } => (width, height, format, ResourceKind::Image),
        // A buffer is rows of 32-bit words: one row, or one per image row for a row buffer, so
        // its bands are copied like an image's.
        ResourceDesc::Buffer { .. } | ResourceDesc::RowBuffer { .. } => {
            let words = info.desc.row_bytes().div_ceil(4).clamp(1, u64::from(u32::MAX)) as u32;
            (words, info.desc.rows(), Format::R32u, ResourceKind::Buffer)
        }
    };
    ExecResource {
        name: info.name.clone(),
        family: info.family,
        view: info.view.0,
        width,
        height,
        format,
        kind,
        storage: a.0,
        // The allocation on device 0 holding a view's finished version is what the frame loop
        // reads back.
        exported: alloc.device.index() == 0 && info.exported.is_some_and(|v| alloc.versions.contains(&v)),
        // Only the allocation holding the frame's starting contents is reset.
        reset: info.reset.clone().filter(|_| alloc.versions.contains(&0)),
    }
}
