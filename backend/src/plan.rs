//! The execution plan: the part of a compiled `Schedule` the executor needs, as plain data with
//! indices resolved. It mirrors the graph crate's op lists one to one (pass, copy-out, signal,
//! wait, copy-in per device, in submission order), so lowering a `Schedule` is a field-by-field
//! translation, and the executor can be tested with hand-written plans.

use std::collections::HashMap;
use std::sync::Arc;

pub use parallax_graph::{Format, HistorySlot, Origin, PassId, ReadSlot, Region, SourcesSlot, WriteSlot};

use crate::error::BackendError;

use crate::recorder::PassKernel;

/// What a plan resource is on the GPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub enum ResourceKind {
    /// A 2D storage image of `width`×`height` texels of `format`.
    Image,
    /// A storage buffer, described as one row (`height` 1) of `width` 32-bit words
    /// (`format` [`Format::R32u`]), so copies and validation treat both kinds alike.
    /// Shaders reach it by address ([`crate::Recorder::buffer_of`]).
    Buffer,
}

/// One allocation: storage of one or more versions of a per-view resource on one device (the
/// schedule's `Allocation`s; a history allocation is two of these, see [`ExecutionPlan::history_pairs`]).
#[derive(Clone, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub struct ExecResource {
    pub name: String,
    pub view: u32,
    pub width: u32,
    pub height: u32,
    pub format: Format,
    pub kind: ResourceKind,
    /// Tells apart allocations of one resource (the schedule's allocation index, or any
    /// distinct number in a hand-laid plan), so a plan change keeps each one's contents.
    pub storage: u32,
    /// A finished output, gathered on device 0 (the graph's `export`): what the frame loop
    /// reads back ([`crate::Executor::submit_frame`]).
    pub exported: bool,
    /// Buffers only: rewritten on the GPU at the start of every frame, before any pass of the
    /// frame touches it, on every device that holds it: the first `reset.len()` words set to
    /// these, the rest zeroed (`Some(vec![])` zeroes it all). For counters and indirect
    /// arguments that passes of the frame accumulate into.
    pub reset: Option<Vec<u32>>,
}

impl ExecResource {
    /// A per-view buffer of at least `bytes` bytes (rounded up to whole 32-bit words).
    pub fn buffer(name: impl Into<String>, view: u32, bytes: u64) -> Self {
        let words = bytes.div_ceil(4).clamp(1, u64::from(u32::MAX)) as u32;
        Self {
            name: name.into(),
            view,
            width: words,
            height: 1,
            format: Format::R32u,
            kind: ResourceKind::Buffer,
            storage: 0,
            exported: false,
            reset: None,
        }
    }

    /// Bytes of the whole resource.
    pub fn bytes(&self) -> u64 {
        self.row_bytes() * u64::from(self.height)
    }

    pub fn row_bytes(&self) -> u64 {
        u64::from(self.width) * self.format.bytes_per_texel()
    }
}

/// One access of a pass instance to a resource version, over a row band.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct ExecAccess {
    /// The allocation (index into [`ExecutionPlan::resources`]).
    pub resource: usize,
    pub version: u32,
    pub rows: Region,
    /// The declared resource's name (what [`ExecutionPlan::final_output`] finds outputs by).
    pub slot: String,
    /// Index of the declared read (or write) this access instantiates among its pass's reads
    /// (or writes): what a slot token ([`ReadSlot`], ...) names.
    pub decl: u16,
    pub origin: Origin,
}

impl ExecAccess {
    /// An access of the instance's own view under slot `slot`, the pass's declared read or
    /// write number `decl`.
    pub fn own(slot: impl Into<String>, decl: u16, resource: usize, version: u32, rows: Region) -> Self {
        Self { resource, version, rows, slot: slot.into(), decl, origin: Origin::Own }
    }
}

