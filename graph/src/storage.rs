//! Storage assignment: which allocation holds each version of each resource on each device.
//!
//! The rule is the simplest one that is always safe: every version a device holds gets an
//! allocation of its own, except a version written in place ([`crate::PassBuilder::modify`]),
//! which stays in the allocation of the version it replaces. So no pass ever writes storage that
//! a pass still to run reads as another version, and `Schedule::validate()` can check that
//! claim on the plain data. Reusing dead allocations for later versions (aliasing) would save
//! memory and needs a liveness proof per device; it is left for when a pipeline's footprint
//! asks for it.
//!
//! A resource read as history keeps its final version in a [`HistoryPair`]: the allocation of the
//! final version is the current half, and a second allocation of the same resource on the same
//! device, holding no version of the frame, is the previous half that history reads see (frame
//! f − 1's final version); the executor swaps the halves' roles by frame parity.

use std::collections::HashMap;

use crate::ids::{AllocId, DeviceId, InstanceId, ResourceId};
use crate::schedule::{Allocation, CrossCopy, HistoryPair, PassInstance};

type Key = (ResourceId, DeviceId, u32);

#[derive(Default)]
struct Storage {
    allocations: Vec<Allocation>,
    by_version: HashMap<Key, AllocId>,
}

impl Storage {
    /// The allocation of `version` of `resource` on `device`, created if it has none.
    fn of(&mut self, resource: ResourceId, device: DeviceId, version: u32) -> AllocId {
        if let Some(&id) = self.by_version.get(&(resource, device, version)) {
            return id;
        }
        let id = AllocId(self.allocations.len() as u32);
        self.allocations.push(Allocation { resource, device, versions: vec![version] });
        self.by_version.insert((resource, device, version), id);
        id
    }

    /// Puts `version` into the allocation that holds `replaced` (an in-place write).
    fn extend(&mut self, resource: ResourceId, device: DeviceId, replaced: u32, version: u32) -> AllocId {
        let id = self.of(resource, device, replaced);
        if let Some(&existing) = self.by_version.get(&(resource, device, version)) {
            return existing;
        }
        let versions = &mut self.allocations[id.index()].versions;
        versions.push(version);
        versions.sort_unstable();
        self.by_version.insert((resource, device, version), id);
        id
    }
}

/// Gives every access and copy of a compiled frame its allocation; returns the allocations and
/// the history pairs among them. `order` is the frame's topological order (in-place writes need
/// the allocation of the version they replace, which an earlier instance created).
pub(crate) fn assign_storage(
    instances: &mut [PassInstance],
    copies: &mut [CrossCopy],
    order: &[InstanceId],
) -> (Vec<Allocation>, Vec<HistoryPair>) {
    let mut storage = Storage::default();
    for &id in order {
        let inst = &mut instances[id.index()];
        let device = inst.device;
        for read in &mut inst.reads {
            read.alloc = storage.of(read.resource, device, read.version);
        }
        for write in &mut inst.writes {
            write.alloc = if write.in_place && write.version > 0 {
                storage.extend(write.resource, device, write.version - 1, write.version)
            } else {
                storage.of(write.resource, device, write.version)
            };
        }
    }
    // Copies after every instance: a copy into a device that also writes the version in place
    // (its own band of a `modify`) must land in that in-place allocation. Assigned at its
    // producer instead, a copy that came first in the order made the version a fresh allocation
    // there, and the in-place write then went into it rather than into the allocation that holds
    // the rows it did not touch.
    for copy in copies.iter_mut() {
        copy.src_alloc = storage.of(copy.resource, copy.from, copy.version);
        copy.dst_alloc = storage.of(copy.resource, copy.to, copy.version);
    }
    // History last: the version it reads is written later in the frame. The previous halves are
    // created after every other allocation, in the order of their current halves.
    let mut currents: Vec<AllocId> = Vec::new();
    for inst in instances.iter() {
        for read in &inst.history_reads {
            currents.push(storage.of(read.resource, inst.device, read.version));
        }
    }
    currents.sort_unstable();
    currents.dedup();
    let mut allocations = storage.allocations;
    let history: Vec<HistoryPair> = currents
        .into_iter()
        .map(|current| {
            let previous = AllocId(allocations.len() as u32);
            let Allocation { resource, device, .. } = allocations[current.index()];
            allocations.push(Allocation { resource, device, versions: Vec::new() });
            HistoryPair { current, previous }
        })
        .collect();
    for inst in instances.iter_mut() {
        for read in &mut inst.history_reads {
            let current = storage.by_version[&(read.resource, inst.device, read.version)];
            read.alloc = history.iter().find(|p| p.current == current).expect("paired above").previous;
        }
    }
    (allocations, history)
}
