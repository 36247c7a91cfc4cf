//! The execution plan: the part of a compiled `Schedule` the executor needs. Its pass
//! instances, copies, device programs (ops in submission order, with their barriers) and history
//! pairs are the schedule's own, as compiled; what it adds is each allocation's GPU description
//! ([`ExecResource`]). The executor can also be tested with hand-laid plans ([`own_access`],
//! [`ExecutionPlan::laid_copy`]).
//!
//! The plan is data only: the kernel of each declared pass travels beside it
//! ([`crate::KernelPlan`], kernel.rs), because a kernel records through a `Recorder` that reads
//! this plan. kernel.rs imports this module and the recorder; this module names neither.

use std::collections::HashMap;

pub use parallax_graph::{
    Access, AllocId, BatchId, CopyBatch, CopyId, CopyKind, CrossCopy, DeviceId, DeviceProgram, FamilyId, Format,
    HistoryPair, HistorySlot, InstanceId, Op, Origin, PassId, PassInstance, ReadSlot, Region, ResourceId, SourcesSlot,
    ViewId, WriteSlot,
};

pub use crate::error::ExecutionPlanError;

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
/// schedule's `Allocation`s; a history allocation is two of these, see [`ExecutionPlan::history`]).
#[derive(Clone, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub struct ExecResource {
    pub name: String,
    /// The declared resource this is an allocation of (what [`ExecutionPlan::final_output`]
    /// finds outputs by).
    pub family: FamilyId,
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
    /// A `width`×`height` image of `format` of family `family` for `view` (storage 0, not
    /// exported, never reset).
    pub fn image(
        name: impl Into<String>,
        family: FamilyId,
        view: u32,
        width: u32,
        height: u32,
        format: Format,
    ) -> Self {
        Self {
            name: name.into(),
            family,
            view,
            width,
            height,
            format,
            kind: ResourceKind::Image,
            storage: 0,
            exported: false,
            reset: None,
        }
    }

    /// A buffer of family `family` for `view` of at least `bytes` bytes (rounded up to whole
    /// 32-bit words).
    pub fn buffer(name: impl Into<String>, family: FamilyId, view: u32, bytes: u64) -> Self {
        let words = bytes.div_ceil(4).clamp(1, u64::from(u32::MAX)) as u32;
        Self {
            name: name.into(),
            family,
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

    /// Bytes of `rows` whole rows: what a copy (or a chunk of one) of that many rows of this
    /// resource moves. Every byte count of the backend's copies is this one
    /// ([`ExecutionPlan::copy_bytes`], `segments::chunk_bytes`, [`ExecutionPlan::laid_copy`]).
    pub fn rows_bytes(&self, rows: u32) -> u64 {
        self.row_bytes() * u64::from(rows)
    }
}

/// An access of a pass instance's own view in a hand-laid plan: allocation `alloc` over `rows`,
/// the pass's declared read or write number `decl`. A hand-laid plan has no declared resources,
/// so the access names its allocation as its resource (ids that say nothing across devices;
/// nothing in the backend reads them), and writes each allocation once a frame: the access is of
/// version 1.
pub fn own_access(decl: u16, alloc: AllocId, rows: Region) -> Access {
    Access {
        resource: ResourceId(alloc.0),
        version: 1,
        region: rows,
        alloc,
        origin: Origin::Own,
        decl,
        in_place: false,
    }
}

impl ExecutionPlan {
    /// A copy in a hand-laid plan: `rows` of allocation `src` on `from` into allocation `dst` on
    /// `to`, its bytes counted from `src`'s description (already in the plan), which it names as
    /// its resource, of version 1, as [`own_access`] does.
    pub fn laid_copy(
        &self,
        (src, dst): (AllocId, AllocId),
        rows: Region,
        (from, to): (DeviceId, DeviceId),
        kind: CopyKind,
    ) -> CrossCopy {
        let bytes = self.resource(src).rows_bytes(rows.len());
        CrossCopy {
            resource: ResourceId(src.0),
            version: 1,
            region: rows,
            from,
            to,
            src_alloc: src,
            dst_alloc: dst,
            bytes,
            kind,
        }
    }
}

/// A whole frame: resources, pass instances, copies and one program (ops and barriers) per
/// device, each indexed by its id ([`ExecutionPlan::resource`], [`ExecutionPlan::pass`], [`ExecutionPlan::copy`],
/// [`ExecutionPlan::program`]).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct ExecutionPlan {
    /// `resources[a]` is allocation `AllocId(a)`.
    pub resources: Vec<ExecResource>,
    /// `passes[i]` is instance `InstanceId(i)`: the schedule's instances as compiled.
    pub passes: Vec<PassInstance>,
    /// `copies[c]` is copy `CopyId(c)`: the schedule's copies as compiled.
    pub copies: Vec<CrossCopy>,
    /// The schedule's copy batches (`parallax_graph::CopyBatch`): each is moved as one transfer,
    /// its copies side by side in the link's staging, in one submission, with one ownership
    /// transfer and one copy command per allocation. A copy in no batch (a gather, or any copy
    /// of a hand-laid plan that lists none) travels on its own.
    pub batches: Vec<CopyBatch>,
    /// `devices[d]` is device d's program: its ops in submission order and the barriers the
    /// schedule placed between them, recorded as they stand (groups of instances a kernel
    /// records together end at one). A hand-laid plan states its own: the executor looks for no
    /// hazard itself.
    pub devices: Vec<DeviceProgram>,
    /// Double-buffered history allocations: passes of an even frame write `current` and read
    /// history from `previous`; odd frames swap the two. Command buffers are recorded once per
    /// parity, so the swap costs nothing per frame.
    pub history: Vec<HistoryPair>,
}