/// One pass instance: a pass of the graph run for one view (or a row band of it) on one device.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ExecPass {
    /// Pass name (for timings and messages; the kernel is [`Self::kernel`]).
    pub name: String,
    /// Index of the pass's kernel in [`ExecutionPlan::kernels`].
    pub kernel: usize,
    /// The declared pass this instantiates: the one whose slot tokens bind here.
    pub pass: PassId,
    pub view: u32,
    pub rows: Region,
    pub device: usize,
    /// Reads in declaration order (sources of one read in source order).
    pub reads: Vec<ExecAccess>,
    pub writes: Vec<ExecAccess>,
    /// Reads of the previous frame's final version (its other half, by frame parity).
    pub history_reads: Vec<ExecAccess>,
}

impl ExecPass {
    /// The own-view read its pass declared as `slot`.
    pub fn read(&self, slot: ReadSlot) -> crate::Result<&ExecAccess> {
        let found = self.reads.iter().find(|a| a.decl == slot.index() && a.origin == Origin::Own);
        found.filter(|_| slot.pass() == self.pass).ok_or_else(|| self.unbound(format!("{slot:?}")))
    }

    /// The reads of every source (in the view's source order) its pass declared as `slot`;
    /// none for a view without sources.
    pub fn sources(&self, slot: SourcesSlot) -> crate::Result<impl Iterator<Item = &ExecAccess> + '_> {
        if slot.pass() != self.pass {
            return Err(self.unbound(format!("{slot:?}")));
        }
        Ok(self.reads.iter().filter(move |a| a.decl == slot.index() && matches!(a.origin, Origin::Source(_))))
    }

    /// Last frame's final version its pass declared as `slot`.
    pub fn history_read(&self, slot: HistorySlot) -> crate::Result<&ExecAccess> {
        let found = self.history_reads.iter().find(|a| a.decl == slot.index());
        found.filter(|_| slot.pass() == self.pass).ok_or_else(|| self.unbound(format!("{slot:?}")))
    }

    /// The write its pass declared as `slot`.
    pub fn write(&self, slot: WriteSlot) -> crate::Result<&ExecAccess> {
        let found = self.writes.iter().find(|a| a.decl == slot.index());
        found.filter(|_| slot.pass() == self.pass).ok_or_else(|| self.unbound(format!("{slot:?}")))
    }

    fn unbound(&self, slot: String) -> BackendError {
        BackendError::UnboundSlot { pass: self.name.clone(), slot }
    }
}

/// A transfer of a row band of one resource version from one device to another.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct ExecCopy {
    /// The version's allocation on `from`.
    pub resource: usize,
    /// Its allocation on `to` (the same description as `resource`).
    pub dst: usize,
    pub version: u32,
    pub rows: Region,
    pub from: usize,
    pub to: usize,
    /// A finished view on its way to device 0 (the schedule's `CopyKind::Gather`, Table 1's
    /// "transfer"), not an intermediate result another device reads.
    pub gather: bool,
}

/// One step of a device program.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub enum ExecOp {
    /// Run pass instance `i`.
    Pass(usize),
    /// Producer side of copy `c`: device → shared host buffer.
    CopyOut(usize),
    /// Producer announces that copy `c` is in the host buffer.
    Signal(usize),
    /// Consumer waits for the producer's signal of copy `c`.
    Wait(usize),
    /// Consumer side of copy `c`: shared host buffer → device.
    CopyIn(usize),
}

/// A whole frame: resources, pass instances, copies and one op list per device.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct ExecutionPlan {
    pub resources: Vec<ExecResource>,
    pub passes: Vec<ExecPass>,
    pub copies: Vec<ExecCopy>,
    /// `devices[d]` is device d's op list in submission order.
    pub devices: Vec<Vec<ExecOp>>,
    /// Double-buffered history allocations as (current, previous) resource pairs: passes of an
    /// even frame write `current` and read history from `previous`; odd frames swap the two.
    /// Command buffers are recorded once per parity, so the swap costs nothing per frame.
    pub history_pairs: Vec<(usize, usize)>,
    /// The kernels passes run, by [`ExecPass::kernel`].
    #[serde(skip)]
    pub kernels: Kernels,
}

/// The kernels of a plan. Two plans' kernels are equal when they are the same objects.
#[derive(Clone, Default)]
pub struct Kernels(pub Vec<Arc<dyn PassKernel>>);

