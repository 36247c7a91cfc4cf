//! Kernels and the plan that carries them: the [`PassKernel`] trait, the [`Kernels`] of a plan's
//! declared passes, and [`KernelPlan`], an [`ExecutionPlan`] with its kernels: what the executor
//! runs.
//!
//! The arrows run one way: a kernel records through a [`Recorder`], which reads the data plan
//! ([`ExecutionPlan`]: passes, resources, copies, programs, all derived from the schedule), so
//! this module imports both `plan` and `recorder`, and neither of them names a kernel. The data
//! plan can be built, inspected, serialised and laid by hand without any kernel in sight.

use std::collections::BTreeMap;
use std::ops::{Deref, DerefMut};
use std::sync::Arc;

use parallax_graph::{Role, ViewTopology};

use crate::error::{ExecutionPlanError, Result};
use crate::plan::{
    AllocId, DeviceId, DeviceProgram, ExecResource, ExecutionPlan, InstanceId, Op, PassId, PassInstance, Region,
    ViewId, WriteSlot, own_access,
};
use crate::recorder::Recorder;

/// The GPU work of one pass (by name). Implemented by the passes crate for path tracing,
/// reprojection, denoising, ...; the backend ships the small kernels its own tests use.
pub trait PassKernel: Send + Sync {
    /// Records instance `index` of the plan (`pass` = `plan.pass(index)`).
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, index: InstanceId) -> Result<()>;

    /// Whether the executor hands this kernel's instances to [`Self::record_group`] in groups
    /// rather than one by one to [`Self::record`]: for work whose instances are too small to
    /// fill a GPU alone (hole filling of many targets), which one dispatch can do for all.
    fn records_groups(&self) -> bool {
        false
    }

    /// Records `instances` (of `rec.plan()`) as one op, with no barrier and
    /// no timestamp between them: consecutive instances of one pass in a submission of one
    /// device that no barrier of the plan separates (the schedule puts one wherever an instance
    /// touches what an earlier one wrote, so any order of their work is right), within one
    /// timestamp pair. Only called when [`Self::records_groups`];
    /// a group may have one instance. The default records each instance alone.
    fn record_group(&self, rec: &mut Recorder<'_>, instances: &[InstanceId]) -> Result<()> {
        for &index in instances {
            self.record(rec, rec.plan().pass(index), index)?;
        }
        Ok(())
    }

    /// Whether the kernel writes memory its pass does not declare (a global buffer, say). The
    /// schedule places barriers only where declared accesses conflict; the executor puts one
    /// before and after such a kernel, so it is ordered against everything around it.
    fn touches_undeclared_memory(&self) -> bool {
        false
    }
}

/// The kernels of a plan, by the declared pass whose instances they record. Two plans' kernels
/// are equal when they are the same objects for the same passes.
#[derive(Clone, Default)]
pub struct Kernels(BTreeMap<PassId, Arc<dyn PassKernel>>);

impl PartialEq for Kernels {
    fn eq(&self, other: &Self) -> bool {
        self.0.len() == other.0.len() && self.0.iter().zip(&other.0).all(|((p, a), (q, b))| p == q && Arc::ptr_eq(a, b))
    }
}

impl std::fmt::Debug for Kernels {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Kernels({})", self.0.len())
    }
}

impl Kernels {
    /// Sets `pass`'s kernel.
    pub fn insert(&mut self, pass: PassId, kernel: Arc<dyn PassKernel>) {
        self.0.insert(pass, kernel);
    }

    /// `pass`'s kernel, if it has one.
    pub fn of(&self, pass: PassId) -> Option<&Arc<dyn PassKernel>> {
        self.0.get(&pass)
    }

    /// Drops `pass`'s kernel (a test's way to make a plan the executor refuses).
    #[cfg(test)]
    fn remove(&mut self, pass: PassId) -> Option<Arc<dyn PassKernel>> {
        self.0.remove(&pass)
    }
}

/// An [`ExecutionPlan`] with the kernel of each of its declared passes: what the executor runs
/// ([`crate::Executor::new`]). It reads as its plan (it derefs to it); two are equal when their
/// plans are and their kernels are the same objects.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct KernelPlan {
    /// The data: passes, resources, copies and device programs.
    pub plan: ExecutionPlan,
    /// The kernel of each declared pass, which records its instances.
    pub kernels: Kernels,
}

impl Deref for KernelPlan {
    type Target = ExecutionPlan;

    fn deref(&self) -> &ExecutionPlan {
        &self.plan
    }
}

impl DerefMut for KernelPlan {
    fn deref_mut(&mut self) -> &mut ExecutionPlan {
        &mut self.plan
    }
}