/// Most words a reset header may have: vkCmdUpdateBuffer writes at most 65536 bytes.
pub const MAX_RESET_WORDS: usize = 65536 / 4;

impl ExecutionPlan {
    /// Places every device program's barriers by the rule compiling a schedule follows
    /// (`parallax_graph::place_barriers`): how a hand-laid plan states them, once its ops are
    /// in order.
    pub fn place_barriers(&mut self) {
        for program in &mut self.devices {
            program.barriers = parallax_graph::place_barriers(&self.passes, &self.copies, &program.ops);
        }
    }

    /// Allocation `a`.
    pub fn resource(&self, a: AllocId) -> &ExecResource {
        &self.resources[a.index()]
    }

    /// Pass instance `i`.
    pub fn pass(&self, i: InstanceId) -> &PassInstance {
        &self.passes[i.index()]
    }

    /// Copy `c`.
    pub fn copy(&self, c: CopyId) -> &CrossCopy {
        &self.copies[c.index()]
    }

    /// The batch of each copy (`[c]` for copy `CopyId(c)`), `None` for a copy in none.
    pub fn batch_of_copies(&self) -> Vec<Option<BatchId>> {
        let mut of = vec![None; self.copies.len()];
        for (b, batch) in self.batches.iter().enumerate() {
            for c in &batch.copies {
                if let Some(slot) = of.get_mut(c.index()) {
                    *slot = Some(BatchId(b as u32));
                }
            }
        }
        of
    }

    /// The order copies are laid out in their links' staging: by id, except that a batch's
    /// copies come together, in its order, where its first copy would be: each batch is one
    /// range of its link's buffer.
    pub fn staging_order(&self) -> Vec<CopyId> {
        let batch_of = self.batch_of_copies();
        let mut order = Vec::with_capacity(self.copies.len());
        for c in (0..self.copies.len()).map(|c| CopyId(c as u32)) {
            match batch_of[c.index()] {
                None => order.push(c),
                Some(b) if self.batches[b.index()].copies.first() == Some(&c) => {
                    order.extend(&self.batches[b.index()].copies);
                }
                Some(_) => {}
            }
        }
        order
    }

    /// Device `d`'s program: its ops in submission order, and its barriers.
    pub fn program(&self, d: DeviceId) -> &DeviceProgram {
        &self.devices[d.index()]
    }