impl PartialEq for Kernels {
    fn eq(&self, other: &Self) -> bool {
        self.0.len() == other.0.len() && self.0.iter().zip(&other.0).all(|(a, b)| Arc::ptr_eq(a, b))
    }
}

impl std::fmt::Debug for Kernels {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Kernels({})", self.0.len())
    }
}

impl Kernels {
    /// Adds `kernel`; returns its index.
    pub fn push(&mut self, kernel: impl PassKernel + 'static) -> usize {
        self.0.push(Arc::new(kernel));
        self.0.len() - 1
    }
}

/// What can be inconsistent in a plan. The graph's `Schedule::validate()` checks the planning
/// invariants; these are the ones the executor depends on to not deadlock or read garbage.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ExecutionPlanError {
    #[error("plan has {plan} device programs but the context has {context} devices")]
    DeviceCount { plan: usize, context: usize },
    #[error("{what} {index} refers to missing {missing} {target}")]
    Dangling { what: &'static str, index: usize, missing: &'static str, target: usize },
    #[error("{what} {index}: rows {y0}..{y1} are outside its {height}-row resource {resource}")]
    RowsOutOfRange { what: &'static str, index: usize, resource: usize, y0: u32, y1: u32, height: u32 },
    #[error("pass instance {pass} is in the program of device {listed} but belongs to device {owner}")]
    PassOnWrongDevice { pass: usize, listed: usize, owner: usize },
    #[error("pass instance {0} is not scheduled exactly once")]
    PassNotScheduledOnce(usize),
    #[error("copy {copy} goes from device {from} to itself")]
    CopyToSelf { copy: usize, from: usize },
    #[error("copy {copy}: {op:?} is missing, duplicated or on the wrong device")]
    CopyOpMisplaced { copy: usize, op: &'static str },
    #[error("copy {copy}: producer ops must be CopyOut then Signal, consumer ops Wait then CopyIn")]
    CopyOpOrder { copy: usize },
    #[error("resource {resource} has zero size")]
    EmptyResource { resource: usize },
    #[error("history pair ({current}, {previous}): the two halves differ in size, format or kind")]
    HistoryPairMismatch { current: usize, previous: usize },
    #[error("resource {resource} is an image: only buffers can be reset each frame")]
    ResetOfImage { resource: usize },
    #[error(
        "resource {resource}: a reset header of {words} words is longer than its {capacity}-word buffer or than the {max} words vkCmdUpdateBuffer writes"
    )]
    ResetTooLong { resource: usize, words: usize, capacity: u32, max: usize },
    #[error("resource {resource} is exported but device 0 never holds it: exports are gathered on device 0")]
    ExportNotOnDevice0 { resource: usize },
    #[error("the devices' copy-ins wait for each other's copy-outs in a cycle: no order of submissions can run")]
    WaitCycle,
}

/// Most words a reset header may have: vkCmdUpdateBuffer writes at most 65536 bytes.
pub const MAX_RESET_WORDS: usize = 65536 / 4;

impl ExecutionPlan {
    /// One pass instance `name` on device 0 writing all of `resource` (version 1) and nothing
    /// else; the other `devices - 1` devices stay idle. What a kernel that runs alone needs.
    pub fn single_pass(
        name: impl Into<String>,
        kernel: impl PassKernel + 'static,
        resource: ExecResource,
        devices: usize,
    ) -> Self {
        let all = Region::new(0, resource.height);
        let mut kernels = Kernels::default();
        ExecutionPlan {
            passes: vec![ExecPass {
                name: name.into(),
                kernel: kernels.push(kernel),
                pass: PassId(0),
                view: resource.view,
                rows: all,
                device: 0,
                reads: vec![],
                writes: vec![ExecAccess::own(resource.name.clone(), 0, 0, 1, all)],
                history_reads: vec![],
            }],
            resources: vec![resource],
            copies: vec![],
            devices: (0..devices.max(1)).map(|d| if d == 0 { vec![ExecOp::Pass(0)] } else { vec![] }).collect(),
            history_pairs: vec![],
            kernels,
        }
    }