impl KernelPlan {
    /// One pass instance `name` on device 0 writing all of `resource` (version 1) and nothing
    /// else; the other `devices - 1` devices stay idle. What a kernel that runs alone needs:
    /// `kernel` makes it from the slot token of that write, declared like any pass's.
    pub fn single_pass<K: PassKernel + 'static>(
        name: &str,
        kernel: impl FnOnce(WriteSlot) -> K,
        resource: ExecResource,
        devices: usize,
    ) -> Self {
        // Only a pass builder mints slot tokens: a one-pass declaration gives the write's, and the
        // pass id the instance must carry for the token to bind.
        let mut graph = parallax_graph::Graph::new(ViewTopology::all_sources(1, 1, 1));
        let mut target = graph.image(&resource.name, resource.format);
        let mut declared = graph.pass(name, Role::All);
        let write = declared.write_slot(&mut target);
        let pass = declared.add();
        let all = Region::new(0, resource.height);
        let mut kernels = Kernels::default();
        kernels.insert(pass, Arc::new(kernel(write)));
        let mut plan = ExecutionPlan {
            passes: vec![PassInstance {
                pass,
                name: name.to_string(),
                view: ViewId(resource.view),
                region: all,
                device: DeviceId(0),
                reads: vec![],
                writes: vec![own_access(write.index(), AllocId(0), all)],
                history_reads: vec![],
            }],
            resources: vec![resource],
            copies: vec![],
            batches: vec![],
            devices: (0..devices.max(1) as u32)
                .map(|d| DeviceProgram {
                    device: DeviceId(d),
                    ops: if d == 0 { vec![Op::Pass(InstanceId(0))] } else { vec![] },
                    barriers: vec![],
                })
                .collect(),
            history: vec![],
        };
        plan.place_barriers();
        KernelPlan { plan, kernels }
    }

    /// The kernel that records instance `i`. Plans the executor runs are validated
    /// ([`Self::validate`]): every instance's pass has one.
    pub fn kernel(&self, i: InstanceId) -> &Arc<dyn PassKernel> {
        let pass = self.pass(i).pass;
        self.kernels.of(pass).unwrap_or_else(|| panic!("pass {pass} has no kernel: the plan was not validated"))
    }

    /// Checks what only the backend knows: the context's device count, the kernels, and that
    /// every reset is one vkCmdUpdateBuffer of a buffer; and that each program's barriers are
    /// increasing indices of its ops (recording walks the two lists side by side, so a hand-laid
    /// list out of order would lose every barrier after the fault).
    pub fn validate(&self, context_devices: usize) -> std::result::Result<(), ExecutionPlanError> {
        self.plan.validate_programs(context_devices)?;
        if let Some((index, p)) = self.pass_ids().find(|(_, p)| self.kernels.of(p.pass).is_none()) {
            return Err(ExecutionPlanError::MissingKernel { pass: p.name.clone(), index });
        }
        self.plan.validate_resets()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::{copy_plan, overhead_plan};
    use crate::plan::{FamilyId, MAX_RESET_WORDS};

    #[test]
    fn a_plan_for_another_device_count_or_without_its_kernel_is_refused() {
        let plan = copy_plan(8, 8).unwrap();
        assert_eq!(plan.validate(3), Err(ExecutionPlanError::DeviceCount { plan: 2, context: 3 }));
        let mut plan = overhead_plan(1, 2, 8).unwrap();
        let removed = plan.passes[1].pass;
        assert!(plan.kernels.remove(removed).is_some());
        let (index, first) = plan.pass_ids().find(|(_, p)| p.pass == removed).unwrap();
        let pass = first.name.clone();
        assert_eq!(plan.validate(1), Err(ExecutionPlanError::MissingKernel { pass, index }));
    }

    /// A kernel for plans that are validated, never recorded.
    struct Nothing;

    impl PassKernel for Nothing {
        fn record(&self, _: &mut crate::Recorder<'_>, _: &PassInstance, _: InstanceId) -> crate::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn reset_headers_fit_their_buffer() {
        let mut plan =
            KernelPlan::single_pass("count", |_| Nothing, ExecResource::buffer("counts", FamilyId(0), 0, 8), 2);
        plan.resources[0].reset = Some(vec![0, 1]);
        assert_eq!(plan.validate(2), Ok(()));
        plan.resources[0].reset = Some(vec![0, 1, 1]);
        assert_eq!(
            plan.validate(2),
            Err(ExecutionPlanError::ResetTooLong { resource: AllocId(0), words: 3, capacity: 2, max: MAX_RESET_WORDS })
        );
    }
}