    /// Every allocation with its id, in id order.
    pub fn resource_ids(&self) -> impl Iterator<Item = (AllocId, &ExecResource)> + '_ {
        self.resources.iter().enumerate().map(|(a, r)| (AllocId(a as u32), r))
    }

    /// Every pass instance with its id, in id order.
    pub fn pass_ids(&self) -> impl Iterator<Item = (InstanceId, &PassInstance)> + '_ {
        self.passes.iter().enumerate().map(|(i, p)| (InstanceId(i as u32), p))
    }

    /// Checks the plan's side of what only the backend knows (`KernelPlan::validate` adds the
    /// kernels between the two halves): the context's device count, and that each program's
    /// barriers are increasing indices of its ops (recording walks the two lists side by side,
    /// so a hand-laid list out of order would lose every barrier after the fault).
    pub(crate) fn validate_programs(&self, context_devices: usize) -> Result<(), ExecutionPlanError> {
        if self.devices.len() != context_devices {
            return Err(ExecutionPlanError::DeviceCount { plan: self.devices.len(), context: context_devices });
        }
        if let Some(fault) = self.devices.iter().find_map(DeviceProgram::barrier_list_fault) {
            return Err(ExecutionPlanError::Barriers(fault));
        }
        Ok(())
    }

    /// Checks that every reset is one vkCmdUpdateBuffer of a buffer.
    pub(crate) fn validate_resets(&self) -> Result<(), ExecutionPlanError> {
        for (a, r) in self.resource_ids() {
            let Some(header) = &r.reset else {
                continue;
            };
            if r.kind != ResourceKind::Buffer {
                return Err(ExecutionPlanError::ResetOfImage { resource: a });
            }
            if header.len() > r.width as usize || header.len() > MAX_RESET_WORDS {
                return Err(ExecutionPlanError::ResetTooLong {
                    resource: a,
                    words: header.len(),
                    capacity: r.width,
                    max: MAX_RESET_WORDS,
                });
            }
        }
        Ok(())
    }

    /// Resources each device touches (reads, writes, copies in or out), sorted.
    pub fn resources_of_device(&self, device: DeviceId) -> Vec<AllocId> {
        let mut used: Vec<AllocId> = Vec::new();
        for op in &self.program(device).ops {
            match *op {
                Op::Pass(p) => {
                    let pass = self.pass(p);
                    used.extend(pass.reads.iter().chain(&pass.writes).chain(&pass.history_reads).map(|a| a.alloc));
                }
                Op::CopyOut(c) => used.push(self.copy(c).src_alloc),
                Op::CopyIn(c) => used.push(self.copy(c).dst_alloc),
                Op::Signal(_) | Op::Wait(_) => {}
            }
        }
        // Both halves of a history allocation live where either is used.
        for &HistoryPair { current: a, previous: b } in &self.history {
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
    pub fn parity_map(&self, parity: usize) -> HashMap<AllocId, AllocId> {
        if parity % 2 == 0 {
            return HashMap::new();
        }
        self.history.iter().flat_map(|p| [(p.current, p.previous), (p.previous, p.current)]).collect()
    }

    /// The writes of the final version of the declared resource `family` for `view` in a frame,
    /// with the device of each: one per row band, in instance order. Empty when no pass writes
    /// `family` there.
    pub fn final_writes(&self, family: FamilyId, view: u32) -> Vec<(DeviceId, &Access)> {
        let writes = || {
            self.passes.iter().filter(move |p| p.view == ViewId(view)).flat_map(move |p| {
                p.writes.iter().filter(move |w| self.resource(w.alloc).family == family).map(move |w| (p.device, w))
            })
        };
        let Some(version) = writes().map(|(_, w)| w.version).max() else {
            return Vec::new();
        };
        writes().filter(|(_, w)| w.version == version).collect()
    }

    /// Where each row band of the final version of `family` for `view` can be read after a
    /// frame, as `(device, resource, rows)` in instance order: on device 0 where the band was
    /// written there or gathered there (a copy of that version and those rows), else on the
    /// device that wrote it. `None` when no pass writes `family` there.
    pub fn final_bands(&self, family: FamilyId, view: u32) -> Option<Vec<(DeviceId, AllocId, Region)>> {
        let primary = DeviceId(0);
        let bands: Vec<_> = self
            .final_writes(family, view)
            .into_iter()
            .map(|(device, w)| {
                let gathered = |c: &&CrossCopy| {
                    c.to == primary && c.src_alloc == w.alloc && c.version == w.version && c.region == w.region
                };
                match (device != primary).then(|| self.copies.iter().find(gathered)).flatten() {
                    Some(copy) => (primary, copy.dst_alloc, w.region),
                    None => (device, w.alloc, w.region),
                }
            })
            .collect();
        (!bands.is_empty()).then_some(bands)
    }

    /// The one `(device, resource)` that holds every row band of the final version of `family`
    /// for `view` after a frame ([`Self::final_bands`]): device 0's when the view was written or
    /// gathered there; `None` when its bands are left on several devices or nothing writes it.
    pub fn final_output(&self, family: FamilyId, view: u32) -> Option<(DeviceId, AllocId)> {
        let bands = self.final_bands(family, view)?;
        let (device, resource, _) = bands[0];
        bands.iter().all(|&(d, r, _)| (d, r) == (device, resource)).then_some((device, resource))
    }

    /// Bytes moved by copy `c` (only the copied rows), as the backend lays them out: whole
    /// rows of its source's description ([`ExecResource::rows_bytes`]). That is the copy's
    /// `bytes` but for a buffer whose declared size is no whole number of 32-bit words, which
    /// the schedule counts as declared and the backend allocates, stages and moves rounded up
    /// to whole words (rows of one stride, so a chunk's offset and size agree with its copy's).
    pub fn copy_bytes(&self, c: CopyId) -> u64 {
        let copy = self.copy(c);
        self.resource(copy.src_alloc).rows_bytes(copy.region.len())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::copy_plan;
    use parallax_graph::{Role, ScheduleError, ViewTopology};

    /// Records nothing: these plans are only inspected.
    struct Idle;

    impl crate::PassKernel for Idle {
        fn record(&self, _: &mut crate::Recorder<'_>, _: &PassInstance, _: InstanceId) -> crate::Result<()> {
            Ok(())
        }
    }

    /// One 8×6 view's `layer` written in three row bands over three devices and then, after
    /// `then`, read: exported (gathered on device 0), read per band where it was written, or
    /// read whole (so on device 0, which gets the other bands as dependency copies).
    fn banded(then: &str) -> (ExecutionPlan, FamilyId) {
        use std::sync::Arc;
        let mut graph = crate::KernelGraph::with_payload(ViewTopology::all_sources(1, 8, 6));
        let mut layer = graph.image("layer", Format::Rgba32f);
        graph.pass("write", Role::All).write(&mut layer).kernel(Arc::new(Idle)).add();
        match then {
            "export" => graph.export(&layer),
            "read per band" => {
                graph.pass("read", Role::All).read(&layer).side_effect().kernel(Arc::new(Idle)).add();
            }
            _ => {
                graph.pass("read", Role::All).read_whole(&layer).side_effect().kernel(Arc::new(Idle)).add();
            }
        }
        let placement = parallax_graph::BandedPlacement { devices: 3, bands: 3 };
        (crate::Compiled::compile(&graph, &placement).unwrap().plan.plan, layer.family())
    }

    #[test]
    fn a_gathered_layer_is_read_whole_from_device_0() {
        for then in ["export", "read whole"] {
            let (plan, layer) = banded(then);
            let bands = plan.final_bands(layer, 0).unwrap();
            assert_eq!(bands.iter().map(|b| b.2).collect::<Vec<_>>(), Region::bands(6, 3), "{then}");
            let (device, resource) = plan.final_output(layer, 0).unwrap();
            assert_eq!(device, DeviceId(0), "{then}");
            assert!(bands.iter().all(|&(d, r, _)| (d, r) == (device, resource)), "{then}: {bands:?}");
        }
    }

    #[test]
    fn bands_left_where_they_were_written_are_read_from_their_devices() {
        let (plan, layer) = banded("read per band");
        let bands = plan.final_bands(layer, 0).unwrap();
        assert_eq!(bands.iter().map(|&(d, _, rows)| (d.index(), rows)).collect::<Vec<_>>(), {
            let rows = Region::bands(6, 3);
            vec![(0, rows[0]), (1, rows[1]), (2, rows[2])]
        });
        assert_eq!(plan.final_output(layer, 0), None, "no one allocation holds every band");
        assert_eq!(plan.final_bands(FamilyId(layer.0 + 1), 0), None, "no such family");
        assert_eq!(plan.final_bands(layer, 1), None, "the plan has one view");
    }

    #[test]
    fn barriers_out_of_order_or_past_the_ops_are_refused() {
        let mut plan = copy_plan(8, 8).unwrap().plan;
        assert_eq!(plan.validate_programs(2), Ok(()));
        let ops = plan.devices[0].ops.len();
        let device = DeviceId(0);
        for (barriers, fault) in [
            (vec![1, 0], ScheduleError::BarriersOutOfOrder { device }),
            (vec![0, 0], ScheduleError::BarriersOutOfOrder { device }),
            (vec![ops as u32], ScheduleError::BarrierOutOfRange { device, index: ops as u32, ops }),
        ] {
            plan.devices[0].barriers = barriers;
            assert_eq!(plan.validate_programs(2), Err(ExecutionPlanError::Barriers(fault)));
        }
    }

    #[test]
    fn ids_serialise_as_the_plain_numbers_they_index() {
        let json = serde_json::to_value(copy_plan(8, 8).unwrap().plan).unwrap();
        assert_eq!(
            (&json["devices"][0]["ops"][0], &json["devices"][0]["barriers"][0], &json["devices"][1]["ops"][0]),
            (&serde_json::json!({ "Pass": 0 }), &serde_json::json!(0), &serde_json::json!({ "Wait": 0 }))
        );
        let copy = &json["copies"][0];
        assert_eq!((copy["from"].as_u64(), copy["to"].as_u64()), (Some(0), Some(1)));
        assert!(copy["src_alloc"].is_u64() && json["passes"][0]["writes"][0]["alloc"].is_u64());
        assert_eq!(json["resources"][0]["family"].as_u64(), Some(0));
    }

    #[test]
    fn copy_bytes_counts_only_the_band() {
        let mut plan = copy_plan(8, 8).unwrap();
        plan.copies[0].region = Region::new(2, 5);
        assert_eq!(plan.copy_bytes(CopyId(0)), 8 * 16 * 3);
        // The payload's allocation on device 1 is the copy's destination.
        assert_eq!(plan.resources_of_device(DeviceId(1)), vec![plan.copies[0].dst_alloc]);
    }
}