    /// Checks the invariants the executor relies on.
    pub fn validate(&self, context_devices: usize) -> Result<(), ExecutionPlanError> {
        if self.devices.len() != context_devices {
            return Err(ExecutionPlanError::DeviceCount { plan: self.devices.len(), context: context_devices });
        }
        for (i, r) in self.resources.iter().enumerate() {
            if r.width == 0 || r.height == 0 {
                return Err(ExecutionPlanError::EmptyResource { resource: i });
            }
            if let Some(header) = &r.reset {
                if r.kind != ResourceKind::Buffer {
                    return Err(ExecutionPlanError::ResetOfImage { resource: i });
                }
                if header.len() > r.width as usize || header.len() > MAX_RESET_WORDS {
                    return Err(ExecutionPlanError::ResetTooLong {
                        resource: i,
                        words: header.len(),
                        capacity: r.width,
                        max: MAX_RESET_WORDS,
                    });
                }
            }
        }
        let check_rows = |what, index, resource: usize, rows: Region| {
            let res = self.resources.get(resource).ok_or(ExecutionPlanError::Dangling {
                what,
                index,
                missing: "resource",
                target: resource,
            })?;
            if rows.y0 >= rows.y1 || rows.y1 > res.height {
                return Err(ExecutionPlanError::RowsOutOfRange {
                    what,
                    index,
                    resource,
                    y0: rows.y0,
                    y1: rows.y1,
                    height: res.height,
                });
            }
            Ok(())
        };
        for (i, p) in self.passes.iter().enumerate() {
            if p.device >= self.devices.len() {
                return Err(ExecutionPlanError::Dangling {
                    what: "pass instance",
                    index: i,
                    missing: "device",
                    target: p.device,
                });
            }
            for a in p.reads.iter().chain(&p.writes).chain(&p.history_reads) {
                check_rows("pass instance", i, a.resource, a.rows)?;
            }
        }
        for (i, p) in self.passes.iter().enumerate() {
            if p.kernel >= self.kernels.0.len() {
                return Err(ExecutionPlanError::Dangling {
                    what: "pass instance",
                    index: i,
                    missing: "kernel",
                    target: p.kernel,
                });
            }
        }
        for &(a, b) in &self.history_pairs {
            for r in [a, b] {
                if r >= self.resources.len() {
                    return Err(ExecutionPlanError::Dangling {
                        what: "history pair",
                        index: a,
                        missing: "resource",
                        target: r,
                    });
                }
            }
            if self.resources[a].width != self.resources[b].width
                || self.resources[a].height != self.resources[b].height
                || self.resources[a].format != self.resources[b].format
                || self.resources[a].kind != self.resources[b].kind
            {
                return Err(ExecutionPlanError::HistoryPairMismatch { current: a, previous: b });
            }
        }
        for (i, c) in self.copies.iter().enumerate() {
            check_rows("copy", i, c.resource, c.rows)?;
            check_rows("copy", i, c.dst, c.rows)?;
            for d in [c.from, c.to] {
                if d >= self.devices.len() {
                    return Err(ExecutionPlanError::Dangling { what: "copy", index: i, missing: "device", target: d });
                }
            }
            if c.from == c.to {
                return Err(ExecutionPlanError::CopyToSelf { copy: i, from: c.from });
            }
        }

        let mut pass_seen = vec![0usize; self.passes.len()];
        // Position of each copy op: (device, index in that device's list).
        let mut copy_ops: HashMap<(usize, &'static str), Vec<(usize, usize)>> = HashMap::new();
        for (d, ops) in self.devices.iter().enumerate() {
            for (pos, op) in ops.iter().enumerate() {
                let (copy, kind) = match *op {
                    ExecOp::Pass(p) => {
                        let pass = self.passes.get(p).ok_or(ExecutionPlanError::Dangling {
                            what: "op of device",
                            index: d,
                            missing: "pass instance",
                            target: p,
                        })?;
                        if pass.device != d {
                            return Err(ExecutionPlanError::PassOnWrongDevice {
                                pass: p,
                                listed: d,
                                owner: pass.device,
                            });
                        }
                        pass_seen[p] += 1;
                        continue;
                    }
                    ExecOp::CopyOut(c) => (c, "CopyOut"),
                    ExecOp::Signal(c) => (c, "Signal"),
                    ExecOp::Wait(c) => (c, "Wait"),
                    ExecOp::CopyIn(c) => (c, "CopyIn"),
                };
                if copy >= self.copies.len() {
                    return Err(ExecutionPlanError::Dangling {
                        what: "op of device",
                        index: d,
                        missing: "copy",
                        target: copy,
                    });
                }
                copy_ops.entry((copy, kind)).or_default().push((d, pos));
            }
        }
        if let Some(p) = pass_seen.iter().position(|&n| n != 1) {
            return Err(ExecutionPlanError::PassNotScheduledOnce(p));
        }
        // Every op index is valid by now, and a context has at least one device.
        if !self.devices.is_empty() {
            let on_device0 = self.resources_of_device(0);
            let missing = self.resources.iter().enumerate().find(|(r, res)| res.exported && !on_device0.contains(r));
            if let Some((r, _)) = missing {
                return Err(ExecutionPlanError::ExportNotOnDevice0 { resource: r });
            }
        }
        for (c, copy) in self.copies.iter().enumerate() {
            let at = |kind: &'static str, device: usize| match copy_ops.get(&(c, kind)).map(Vec::as_slice) {
                Some(&[(d, pos)]) if d == device => Ok(pos),
                _ => Err(ExecutionPlanError::CopyOpMisplaced { copy: c, op: kind }),
            };
            let out = at("CopyOut", copy.from)?;
            let signal = at("Signal", copy.from)?;
            let wait = at("Wait", copy.to)?;
            let copy_in = at("CopyIn", copy.to)?;
            if out > signal || wait > copy_in {
                return Err(ExecutionPlanError::CopyOpOrder { copy: c });
            }
        }
        Ok(())
    }

    /// Resources each device touches (reads, writes, copies in or out), sorted.
    pub fn resources_of_device(&self, device: usize) -> Vec<usize> {
        let mut used: Vec<usize> = Vec::new();
        for op in &self.devices[device] {
            match *op {
                ExecOp::Pass(p) => {
                    let pass = &self.passes[p];
                    used.extend(pass.reads.iter().chain(&pass.writes).chain(&pass.history_reads).map(|a| a.resource));
                }
                ExecOp::CopyOut(c) => used.push(self.copies[c].resource),
                ExecOp::CopyIn(c) => used.push(self.copies[c].dst),
                ExecOp::Signal(_) | ExecOp::Wait(_) => {}
            }
        }
        // Both halves of a history allocation live where either is used.
        for &(a, b) in &self.history_pairs {
            if used.contains(&a) || used.contains(&b) {
                used.extend([a, b]);
            }
        }
        used.sort_unstable();
        used.dedup();
        used
    }

    /// Where each resource reads from and writes to in a frame of `parity` (0 even, 1 odd): the
    /// identity but for history pairs, which swap on odd frames.
    pub fn parity_map(&self, parity: usize) -> HashMap<usize, usize> {
        if parity % 2 == 0 {
            return HashMap::new();
        }
        self.history_pairs.iter().flat_map(|&(a, b)| [(a, b), (b, a)]).collect()
    }

    /// Where the final version of the resource written under slot `slot` for `view` can be
    /// read after a frame: `(device, resource)`, on device 0 when it is there (written there or
    /// gathered), else on the device that wrote it.
    pub fn final_output(&self, slot: &str, view: u32) -> Option<(usize, usize)> {
        let writes = || {
            self.passes
                .iter()
                .filter(move |p| p.view == view)
                .flat_map(|p| p.writes.iter().filter(|w| w.slot == slot).map(move |w| (p.device, w)))
        };
        let version = writes().map(|(_, w)| w.version).max()?;
        let finals = || writes().filter(move |(_, w)| w.version == version);
        let on_primary = finals().find(|(d, _)| *d == 0).map(|(_, w)| w.resource).or_else(|| {
            let sources: Vec<usize> = finals().map(|(_, w)| w.resource).collect();
            self.copies.iter().find(|c| c.to == 0 && sources.contains(&c.resource)).map(|c| c.dst)
        });
        on_primary.map(|r| (0, r)).or_else(|| finals().next().map(|(d, w)| (d, w.resource)))
    }

    /// Bytes moved by copy `c` (only the copied rows).
    pub fn copy_bytes(&self, c: usize) -> u64 {
        let copy = &self.copies[c];
        self.resources[copy.resource].row_bytes() * u64::from(copy.rows.len())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::{copy_plan, overhead_plan};

    #[test]
    fn signal_before_copy_out_is_refused() {
        let mut plan = copy_plan(8, 8).unwrap();
        plan.devices[0] = vec![ExecOp::Pass(0), ExecOp::Signal(0), ExecOp::CopyOut(0)];
        assert_eq!(plan.validate(2), Err(ExecutionPlanError::CopyOpOrder { copy: 0 }));
    }

    #[test]
    fn pass_listed_on_another_device_is_refused() {
        let mut plan = copy_plan(8, 8).unwrap();
        plan.devices[1].insert(0, ExecOp::Pass(0));
        assert_eq!(plan.validate(2), Err(ExecutionPlanError::PassOnWrongDevice { pass: 0, listed: 1, owner: 0 }));
    }

    #[test]
    fn rows_outside_the_image_are_refused() {
        let mut plan = copy_plan(8, 8).unwrap();
        plan.copies[0].rows = Region::new(4, 9);
        assert_eq!(
            plan.validate(2),
            Err(ExecutionPlanError::RowsOutOfRange { what: "copy", index: 0, resource: 0, y0: 4, y1: 9, height: 8 })
        );
    }

    #[test]
    fn copy_to_self_and_unscheduled_pass_are_refused() {
        let mut plan = copy_plan(8, 8).unwrap();
        plan.copies[0].to = 0;
        assert_eq!(plan.validate(2), Err(ExecutionPlanError::CopyToSelf { copy: 0, from: 0 }));
        let mut plan = overhead_plan(1, 2, 8).unwrap();
        plan.devices[0].retain(|op| *op != ExecOp::Pass(1));
        assert_eq!(plan.validate(1), Err(ExecutionPlanError::PassNotScheduledOnce(1)));
    }

    /// A kernel for plans that are validated, never recorded.
    struct Nothing;

    impl PassKernel for Nothing {
        fn record(&self, _: &mut crate::Recorder<'_>, _: &ExecPass, _: usize) -> crate::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn exports_must_reach_device_0_and_reset_headers_fit_their_buffer() {
        let mut plan = ExecutionPlan::single_pass("count", Nothing, ExecResource::buffer("counts", 0, 8), 2);
        plan.resources[0].reset = Some(vec![0, 1]);
        plan.resources[0].exported = true;
        assert_eq!(plan.validate(2), Ok(()));
        plan.resources[0].reset = Some(vec![0, 1, 1]);
        assert_eq!(
            plan.validate(2),
            Err(ExecutionPlanError::ResetTooLong { resource: 0, words: 3, capacity: 2, max: MAX_RESET_WORDS })
        );
        plan.resources[0].reset = None;
        plan.passes[0].device = 1;
        plan.devices = vec![vec![], vec![ExecOp::Pass(0)]];
        assert_eq!(plan.validate(2), Err(ExecutionPlanError::ExportNotOnDevice0 { resource: 0 }));
    }

    #[test]
    fn copy_bytes_counts_only_the_band() {
        let mut plan = copy_plan(8, 8).unwrap();
        plan.copies[0].rows = Region::new(2, 5);
        assert_eq!(plan.copy_bytes(0), 8 * 16 * 3);
        // The payload's allocation on device 1 is the copy's destination.
        assert_eq!(plan.resources_of_device(1), vec![plan.copies[0].dst]);
    }
}
